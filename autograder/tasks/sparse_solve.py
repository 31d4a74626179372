"""The upper triangle and the sparse Cholesky solver, with ``qdldl.Solver`` counted
(``checks/sparse_solve.py``)."""

from contextlib import contextmanager

import numpy as np

from autograder.tasks.common import OutputError, encode_text, exclusive


def upper_triangle(H, as_sparse, impl):
    """``sparse_solve.upper_triangle_csc`` of ``H`` given dense or as a scipy CSR matrix."""
    import scipy.sparse as sp

    H = np.asarray(H, dtype=float)
    given = sp.csr_matrix(H) if as_sparse else H
    out = impl.module("sparse_solve").upper_triangle_csc(given)
    is_sparse = sp.issparse(out)
    values = out.toarray() if is_sparse else np.asarray(out)
    return {
        "M": values,
        "sparse": float(is_sparse),
        "csc": float(is_sparse and getattr(out, "format", "") == "csc"),
        "format": encode_text(getattr(out, "format", type(out).__name__)),
    }


_COUNTING: dict = {}  # qdldl.Solver -> its counting subclass (one per process, so captures keep counting)


def _counting_solver(original):
    """A subclass of ``qdldl.Solver`` counting the objects made (``made``)."""
    if original not in _COUNTING:
        class Solver(original):
            made = 0

            def __init__(self, *args, **kwargs):
                Solver.made += 1
                super().__init__(*args, **kwargs)

        Solver.__module__, Solver.__qualname__ = original.__module__, original.__qualname__
        _COUNTING[original] = Solver
    return _COUNTING[original]


@contextmanager
def _sparse_solve_counted(impl):
    """``(module, counter)``: the implementation's ``sparse_solve`` with ``qdldl.Solver``
    counted (``counter.made``), or ``counter`` None where it cannot be (another thread runs).

    The counting class is installed in ``qdldl`` before the student's module is imported,
    so that ``from qdldl import Solver`` at import time takes it too, and over every name
    of the module bound to the original; both are restored afterwards.
    """
    import qdldl

    if not exclusive():
        yield impl.module("sparse_solve"), None
        return
    original = qdldl.Solver
    counter = _counting_solver(original)
    counter.made = 0
    qdldl.Solver = counter
    module = None
    try:
        module = impl.module("sparse_solve")
        for name, value in list(vars(module).items()):
            if value is original:
                setattr(module, name, counter)
        yield module, counter
    finally:
        qdldl.Solver = original
        if module is not None:
            for name, value in list(vars(module).items()):
                if value is counter:
                    setattr(module, name, original)


def _solve_once(solver, shape, indices, indptr, data, b, what):
    import scipy.sparse as sp

    H = sp.csc_matrix((np.array(data, dtype=float), np.array(indices), np.array(indptr)), shape=tuple(shape))
    dx = solver.solve(H, np.array(b, dtype=float))
    if sp.issparse(dx):
        raise OutputError(f"returned a scipy sparse matrix on {what}, expected a (n,) array")
    return dx


def sparse_solves(shape, indices, indptr, values, rhs, impl):
    """One ``SparseCholeskySolver`` solving ``H_k dx = -b_k`` for k = 0, 1, ...

    Every ``H_k`` is the upper triangle in CSC with the same pattern (``indices``,
    ``indptr``) and its own ``values[k]``. Returns ``dx0, dx1, ...`` and
    ``solvers_created``, the number of ``qdldl.Solver`` objects made (NaN when they
    could not be counted).
    """
    out = {}
    with _sparse_solve_counted(impl) as (module, counter):
        solver = module.SparseCholeskySolver()
        for k, (data, b) in enumerate(zip(values, rhs)):
            out[f"dx{k}"] = _solve_once(solver, shape, indices, indptr, data, b, f"call {k + 1}")
        out["solvers_created"] = float(counter.made) if counter is not None else float("nan")
    return out


def alternating_solves(first, second, impl):
    """Two ``SparseCholeskySolver`` objects, one per pattern, called alternately.

    ``first`` and ``second`` are ``(shape, indices, indptr, values, rhs)`` as for
    :func:`sparse_solves`; the calls go first solver, second solver, first, second, ...
    Returns ``a0, a1, ...`` (the first solver's steps), ``b0, b1, ...`` (the second's)
    and ``solvers_created``.
    """
    out = {}
    with _sparse_solve_counted(impl) as (module, counter):
        solvers = (module.SparseCholeskySolver(), module.SparseCholeskySolver())
        for k in range(len(first[3])):
            for prefix, solver, (shape, indices, indptr, values, rhs), which in (
                    ("a", solvers[0], first, "first"), ("b", solvers[1], second, "second")):
                out[f"{prefix}{k}"] = _solve_once(solver, shape, indices, indptr, values[k], rhs[k],
                                                  f"the {which} solver's call {k + 1}")
        out["solvers_created"] = float(counter.made) if counter is not None else float("nan")
    return out


def pattern_solves(shape, patterns, rhs, impl):
    """One ``SparseCholeskySolver`` solving ``H_k dx = -b_k`` where the pattern changes between calls:
    ``patterns[k]`` is ``(indices, indptr, data)`` of the k-th upper triangle (CSC). Returns ``dx0,
    dx1, ...`` and ``solvers_created`` (NaN when they could not be counted)."""
    out = {}
    with _sparse_solve_counted(impl) as (module, counter):
        solver = module.SparseCholeskySolver()
        for k, ((indices, indptr, data), b) in enumerate(zip(patterns, rhs)):
            out[f"dx{k}"] = _solve_once(solver, shape, indices, indptr, data, b, f"call {k + 1}")
        out["solvers_created"] = float(counter.made) if counter is not None else float("nan")
    return out
