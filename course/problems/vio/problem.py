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

- IMU between consecutive frames i, j (the ``imu_preintegration`` exercise): ``r_imu`` (9,) of
  ``imu_factor_residual`` whitened by the preintegrated covariance ``Sigma`` (9, 9):
  ``L^T r_imu`` with ``L L^T = Sigma^-1``; and the bias random walk
  ``((b_g,j - b_g,i) / (sigma_g sqrt(dT)), (b_a,j - b_a,i) / (sigma_a sqrt(dT)))`` (6,).
  The Jacobians of ``r_imu`` in the 30 tangent coordinates of (i, j) are analytic
  (``course.problems.vio.imu_jacobians``, Forster et al.'s, at the rotation rows of the loaded
  implementation's residual; 56 times faster than the central differences with step :data:`FD_STEP`
  through :meth:`retract` that ``imu_jacobian="numeric"`` takes of that residual); the bias walk's are exact.
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

H and b are summed factor by factor: every factor's ``J_k^T J_k`` and ``J_k^T r_k`` (the IMU
factors' 30 columns, a reprojection's 9: its frame's dphi and dp and its point) added where its
columns say, the priors' constant ``J^T J`` kept from the first linearization. A problem of at
least :data:`SPARSE_FROM` unknowns (the 12-s batch: 1488) sums them into H's upper triangle on a
CSC pattern made once and takes the step by the implementation's sparse Cholesky (chapter 2;
SuperLU where qdldl is not installed; the pattern is made once, so it is analysed once); a smaller
one (a window: a few hundred unknowns, with the marginalisation prior's dense block) sums them into a
dense H and takes the implementation's dense Cholesky step (chapter 2's ``dense_solve``), the landmarks
no prior touches eliminated first (:meth:`VioProblem.solve`), which is faster there.
:meth:`VioProblem.residual_and_jacobian` stacks the same rows into a sparse J (the
marginalisation and the tests use it).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, NamedTuple

import numpy as np
import scipy.sparse as sp

from course.core import impl as impl_loader
from course.core.errors import SingularSystemError
from course.geometry.so3 import exp_many, log_many, so3_exp, so3_log
from course.problems.vio.imu_jacobians import imu_jacobians, stack_preintegrated
from course.solver.linearization import Linearization
from course.solver.robust import RobustLoss, evaluate, reweight
from course.solver.superlu import sparse_solver

EZ = np.array([0.0, 0.0, 1.0])

FRAME_DOF, POINT_DOF = 15, 3
#: a frame's rotation and position, the first 6 of its 15 tangent coordinates (a reprojection's only)
POSE_DOF = 6
#: the central-difference step of the numerical IMU Jacobians (tangent units: rad, m, m/s, ...)
FD_STEP = 1e-6
#: below this camera depth (m) a reprojection is clamped (a point behind or at the camera)
MIN_DEPTH = 1e-3
DEFAULT_LOSS = RobustLoss("cauchy", 3.0)
#: from this many unknowns on, H is kept sparse and solved by a sparse Cholesky (measured: the
#: window, 150-400 unknowns with a dense prior block, is faster dense; the batch, 1488, sparse)
SPARSE_FROM = 1000
#: the dense step eliminates the landmarks no prior touches first when there are at least this many
MIN_ELIMINATED = 4


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


class _PriorRows(NamedTuple):
    """A prior as the problem evaluates it: ``e0 + J (x_k [-] x_lin)`` over ``frames`` (a,) and
    ``landmarks`` (c,), linearised at ``frame_lin`` (a, 15) (``R_lin_t`` (a, 3, 3) the transposes of
    their rotations, kept) and ``landmark_lin`` (c, 3); ``columns`` (15a + 3c,) its tangent indices,
    ``J`` (r, 15a + 3c) constant."""

    frames: np.ndarray
    frame_lin: np.ndarray
    R_lin_t: np.ndarray
    e0: np.ndarray
    landmarks: np.ndarray
    landmark_lin: np.ndarray
    columns: np.ndarray
    J: np.ndarray


class _UpperPattern(NamedTuple):
    """H's upper triangle as CSC (``indices`` (nnz,), ``indptr`` (n + 1,)); ``upper``: the entries of
    the factors' concatenated ``J^T J`` blocks on or above the diagonal, ``where``: their positions in
    ``data``; ``prior_data`` (nnz,): the priors' constant ``J^T J``; ``diagonal`` (n,): the diagonal's
    positions."""

    upper: np.ndarray
    where: np.ndarray
    indices: np.ndarray
    indptr: np.ndarray
    prior_data: np.ndarray
    diagonal: np.ndarray


