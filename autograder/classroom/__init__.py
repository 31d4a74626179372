"""Grading a whole class: ``python -m autograder batch SUBMISSIONS --out DIR`` grades every
student's submission and leaves in ``DIR`` one ``results/<id>.json`` (Gradescope's results with
extra data), the graded package under ``submissions/<id>/`` and ``grades.csv``; from these,
:mod:`autograder.classroom.report` writes ``DIR/report.html`` (scores, pass rates per check,
the known mistakes, the submissions that failed to run) and :mod:`autograder.classroom.similarity`
finds pairs of submissions whose code is unusually similar once the shipped stubs and the
reference are discounted. Submissions are only read as text here, never imported.
"""
