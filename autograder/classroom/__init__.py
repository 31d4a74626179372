"""Grading a whole class: the submissions read (``intake``: a folder of uploads or
Gradescope's export), graded in one run (``batch``), recorded (``gradebook``:
``results/<id>.json`` per student and ``grades.csv``), joined across machines (``merge``)
and summed up (``report``: ``report.html`` with scores, pass rates per check, the known
mistakes, the submissions that failed to run, and the pairs ``similarity`` finds whose code
is unusually similar once the shipped stubs and the reference are discounted, and the files
that reproduce the reference), exported to a learning platform (``export``: Canvas, Moodle),
and returned to each student (``student_feedback``: ``feedback/<id>/``).
Around the grading: the instructor's ``roster`` (who, when, extensions) and ``overrides`` (a
check's points and why), applied to the records with the late penalty (``gradebook.adjust``).
The written answers (``written``: the command line): the ``questions`` of the lessons and the answer
sheet students hand in, the filled sheets gathered per question (``answers``), the ``rubric`` of each
question and the instructor's ``marks``, merged into the records as one test per question.
Submissions are only read as text here, never imported.
"""
