"""Chapter 4 problem: bundle adjustment (BAL) as the loop sees it.

The unknown is ``x = concat(cameras.ravel(), points.ravel())`` (9C + 3P,). ``linearize``
uses the implementation's ``bundle_adjustment.reprojection_residuals_and_jacobians`` and
``normal_equations`` and keeps H as its blocks (U, V, W) in a :class:`BlockLinearization`;
``solve`` splits the damping into its camera and point parts and calls the implementation's
``schur_solve``. ``chi2 = sum |r|^2`` (unit information): twice the BAL cost. ``retract``
is addition (the rotation's angle-axis vector too).

Bundle adjustment has a 7-dimensional gauge freedom (a similarity of the whole scene), so
undamped Gauss-Newton meets a singular system: it stops with a ``SingularSystemError``;
use Levenberg-Marquardt or the dogleg (which damps a singular system itself).
"""

from dataclasses import dataclass
from typing import Any

import numpy as np

from course.core import impl as impl_loader
from course.core.errors import check_array
from course.problems.bal.dataset import BALProblem, residuals, rotate
from course.solver import robust
from course.solver.linearization import Linearization


@dataclass
class BlockLinearization(Linearization):
    """H kept as the blocks of ``normal_equations``: ``U`` (C, 9, 9), ``V`` (P, 3, 3), ``W`` (K, 9, 3).

    ``H`` is None (never formed); ``b`` (9C + 3P,) and ``chi2`` as in :class:`Linearization`;
    ``diagonal()`` and ``matvec(v)`` give what the strategies need.
    """

    U: Any = None
    V: Any = None
    W: Any = None
    camera_index: Any = None
    point_index: Any = None

    def diagonal(self):
        return np.concatenate([np.einsum("cii->ci", self.U).ravel(), np.einsum("pii->pi", self.V).ravel()])

    def matvec(self, v):
        """``H v``: ``[U v_c + sum_k W_k v_p ; sum_k W_k^T v_c + V v_p]`` (no H formed)."""
        C, P = len(self.U), len(self.V)
        vc, vp = v[:9 * C].reshape(C, 9), v[9 * C:].reshape(P, 3)
        ci, pi = self.camera_index, self.point_index
        out_c = np.matmul(self.U, vc[:, :, None])[:, :, 0]
        out_p = np.matmul(self.V, vp[:, :, None])[:, :, 0]
        Wv = np.matmul(self.W, vp[pi][:, :, None])[:, :, 0]  # (K, 9)
        Wtv = np.matmul(self.W.transpose(0, 2, 1), vc[ci][:, :, None])[:, :, 0]  # (K, 3)
        out_c += np.bincount((ci[:, None] * 9 + np.arange(9)).ravel(), weights=Wv.ravel(),
                             minlength=9 * C).reshape(C, 9)
        out_p += np.bincount((pi[:, None] * 3 + np.arange(3)).ravel(), weights=Wtv.ravel(),
                             minlength=3 * P).reshape(P, 3)
        return np.concatenate([out_c.ravel(), out_p.ravel()])

    def with_diagonal_added(self, d):
        raise NotImplementedError("a bundle-adjustment H is kept as blocks: use BundleAdjustmentProblem.solve")


def gauge_parameters(problem: BALProblem) -> np.ndarray:
    """The camera parameters (C, 9) bool that fix the gauge: camera 0's pose (w, t) and the translation
    component of camera 1 along which the scene's scale moves it most, 7 in all."""
    if problem.num_cameras < 2:
        raise ValueError("fix_gauge needs at least 2 cameras")
    fixed = np.zeros((problem.num_cameras, 9), dtype=bool)
    fixed[0, :6] = True
    cam = problem.cameras
    centres = -rotate(-cam[:2, :3], cam[:2, 3:6])  # c = -R^T t
    baseline = rotate(cam[1:2, :3], (centres[1] - centres[0])[None])[0]  # d t_1 / d scale, up to sign
    fixed[1, 3 + int(np.argmax(np.abs(baseline)))] = True
    return fixed


