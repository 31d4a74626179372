"""Chapter 4 exercise: bundle adjustment in the BAL convention, vectorised over observations.

Source: Agarwal, Snavely, Seitz, Szeliski, "Bundle Adjustment in the Large" (ECCV 2010)
for the camera model; Triggs, McLauchlan, Hartley, Fitzgibbon, "Bundle Adjustment - A
Modern Synthesis" (1999), section 6.1, for the Schur complement; G. Gallego, A. Yezzi,
"A compact formula for the derivative of a 3-D rotation in exponential coordinates"
(2015) for ``d R(w) v / d w``.

Camera c has 9 parameters ``(w (3), t (3), f, k1, k2)``, point p has 3, and observation k
of point ``point_index[k]`` by camera ``camera_index[k]`` gives the residual (2,)::

    P = R(w) X + t,  p = -P[:2] / P[2],  d = 1 + k1 |p|^2 + k2 |p|^4,  r = f d p - observed

The unknowns are updated by plain addition (also w), so the Jacobians are derivatives
with respect to the angle-axis vector itself. No Python loop over observations anywhere.
K >= 1 observations; a camera that sees no point or a point seen by none is allowed (its blocks of
U, V and g are zero; the Schur step then needs damping on them).

Inputs at the edges of the contract (each is a check input):
- reprojection_residuals_and_jacobians: a camera not rotated at all (w = 0 exactly)
- reprojection_residuals_and_jacobians: a camera rotated by nearly pi (|w| = pi - 1e-3)
- reprojection_residuals_and_jacobians: one observation (K = 1: one camera, one point)
- normal_equations: one observation (K = 1)
- normal_equations: a camera that sees no point, the last (U_c = 0, g_cam_c = 0)
- normal_equations: a point seen by no camera, the last (V_p = 0, g_point_p = 0)
- normal_equations: a point seen by one camera (V_p of rank 2)
- schur_solve: a point seen once, V_p of rank 2 made definite by the damping alone (lambda = 1e-2)
- schur_solve: a camera that sees no point and a point seen by none (their blocks: the damping alone)
- schur_solve: the damping already in U and V (no damping arguments)
- schur_solve: 9C above DENSE_LIMIT (112 cameras: the sparse branch)

Allowed imports: numpy, scipy, course.core.errors, course.geometry.so3, course.solver.schur_reduction.
"""

import numpy as np
import scipy.linalg
import scipy.sparse as sp
import scipy.sparse.linalg as spla

from course.core.errors import SingularSystemError
from course.geometry.so3 import skew
from course.solver.schur_reduction import schur_reduction

#: below this |w| the coefficients of Rodrigues' formula use their Taylor series
SMALL_ANGLE = 1e-4
#: the reduced camera system is solved densely up to this size (9 C), sparsely beyond
DENSE_LIMIT = 1000
#: ... or when at least this share of its entries is nonzero: a sparse factorization of a nearly
#: dense matrix does the dense one's work with more bookkeeping (400 cameras that all see each
#: other's points: SuperLU 3.8 s, a dense Cholesky 0.3 s)
DENSE_FILL = 0.25


def reprojection_residuals_and_jacobians(cameras, points, camera_index, point_index, observations):
    """Residuals and Jacobians of all observations: ``r`` (K, 2), ``J_cam`` (K, 2, 9), ``J_point`` (K, 2, 3).

    Args: cameras (C, 9), points (P, 3), camera_index, point_index (K,) int, observations (K, 2).

    Rodrigues, with ``theta = |w|`` and ``W = [w]_x``::

        R(w) = I + a W + b W^2,   a = sin(theta) / theta,  b = (1 - cos(theta)) / theta^2

    Near theta = 0 (below ``SMALL_ANGLE``) use ``a = 1 - theta^2 / 6``, ``b = 1/2 - theta^2 / 24``
    (never divide by theta).

    Derive the Jacobians by the chain rule, per observation, through ``P``, then ``p``, then the
    prediction ``f d p``: ``J_cam`` columns in the order ``(w, t, f, k1, k2)``, ``J_point`` the
    derivative in ``X``. The derivative of ``R(w) X`` in w is the hard part; the grader compares
    values and finite differences, so any correct form scores (``python -m autograder hint
    reprojection_residuals_and_jacobians 1``, then 2 and 3). Batch the (K, ...) arrays with ``np.matmul``.

    Hint: gather the cameras and points of the observations first (``cameras[camera_index]``).
    """
    raise NotImplementedError("TODO bundle_adjustment.reprojection_residuals_and_jacobians: not implemented yet")