class VioProblem:
    """``linearize`` / ``chi2`` / ``solve`` / ``retract`` for F frames and L landmarks.

    ``frames0`` (F, 15) and ``landmarks0`` (L, 3) the start; ``data`` a :class:`VioData`;
    ``loss`` the robust loss of the reprojections (None: plain least squares); ``imu_jacobian``
    ``"analytic"`` (Forster's formulas at the implementation's residual) or ``"numeric"`` (central
    differences of it);
    ``sparse`` True or False, or None: sparse from :data:`SPARSE_FROM` unknowns.
    ``imu_known``: IMU residuals already computed by the same implementation
    (:meth:`known_imu_residuals` of another problem, e.g. the previous window's at its solution),
    used at the first point where a factor's preintegration and states are the same.
    """

    def __init__(self, frames0, landmarks0, data: VioData, impl="solutions", loss=DEFAULT_LOSS,
                 imu_jacobian="analytic", sparse=None, imu_known: dict | None = None):
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
        self._last_point: tuple | None = None  # (x, {name: value}): :meth:`_at_point`
        self._walk_rows: np.ndarray | None = None  # the bias walk's Jacobian rows, made on the first linearization
        self._imu_known = imu_known or None  # read at the first point only
        self.sparse = self.n >= SPARSE_FROM if sparse is None else bool(sparse)
        self._sparse_solver: Any = None  # the implementation's, made on the first sparse step (one pattern)
        self._dense_module: Any = None  # the implementation's sparse_solve, for dense_solve, on the first dense step
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
        # the tangent columns of every IMU factor (K, 30: frame i's 15, then frame j's) and of every
        # observation (M, 9: its frame's dphi and dp, the only ones a reprojection depends on, then its point's 3)
        self._imu_columns = np.concatenate([FRAME_DOF * self._imu_i[:, None] + np.arange(FRAME_DOF),
                                            FRAME_DOF * self._imu_j[:, None] + np.arange(FRAME_DOF)],
                                           axis=1).reshape(-1, 2 * FRAME_DOF)
        self._obs_columns = np.concatenate(
            [FRAME_DOF * np.asarray(data.obs_frame, dtype=np.int64)[:, None] + np.arange(POSE_DOF),
             self.split + POINT_DOF * np.asarray(data.obs_landmark, dtype=np.int64)[:, None] + np.arange(POINT_DOF)],
            axis=1).reshape(-1, POSE_DOF + POINT_DOF)
        self._all_columns = np.concatenate([self._imu_columns.ravel(), self._obs_columns.ravel()])
        self._flat_index: np.ndarray | None = None  # the dense H's positions of every factor's J^T J
        self._last_rotations: tuple | None = None
        self._priors = [self._frame_prior_rows(prior) for prior in data.frame_priors]
        self._priors += [self._linear_prior_rows(lp) for lp in (data.linear_prior, data.anchor) if lp is not None]
        self._prior_JtJ = np.zeros(0)  # the priors' J^T J blocks (constant), flattened, made with _flat_index
        # the landmarks no prior touches: only their reprojections do, so their block of H is
        # 3x3 block diagonal and the dense step eliminates them first (:meth:`solve`)
        in_priors = {int(k) for lp in (data.linear_prior, data.anchor) if lp is not None for k in lp.landmarks}
        free = np.array([k for k in range(self.num_landmarks) if k not in in_priors], dtype=np.int64)
        self._free_columns = self.split + POINT_DOF * free[:, None] + np.arange(POINT_DOF)  # (e, 3)
        self._kept_columns = np.setdiff1d(np.arange(self.n), self._free_columns.ravel())  # frames first
        self._pattern: _UpperPattern | None = None  # H's upper triangle, made on the first sparse linearization
        self._kept_block: np.ndarray | None = None  # A_KK's flat positions in A, made on the first dense step
        self._free_blocks: np.ndarray = np.zeros(0, dtype=np.int64)  # likewise (e, 3, 3)
        self._pose_free: np.ndarray = np.zeros(0, dtype=np.int64)  # likewise (6F, 3e)
        self._pose_pose: np.ndarray = np.zeros(0, dtype=np.int64)  # likewise (36 F^2,)
        #: every frame's dphi and dp columns (6F,): the only frame columns a reprojection has
        self._pose_columns = (FRAME_DOF * np.arange(self.num_frames)[:, None] + np.arange(POSE_DOF)).ravel()

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
        frames[:, 0:3] = log_many(np.matmul(self._rotations(self.frames(x)), exp_many(dframes[:, 0:3])))
        return np.concatenate([frames.ravel(), self.landmarks(x).ravel() + h[self.split:]])

    def _rotations(self, frames) -> np.ndarray:
        """``Exp(phi_f)`` (F, 3, 3) of the frame states ``frames`` (F, 15); the last point's kept
        (every factor type needs them, and the loop asks for the same point more than once)."""
        last = self._last_rotations
        if last is not None and _same(last[0], frames[:, 0:3]):
            return last[1]
        R = exp_many(frames[:, 0:3])
        self._last_rotations = (frames[:, 0:3].copy(), R)
        return R

    # ------------------------------------------------------------------ residuals
    def _imu_residuals(self, frames) -> np.ndarray:
        """Every IMU factor's :meth:`_imu_residual` at the frame states ``frames`` (F, 15): (K, 15).

        The loop calls ``chi2`` at a trial point and then ``linearize`` at the same point once the
        step is taken: the last point's residuals are kept, so each point costs one call of the
        implementation's residual per factor."""
        frames = np.asarray(frames, dtype=float)
        last = self._last_imu
        if last is not None and _same(last[0], frames):
            return last[1]
        raw = self._raw_imu_residuals(frames)
        walk = (frames[self._imu_j, 9:15] - frames[self._imu_i, 9:15]) * self._walk_scale
        r = np.concatenate([np.matmul(self._root_t, raw[:, :, None])[:, :, 0], walk], axis=1)
        self._last_imu = (frames.copy(), r, raw)
        return r

    def _raw_imu_residuals(self, frames) -> np.ndarray:
        """The implementation's ``imu_factor_residual`` (K, 9) of every IMU factor at the frame states
        ``frames`` (F, 15), not whitened (the last point's kept by :meth:`_imu_residuals`)."""
        last = self._last_imu
        if last is not None and _same(last[0], frames):
            return last[2]
        R = self._rotations(frames)
        given = frames.copy()  # the implementation gets copies: what it does to them stays there
        known, self._imu_known = self._imu_known or {}, None
        rows = []
        for k, f in enumerate(self.data.imu):
            hit = known.get(_imu_key(f, given[f.i], given[f.j])) if known else None
            rows.append(hit[1] if hit is not None and hit[0] is f.preintegrated else
                        self._raw_imu_residual(k, given[f.i], given[f.j], R[f.i].copy(), R[f.j].copy()))
        return np.array(rows).reshape(-1, 9)

    def known_imu_residuals(self, x) -> dict:
        """The implementation's IMU residuals at ``x`` (n,), for another problem's ``imu_known``:
        ``{key: (preintegrated, r (9,))}``, the key naming the preintegration and the two states."""
        frames = np.array(self.frames(np.asarray(x, dtype=float)), dtype=float)
        raw = self._raw_imu_residuals(frames)
        return {_imu_key(f, frames[f.i], frames[f.j]): (f.preintegrated, raw[k].copy())
                for k, f in enumerate(self.data.imu)}

    def _raw_imu_residual(self, k, s_i, s_j, Ri=None, Rj=None):
        """The implementation's ``imu_factor_residual`` (9,) of IMU factor k at frame states ``s_i``,
        ``s_j`` (15,); ``Ri``, ``Rj`` ``Exp`` of their rotation vectors where known."""
        Ri = so3_exp(s_i[0:3]) if Ri is None else Ri
        Rj = so3_exp(s_j[0:3]) if Rj is None else Rj
        return self.imu.imu_factor_residual((Ri, s_i[6:9], s_i[3:6]), (Rj, s_j[6:9], s_j[3:6]),
                                            self.data.imu[k].preintegrated, (s_i[9:12], s_i[12:15]),
                                            self.data.gravity)

    def _imu_residual(self, k, s_i, s_j):
        """The whitened (15,) residual of IMU factor k: ``L^T r_imu`` (9,) then the bias walk (6,)."""
        walk = (s_j[9:15] - s_i[9:15]) * self._walk_scale[k]
        return np.concatenate([self._root_t[k] @ self._raw_imu_residual(k, s_i, s_j), walk])

    def _imu_jacobians(self, frames) -> np.ndarray:
        """(K, 15, 30): the rows of every :meth:`_imu_residual` in the tangents of its (i, j), at the
        frame states ``frames`` (F, 15): analytic (``course.problems.vio.imu_jacobians``, all factors at
        once, at the rotation rows of the loaded implementation's residual) or, with
        ``imu_jacobian="numeric"``, central differences of that residual; exact for the bias walk."""
        K = len(self._imu_i)
        if self._walk_rows is None:  # the bias walk's rows (K, 6, 30), constant
            self._walk_rows = np.zeros((K, 6, 2 * FRAME_DOF))
            walk = np.arange(6)
            self._walk_rows[:, walk, 9 + walk] = -self._walk_scale
            self._walk_rows[:, walk, 24 + walk] = self._walk_scale
        J = np.empty((K, 15, 2 * FRAME_DOF))
        J[:, 9:] = self._walk_rows
        if self.imu_jacobian == "analytic":
            R = self._rotations(frames)
            r_R = self._raw_imu_residuals(frames)[:, 0:3]
            J_imu = imu_jacobians(frames[self._imu_i], frames[self._imu_j], self._stacked, self.data.gravity, r_R,
                                  R[self._imu_i], R[self._imu_j])
            np.matmul(self._root_t, J_imu, out=J[:, :9])
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
        return J

    def _reprojection(self, x, jacobians):
        """Whitened residuals r (M, 2) and, when asked, Jacobians (M, 2, 9) in the observation's
        columns (:attr:`_obs_columns`: its frame's dphi and dp, then its point's 3), else None."""
        d = self.data
        cache = self._at_point(x)
        if "projection" not in cache:
            frames, points = self.frames(x), self.landmarks(x)
            Rf, pf = self._rotations(frames)[d.obs_frame], frames[d.obs_frame, 3:6]
            X_b = np.einsum("mji,mj->mi", Rf, points[d.obs_landmark] - pf)  # R^T (X - p)
            X_c = (X_b - d.t_bc) @ d.R_bc  # R_bc^T (X_b - t_bc), row-wise
            z = np.maximum(X_c[:, 2], MIN_DEPTH)
            uv = np.stack([d.K[0, 0] * X_c[:, 0] / z + d.K[0, 2], d.K[1, 1] * X_c[:, 1] / z + d.K[1, 2]], axis=1)
            cache["projection"] = ((uv - d.pixels) / d.pixel_sigma, Rf, X_b, X_c, z)
        r, Rf, X_b, X_c, z = cache["projection"]
        if not jacobians:
            return r, None
        fx, fy = d.K[0, 0], d.K[1, 1]
        M = len(r)
        P = np.zeros((M, 2, 3))
        P[:, 0, 0], P[:, 0, 2] = fx / z, -fx * X_c[:, 0] / z**2
        P[:, 1, 1], P[:, 1, 2] = fy / z, -fy * X_c[:, 1] / z**2
        P /= d.pixel_sigma
        PB = P @ d.R_bc.T  # (M, 2, 3): d r / d X_b
        J = np.empty((M, 2, POSE_DOF + POINT_DOF))
        a0, a1, a2 = PB[:, :, 0], PB[:, :, 1], PB[:, :, 2]  # each row a (M, 2): a [X_b]_x = a x X_b
        x0, x1, x2 = X_b[:, 0:1], X_b[:, 1:2], X_b[:, 2:3]
        J[:, :, 0], J[:, :, 1], J[:, :, 2] = a1 * x2 - a2 * x1, a2 * x0 - a0 * x2, a0 * x1 - a1 * x0
        J_point = np.matmul(PB, Rf.transpose(0, 2, 1))
        np.negative(J_point, out=J[:, :, 3:6])
        J[:, :, 6:9] = J_point
        return r, J

    def _frame_prior_rows(self, prior: FramePrior) -> _PriorRows:
        """A frame prior in the linear form of :class:`_PriorRows`: ``e0 = 0`` and ``J`` the rows of
        the identity it keeps, scaled by ``1 / sigma`` (its Jacobian, taken at the reference)."""
        keep = np.isfinite(prior.sigmas)
        reference = np.asarray(prior.reference, dtype=float).reshape(1, FRAME_DOF)
        J = (1.0 / np.asarray(prior.sigmas, dtype=float)[keep])[:, None] * np.eye(FRAME_DOF)[keep]
        return _PriorRows(np.array([prior.frame]), reference, exp_many(reference[:, 0:3]).transpose(0, 2, 1),
                          np.zeros(len(J)), np.zeros(0, dtype=np.int64), np.zeros((0, POINT_DOF)),
                          FRAME_DOF * prior.frame + np.arange(FRAME_DOF), J)

    def _linear_prior_rows(self, lp: LinearPrior) -> _PriorRows:
        """A :class:`LinearPrior` as :class:`_PriorRows`, its reference rotations made once."""
        frame_lin = np.asarray(lp.frame_lin, dtype=float).reshape(-1, FRAME_DOF)
        return _PriorRows(np.asarray(lp.frames, dtype=np.int64), frame_lin,
                          exp_many(frame_lin[:, 0:3]).transpose(0, 2, 1), np.asarray(lp.e0, dtype=float),
                          np.asarray(lp.landmarks, dtype=np.int64),
                          np.asarray(lp.landmark_lin, dtype=float).reshape(-1, POINT_DOF),
                          self.columns(lp.frames, lp.landmarks), np.asarray(lp.J, dtype=float))

    def _prior_rows(self, x, jacobians):
        """The frame priors' and the linear priors' residuals (and Jacobian rows) as a list of
        ``(r (k,), columns (c,), block (k, c) or None)``; every block is constant."""
        cache = self._at_point(x)
        if "priors" not in cache:
            frames, points = self.frames(x), self.landmarks(x)
            R = self._rotations(frames) if self._priors else None
            rows = []
            for prior in self._priors:
                d = frames[prior.frames] - prior.frame_lin  # the tangent difference s [-] s_lin of frame_difference
                d[:, 0:3] = log_many(np.matmul(prior.R_lin_t, R[prior.frames]))
                delta = np.concatenate([d.ravel(), (points[prior.landmarks] - prior.landmark_lin).ravel()])
                rows.append(prior.e0 + prior.J @ delta)
            cache["priors"] = rows
        return [(r, prior.columns, prior.J if jacobians else None) for r, prior in zip(cache["priors"], self._priors)]

    def _kernel_values(self, x, r) -> tuple:
        """The robust kernel's ``(rho, d_rho, dd_rho)`` (M,) at the reprojection residuals r (M, 2) of
        the point x (``course.solver.robust.evaluate``), kept for the last point."""
        cache = self._at_point(x)
        if "kernel" not in cache:
            assert self.loss is not None  # asked only under a robust loss
            cache["kernel"] = evaluate(self.kernels, self.loss, np.sum(r * r, axis=1))
        return cache["kernel"]

    def _at_point(self, x) -> dict:
        """What was computed at the point ``x`` (n,) (the reprojections' forward pass, the priors'
        residuals), kept for the last point only: the loop asks ``chi2`` at a trial point and then
        ``linearize`` at the same point once the step is taken."""
        last = self._last_point
        if last is not None and _same(last[0], x):
            return last[1]
        self._last_point = (np.array(x, dtype=float), {})
        return self._last_point[1]

    def chi2_by_factor(self, x) -> dict:
        """``{factor type: (chi2, dof)}`` at ``x`` in plain squares (no robust loss): the IMU
        factors' rotation, velocity and position rows, the gyroscope's and the accelerometer's
        bias walks, the reprojections and the priors. At the true state of data whose noise the
        factors model, every ``chi2 / dof`` is near 1 (the priors' excepted: their centre is the truth)."""
        x = np.asarray(x, dtype=float)
        frames = self.frames(x)
        imu = self._imu_residuals(frames)
        r, _ = self._reprojection(x, False)
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
        r, _ = self._reprojection(x, False)
        if len(r):
            if not self.loss:
                total += float(np.sum(r * r))
            elif not np.all(np.isfinite(r)):
                total = float("inf")
            else:
                total += float(np.sum(self._kernel_values(x, r)[0]))
        for rows, _, _ in self._prior_rows(x, False):
            total += float(rows @ rows)
        return total if np.isfinite(total) else float("inf")

    def residual_and_jacobian(self, x):
        """``(r (m,), J (m, n) sparse CSR, chi2)``, the reprojections reweighted by the robust loss;
        the rows: the IMU factors' (15 each), the reprojections' (2 each), then the priors'."""
        groups, priors, chi2 = self._factor_blocks(x)
        rows, cols, vals, res = [], [], [], []
        m = 0
        for r, c_idx, block in groups:
            k, d = r.shape
            row = m + d * np.arange(k)[:, None, None] + np.arange(d)[None, :, None]
            rows.append(np.broadcast_to(row, block.shape).ravel())
            cols.append(np.broadcast_to(c_idx[:, None, :], block.shape).ravel())
            vals.append(block.ravel())
            res.append(r.ravel())
            m += k * d
        starts = []
        for r, c_idx, block in priors:
            starts.append(m)
            rr, cc = np.meshgrid(m + np.arange(len(r)), c_idx, indexing="ij")
            rows.append(rr.ravel())
            cols.append(cc.ravel())
            vals.append(np.asarray(block, dtype=float).ravel())
            res.append(r)
            m += len(r)
        starts.append(m)
        # the rows of the linear prior and of the anchor, the last one or two groups
        named = [name for name, g in (("linear_prior", self.data.linear_prior), ("anchor", self.data.anchor))
                 if g is not None]
        self.prior_row_ranges = dict(zip(named, zip(starts[len(starts) - 1 - len(named):-1],
                                                    starts[len(starts) - len(named):])))
        J = sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(m, self.n))
        return np.concatenate(res), J, chi2

    def _factor_blocks(self, x):
        """The whitened (and robustly reweighted) rows at ``x`` by factor type, with their Jacobians:
        ``(groups, priors, chi2)``. ``groups``: the IMU factors' ``(r (K, 15), columns (K, 30), J (K,
        15, 30))`` and the reprojections' ``(r (M, 2), columns (M, 9), J (M, 2, 9))`` (the frame's
        dphi and dp columns, then the point's 3), where there are any; ``priors``: a list of ``(r (k,),
        columns (c,), block (k, c))``, dense over their variables."""
        x = np.asarray(x, dtype=float)
        frames = self.frames(x)
        fej = self.data.first_estimates
        if fej is not None:
            x_fej = x.copy()
            fej_frames = self.frames(x_fej)
            fej_frames[np.asarray(fej[0], dtype=np.int64)] = fej[1]
            self.landmarks(x_fej)[np.asarray(fej[2], dtype=np.int64)] = fej[3]
        groups = []
        chi2 = 0.0
        imu_cols, obs_cols = self._imu_columns, self._obs_columns
        if len(self._imu_i):
            r_imu = self._imu_residuals(frames)
            chi2 += float(np.sum(r_imu * r_imu))
            # the Jacobians at the first estimates where given, linearised around the residuals at x
            groups.append((r_imu, imu_cols, self._imu_jacobians(frames if fej is None else fej_frames)))
        r, J_obs = self._reprojection(x, True)
        if fej is not None:
            _, J_obs = self._reprojection(x_fej, True)
        if len(r):
            if self.loss is not None:
                r, (J_obs,), c = reweight(self.kernels, self.loss, r, (J_obs,), self._kernel_values(x, r))
                chi2 += c
            else:
                chi2 += float(np.sum(r * r))
            groups.append((r, obs_cols, J_obs))
        priors = self._prior_rows(x, True)
        chi2 += sum(float(r @ r) for r, _, _ in priors)
        return groups, priors, chi2

    def _dense_normal_equations(self, x) -> tuple[np.ndarray, np.ndarray, float]:
        """``(H (n, n), b (n,), chi2)`` summed factor by factor: each factor's ``J_k^T J_k`` and
        ``J_k^T r_k`` added at its columns, the priors' constant ``J^T J`` blocks with them (one
        ``bincount`` over all of them, which writes H once); equal to ``J^T J`` and ``J^T r`` of
        :meth:`residual_and_jacobian` to rounding."""
        groups, priors, chi2 = self._factor_blocks(x)
        n = self.n
        if self._flat_index is None:  # the (c, c) positions in H of every factor's block, then the priors'
            self._flat_index = np.concatenate([(c[:, :, None] * n + c[:, None, :]).ravel()
                                               for c in (self._imu_columns, self._obs_columns)]
                                              + [(columns[:, None] * n + columns).ravel() for _, columns, _ in priors])
            self._prior_JtJ = np.concatenate([(block.T @ block).ravel() for _, _, block in priors] + [np.zeros(0)])
        JtJ, b = self._block_products(groups, priors, self._prior_JtJ)
        H: np.ndarray = np.bincount(self._flat_index, JtJ, minlength=n * n).reshape(n, n).astype(float, copy=False)
        return H, b, chi2

    def _block_products(self, groups, priors, tail=None) -> tuple[np.ndarray, np.ndarray]:
        """Every factor's ``J_k^T J_k``, flattened and concatenated (the IMU factors', then the
        reprojections', then ``tail`` where given), and b (n,): the factors' ``J_k^T r_k`` summed at
        their columns, the priors' added."""
        JtJ = np.concatenate([np.matmul(J.transpose(0, 2, 1), J).ravel() for _, _, J in groups]
                             + [np.zeros(0) if tail is None else tail])
        Jtr = np.concatenate([np.matmul(r[:, None, :], J).ravel() for r, _, J in groups] + [np.zeros(0)])
        b: np.ndarray = np.bincount(self._all_columns, Jtr, minlength=self.n).astype(float, copy=False)
        for r_p, columns, block in priors:
            b[columns] += r_p @ block
        return JtJ, b

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

    def _upper_pattern(self, groups, priors) -> _UpperPattern:
        """The pattern of H's upper triangle (CSC) from the factors' columns, the priors' and the
        diagonal, and where every upper entry of every factor's ``J^T J`` block and of the priors'
        (constant) ``J^T J`` adds in its ``data``: made once, as chapter 2 scatters into a pattern."""
        n = self.n
        block_rows = [np.broadcast_to(c[:, :, None], (len(c), c.shape[1], c.shape[1])).ravel() for _, c, _ in groups]
        block_cols = [np.broadcast_to(c[:, None, :], (len(c), c.shape[1], c.shape[1])).ravel() for _, c, _ in groups]
        rows, cols = np.concatenate(block_rows + [np.zeros(0, dtype=np.int64)]), \
            np.concatenate(block_cols + [np.zeros(0, dtype=np.int64)])
        upper = np.flatnonzero(rows <= cols)
        prior_rows, prior_cols, prior_values = [], [], []
        for _, columns, block in priors:
            JtJ = block.T @ block
            r, c = np.meshgrid(columns, columns, indexing="ij")
            keep = r <= c
            prior_rows.append(r[keep])
            prior_cols.append(c[keep])
            prior_values.append(JtJ[keep])
        diagonal = np.arange(n)
        all_rows = np.concatenate([rows[upper], *prior_rows, diagonal])
        all_cols = np.concatenate([cols[upper], *prior_cols, diagonal])
        shape = sp.csc_matrix((np.ones(len(all_rows)), (all_rows, all_cols)), shape=(n, n))  # duplicates summed
        shape.sort_indices()
        indptr, nnz = shape.indptr, shape.nnz
        keys = np.repeat(np.arange(n, dtype=np.int64), np.diff(indptr)) * n + shape.indices  # ascending: CSC order
        where = np.searchsorted(keys, all_cols * n + all_rows)
        prior_where = where[len(upper):len(all_rows) - n]
        prior_data = np.bincount(prior_where, np.concatenate(prior_values + [np.zeros(0)]), minlength=nnz)
        return _UpperPattern(upper, where[:len(upper)], (keys % n).astype(np.int32), indptr.astype(np.int32),
                             prior_data.astype(float), np.searchsorted(keys, diagonal * n + diagonal))

    def _sparse_normal_equations(self, x) -> Linearization:
        """:meth:`_dense_normal_equations` into H's upper triangle (CSC) on the pattern of
        :meth:`_upper_pattern`."""
        groups, priors, chi2 = self._factor_blocks(x)
        if self._pattern is None:
            self._pattern = self._upper_pattern(groups, priors)
        pattern = self._pattern
        JtJ, b = self._block_products(groups, priors)
        data = np.bincount(pattern.where, JtJ[pattern.upper], minlength=len(pattern.prior_data)) + pattern.prior_data
        H = sp.csc_matrix((data, pattern.indices, pattern.indptr), shape=(self.n, self.n))
        return Linearization(H=H, b=b, chi2=float(chi2), upper=True, diagonal_positions=pattern.diagonal)

    def linearize(self, x) -> Linearization:
        """``H = J~^T J~`` (n, n): dense, or its upper triangle (CSC) where the problem is sparse;
        ``b = J~^T r~`` (n,), chi2 (robust)."""
        if self.sparse:
            return self._sparse_normal_equations(x)
        H, b, chi2 = self._dense_normal_equations(x)
        return Linearization(H=H, b=b, chi2=float(chi2))

    def solve(self, lin: Linearization, damping=None):
        """Step (n,) of ``(H + diag(damping)) h = -b`` by a dense or a sparse Cholesky factorisation."""
        A = lin.with_diagonal_added(damping)
        if lin.upper:
            if self._sparse_solver is None:  # H's pattern is made once (:meth:`_upper_pattern`): one analysis
                self._sparse_solver = sparse_solver(self.impl.module("sparse_solve"))
            h = np.asarray(self._sparse_solver.solve(A, lin.b), dtype=np.float64)
            if h.shape != lin.b.shape or not np.all(np.isfinite(h)) or h @ lin.b > 0:
                raise SingularSystemError("vio: the sparse solve gave a non-finite step or an ascent direction: "
                                          "H (+ damping) is not positive definite")
            return h
        if not np.all(np.isfinite(A)):
            raise SingularSystemError("vio: H (+ damping) has a non-finite entry")
        try:
            h = self._eliminating_free_landmarks(A, lin.b) if len(self._free_columns) >= MIN_ELIMINATED \
                else self._dense_step(A, lin.b)
        except np.linalg.LinAlgError:
            raise SingularSystemError("vio: H (+ damping) is not positive definite") from None
        if not np.all(np.isfinite(h)):
            raise SingularSystemError("vio: the Cholesky solve gave a non-finite step")
        return h

    def _eliminating_free_landmarks(self, A, b) -> np.ndarray:
        """``h`` of ``A h = -b`` (A dense (n, n), positive definite) with the landmarks no prior touches
        (e of them, columns E; the rest K, frames first) eliminated first: their block ``A_EE`` is 3x3
        block diagonal and they are coupled to the frames' pose columns P (each frame's dphi and dp,
        the only ones a reprojection has) alone, so with ``W = A_PE A_EE^-1``::

            S = A_KK - [W A_EP at (P, P)],   S h_K = -b_K + [W b_E at P],   h_E = -A_EE^-1 (b_E + A_EP h_P)

        a Cholesky factorisation of S (frames and the priors' landmarks) instead of the whole A:
        the same step to rounding, about half the flops on a window. A is positive definite
        exactly when every 3x3 block of ``A_EE`` and S are (``LinAlgError`` otherwise; the blocks'
        leading minors decide theirs, :func:`_inverse_3x3_spd`)."""
        E, K = self._free_columns, self._kept_columns
        e, n = len(E), self.n
        if self._kept_block is None:  # flat positions in A, made on the first dense step
            E_flat, P = E.ravel(), self._pose_columns
            self._kept_block = K[:, None] * n + K
            self._free_blocks = (E[:, :, None] * n + E[:, None, :]).reshape(e, POINT_DOF, POINT_DOF)
            self._pose_free = P[:, None] * n + E_flat  # (6F, 3e)
            self._pose_pose = (P[:, None] * len(K) + P).ravel()  # (P, P) in S (the frames lead K)
        inv_EE = _inverse_3x3_spd(A.take(self._free_blocks))
        A_PE = A.take(self._pose_free)  # (p, 3e)
        P = self._pose_columns
        W = np.matmul(A_PE.reshape(len(P), e, POINT_DOF).transpose(1, 0, 2), inv_EE).transpose(1, 0, 2)
        W = W.reshape(len(P), -1)
        S = A.take(self._kept_block)
        S.reshape(-1)[self._pose_pose] -= (W @ A_PE.T).ravel()
        b_E = b[E.ravel()]
        rhs = -b[K]
        rhs[P] += W @ b_E
        h = np.empty(n)
        h[K] = self._dense_step(S, -rhs)
        coupled = (b_E + A_PE.T @ h[P]).reshape(e, POINT_DOF)
        h[E.ravel()] = -np.einsum("eij,ej->ei", inv_EE, coupled).ravel()
        return h

    def _dense_step(self, A, b) -> np.ndarray:
        """``h`` (n,) of ``A h = -b``, A dense and positive definite: the implementation's
        ``sparse_solve.dense_solve`` (chapter 2's exercise; ``LinAlgError`` from the reference when A
        is not positive definite)."""
        if self._dense_module is None:  # looked up once (the implementation's modules are instrumented then)
            self._dense_module = self.impl.module("sparse_solve")
        return np.asarray(self._dense_module.dense_solve(A, b), dtype=np.float64)


