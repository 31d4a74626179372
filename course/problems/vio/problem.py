"""Chapter 5 problem: a set of visual-inertial keyframes and 3D landmarks, as the minimizer sees it.

Unknowns. Frame f has 15 degrees of freedom, stored in ``x`` as ``s_f = (phi, p, v, b_g, b_a)``
(15,): ``R_wb = Exp(phi)`` (a rotation vector), position ``p`` and velocity ``v`` in the world,
gyro and accelerometer biases. Its *tangent* (the step h) is ``(dphi, dp, dv, db_g, db_a)`` with
the right perturbation ``R <- R Exp(dphi)`` and addition for the rest (:meth:`VioProblem.retract`).
Landmark l is a 3D point ``X_l`` in the world (3,). So ``x = (s_0 .. s_{F-1}, X_0 .. X_{L-1})``
((15 F + 3 L,)), and the step h has the same layout.

Why 3D points and not inverse depth: a point needs no anchor frame, so marginalising the frame
that first saw it needs no re-anchoring, and every factor touches one frame and one point (the
course's bundle-adjustment structure). Inverse depth is better conditioned for far, low-parallax
points; the simulated walls are 5-40 m away with metres of baseline per keyframe, where points
are well triangulated.

Factors (every residual whitened, so chi2 is a plain sum of squares, as in the course:
``chi2 = sum_k rho_k``, ``H = J^T W J``, ``b = J^T W r``, the step solves ``H h = -b``):

- IMU between consecutive frames i, j (``solutions.imu_preintegration``): ``r_imu`` (9,) of
  ``imu_factor_residual`` whitened by the preintegrated covariance ``Sigma`` (9, 9):
  ``L^T r_imu`` with ``L L^T = Sigma^-1``; and the bias random walk
  ``((b_g,j - b_g,i) / (sigma_g sqrt(dT)), (b_a,j - b_a,i) / (sigma_a sqrt(dT)))`` (6,).
  The Jacobians of ``r_imu`` in the 30 tangent coordinates of (i, j) are analytic
  (``course.problems.vio.imu_jacobians``, Forster et al.'s, 56 times faster than the central differences
  with step :data:`FD_STEP` through :meth:`retract` that ``imu_jacobian="numeric"`` takes of the
  loaded implementation's residual); the bias walk's are exact.
- Reprojection (pinhole, **analytic** Jacobians): ``X_b = R^T (X - p)``, ``X_c = R_bc^T (X_b -
  t_bc)``, ``r = (pi(K X_c) - u) / sigma_px`` (2,). With ``P = d pi / d X_c`` (2, 3) =
  ``[[fx/z, 0, -fx x/z^2], [0, fy/z, -fy y/z^2]] / sigma_px``::

      dr/ddphi = P R_bc^T [X_b]_x,   dr/ddp = -P R_bc^T R^T,   dr/dX = P R_bc^T R^T

  under a robust kernel (default Cauchy, scale 3 whitened pixels) applied with
  ``course.solver.robust.reweight`` and the implementation's ``robust_kernels``.
- Priors on single frames (:class:`FramePrior`): ``(s_f [-] s_ref) / sigma`` over the finite
  sigmas, where ``[-]`` is the tangent difference ``(Log(R_ref^T R), p - p_ref, ...)``
  (its Jacobian taken as the identity: first order at s_ref).
- An optional linear prior (:class:`LinearPrior`) from marginalisation, in residual form
  ``e = e0 + J (x_k [-] x_lin)`` over its variables (``marginalisation.prior_residual`` /
  ``prior_update``), the Jacobian J fixed at the linearisation point.
- First-estimate Jacobians (``VioData.first_estimates``, Huang, Mourikis, Roumeliotis 2009):
  the Jacobians of every factor are evaluated with the listed variables (the prior's frames, or
  its frames and landmarks) at their linearisation point, the residuals at x, so that the prior
  and the relinearised factors agree about the directions nothing measures (position, yaw:
  :func:`gauge_directions`). ``course.problems.vio.window`` takes those directions out of the prior instead
  and leaves this off by default (its docstring has the figures).
- An optional gauge anchor (``VioData.anchor``, the same linear form), kept apart from the prior
  so that :meth:`VioProblem.marginal_system` can leave it out.

H is formed from a sparse J. A problem of at least :data:`SPARSE_FROM` unknowns (the 12-s batch:
1488) keeps H sparse (its upper triangle) and takes the step by the implementation's sparse
Cholesky (chapter 2; SuperLU where qdldl is not installed), the pattern analysed once while it
holds (:class:`course.solver.per_pattern.PerPattern`); a smaller one (a window: a few hundred
unknowns, with the marginalisation prior's dense block) forms H dense and takes a dense Cholesky
step, which is faster there.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import scipy.linalg
import scipy.sparse as sp

from course.core import impl as impl_loader
from course.core.errors import SingularSystemError
from course.geometry.so3 import exp_many, log_many, so3_exp, so3_log
from course.problems.vio.imu_jacobians import imu_residual_jacobians, stack_preintegrated
from course.solver.linearization import Linearization
from course.solver.per_pattern import PerPattern
from course.solver.robust import RobustLoss, reweight, robust_chi2
from course.solver.superlu import sparse_solver

EZ = np.array([0.0, 0.0, 1.0])

FRAME_DOF, POINT_DOF = 15, 3
#: the central-difference step of the numerical IMU Jacobians (tangent units: rad, m, m/s, ...)
FD_STEP = 1e-6
#: below this camera depth (m) a reprojection is clamped (a point behind or at the camera)
MIN_DEPTH = 1e-3
DEFAULT_LOSS = RobustLoss("cauchy", 3.0)
#: from this many unknowns on, H is kept sparse and solved by a sparse Cholesky (measured: the
#: window, 150-400 unknowns with a dense prior block, is faster dense; the batch, 1488, sparse)
SPARSE_FROM = 1000


@dataclass
class FramePrior:
    """A prior ``(s_f [-] reference) / sigmas`` on frame ``frame`` (a problem-local index);
    ``reference`` (15,) a frame state, ``sigmas`` (15,) with ``inf`` for unconstrained entries."""

    frame: int
    reference: np.ndarray
    sigmas: np.ndarray


@dataclass
class LinearPrior:
    """``e0 + J (x_k [-] x_lin)`` over frames ``frames`` (a,) and landmarks ``landmarks`` (c,)
    (problem-local indices; tangent order: the frames' 15 each, then the landmarks' 3 each);
    ``frame_lin`` (a, 15), ``landmark_lin`` (c, 3) the linearisation point, ``J`` (r, 15a + 3c),
    ``e0`` (r,)."""

    frames: np.ndarray
    landmarks: np.ndarray
    frame_lin: np.ndarray
    landmark_lin: np.ndarray
    J: np.ndarray
    e0: np.ndarray


@dataclass
class ImuFactor:
    """Frames ``i``, ``j`` (problem-local) and the preintegration between them."""

    i: int
    j: int
    preintegrated: tuple


@dataclass
class VioData:
    """Everything fixed in a problem: ``imu`` factors; observations ``obs_frame``, ``obs_landmark``
    (M,) problem-local, ``pixels`` (M, 2); the camera ``K``, ``R_bc``, ``t_bc``; noise levels."""

    imu: list
    obs_frame: np.ndarray
    obs_landmark: np.ndarray
    pixels: np.ndarray
    K: np.ndarray
    R_bc: np.ndarray
    t_bc: np.ndarray
    gravity: np.ndarray
    pixel_sigma: float
    gyro_walk: float
    accel_walk: float
    frame_priors: list = field(default_factory=list)
    linear_prior: LinearPrior | None = None
    #: a linear gauge anchor (same form as the linear prior), kept apart so that it can be
    #: left out of what is marginalised
    anchor: LinearPrior | None = None
    #: first-estimate Jacobians: ``(frames (a,), states (a, 15), landmarks (c,), points (c, 3))``
    #: whose Jacobians (not residuals) are evaluated at these values, or None
    first_estimates: tuple | None = None


def frame_difference(s, s_ref):
    """The tangent difference ``s [-] s_ref`` (..., 15) of frame states (..., 15)."""
    s, s_ref = np.asarray(s, dtype=float), np.asarray(s_ref, dtype=float)
    out = s - s_ref
    flat, flat_ref = np.broadcast_to(s, out.shape).reshape(-1, 15), np.broadcast_to(s_ref, out.shape).reshape(-1, 15)
    flat_out = out.reshape(-1, 15)
    flat_out[:, 0:3] = log_many(np.matmul(exp_many(flat_ref[:, 0:3]).transpose(0, 2, 1), exp_many(flat[:, 0:3])))
    return flat_out.reshape(out.shape)


def gauge_directions(frames, landmarks) -> np.ndarray:
    """The 4 directions (15a + 3c, 4) along which no IMU or reprojection residual changes, at
    frame states ``frames`` (a, 15) and points ``landmarks`` (c, 3), in tangent coordinates:
    a translation of the world (3 columns: ``dp = dX = e_k``) and a rotation about gravity
    (``dphi = R^T e_z``, ``dp = e_z x p``, ``dv = e_z x v``, ``dX = e_z x X``; the biases, in
    the body frame, do not change). Roll and pitch are seen through gravity, scale through the
    accelerometer, so a visual-inertial problem without an anchor has exactly these 4."""
    frames = np.asarray(frames, dtype=float).reshape(-1, FRAME_DOF)
    landmarks = np.asarray(landmarks, dtype=float).reshape(-1, POINT_DOF)
    N_f = np.zeros((len(frames), FRAME_DOF, 4))
    N_f[:, 3:6, 0:3] = np.eye(3)
    for k, s in enumerate(frames):
        N_f[k, 0:3, 3] = so3_exp(s[0:3]).T @ EZ
        N_f[k, 3:6, 3] = np.cross(EZ, s[3:6])
        N_f[k, 6:9, 3] = np.cross(EZ, s[6:9])
    N_l = np.zeros((len(landmarks), POINT_DOF, 4))
    N_l[:, :, 0:3] = np.eye(3)
    N_l[:, :, 3] = np.cross(EZ, landmarks)
    return np.concatenate([N_f.reshape(-1, 4), N_l.reshape(-1, 4)])


def frame_retract(s, d):
    """``s [+] d``: ``phi <- Log(Exp(phi) Exp(dphi))``, the rest added; (15,) each."""
    out = np.asarray(s, dtype=float) + d
    out[0:3] = so3_log(so3_exp(s[0:3]) @ so3_exp(d[0:3]))
    return out


class VioProblem:
    """``linearize`` / ``chi2`` / ``solve`` / ``retract`` for F frames and L landmarks.

    ``frames0`` (F, 15) and ``landmarks0`` (L, 3) the start; ``data`` a :class:`VioData`;
    ``loss`` the robust loss of the reprojections (None: plain least squares); ``imu_jacobian``
    ``"analytic"`` (the reference residual's) or ``"numeric"`` (of the loaded implementation's);
    ``sparse`` True or False, or None: sparse from :data:`SPARSE_FROM` unknowns.
    """

    def __init__(self, frames0, landmarks0, data: VioData, impl="solutions", loss=DEFAULT_LOSS,
                 imu_jacobian="analytic", sparse=None):
        if imu_jacobian not in ("analytic", "numeric"):
            raise ValueError(f"imu_jacobian must be 'analytic' or 'numeric', got {imu_jacobian!r}")
        self.imu_jacobian = imu_jacobian
        self.impl = impl_loader.load(impl)
        self.imu = self.impl.module("imu_preintegration")
        self.kernels = self.impl.module("robust_kernels")
        self.loss = RobustLoss.of(loss)
        self.data = data
        self.num_frames, self.num_landmarks = len(frames0), len(landmarks0)
        self.split = FRAME_DOF * self.num_frames
        self.n = self.split + POINT_DOF * self.num_landmarks
        self.x0 = np.concatenate([np.asarray(frames0, dtype=float).ravel(),
                                  np.asarray(landmarks0, dtype=float).ravel()])
        self._last_imu: tuple | None = None
        self.sparse = self.n >= SPARSE_FROM if sparse is None else bool(sparse)
        self._sparse_solver = PerPattern(lambda: sparse_solver(self.impl.module("sparse_solve")))
        self._info_roots = []
        for factor in data.imu:
            cov = np.asarray(factor.preintegrated.covariance)
            info = np.linalg.inv(cov + 1e-15 * np.eye(9))
            self._info_roots.append(np.linalg.cholesky(0.5 * (info + info.T)))  # L L^T = Sigma^-1
        # the IMU factors as arrays, for the analytic Jacobians of all of them at once
        self._imu_i = np.array([f.i for f in data.imu], dtype=np.int64)
        self._imu_j = np.array([f.j for f in data.imu], dtype=np.int64)
        self._stacked = stack_preintegrated([f.preintegrated for f in data.imu])
        self._root_t = np.array(self._info_roots).reshape(-1, 9, 9).transpose(0, 2, 1)  # L^T (K, 9, 9)
        root_dt = np.sqrt(self._stacked.delta_t)[:, None]
        self._walk_scale = np.hstack([np.ones((1, 3)) / data.gyro_walk,
                                      np.ones((1, 3)) / data.accel_walk]) / root_dt  # (K, 6)

    # ------------------------------------------------------------------ layout
    def frames(self, x):
        return np.asarray(x[:self.split]).reshape(-1, FRAME_DOF)

    def landmarks(self, x):
        return np.asarray(x[self.split:]).reshape(-1, POINT_DOF)

    def columns(self, frames, landmarks) -> np.ndarray:
        """The tangent indices of problem-local ``frames`` (a,) then ``landmarks`` (c,): (15a + 3c,)."""
        frames, landmarks = np.asarray(frames, dtype=np.int64), np.asarray(landmarks, dtype=np.int64)
        return np.concatenate([(FRAME_DOF * frames[:, None] + np.arange(FRAME_DOF)).ravel(),
                               (self.split + POINT_DOF * landmarks[:, None] + np.arange(POINT_DOF)).ravel()])

    def retract(self, x, h):
        """Frames by :func:`frame_retract`, landmarks by addition."""
        frames = self.frames(x)
        dframes = np.asarray(h[:self.split]).reshape(-1, FRAME_DOF)
        frames = frames + dframes
        frames[:, 0:3] = log_many(np.matmul(exp_many(self.frames(x)[:, 0:3]), exp_many(dframes[:, 0:3])))
        return np.concatenate([frames.ravel(), self.landmarks(x).ravel() + h[self.split:]])

    # ------------------------------------------------------------------ residuals
    def _imu_residuals(self, frames) -> np.ndarray:
        """Every IMU factor's :meth:`_imu_residual` at the frame states ``frames`` (F, 15): (K, 15).

        The loop calls ``chi2`` at a trial point and then ``linearize`` at the same point once the
        step is taken: the last point's residuals are kept, so each point costs one call of the
        implementation's residual per factor."""
        frames = np.asarray(frames, dtype=float)
        last = self._last_imu
        if last is not None and np.array_equal(last[0], frames):
            return last[1]
        R = exp_many(frames[:, 0:3])
        r = np.array([self._imu_residual(k, frames[f.i], frames[f.j], R[f.i], R[f.j])
                      for k, f in enumerate(self.data.imu)]).reshape(-1, 15)
        self._last_imu = (frames.copy(), r)
        return r

    def _imu_residual(self, k, s_i, s_j, Ri=None, Rj=None):
        """The whitened (15,) residual of IMU factor k: ``L^T r_imu`` (9,) then the bias walk (6,);
        ``Ri``, ``Rj`` ``Exp`` of the frames' rotation vectors where known."""
        d = self.data
        factor = d.imu[k]
        Ri = so3_exp(s_i[0:3]) if Ri is None else Ri
        Rj = so3_exp(s_j[0:3]) if Rj is None else Rj
        r = self.imu.imu_factor_residual((Ri, s_i[6:9], s_i[3:6]), (Rj, s_j[6:9], s_j[3:6]),
                                         factor.preintegrated, (s_i[9:12], s_i[12:15]), d.gravity)
        root_t = np.sqrt(factor.preintegrated.delta_t)
        walk = np.concatenate([(s_j[9:12] - s_i[9:12]) / (d.gyro_walk * root_t),
                               (s_j[12:15] - s_i[12:15]) / (d.accel_walk * root_t)])
        return np.concatenate([self._info_roots[k].T @ r, walk])

    def _imu_jacobians(self, frames) -> np.ndarray:
        """(K, 15, 30): the rows of every :meth:`_imu_residual` in the tangents of its (i, j), at the
        frame states ``frames`` (F, 15): analytic (``course.problems.vio.imu_jacobians``, the
        reference residual's, all factors at once) or, with ``imu_jacobian="numeric"``, central
        differences of the loaded implementation's residual; exact for the bias walk."""
        K = len(self._imu_i)
        J = np.zeros((K, 15, 30))
        if self.imu_jacobian == "analytic":
            _, J_imu = imu_residual_jacobians(frames[self._imu_i], frames[self._imu_j], self._stacked,
                                              self.data.gravity)
            J[:, :9] = np.matmul(self._root_t, J_imu)
        else:
            for k in range(K):
                s_i, s_j = frames[self._imu_i[k]], frames[self._imu_j[k]]
                for col in range(30):
                    d = np.zeros(FRAME_DOF)
                    d[col % 15] = FD_STEP
                    if col < 15:
                        plus = self._imu_residual(k, frame_retract(s_i, d), s_j)
                        minus = self._imu_residual(k, frame_retract(s_i, -d), s_j)
                    else:
                        plus = self._imu_residual(k, s_i, frame_retract(s_j, d))
                        minus = self._imu_residual(k, s_i, frame_retract(s_j, -d))
                    J[k, :9, col] = (plus[:9] - minus[:9]) / (2.0 * FD_STEP)
        walk = np.arange(6)
        J[:, 9 + walk, 9 + walk] = -self._walk_scale
        J[:, 9 + walk, 24 + walk] = self._walk_scale
        return J

    def _reprojection(self, x, jacobians):
        """Whitened residuals (M, 2) and, when asked, Jacobians (M, 2, 15) in the frame, (M, 2, 3) in the point."""
        d = self.data
        frames, points = self.frames(x), self.landmarks(x)
        R = exp_many(frames[:, 0:3])
        Rf, pf = R[d.obs_frame], frames[d.obs_frame, 3:6]
        X_b = np.einsum("mji,mj->mi", Rf, points[d.obs_landmark] - pf)  # R^T (X - p)
        X_c = (X_b - d.t_bc) @ d.R_bc  # R_bc^T (X_b - t_bc), row-wise
        z = np.maximum(X_c[:, 2], MIN_DEPTH)
        fx, fy, cx, cy = d.K[0, 0], d.K[1, 1], d.K[0, 2], d.K[1, 2]
        uv = np.stack([fx * X_c[:, 0] / z + cx, fy * X_c[:, 1] / z + cy], axis=1)
        r = (uv - d.pixels) / d.pixel_sigma
        if not jacobians:
            return r, None, None
        M = len(r)
        P = np.zeros((M, 2, 3))
        P[:, 0, 0], P[:, 0, 2] = fx / z, -fx * X_c[:, 0] / z**2
        P[:, 1, 1], P[:, 1, 2] = fy / z, -fy * X_c[:, 1] / z**2
        P /= d.pixel_sigma
        PB = P @ d.R_bc.T  # (M, 2, 3): d r / d X_b
        skew = np.zeros((M, 3, 3))
        skew[:, 0, 1], skew[:, 0, 2], skew[:, 1, 2] = -X_b[:, 2], X_b[:, 1], -X_b[:, 0]
        skew[:, 1, 0], skew[:, 2, 0], skew[:, 2, 1] = X_b[:, 2], -X_b[:, 1], X_b[:, 0]
        J_frame = np.zeros((M, 2, FRAME_DOF))
        J_frame[:, :, 0:3] = PB @ skew
        J_point = PB @ Rf.transpose(0, 2, 1)
        J_frame[:, :, 3:6] = -J_point
        return r, J_frame, J_point

    def _prior_rows(self, x, jacobians):
        """The frame priors' and the linear prior's residuals (and Jacobian rows as (cols, block))."""
        frames, points = self.frames(x), self.landmarks(x)
        out = []
        for prior in self.data.frame_priors:
            keep = np.isfinite(prior.sigmas)
            r = (frame_difference(frames[prior.frame], prior.reference) / np.where(keep, prior.sigmas, 1.0))[keep]
            cols = FRAME_DOF * prior.frame + np.arange(FRAME_DOF)
            out.append((r, cols, np.diag(1.0 / prior.sigmas[keep]) @ np.eye(FRAME_DOF)[keep] if jacobians else None))
        for lp in (self.data.linear_prior, self.data.anchor):
            if lp is None:
                continue
            dx = np.concatenate([frame_difference(frames[lp.frames], lp.frame_lin).ravel(),
                                 (points[lp.landmarks] - lp.landmark_lin).ravel()])
            out.append((lp.e0 + lp.J @ dx, self.columns(lp.frames, lp.landmarks), lp.J if jacobians else None))
        return out

    def chi2_by_factor(self, x) -> dict:
        """``{factor type: (chi2, dof)}`` at ``x`` in plain squares (no robust loss): the IMU
        factors' rotation, velocity and position rows, the gyroscope's and the accelerometer's
        bias walks, the reprojections and the priors. At the true state of data whose noise the
        factors model, every ``chi2 / dof`` is near 1 (the priors' excepted: their centre is the truth)."""
        x = np.asarray(x, dtype=float)
        frames = self.frames(x)
        imu = self._imu_residuals(frames)
        r, _, _ = self._reprojection(x, False)
        priors = [rows for rows, _, _ in self._prior_rows(x, False)]
        out = {name: (float(np.sum(imu[:, part] ** 2)), imu[:, part].size)
               for name, part in (("IMU rotation", slice(0, 3)), ("IMU velocity", slice(3, 6)),
                                  ("IMU position", slice(6, 9)), ("gyroscope bias walk", slice(9, 12)),
                                  ("accelerometer bias walk", slice(12, 15)))}
        out["reprojection"] = (float(np.sum(r * r)), r.size)
        out["priors"] = (float(sum(rows @ rows for rows in priors)), sum(len(rows) for rows in priors))
        return out

    # ------------------------------------------------------------------ the minimizer's interface
    def chi2(self, x) -> float:
        x = np.asarray(x, dtype=float)
        frames = self.frames(x)
        total = float(np.sum(self._imu_residuals(frames) ** 2))
        r, _, _ = self._reprojection(x, False)
        if len(r):
            total += robust_chi2(self.kernels, self.loss, r) if self.loss else float(np.sum(r * r))
        for rows, _, _ in self._prior_rows(x, False):
            total += float(rows @ rows)
        return total if np.isfinite(total) else float("inf")

    def residual_and_jacobian(self, x):
        """``(r (m,), J (m, n) sparse CSR, chi2)``, the reprojections reweighted by the robust loss."""
        r, J, chi2, _ = self._rows(x, priors_in_J=True)
        return r, J, chi2

    def _rows(self, x, priors_in_J):
        """:meth:`residual_and_jacobian` and, when not ``priors_in_J``, the priors' rows apart (they
        are dense over their variables, where a sparse ``J^T J`` is slow): ``(r, J, chi2, priors)``,
        ``priors`` a list of ``(r (k,), columns (c,), block (k, c))``."""
        x = np.asarray(x, dtype=float)
        frames = self.frames(x)
        fej = self.data.first_estimates
        if fej is not None:
            x_fej = x.copy()
            fej_frames = self.frames(x_fej)
            fej_frames[np.asarray(fej[0], dtype=np.int64)] = fej[1]
            self.landmarks(x_fej)[np.asarray(fej[2], dtype=np.int64)] = fej[3]
        rows, cols, vals, res = [], [], [], []
        m = 0
        chi2 = 0.0

        def add(r, c_idx, block):
            nonlocal m
            k = len(r)
            rr, cc = np.meshgrid(m + np.arange(k), c_idx, indexing="ij")
            rows.append(rr.ravel())
            cols.append(cc.ravel())
            vals.append(np.asarray(block, dtype=float).ravel())
            res.append(r)
            m += k

        K = len(self._imu_i)
        if K:
            r_imu = self._imu_residuals(frames)
            chi2 += float(np.sum(r_imu * r_imu))
            # the Jacobians at the first estimates where given, linearised around the residuals at x
            J_imu = self._imu_jacobians(frames if fej is None else fej_frames)  # (K, 15, 30)
            row = m + 15 * np.arange(K)[:, None, None] + np.arange(15)[None, :, None]
            col = np.concatenate([FRAME_DOF * self._imu_i[:, None] + np.arange(FRAME_DOF),
                                  FRAME_DOF * self._imu_j[:, None] + np.arange(FRAME_DOF)], axis=1)[:, None, :]
            rows.append(np.broadcast_to(row, J_imu.shape).ravel())
            cols.append(np.broadcast_to(col, J_imu.shape).ravel())
            vals.append(J_imu.ravel())
            res.append(r_imu.ravel())
            m += 15 * K
        r, J_f, J_p = self._reprojection(x, True)
        if fej is not None:
            _, J_f, J_p = self._reprojection(x_fej, True)
        if len(r):
            if self.loss is not None:
                r, (J_f, J_p), c = reweight(self.kernels, self.loss, r, (J_f, J_p))
                chi2 += c
            else:
                chi2 += float(np.sum(r * r))
            M = len(r)
            d = self.data
            row = m + 2 * np.arange(M)[:, None, None] + np.arange(2)[None, :, None]
            cf = FRAME_DOF * d.obs_frame[:, None, None] + np.arange(FRAME_DOF)[None, None, :]
            cp = self.split + POINT_DOF * d.obs_landmark[:, None, None] + np.arange(POINT_DOF)[None, None, :]
            rows += [np.broadcast_to(row, J_f.shape).ravel(), np.broadcast_to(row, J_p.shape).ravel()]
            cols += [np.broadcast_to(cf, J_f.shape).ravel(), np.broadcast_to(cp, J_p.shape).ravel()]
            vals += [J_f.ravel(), J_p.ravel()]
            res.append(r.ravel())
            m += 2 * M
        priors = self._prior_rows(x, True)
        chi2 += sum(float(r @ r) for r, _, _ in priors)
        if not priors_in_J:
            J = sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(m, self.n))
            return np.concatenate(res), J, chi2, priors
        starts = []
        for r, c_idx, block in priors:
            starts.append(m)
            add(r, c_idx, block)
        starts.append(m)
        # the rows of the linear prior and of the anchor, the last one or two groups
        groups = [self.data.linear_prior, self.data.anchor]
        n_groups = sum(g is not None for g in groups)
        ranges = list(zip(starts[-n_groups - 1:-1], starts[-n_groups:])) if n_groups else []
        named = [name for name, g in zip(("linear_prior", "anchor"), groups) if g is not None]
        self.prior_row_ranges = dict(zip(named, ranges))
        J = sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(m, self.n))
        return np.concatenate(res), J, chi2, []

    def marginal_system(self, x, remove) -> tuple[np.ndarray, np.ndarray]:
        """``(H, b)`` (n, n), (n,) of the factors that leave the window when the tangent indices
        ``remove`` do: every factor with a row touching them, and the whole linear prior (the new
        prior replaces it); not the anchor, not the factors among the variables that stay (they are
        still in the next window: putting them in the prior too would count them twice)."""
        r, J, _ = self.residual_and_jacobian(x)
        touches = np.asarray(abs(J)[:, np.asarray(remove)].sum(axis=1)).ravel() > 0
        ranges = self.prior_row_ranges
        if "linear_prior" in ranges:
            touches[slice(*ranges["linear_prior"])] = True
        if "anchor" in ranges:
            touches[slice(*ranges["anchor"])] = False
        J_out, r_out = J[touches], r[touches]
        return (J_out.T @ J_out).toarray(), np.asarray(J_out.T @ r_out).ravel()

    def linearize(self, x) -> Linearization:
        """``H = J~^T J~`` (n, n): dense, or its upper triangle (CSC) where the problem is sparse;
        ``b = J~^T r~`` (n,), chi2 (robust)."""
        if self.sparse:
            r, J, chi2 = self.residual_and_jacobian(x)
            return Linearization(H=sp.triu(J.T @ J, format="csc"), b=np.asarray(J.T @ r).ravel(), chi2=float(chi2),
                                 upper=True)
        r, J, chi2, priors = self._rows(x, priors_in_J=False)
        H, b = (J.T @ J).toarray(), np.asarray(J.T @ r).ravel()
        for r_p, columns, block in priors:
            H[np.ix_(columns, columns)] += block.T @ block
            b[columns] += block.T @ r_p
        return Linearization(H=H, b=b, chi2=float(chi2))

    def solve(self, lin: Linearization, damping=None):
        """Step (n,) of ``(H + diag(damping)) h = -b`` by a dense or a sparse Cholesky factorisation."""
        A = lin.with_diagonal_added(damping)
        if lin.upper:
            h = np.asarray(self._sparse_solver.solve(A, lin.b), dtype=np.float64)
            if h.shape != lin.b.shape or not np.all(np.isfinite(h)) or h @ lin.b > 0:
                raise SingularSystemError("vio: the sparse solve gave a non-finite step or an ascent direction: "
                                          "H (+ damping) is not positive definite")
            return h
        try:
            h = scipy.linalg.cho_solve(scipy.linalg.cho_factor(A), -lin.b)
        except np.linalg.LinAlgError:
            raise SingularSystemError("vio: H (+ damping) is not positive definite") from None
        if not np.all(np.isfinite(h)):
            raise SingularSystemError("vio: the Cholesky solve gave a non-finite step")
        return h
