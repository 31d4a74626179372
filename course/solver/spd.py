"""One solve of a sparse symmetric positive definite system: ``spd_solve(H, rhs)``.

For the linear least-squares problems of the chordal initialisations (chapters 3b and 6),
which factorize their normal equations once. qdldl's LDL^T (chapter 2's solver, with an AMD
ordering) where it is installed; elsewhere (qdldl has no wheel for every Python) SuperLU
without pivoting in its symmetric mode, which keeps its fill-reducing order (minimum degree on
``H + H^T``) as it is. On the chordal systems of the public graphs qdldl is 1.5 to 3 times
faster (parking-garage's 3D rotations: 7.5 against 12.2 ms, fr079's 2D translations: 0.65
against 1.6 ms; this machine).

Inside ``with shared_analysis():`` the qdldl solves keep the analysis (the AMD ordering, the
elimination tree, the factor's pattern) of the last pattern they factorized: a system stored with
the same pattern (``indptr`` and ``indices``) is factorized numerically only, as chapter 2's
``SparseCholeskySolver`` does between iterations. The 2D chordal start solves its rotations and its
translations in one pattern of 2x2 blocks where the translation information is anisotropic: the
second solve skips the analysis (fr079: 0.08 against 0.6 ms). Outside the block nothing is kept, so
a solve never reuses an analysis made for another call.
"""

from collections.abc import Iterator
from contextlib import contextmanager
from contextvars import ContextVar

import numpy as np
import scipy.sparse as sp
from scipy.sparse.linalg import splu

#: inside :func:`shared_analysis`: ``[indptr, indices, qdldl.Solver]`` of the last factorization (empty at first)
_KEPT: ContextVar[list | None] = ContextVar("spd_kept_analysis", default=None)


@contextmanager
def shared_analysis() -> Iterator[None]:
    """Within the block, :func:`spd_solve` reuses the analysis of a pattern it has just factorized
    (qdldl only; one pattern kept: the last). Nothing outlives the block."""
    token = _KEPT.set([])
    try:
        yield
    finally:
        _KEPT.reset(token)


def spd_solve(H, rhs, upper=False):
    """``H^-1 rhs`` for ``H`` sparse (n, n), symmetric positive definite, both triangles stored
    (``upper=True``: only its upper triangle, diagonal included, which saves qdldl taking it:
    fr079's chordal translations 0.25 ms of 1.0), ``rhs`` (n,) or (n, k)."""
    rhs = np.asarray(rhs, dtype=float)
    try:
        import qdldl
    except ImportError:
        H = sp.csc_matrix(H)
        if upper:
            H = (H + sp.triu(H, k=1, format="csc").T).tocsc()
        factor = splu(H, permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0, options={"SymmetricMode": True})
        return factor.solve(rhs)
    A = sp.csc_matrix(H) if upper else sp.triu(H, format="csc")
    kept = _KEPT.get()
    if kept and np.array_equal(A.indptr, kept[0]) and np.array_equal(A.indices, kept[1]):
        factor = kept[2]
        factor.update(A, upper=True)
    else:
        factor = qdldl.Solver(A, upper=True)
        if kept is not None:
            kept[:] = [A.indptr.copy(), A.indices.copy(), factor]
    if rhs.ndim == 1:
        return factor.solve(rhs)
    return np.column_stack([factor.solve(np.ascontiguousarray(column)) for column in rhs.T])
