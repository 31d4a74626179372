"""Peer back ends: the same problem, from the same start, through other libraries.

One module per (library, problem): ``solve(data, method, max_iterations, **options) ->
RunResult`` in the trace schema of our own solvers. Which back end solves which problem
with which methods is listed once, in :mod:`course.backends.registry`; a back end's module (and
its library) is imported only when it runs.
"""
