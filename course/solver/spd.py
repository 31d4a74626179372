"""One solve of a sparse symmetric positive definite system: ``spd_solve(H, rhs)``.

For the linear least-squares problems of the chordal initialisations (chapters 3b and 6),
which factorize their normal equations once. qdldl's LDL^T (chapter 2's solver, with an AMD
ordering) where it is installed; elsewhere (qdldl has no wheel for every Python) SuperLU
without pivoting in its symmetric mode, which keeps its fill-reducing order (minimum degree on
``H + H^T``) as it is. On the chordal systems of the public graphs qdldl is 1.5 to 3 times
faster (parking-garage's 3D rotations: 7.5 against 12.2 ms, fr079's 2D translations: 0.65
against 1.6 ms; this machine).
"""

import numpy as np
import scipy.sparse as sp
from scipy.sparse.linalg import splu


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
    factor = qdldl.Solver(sp.csc_matrix(H) if upper else sp.triu(H, format="csc"), upper=True)
    if rhs.ndim == 1:
        return factor.solve(rhs)
    return np.column_stack([factor.solve(np.ascontiguousarray(column)) for column in rhs.T])