class BundleAdjustmentProblem:
    """``linearize`` / ``chi2`` / ``solve`` / ``retract`` for one BAL problem and implementation."""

    #: the solve of ``H h = -b`` (``compare``'s ``solve`` column): the implementation's
    #: ``bundle_adjustment.schur_solve`` (points eliminated, the reduced camera system solved its way)
    linear_solve = "schur"

    def __init__(self, problem: BALProblem, impl="solutions", fix_gauge: bool = False, loss=None):
        """``fix_gauge``: hold camera 0's pose (w, t) and one translation component of camera 1 (the
        one along which the scene's scale moves it most) at their start values, which removes the
        7-dimensional gauge freedom; Gauss-Newton then works. The minimum cost is the same.

        ``loss``: None (least squares), or a robust loss ``(kernel, scale)`` such as ``("huber", 2.0)``
        (:class:`course.solver.robust.RobustLoss`, the implementation's ``robust_kernels``) on each
        observation's ``s = |r|^2``: chi2 is then ``sum rho(s)``, in ``chi2(x)`` and ``linearize`` alike."""
        self.loss = robust.RobustLoss.of(loss)
        self.problem = problem
        self.impl = impl_loader.load(impl)
        self.ba = self.impl.module("bundle_adjustment")
        self.kernels = self.impl.module("robust_kernels") if self.loss is not None else None
        self.num_cameras, self.num_points = problem.num_cameras, problem.num_points
        self.x0 = np.concatenate([problem.cameras.ravel(), problem.points.ravel()]).astype(float)
        self._split = 9 * self.num_cameras
        # camera parameters held fixed
        self.fixed = gauge_parameters(problem) if fix_gauge else np.zeros((self.num_cameras, 9), dtype=bool)
        # the rows (observation k, parameter j) of W that a fixed parameter zeroes, found once (a boolean mask
        # over all K x 9 rows at every linearization cost more than the zeroing)
        self._fixed_rows = np.nonzero(self.fixed[problem.camera_index])

    def unpack(self, x):
        """``(cameras (C, 9), points (P, 3))`` of a state vector x."""
        x = np.asarray(x, dtype=float)
        return x[:self._split].reshape(-1, 9), x[self._split:].reshape(-1, 3)

    def cost(self, x) -> float:
        """The BAL cost ``0.5 sum |r|^2`` at x (half the chi2)."""
        return 0.5 * self.chi2(x)

    def chi2(self, x) -> float:
        p = self.problem
        cameras, points = self.unpack(x)
        r = residuals(cameras, points, p.camera_index, p.point_index, p.observations)
        if self.loss is not None:
            return robust.robust_chi2(self.kernels, self.loss, r)
        value = float(np.sum(r * r))
        return value if np.isfinite(value) else float("inf")

    def linearize(self, x) -> BlockLinearization:
        p = self.problem
        C, P, K = self.num_cameras, self.num_points, p.num_observations
        cameras, points = self.unpack(x)
        where = "bundle_adjustment.reprojection_residuals_and_jacobians"
        r, J_cam, J_point = self.ba.reprojection_residuals_and_jacobians(
            cameras, points, p.camera_index, p.point_index, p.observations)
        r = check_array(r, (K, 2), where, "r")
        J_cam = check_array(J_cam, (K, 2, 9), where, "J_cam")
        J_point = check_array(J_point, (K, 2, 3), where, "J_point")
        robust_chi2 = None
        # r~, J~ such that normal_equations gives J^T W J and rho' J^T r (course.solver.robust)
        if self.loss is not None:
            r, (J_cam, J_point), robust_chi2 = robust.reweight(self.kernels, self.loss, r, (J_cam, J_point))
        where = "bundle_adjustment.normal_equations"
        U, V, W, g_cam, g_point, chi2 = self.ba.normal_equations(
            r, J_cam, J_point, p.camera_index, p.point_index, C, P)
        U = check_array(U, (C, 9, 9), where, "U")
        V = check_array(V, (P, 3, 3), where, "V")
        W = check_array(W, (K, 9, 3), where, "W")
        g_cam = check_array(g_cam, (C, 9), where, "g_cam")
        if self.fixed.any():  # zero rows and columns of the fixed parameters, unit diagonal: their step is 0
            U, g_cam = U.copy(), g_cam.copy()
            # W (K, 9, 3), the largest output, is zeroed where it lies when the implementation handed over an
            # array of its own (its fresh result; ladybug-49: a 7.6 MB copy saved), copied first otherwise (a view)
            if not (W.flags.owndata and W.flags.writeable):
                W = W.copy()
            cams, params = np.nonzero(self.fixed)
            U[cams, params, :] = 0.0
            U[cams, :, params] = 0.0
            U[cams, params, params] = 1.0
            W[self._fixed_rows] = 0.0
            g_cam[self.fixed] = 0.0
        b = np.concatenate([g_cam.ravel(), check_array(g_point, (P, 3), where, "g_point").ravel()])
        chi2 = float(chi2) if robust_chi2 is None else robust_chi2
        return BlockLinearization(H=None, b=b, chi2=chi2, U=U, V=V, W=W,
                                  camera_index=p.camera_index, point_index=p.point_index)

    def solve(self, lin: Linearization, damping=None):
        """Step (9C + 3P,) of ``(H + diag(damping)) h = -b`` by the implementation's ``schur_solve``."""
        assert isinstance(lin, BlockLinearization)
        C, P = self.num_cameras, self.num_points
        d_cam = d_point = None
        if damping is not None:
            damping = np.asarray(damping, dtype=float)
            d_cam, d_point = damping[:self._split].reshape(C, 9), damping[self._split:].reshape(P, 3)
        g_cam, g_point = lin.b[:self._split].reshape(C, 9), lin.b[self._split:].reshape(P, 3)
        dx_cam, dx_point = self.ba.schur_solve(lin.U, lin.V, lin.W, g_cam, g_point, lin.camera_index,
                                               lin.point_index, damping_cam=d_cam, damping_point=d_point)
        where = "bundle_adjustment.schur_solve"
        return np.concatenate([check_array(dx_cam, (C, 9), where, "dx_cam").ravel(),
                               check_array(dx_point, (P, 3), where, "dx_point").ravel()])

    def retract(self, x, h):
        return np.asarray(x, dtype=float) + h