def normal_equations(r, J_cam, J_point, camera_index, point_index, num_cameras, num_points):
    """The blocks of ``H = J^T J`` and ``g = J^T r`` (unit information), and ``chi2``.

    Returns ``U`` (C, 9, 9), ``V`` (P, 3, 3), ``W`` (K, 9, 3), ``g_cam`` (C, 9), ``g_point`` (P, 3),
    ``chi2`` (float)::

        U_c = sum over c's observations of J_cam_k^T J_cam_k
        V_p = sum over p's observations of J_point_k^T J_point_k
        W_k = J_cam_k^T J_point_k              (one coupling block per observation)
        g_cam_c = sum J_cam_k^T r_k,  g_point_p = sum J_point_k^T r_k,  chi2 = sum r_k^T r_k

    so that the Gauss-Newton step solves ``H dx = -g``. Hint: per-observation products with
    ``np.matmul`` on transposed stacks, then a scatter-add to cameras and points
    (``np.add.at``, or ``np.bincount`` with weights on flattened indices; no loop over k).
    """
    raise NotImplementedError("TODO bundle_adjustment.normal_equations: not implemented yet")


def schur_solve(U, V, W, g_cam, g_point, camera_index, point_index, damping_cam=None, damping_point=None):
    """The step ``(dx_cam (C, 9), dx_point (P, 3))`` of ``(H + D) dx = -g`` by the Schur complement.

    With the damping diagonals added first (``U_c += diag(damping_cam[c])`` (C, 9),
    ``V_p += diag(damping_point[p])`` (P, 3); None means no damping), eliminate the points: derive the
    reduced camera system ``S dx_cam = rhs`` ((9C, 9C), symmetric positive definite) from the block
    rows of ``(H + D) dx = -g``, and the points' step from ``dx_cam`` (``python -m autograder hint
    schur_solve 1``, then 2 and 3).

    Solve S by a dense Cholesky factorization when 9C <= ``DENSE_LIMIT`` or at least
    ``DENSE_FILL`` of its entries are nonzero, else sparse (``scipy.sparse.linalg.splu``).
    Raise ``course.core.errors.SingularSystemError`` naming the block when some damped V_p or S
    is not positive definite.

    Hint: with ``Y_k = W_k V_{p_k}^-1`` (K, 9, 3), the sum over pairs of observations of one point
    is ``Ys @ Ws^T`` where Ys
    and Ws are the sparse (9C, 3P) matrices holding the blocks Y_k and W_k at (c_k, p_k)
    (``scipy.sparse.csr_matrix((data, (rows, cols)), shape)``): no loop over pairs. Faster:
    ``scipy.sparse.bsr_matrix((blocks, block_columns, block_row_pointers), shape)``, which
    multiplies 9x3 blocks at a time. Fastest: the framework's
    ``course.solver.schur_reduction.schur_reduction(W, V_inv, camera_index, point_index, C)``,
    the same sum by camera pair, compiled where numba is installed (write the BSR product first:
    it is the idea); with ``g_point=g_point`` it also returns ``sum_k W_k V_p^-1 g_point_p`` by
    camera, (C, 9), from the same pass.
    """
    raise NotImplementedError("TODO bundle_adjustment.schur_solve: not implemented yet")
