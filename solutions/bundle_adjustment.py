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
    # BEGIN SOLUTION
    cameras = np.asarray(cameras, dtype=float)
    # R(w) and J_r(w) once per camera (C is small), then gathered per observation
    w = cameras[:, :3]
    t2 = np.sum(w * w, axis=1)
    theta = np.sqrt(t2)
    small = theta < SMALL_ANGLE
    safe = np.where(small, 1.0, theta)
    a = np.where(small, 1.0 - t2 / 6.0, np.sin(safe) / safe)
    b = np.where(small, 0.5 - t2 / 24.0, (1.0 - np.cos(safe)) / safe**2)
    c = np.where(small, 1.0 / 6.0 - t2 / 120.0, (safe - np.sin(safe)) / safe**3)
    Wx = skew(w)
    Wx2 = np.matmul(Wx, Wx)
    eye = np.eye(3)
    # every quantity as rows of (K,) arrays, gathered per observation from (9, C) and (3, P) tables: each step is
    # then one contiguous pass over K numbers (numpy's batched 2x3 and 3x3 products loop per observation;
    # ladybug-49: about 6 against 12 ms). R[3 i + j] is R_ij, likewise Jr.
    def gathered(table, index):  # table (n, N) -> (n, K), row by row (np.take on contiguous rows is the fastest)
        return np.take(np.ascontiguousarray(table), index, axis=1)

    R = gathered((eye + a[:, None, None] * Wx + b[:, None, None] * Wx2).reshape(-1, 9).T, camera_index)
    Jr = gathered((eye - b[:, None, None] * Wx + c[:, None, None] * Wx2).reshape(-1, 9).T, camera_index)
    t, f, k1, k2 = np.split(gathered(cameras[:, 3:].T, camera_index), [3, 4, 5])
    f, k1, k2 = f[0], k1[0], k2[0]
    X = gathered(np.asarray(points, dtype=float).T, point_index)
    P = [R[3 * i] * X[0] + R[3 * i + 1] * X[1] + R[3 * i + 2] * X[2] + t[i] for i in range(3)]
    z = P[2]
    p = (-P[0] / z, -P[1] / z)
    n = p[0] * p[0] + p[1] * p[1]
    d = 1.0 + k1 * n + k2 * n * n
    fd = f * d
    r = np.stack([fd * p[0], fd * p[1]], axis=1) - observations

    # A = (d predicted / dp) (dp / dP), one row i at a time: d predicted_i / dp_m = s p_i p_m + f d [i = m],
    # dp/dP = [[-1/z, 0, P_x / z^2], [0, -1/z, P_y / z^2]]
    s = f * (2.0 * k1 + 4.0 * k2 * n)
    minus_inv_z = -1.0 / z
    zz = z * z
    q = (P[0] / zz, P[1] / zz)
    K = len(z)
    J_cam = np.empty((2, 9, K))  # rows of (K,) arrays, handed out as (K, 2, 9) below
    J_point = np.empty((2, 3, K))
    fn, fnn = f * n, f * n * n
    for i in range(2):  # A and AR written where they belong: A is J_cam's t columns, AR is J_point's row
        m0, m1 = s * (p[i] * p[0]), s * (p[i] * p[1])
        m0, m1 = (m0 + fd, m1) if i == 0 else (m0, m1 + fd)
        A, AR = J_cam[i, 3:6], J_point[i]
        np.multiply(m0, minus_inv_z, out=A[0])
        np.multiply(m1, minus_inv_z, out=A[1])
        np.add(m0 * q[0], m1 * q[1], out=A[2])
        for j in range(3):  # d predicted_i / d X = A R
            np.multiply(A[0], R[j], out=AR[j])
            AR[j] += A[1] * R[3 + j]
            AR[j] += A[2] * R[6 + j]
        # A d(RX)/dw with d(RX)/dw = -R [X]_x J_r; the row (AR) [X]_x is the cross product AR x X
        cross = (AR[1] * X[2] - AR[2] * X[1], AR[2] * X[0] - AR[0] * X[2], AR[0] * X[1] - AR[1] * X[0])
        for j in range(3):
            J_w = J_cam[i, j]
            np.multiply(cross[0], Jr[j], out=J_w)
            J_w += cross[1] * Jr[3 + j]
            J_w += cross[2] * Jr[6 + j]
            np.negative(J_w, out=J_w)
        np.multiply(d, p[i], out=J_cam[i, 6])
        np.multiply(fn, p[i], out=J_cam[i, 7])
        np.multiply(fnn, p[i], out=J_cam[i, 8])
    J_cam, J_point = np.ascontiguousarray(J_cam.transpose(2, 0, 1)), np.ascontiguousarray(J_point.transpose(2, 0, 1))
    return r, J_cam, J_point
    # END SOLUTION


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
    # BEGIN SOLUTION
    ci, pi = np.asarray(camera_index), np.asarray(point_index)
    K = len(ci)
    # U_c = J_c^T J_c and g_cam_c = J_c^T r_c, J_c camera c's rows stacked (2 K_c, 9): one product per camera
    # (C is small); np.dot lets other threads run during the product (course.app.parallel_speedup.gil_table)
    # a stable sort of 16-bit keys is a radix sort (ladybug-49: 0.2 against 1.1 ms for int64 keys)
    order = np.argsort(ci.astype(np.int16) if num_cameras <= np.iinfo(np.int16).max else ci, kind="stable")
    bounds = 2 * np.concatenate([[0], np.cumsum(np.bincount(ci, minlength=num_cameras))])
    rows, r_rows = np.take(J_cam, order, axis=0).reshape(-1, 9), np.take(r, order, axis=0).reshape(-1)
    per_camera = list(zip(bounds[:-1], bounds[1:]))
    U = np.stack([np.dot(rows[lo:hi].T, rows[lo:hi]) for lo, hi in per_camera])
    g_cam = np.stack([np.dot(rows[lo:hi].T, r_rows[lo:hi]) for lo, hi in per_camera])
    W = np.matmul(J_cam.transpose(0, 2, 1), J_point)
    # V_p and g_point_p entry by entry: the 6 distinct entries of J_point_k^T J_point_k and the 3 of
    # J_point_k^T r_k as (K,) arrays, summed per point (no (K, 3, 3) products to scatter)
    Jp = np.ascontiguousarray(J_point.reshape(K, 6).T)  # Jp[3 i + a]: row i, column a of every J_point_k
    r0, r1 = r[:, 0], r[:, 1]

    def per_point(values):
        return np.bincount(pi, weights=values, minlength=num_points)

    V = np.empty((num_points, 3, 3))
    for a in range(3):
        for b in range(a, 3):
            V[:, a, b] = V[:, b, a] = per_point(Jp[a] * Jp[b] + Jp[3 + a] * Jp[3 + b])
    g_point = np.stack([per_point(Jp[a] * r0 + Jp[3 + a] * r1) for a in range(3)], axis=1)
    return U, V, W, g_cam, g_point, float(np.sum(r * r))
    # END SOLUTION


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
    # BEGIN SOLUTION
    ci, pi = np.asarray(camera_index), np.asarray(point_index)
    C, P = len(U), len(V)
    U = np.array(U, dtype=float)
    V = np.array(V, dtype=float)
    if damping_cam is not None:
        U[:, np.arange(9), np.arange(9)] += damping_cam
    if damping_point is not None:
        V[:, np.arange(3), np.arange(3)] += damping_point
    # V_p^-1 by Cholesky of every 3x3 block; a failure names the first bad point
    try:
        L = np.linalg.cholesky(V)
    except np.linalg.LinAlgError:
        lowest = np.linalg.eigvalsh(V)
        bad = int(np.argmin(lowest[:, 0] / np.maximum(np.abs(lowest[:, -1]), np.finfo(float).tiny)))
        raise SingularSystemError(f"schur_solve: V[{bad}] (point {bad}, plus damping) is not positive definite "
                                  f"(eigenvalues {lowest[bad]}): is the point seen by fewer than 2 cameras, "
                                  "or from one place, undamped?") from None
    # L^-1 of every lower-triangular 3x3 factor by forward substitution, written out: one pass over the points
    # instead of a LAPACK call per point (ladybug-49's 7,776 points: 0.2 against 2.5 ms)
    L_inv = np.zeros_like(L)
    L_inv[:, 0, 0], L_inv[:, 1, 1], L_inv[:, 2, 2] = 1.0 / L[:, 0, 0], 1.0 / L[:, 1, 1], 1.0 / L[:, 2, 2]
    L_inv[:, 1, 0] = -L[:, 1, 0] * L_inv[:, 0, 0] * L_inv[:, 1, 1]
    L_inv[:, 2, 1] = -L[:, 2, 1] * L_inv[:, 1, 1] * L_inv[:, 2, 2]
    L_inv[:, 2, 0] = -(L[:, 2, 0] * L_inv[:, 0, 0] + L[:, 2, 1] * L_inv[:, 1, 0]) * L_inv[:, 2, 2]
    V_inv = np.matmul(L_inv.transpose(0, 2, 1), L_inv)

    # sum over pairs of W_k V_p^-1 W_l^T: Ys @ Ws.T as the hint says, by camera pair (the framework's
    # compiled pass, where numba is installed: a sixth of the time)
    W = np.asarray(W, dtype=float)
    # and sum_k W_k V_p^-1 g_p into block c_k, in the same pass
    g_point = np.asarray(g_point, dtype=float)
    reduction, Wg = schur_reduction(W, V_inv, ci, pi, C, g_point=g_point)  # (9C, 9C), blocks (9, 9); (C, 9)
    rhs = -np.asarray(g_cam, dtype=float).ravel() + Wg.ravel()

    n = 9 * C
    if n <= DENSE_LIMIT or reduction.nnz >= DENSE_FILL * n * n:
        # S = U - R written block by block into a (C, 9, C, 9) array: R's blocks where its BSR form lists them
        # (the framework's R is in that form already: no copy)
        R = sp.bsr_matrix(reduction, blocksize=(9, 9))
        S = np.zeros((C, 9, C, 9))
        block_rows = np.repeat(np.arange(C), np.diff(R.indptr))
        S[block_rows, :, R.indices, :] = -R.data
        S[np.arange(C), :, np.arange(C), :] += U
        S = S.reshape(n, n)
        S = 0.5 * (S + S.T)
        try:
            factor = scipy.linalg.cho_factor(S, lower=True, check_finite=False)
        except np.linalg.LinAlgError:
            raise SingularSystemError(
                "schur_solve: the reduced camera system S is not positive definite (undamped bundle adjustment has "
                "a 7-dimensional gauge freedom, and weakly observed points make S ill-conditioned: add damping, "
                "e.g. Levenberg-Marquardt)") from None
        # pivot / diagonal entry: the part of S_ii left after elimination (scale-free)
        kept = np.diag(factor[0]) ** 2 / np.diag(S)
        if not np.all(np.isfinite(kept)) or kept.min() <= n * np.finfo(float).eps:
            raise SingularSystemError(
                f"schur_solve: the reduced camera system S is numerically singular (a pivot keeps {kept.min():.3g} "
                "of its diagonal entry; undamped bundle adjustment has a 7-dimensional gauge freedom: add damping)")
        dx = scipy.linalg.cho_solve(factor, rhs, check_finite=False)
    else:
        blocks = sp.block_diag(list(U), format="csc")
        S_sparse = (blocks - reduction).tocsc()
        try:
            dx = spla.splu(S_sparse, permc_spec="MMD_AT_PLUS_A").solve(rhs)
        except RuntimeError as exc:
            raise SingularSystemError(f"schur_solve: the reduced camera system S is singular ({exc})") from None
        if not np.all(np.isfinite(dx)) or dx @ rhs <= 0:
            raise SingularSystemError("schur_solve: the reduced camera system S is not positive definite")
    dx_cam = dx.reshape(C, 9)

    Wt_dx = np.matmul(W.transpose(0, 2, 1), np.take(dx_cam, ci, axis=0)[:, :, None])[:, :, 0]  # (K, 3)
    back = np.stack([np.bincount(pi, weights=Wt_dx[:, j], minlength=P) for j in range(3)], axis=1)  # (P, 3)
    dx_point = np.matmul(V_inv, (-np.asarray(g_point, dtype=float) - back)[:, :, None])[:, :, 0]
    return dx_cam, dx_point
    # END SOLUTION