def _inverse_3x3_spd(A) -> np.ndarray:
    """``A^-1`` (e, 3, 3) of symmetric 3x3 blocks A (e, 3, 3) by their adjugates; ``LinAlgError``
    unless every block is positive definite (its three leading minors positive, Sylvester's criterion)."""
    a, b, c = A[:, 0, 0], A[:, 0, 1], A[:, 0, 2]
    d, f, g = A[:, 1, 1], A[:, 1, 2], A[:, 2, 2]
    c00, c01, c02 = d * g - f * f, c * f - b * g, b * f - c * d
    det = a * c00 + b * c01 + c * c02
    if not (np.all(a > 0) and np.all(a * d - b * b > 0) and np.all(det > 0)):
        raise np.linalg.LinAlgError("a 3x3 block is not positive definite")
    out = np.empty_like(A)
    out[:, 0, 0], out[:, 0, 1], out[:, 0, 2] = c00, c01, c02
    out[:, 1, 1], out[:, 1, 2], out[:, 2, 2] = a * g - c * c, b * c - a * f, a * d - b * b
    out[:, 1, 0], out[:, 2, 0], out[:, 2, 1] = c01, c02, out[:, 1, 2]
    out /= det[:, None, None]
    return out


def _same(kept: np.ndarray, a: np.ndarray) -> bool:
    """``np.array_equal`` of a kept array and a float array ``a``, without its conversions (the caches'
    test, made several times per point)."""
    return kept.shape == a.shape and bool((kept == a).all())


def _imu_key(factor: ImuFactor, s_i: np.ndarray, s_j: np.ndarray) -> tuple:
    """What an IMU residual depends on: the factor's preintegration (by identity: the value kept
    with the residual is compared with ``is``) and the two frame states (15,), by their bytes."""
    return id(factor.preintegrated), s_i.tobytes(), s_j.tobytes()
