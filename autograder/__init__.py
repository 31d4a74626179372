"""The course autograder: ``python -m autograder --impl solutions|exercises|PATH``.

Student code never runs in the grading process. For each check the parent starts a
child process (:mod:`autograder.child`, under a time and memory limit, see
:mod:`autograder.sandbox`) that loads the implementation, runs the check's calls and
writes the raw outputs as plain float arrays; the parent reads them with
``numpy.load(..., allow_pickle=False)``, computes the reference itself (from
``solutions``), and alone writes the results: a terminal table and Gradescope's
``results.json`` (:mod:`autograder.report`).

Modules: ``checks/`` (the registry, one module per exercise), ``feedback.py``
(tolerance comparisons that produce feedback), ``grade.py`` (runs the checks on two
workers), ``tasks/`` (framework runs such as a whole ``minimize`` that the child
performs with the student's code, one module per exercise), ``report.py``,
``sandbox.py``, ``child.py``.

This ``__init__`` imports nothing on purpose: the child imports ``autograder.child``
and must set its resource limits before numpy loads. Use ``autograder.grade.grade``.
"""