#: the derived results, in three levels (``python -m autograder hint NAME LEVEL``; the release
#: prints levels 1..N into the docstrings with ``--hints N``, course.core.hints)
HINTS = {
    "reprojection_residuals_and_jacobians": (
        """Chain rule through the stages: ``(w, t, X) -> P -> p -> f d p``. The camera's t and the point
        X enter only through P (``dP/dt = I``, ``dP/dX = R(w)``); f, k1, k2 only at the last stage.
        For ``d (R(w) X) / d w`` compare ``R(w + dw)`` with ``R(w) Exp(J_r(w) dw)``: a small change of
        the angle-axis vector is a right perturbation through the right Jacobian of SO(3).""",
        """``R(w + dw) = R(w) Exp(J_r(w) dw)`` to first order and ``[phi]x X = -[X]x phi``, so::

            d (R(w) X) / d w = -R(w) [X]_x J_r(w),
            J_r(w) = I - b W + c W^2,  c = (theta - sin(theta)) / theta^3   (1/6 - theta^2 / 120 near 0)

        and ``d predicted / dp = f (d I + p (d d/dp))`` with ``d d/dp = (2 k1 + 4 k2 |p|^2) p^T``.""",
        """Chain rule, per observation (all (K, ...) arrays, batched with ``np.matmul``):

        - ``dp/dP = [[-1/P_z, 0, P_x/P_z^2], [0, -1/P_z, P_y/P_z^2]]`` (2, 3)
        - ``d predicted/dp = f (d I + (2 k1 + 4 k2 |p|^2) p p^T)`` (2, 2); call ``A = (d predicted/dp) (dp/dP)`` (2, 3)
        - camera columns: ``A d(RX)/dw`` (w), ``A`` (t), ``d p`` (f), ``f |p|^2 p`` (k1), ``f |p|^4 p`` (k2)
        - point columns: ``A R(w)``

        with ``d (R(w) X) / d w = -R(w) [X]_x J_r(w)``, ``J_r(w) = I - b W + c W^2``,
        ``c = (theta - sin(theta)) / theta^3`` (``1/6 - theta^2 / 120`` near 0).""",
    ),
    "schur_solve": (
        """Order the unknowns cameras first, points second: ``[[U, W], [W^T, V]] [dx_cam; dx_point] =
        [-g_cam; -g_point]`` with U and V block diagonal. Solve the second block row for ``dx_point``
        (V is block diagonal: one 3x3 inverse per point) and put it into the first.""",
        """``dx_point = V^-1 (-g_point - W^T dx_cam)``, so ``(U - W V^-1 W^T) dx_cam = -g_cam + W V^-1 g_point``.
        In blocks, ``W V^-1 W^T`` couples two cameras only through a point they both see.""",
        """::

            S = U - sum_k sum_l W_k V_p^-1 W_l^T    at block (c_k, c_l), over pairs k, l of
                                                     observations of the same point p
            rhs = -g_cam + sum_k W_k V_{p_k}^-1 g_point_{p_k}    (into block c_k)
            S dx_cam = rhs                         ((9C, 9C), symmetric positive definite)
            dx_point_p = V_p^-1 (-g_point_p - sum over p's observations of W_k^T dx_cam_{c_k})""",
    ),
}
