"""A supernodal sparse Cholesky for large systems with fill-in: CHOLMOD, through cvxopt.

``CholmodSolver().solve(H_upper, b)`` has the interface of the exercise's
``sparse_solve.SparseCholeskySolver``: ``dx`` (n,) with ``H dx = -b``, from the upper triangle
of H (CSC, (n, n)). CHOLMOD (SuiteSparse, the factorization g2o and Ceres use) orders H by
AMD and factorizes it in dense supernodal blocks; the pattern's analysis is kept and redone
only when the pattern changes. Where a graph's edges join far-apart poses (random wrong loop
closures), L fills in and a simplicial LDL^T such as qdldl slows down ten-fold; the supernodal
factor does not (sphere2500 with 20% random closures: 0.3 s against qdldl's 3.6 s, this
machine). cvxopt comes with the ``peers`` extra where it has a wheel (``peers.installed``).

``analyse(H_upper)`` does the analysis ahead of the first solve, from the pattern alone: a problem
whose pattern is fixed when it is made calls it there (:func:`analyse_ahead`), as GTSAM's optimizers
compute their elimination ordering when they are made, not in their iterations.
"""

import numpy as np
import scipy.sparse as sp

from course.core.errors import SingularSystemError


class CholmodSolver:
    """``H dx = -b`` by CHOLMOD's supernodal ``L L^T``, the symbolic analysis kept per pattern.

    CHOLMOD reads the upper triangle as it is (``uplo="U"``). For a pattern seen before, the
    kept cvxopt matrix gets the new values in place (its ``V``, in the CSC order of ``H_upper``
    with sorted indices): building a cvxopt matrix from triplets sorts them, and costs more than
    the numeric factorization of a pose graph's H. The pattern is compared with the analysed one
    as given (``indptr``, ``indices``); a pattern given with unsorted indices keeps the order that
    sorts them.
    """

    label = "cholmod"  # compare's name for it (``course.solver.choice``)

    def __init__(self):
        import cvxopt  # here, not in ``solve``: a run's timed iterations do not pay the import
        from cvxopt import cholmod

        self._cvxopt, self._cholmod = cvxopt, cholmod
        self._indptr: np.ndarray | None = None  # the analysed pattern, as it was given
        self._indices: np.ndarray | None = None
        self._order: np.ndarray | None = None  # the order of ``data`` that sorts each column's rows, or None
        self._matrix = None
        self._symbolic = None

    def _same_pattern(self, upper) -> bool:
        if self._indptr is None or self._indices is None:
            return False
        return np.array_equal(upper.indptr, self._indptr) and np.array_equal(upper.indices, self._indices)

    def analyse(self, H_upper) -> None:
        """The symbolic analysis (ordering, supernodes) of ``H_upper``'s pattern, its values unused."""
        upper = H_upper if sp.isspmatrix_csc(H_upper) else sp.csc_matrix(H_upper)
        if not self._same_pattern(upper):
            self._analyse(upper)

    def _analyse(self, upper) -> None:
        n = upper.shape[0]
        indptr, indices = np.array(upper.indptr), np.array(upper.indices)
        self._order = None
        if not upper.has_sorted_indices:  # the position each sorted entry comes from
            numbered = sp.csc_matrix((np.arange(upper.nnz, dtype=float), indices, indptr), shape=upper.shape)
            numbered = numbered.sorted_indices()
            self._order = numbered.data.astype(np.int64)
            rows = numbered.indices
        else:
            rows = indices
        columns = np.repeat(np.arange(n), np.diff(indptr))
        self._matrix = self._cvxopt.spmatrix(1.0, rows.astype(np.int64), columns, (n, n))
        self._symbolic = self._cholmod.symbolic(self._matrix, uplo="U")
        self._indptr, self._indices = indptr, indices

    def solve(self, H_upper, b):
        cvxopt, cholmod = self._cvxopt, self._cholmod
        upper = H_upper if sp.isspmatrix_csc(H_upper) else sp.csc_matrix(H_upper)
        if not self._same_pattern(upper):
            self._analyse(upper)
        data = np.asarray(upper.data, dtype=float)
        self._matrix.V = cvxopt.matrix(data if self._order is None else data[self._order])
        try:
            cholmod.numeric(self._matrix, self._symbolic)
        except ArithmeticError as exc:
            raise SingularSystemError(f"CHOLMOD could not factorize H: it is not positive definite ({exc})") from exc
        x = cvxopt.matrix(-np.asarray(b, dtype=float))
        cholmod.solve(self._symbolic, x)
        return np.array(x).ravel()


def analyse_ahead(solver, upper_of) -> None:
    """``solver.analyse(upper_of())`` where the solver has an ``analyse`` (:class:`CholmodSolver`), else
    nothing (the exercise's solver analyses its pattern in its first solve). ``upper_of()`` gives an H
    (upper triangle, CSC) of the problem's pattern; where it meets a TODO (``NotImplementedError``), the
    analysis waits for the first solve, and the first linearisation reports the TODO."""
    analyse = getattr(solver, "analyse", None)
    if not callable(analyse):
        return
    try:
        upper = upper_of()
    except NotImplementedError:
        return
    analyse(upper)
