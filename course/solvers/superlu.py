"""The sparse solve where qdldl has no wheel: scipy's SuperLU on the full symmetric H.

``SuperLUSolver().solve(H_upper, b)`` has the interface of the exercise's
``sparse_solve.SparseCholeskySolver``: ``dx`` (n,) with ``H dx = -b``, from the upper
triangle of H (CSC, (n, n)). SuperLU is an LU factorization: it is given the whole of H
(``U + U^T - diag(U)``), a symmetric ordering (minimum degree on ``A^T + A``) and
diagonal pivoting, which on a positive definite H is a Cholesky-like ``L U`` with
``U = D L^T``. scipy does not expose a numeric refactorization, so each call analyses
the pattern again: slower than qdldl, same step to rounding.
"""

import numpy as np
import scipy.sparse as sp
from scipy.sparse.linalg import splu

from course.errors import SingularSystemError


class SuperLUSolver:
    """``H dx = -b`` by ``scipy.sparse.linalg.splu`` on the symmetric H of its upper triangle."""

    def solve(self, H_upper, b):
        upper = sp.csc_matrix(H_upper)
        H = (upper + sp.triu(upper, k=1, format="csc").T).tocsc()
        try:
            lu = splu(H, permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0, options={"SymmetricMode": True})
        except RuntimeError as exc:  # "Factor is exactly singular"
            raise SingularSystemError(f"SuperLU could not factorize H: {exc}") from exc
        return -lu.solve(np.asarray(b, dtype=float))
