"""The sparse solve where qdldl has no wheel: scipy's SuperLU on the full symmetric H.

``SuperLUSolver().solve(H_upper, b)`` has the interface of the exercise's
``sparse_solve.SparseCholeskySolver``: ``dx`` (n,) with ``H dx = -b``, from the upper
triangle of H (CSC, (n, n)). SuperLU is an LU factorization: it is given the whole of H
(``U + U^T - diag(U)``), a symmetric ordering (minimum degree on ``A^T + A``) and
diagonal pivoting, which on a positive definite H is a Cholesky-like ``L U`` with
``U = D L^T``. scipy does not expose a numeric refactorization, so each call analyses
the pattern again: slower than qdldl, same step to rounding. With diagonal pivots, U's
diagonal holds the pivots d_k of ``L D L^T``, and ``d_k / H_kk`` is the part of a
diagonal entry left after elimination: in (0, 1] when H is positive definite, down to
rounding (1e-16 to 1e-13) in the directions a singular H (a graph with no fixed pose)
cannot pin, where SuperLU need not fail. That ratio is checked.
"""

import numpy as np
import scipy.sparse as sp
from scipy.sparse.linalg import splu

from course.core import peers
from course.core.errors import SingularSystemError

#: ``d_k / H_kk`` at or below this means H is singular to working precision (measured: a free
#: gauge leaves 1e-16 to 2.5e-13; intel-g2o, badly conditioned but definite, 6e-11)
PIVOT_TOLERANCE = 1e-12


class SuperLUSolver:
    """``H dx = -b`` by ``scipy.sparse.linalg.splu`` on the symmetric H of its upper triangle."""

    label = "superlu"  # compare's name for it (``course.solver.choice``)

    def solve(self, H_upper, b):
        upper = sp.csc_matrix(H_upper)
        H = (upper + sp.triu(upper, k=1, format="csc").T).tocsc()
        try:
            lu = splu(H, permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0, options={"SymmetricMode": True})
        except RuntimeError as exc:  # "Factor is exactly singular"
            raise SingularSystemError(f"SuperLU could not factorize H: {exc}; H is not positive definite") from exc
        remaining = lu.U.diagonal()[lu.perm_c] / H.diagonal()  # perm_r == perm_c: diagonal pivots
        if not np.all(remaining > PIVOT_TOLERANCE):
            k = int(np.argmin(remaining))
            raise SingularSystemError(f"H is not positive definite: elimination leaves {remaining[k]:.3g} of "
                                      f"its diagonal entry {k} (SuperLU)")
        return -lu.solve(np.asarray(b, dtype=float))


def sparse_solver(sparse_module):
    """The implementation's ``SparseCholeskySolver()`` (``sparse_module``: its ``sparse_solve``),
    or ``SuperLUSolver()`` where qdldl is not installed (said once)."""
    if peers.installed("qdldl"):
        return sparse_module.SparseCholeskySolver()
    peers.announce("qdldl")
    return SuperLUSolver()


def checked_step(solver, H, b, fixed_dof, name: str, what: str = "pose") -> np.ndarray:
    """The step ``h`` (n,) of ``H h = -b`` by ``solver.solve(H, b)`` (H its upper triangle, CSC), with
    the entries ``fixed_dof`` set to 0. A step of another shape, not finite, or uphill (``h . b > 0``)
    means H is not positive definite: ``SingularSystemError`` naming ``name`` (the problem) and asking
    whether a ``what`` is fixed."""
    try:
        h = np.asarray(solver.solve(H, b), dtype=float)
    except (ValueError, RuntimeError, ArithmeticError) as exc:  # qdldl: "not quasi-definite", SuperLU: singular
        if isinstance(exc, (SingularSystemError, NotImplementedError)):  # a TODO is a RuntimeError too
            raise
        raise SingularSystemError(f"{name}: the sparse solve failed ({exc}): H is not positive definite "
                                  f"(is a {what} fixed?)") from exc
    if h.shape != np.shape(b) or not np.all(np.isfinite(h)) or (h @ b > 0):
        raise SingularSystemError(
            f"{name}: the sparse solve gave "
            + ("a non-finite step" if h.shape == np.shape(b) else f"shape {h.shape}")
            + f" or an ascent direction: H is not positive definite (is a {what} fixed?)")
    h[fixed_dof] = 0.0
    return h
