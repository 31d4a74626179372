"""Which sparse solve of ``H dx = -b`` a problem runs: the one place that decides it.

``choose(name, sparse_module, unknowns) -> (solver, label)``: ``solver`` has ``solve(H_upper, b) -> dx``
(``H_upper`` the upper triangle of H, CSC, (n, n); ``dx`` (n,)) and ``label`` names what runs, for
``compare``'s ``solve`` column. The names (``SOLVES``):

- ``ours``: the implementation's ``sparse_solve.SparseCholeskySolver`` (chapter 2, qdldl's simplicial
  ``L D L^T``), what the student wrote; scipy's SuperLU where qdldl is not installed (said once).
- ``cholmod``: CHOLMOD's supernodal ``L L^T`` (``course.solver.cholmod``, through cvxopt); where
  cvxopt is not installed, ``ours`` (said once).
- ``superlu``: scipy's SuperLU (``course.solver.superlu``).
- ``auto`` (the default): ``cholmod`` from ``AUTO_MIN_UNKNOWNS`` unknowns up where cvxopt is
  installed, else ``ours``. A small graph keeps the student's solver; on a large one the supernodal
  factor is several times faster (measured, one numeric factorization and solve, same H:
  sphere2500 n = 15000, qdldl 152 ms, CHOLMOD 26 ms; torus3D n = 30000, 510 against 63 ms;
  parking-garage n = 9966, 9.1 against 6.4 ms; intel n = 2187, 1.1 ms both; smallGrid3D
  n = 750, 1.6 against 0.7 ms).
"""

import importlib

from course.core import peers
from course.core.solve_names import AUTO_MIN_UNKNOWNS, SOLVES

__all__ = ["AUTO_MIN_UNKNOWNS", "SOLVES", "UnknownSolveError", "check_name", "choose", "label_of"]


class UnknownSolveError(ValueError):
    """A sparse solve's name that is not one of ``SOLVES``."""


def check_name(name) -> str:
    """``name`` (``None`` means ``auto``) if it is one of ``SOLVES``, else ``UnknownSolveError`` listing them."""
    name = "auto" if name is None else name
    if name not in SOLVES:
        raise UnknownSolveError(f"unknown sparse solve {name!r}; choose one of {', '.join(SOLVES)}")
    return name


def label_of(solver) -> str:
    """The label of a solver object given in place of a name: its ``label`` attribute, else its class name."""
    return str(getattr(solver, "label", type(solver).__name__))


def choose(name, sparse_module, unknowns: int):
    """``(solver, label)`` for a system of ``unknowns`` unknowns: ``name`` one of ``SOLVES`` (``None``:
    ``auto``), or a solver object (kept, labelled by :func:`label_of`). ``sparse_module`` is the
    implementation's ``sparse_solve``; its ``SparseCholeskySolver`` is made only where it runs."""
    from course.solver.cholmod import CholmodSolver
    from course.solver.superlu import SuperLUSolver

    if name is not None and not isinstance(name, str):
        return name, label_of(name)
    name = check_name(name)
    if name == "auto":
        name = "cholmod" if unknowns >= AUTO_MIN_UNKNOWNS and peers.installed("cvxopt") else "ours"
    if name == "cholmod":
        if peers.installed("cvxopt"):
            return CholmodSolver(), "cholmod"
        peers.announce("cvxopt")
        name = "ours"
    if name == "superlu":
        return SuperLUSolver(), "superlu"
    if peers.installed("qdldl"):
        importlib.import_module("qdldl")  # the exercise imports it in its first solve: not in a run's time
        return sparse_module.SparseCholeskySolver(), "ours"
    peers.announce("qdldl")
    return SuperLUSolver(), "superlu"
