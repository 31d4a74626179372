"""Compiled kernels where numba is installed, and the switch that turns them off.

A few framework loops that numpy cannot vectorize well (the Schur complement's reduction, the
bundle-adjustment residuals of a trial step) are written as plain Python loops over arrays and
compiled by numba at their first call. :func:`kernels` compiles a module's kernels together;
it returns None where they must run as numpy instead, and the caller then takes its numpy path:

- numba is not installed (no wheel for every Python): said once, as for the other optional
  libraries (:mod:`course.core.peers`);
- ``COURSE_NO_JIT=1``: the autograder's children set it, since compiling takes seconds of a
  check's time limit and writes a cache, and a check needs no speed.

Compiled code keeps numpy's float semantics (``error_model="numpy"``: a division by zero gives
inf or nan, as in the numpy path) and is cached on disk where numba may write its cache (next to
the module, else in the user's cache folder); elsewhere it is compiled once per process.
"""

import os

from course.core import peers

#: set to 1, every kernel runs its numpy path
NO_JIT = "COURSE_NO_JIT"

_compiled: dict = {}


def kernels(namespace: dict, names: tuple) -> tuple | None:
    """``namespace[name]`` compiled for each of ``names``, or None (the module docstring says when).

    ``namespace`` is the calling module's ``globals()``. Kernels call one another by their global
    names, and a compiled kernel can only call compiled ones: so every name is rebound, in
    ``namespace``, to its compiled version (which also runs when called from Python).
    """
    if os.environ.get(NO_JIT) == "1":
        return None
    if not peers.installed("numba"):
        peers.announce("numba")
        return None
    key = (namespace["__name__"], names)
    if key not in _compiled:
        import numba  # here: importing it takes a third of a second

        def compiled(cache):  # numba compiles at the first call; this only wraps
            return [numba.njit(namespace[name], cache=cache, error_model="numpy") for name in names]

        try:
            dispatchers = compiled(cache=True)
        except RuntimeError:  # "no locator available": nowhere to write the cache (a read-only install)
            dispatchers = compiled(cache=False)
        namespace.update(zip(names, dispatchers))
        _compiled[key] = tuple(dispatchers)
    return _compiled[key]
