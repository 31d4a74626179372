"""Chapter 5: a sliding-window visual-inertial back end on the simulated data (``course.problems.vio.sim``).

Keyframes are every ``keyframe_every``-th camera frame (default 5: 4 Hz at 20 Hz). The window
holds the last ``window`` keyframes (default 10) and the landmarks (3D points, see
``course.problems.vio.problem``) seen by at least two of them. Each step:

1. add the newest keyframe, initialised by IMU propagation from the previous one
   (``R_j = R_i Delta R``, ``v_j = v_i + g dT + R_i Delta v``,
   ``p_j = p_i + v_i dT + 1/2 g dT^2 + R_i Delta p``, biases carried over), with the IMU factor
   preintegrated at the previous keyframe's current biases;
2. triangulate the landmarks newly seen twice in the window (the point nearest to all the
   rays in least squares, ``sum_k (I - d_k d_k^T)(X - c_k) = 0``; kept when the rays span
   more than :data:`MIN_PARALLAX` and the point is in front of every camera);
3. solve the window with the one minimizer (``minimize(problem, method)``; ``dogleg`` by
   default: Levenberg-Marquardt type 3 starts at lambda ~ 1e8 here (tau max diag(H), with the
   tight first-frame prior) and needs 15 or more iterations where dogleg needs about 5);
4. when the window is full, remove the oldest keyframe and the landmarks no remaining keyframe
   sees:

   - ``"prior"``: marginalise them: the factors that leave with them (every factor on a removed
     variable, and the previous prior; not the factors among the variables that stay, which the
     next window still has) give H, b at the solution (``VioProblem.marginal_system``), Jacobi-scaled,
     reduced by ``marginalisation.marginalise``; the 4 directions no visual-inertial residual sees
     (a translation of the world and a rotation about gravity,
     ``course.problems.vio.problem.gauge_directions``) are taken out of the result (``gauge="project"``),
     and ``prior_residual`` gives the prior ``e0 + J (x [-] x_lin)`` on the kept frames and
     landmarks it touches; the window is then held by :func:`anchor` (position and yaw of its
     oldest frame, at the estimate it had when it became the oldest);
   - ``"drop"``: forget them and their measurements; the window's gauge (position and yaw, and
     the rest of the oldest pose) is held by a prior on the new oldest frame's pose at its
     current estimate (:data:`ANCHOR_SIGMAS`) - no information about v and the biases is kept.

A keyframe's estimate is the one it has when it leaves the window (the last solve that
contained it: a fixed-lag smoother), the last window's for the others. The first keyframe has
a prior (:data:`FIRST_SIGMAS`) at the true pose and velocity and zero biases (the gauge and an
initialisation, as a VIO front end would give). :func:`batch` solves all keyframes at once (the
same factors, no marginalisation), started from a window's estimate. :func:`compare` runs the
three, and GTSAM's batch and fixed-lag smoother on the same problem
(``course.backends.vio.gtsam``), and reports the APE (``course.problems.vio.ape``, SE(3) alignment) and the
time per solve (``python -m course vio NAME``).

Why the prior must not know the gauge. Without the projection the first keyframe's prior (its
position and yaw to 1e-3) passes into every later prior, stiff, linearised once; the factors
that join it are relinearised at every solve, so the prior's "known" directions no longer match
the factors' null directions and it pulls the window along directions nothing measures. The
first-estimate Jacobians (``first_estimates``: the factors on the prior's variables linearised at
``x_lin``, Huang, Mourikis and Roumeliotis 2009) are the other remedy; here they bring little
once the gauge is projected out and make each solve take twice the iterations, so they are off
by default.

APE rmse (m, SE(3) alignment) on six simulations (dogleg; ``python -m course vio NAME``;
GTSAM's batch starts from IMU propagation, ours from our window's estimate)::

                 prior   drop    batch   GTSAM fixed-lag  GTSAM batch   prior, gauge="keep"
    vio-sim:12:0 0.124   0.172   0.165       0.200          0.165           0.163
    vio-sim:8:0  0.067   0.143   0.056       0.064          0.056           0.065
    vio-sim:8:1  0.028   0.097   0.090       0.076          0.090           0.104
    vio-sim:12:1 0.064   0.192   0.043       failed         0.042           0.060
    vio-sim:12:2 0.088   0.244   0.044       0.083          0.044           0.073
    vio-sim:12:3 0.027   0.099   0.019       failed         1.78            -

The window with the prior beats the one without on all six, by 1.4x to 3.6x. Against the batch
it is better on two, within 20% on one, and 1.4x to 2x on the others, as GTSAM's own fixed-lag
smoother is where it runs (0.8x to 1.9x its batch; on two of the six it stops on an
indeterminate system, and its batch from dead reckoning does not reach the optimum on 12:3).
A window's estimate of a keyframe uses the data up to 2.5 s after it, the batch all of it.
Every estimate carries a scale error of up to 1%, the batch included (GTSAM's batch reaches the
same optimum as ours): the noise's doing, not the model's, since without noise GTSAM's batch is
within 0.4 mm of the truth, at a scale of 1.00003.

vio-sim:12:0, where the batch loses to the window, is one draw, not a biased model. Over 20 seeds
(``python -m course vio --seeds 20``) the batch is the closer to the truth on 19, with a mean APE
rmse of 0.052 m against the window's 0.093 m (medians 0.039 and 0.078). At the truth every factor
type's chi2 per degree of freedom is within one standard deviation of 1 (``python -m course vio
--consistency``: IMU rows 0.89 to 1.08, bias walks 0.91 and 1.01, reprojections 0.96), so the
covariances are the simulator's noise (continuous densities made discrete as it draws them); the
analytic gradient agrees with central differences to 4e-7 relative, and the batch ends where it is
zero. Seed 0's noise happens to make the batch's yaw drift (31 mrad over 12 s, against the
window's 20) and scale error larger.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np
from scipy.spatial.transform import Rotation

from course.core import impl as impl_loader
from course.geometry.so3 import so3_exp, so3_log
from course.problems.vio.problem import (
    FRAME_DOF,
    POINT_DOF,
    FramePrior,
    ImuFactor,
    LinearPrior,
    VioData,
    VioProblem,
    frame_difference,
    gauge_directions,
)
from course.problems.vio.sim import VioSim
from course.problems.vio.trajectory_io import Trajectory
from course.solver import SolverOptions, minimize

#: the first keyframe's prior sigmas: rotation (rad), position (m), velocity (m/s), b_g (rad/s), b_a (m/s^2)
FIRST_SIGMAS = np.r_[np.full(3, 1e-3), np.full(3, 1e-3), np.full(3, 0.05), np.full(3, 0.02), np.full(3, 0.1)]
#: the "drop" variant's gauge prior on the oldest frame: its pose only
ANCHOR_SIGMAS = np.r_[np.full(6, 1e-3), np.full(9, np.inf)]
#: the "prior" variant's anchor (position, m, and yaw, rad) on its oldest frame
ANCHOR_GAUGE_SIGMA = 1e-3
#: rays must span this angle (rad) for a landmark to be triangulated
MIN_PARALLAX = np.deg2rad(2.0)
#: a landmark enters the window when this many of its keyframes have seen it
MIN_VIEWS = 2
MIN_TRIANGULATION_DEPTH = 0.5
#: the dogleg's first radius: 1 (tangent units), not Ceres' 1e4, which the halving on a rejected step
#: takes 15 attempts to bring down to a Gauss-Newton step of norm ~0.3 that the Cauchy kernel's
#: curvature makes overshoot
WINDOW_OPTIONS = SolverOptions(max_iterations=20, gradient_tolerance=1e-8, step_tolerance=1e-10,
                               cost_tolerance=1e-6, initial_radius=1.0)
BATCH_OPTIONS = SolverOptions(max_iterations=40, gradient_tolerance=1e-8, step_tolerance=1e-10, cost_tolerance=1e-8,
                              initial_radius=1.0)
VARIANTS = ("prior", "drop")


@dataclass
class VioRun:
    """An estimate: keyframe ``times`` (F,), ``states`` (F, 15) ``(phi, p, v, b_g, b_a)``,
    ``solve_seconds`` (one per minimize call), ``iterations`` (same), ``label``.

    ``steps`` (one dict per solve of a window): ``time`` (s, the newest keyframe's), ``chi2``
    (at the solution, robust), ``frames``, ``landmarks`` (in the window), ``prior_dof`` (the
    variables the marginalisation prior touches, tangent dimension; 0 without) and
    ``prior_rank`` (its rows). ``hessians`` (when asked for with ``keep_hessians_at``):
    ``before`` the window's H (n, n) at its solution, ``removed`` the indices marginalised out of
    it, ``after`` the next window's H at its start (its prior included); ``*_frames`` the frame
    counts (frames first in the layout, 15 each, then the landmarks, 3 each); ``prior_J``
    (r, 15a + 3c) the new prior's Jacobian and its linearisation point ``prior_frame_lin`` (a, 15),
    ``prior_landmark_lin`` (c, 3).
    """

    label: str
    times: np.ndarray
    states: np.ndarray
    solve_seconds: list
    iterations: list
    steps: list = field(default_factory=list)
    hessians: dict = field(default_factory=dict)

    def trajectory(self) -> Trajectory:
        rotations = Rotation.from_rotvec(self.states[:, 0:3])
        return Trajectory(self.times, self.states[:, 3:6].copy(), _quaternions(rotations))


def _quaternions(rotation: Rotation) -> np.ndarray:
    """(N, 4) unit quaternions (w, x, y, z), the trajectory files' order, of N rotations."""
    return np.roll(rotation.as_quat(), 1, axis=1)  # scipy gives (x, y, z, w)


class Keyframes:
    """The keyframes of a simulation: camera frames every ``every``, their IMU indices, observations."""

    def __init__(self, sim: VioSim, every: int):
        self.sim = sim
        self.camera = np.arange(0, len(sim.frame_imu_index), every)
        self.imu_index = sim.frame_imu_index[self.camera]
        self.times = sim.imu_times[self.imu_index]
        self.obs = []
        for f in self.camera:
            sel = np.flatnonzero(sim.obs_frame == f)
            self.obs.append((sim.obs_landmark[sel], sim.obs_pixels[sel]))

    def __len__(self):
        return len(self.camera)

    def truth(self, k) -> np.ndarray:
        i = self.imu_index[k]
        return np.r_[so3_log(self.sim.rotations[i]), self.sim.positions[i], self.sim.velocities[i], np.zeros(6)]

    def preintegrate(self, imu_module, k, state):
        """The preintegration from keyframe k to k + 1 at the biases of ``state``."""
        s = self.sim
        a, b = self.imu_index[k], self.imu_index[k + 1]
        return imu_module.preintegrate(s.gyro[a:b + 1], s.accel[a:b + 1], s.dt, state[9:12], state[12:15],
                                       s.gyro_noise, s.accel_noise)


def propagate(state, pre, gravity) -> np.ndarray:
    """The state (15,) at the end of a preintegration from ``state`` (the module docstring's step 1)."""
    R = so3_exp(state[0:3])
    p, v, T = state[3:6], state[6:9], pre.delta_t
    return np.r_[so3_log(R @ pre.delta_R), p + v * T + 0.5 * gravity * T * T + R @ pre.delta_p,
                 v + gravity * T + R @ pre.delta_v, state[9:15]]


def triangulate(sim: VioSim, states, pixels):
    """The point (3,) nearest to the rays of ``pixels`` (k, 2) seen from frame ``states`` (k, 15),
    or None (parallax below :data:`MIN_PARALLAX`, or behind a camera)."""
    Kinv = np.linalg.inv(sim.K)
    A, rhs, dirs, centres = np.zeros((3, 3)), np.zeros(3), [], []
    for s, uv in zip(states, pixels):
        R = so3_exp(s[0:3])
        d = R @ sim.R_bc @ (Kinv @ np.r_[uv, 1.0])
        d /= np.linalg.norm(d)
        c = s[3:6] + R @ sim.t_bc
        P = np.eye(3) - np.outer(d, d)
        A += P
        rhs += P @ c
        dirs.append(d)
        centres.append(c)
    rays = np.array(dirs)
    cos = np.clip(rays @ rays.T, -1.0, 1.0)
    if np.arccos(cos.min()) < MIN_PARALLAX:
        return None
    X = np.linalg.solve(A, rhs)
    if np.any(np.einsum("ki,ki->k", X - np.array(centres), rays) < MIN_TRIANGULATION_DEPTH):
        return None
    return X


def anchor(state) -> LinearPrior:
    """The gauge anchor of a window whose prior has no gauge information: position and yaw (the
    rotation about gravity, ``(R^T e_z)^T dphi``) of its oldest frame (local index 0) held at
    ``state`` (15,) with :data:`ANCHOR_GAUGE_SIGMA`; (4, 15) rows, ``e = J (s [-] state)``."""
    J = np.zeros((4, FRAME_DOF))
    J[0:3, 3:6] = np.eye(3)
    J[3, 0:3] = so3_exp(state[0:3]).T @ np.array([0.0, 0.0, 1.0])
    return LinearPrior(np.zeros(1, dtype=np.int64), np.zeros(0, dtype=np.int64), np.asarray(state)[None].copy(),
                       np.zeros((0, POINT_DOF)), J / ANCHOR_GAUGE_SIGMA, np.zeros(4))


def _without_gauge(H, b, N):
    """``(P H P, P b)`` with ``P = I - N (N^T N)^-1 N^T`` the projector off the columns of N
    (n, k): the prior then says nothing along them (``H N = 0``, ``b^T N = 0``)."""
    Q, _ = np.linalg.qr(N)
    P = np.eye(len(b)) - Q @ Q.T
    return P @ H @ P, P @ b


def window_data(sim, kfs, frame_ids, landmark_ids, preints, frame_priors, linear_prior=None) -> VioData:
    """A :class:`VioData` over keyframes ``frame_ids`` (consecutive) and ``landmark_ids``."""
    f_local = {f: k for k, f in enumerate(frame_ids)}
    l_local = {lm: k for k, lm in enumerate(landmark_ids)}
    imu = [ImuFactor(f_local[f], f_local[f] + 1, preints[f]) for f in frame_ids[:-1]]
    of, ol, px = [], [], []
    for f in frame_ids:
        lms, pixels = kfs.obs[f]
        for lm, uv in zip(lms, pixels):
            if lm in l_local:
                of.append(f_local[f])
                ol.append(l_local[lm])
                px.append(uv)
    return VioData(imu=imu, obs_frame=np.array(of, dtype=np.int64), obs_landmark=np.array(ol, dtype=np.int64),
                   pixels=np.array(px).reshape(-1, 2), K=sim.K, R_bc=sim.R_bc, t_bc=sim.t_bc, gravity=sim.gravity,
                   pixel_sigma=sim.pixel_noise, gyro_walk=sim.gyro_walk, accel_walk=sim.accel_walk,
                   frame_priors=frame_priors, linear_prior=linear_prior)


def add_landmarks(sim, kfs, frame_ids, states, points, extra=()):
    """The landmark ids of the window (sorted): those with an estimate (triangulated now if
    needed) seen by at least two of ``frame_ids``, and those in ``extra``."""
    seen = {}
    for f in frame_ids:
        lms, pixels = kfs.obs[f]
        for lm, uv in zip(lms, pixels):
            seen.setdefault(int(lm), []).append((f, uv))
    ids = set(int(i) for i in extra)
    for lm, views in seen.items():
        if len(views) < MIN_VIEWS:
            continue
        if lm not in points:
            X = triangulate(sim, [states[f] for f, _ in views], [uv for _, uv in views])
            if X is None:
                continue
            points[lm] = X
        ids.add(lm)
    return sorted(ids)


class _Prior(NamedTuple):
    """The marginalisation prior ``e(x) = e0 + J (x [-] x_lin)`` carried to the next window:
    keyframe ids ``frames`` (a,), landmark ids ``landmarks`` (c,), the linearisation point
    ``frame_lin`` (a, 15) and ``landmark_lin`` (c, 3), ``J`` (r, 15a + 3c), ``e0`` (r,)."""

    frames: list
    landmarks: list
    frame_lin: np.ndarray
    landmark_lin: np.ndarray
    J: np.ndarray
    e0: np.ndarray

    def local(self, frame_ids, lm_ids) -> LinearPrior:
        """The prior on a window over ``frame_ids`` and ``lm_ids`` (its variables in local indices)."""
        f_local = {f: k for k, f in enumerate(frame_ids)}
        l_local = {lm: k for k, lm in enumerate(lm_ids)}
        return LinearPrior(np.array([f_local[f] for f in self.frames], dtype=np.int64),
                           np.array([l_local[lm] for lm in self.landmarks], dtype=np.int64),
                           self.frame_lin, self.landmark_lin, self.J, self.e0)


@dataclass
class _Window:
    """What the sliding window carries from one step to the next: the estimates ``states``
    (keyframe -> (15,)) and ``points`` (landmark -> (3,)), ``preints`` (k -> the preintegration
    from keyframe k to k + 1), the keyframes in the window ``frame_ids`` (consecutive), the
    marginalisation ``prior`` (None until the first), ``anchor_refs`` (oldest keyframe -> the
    (15,) its anchor holds), ``final`` (keyframe -> its (15,) estimate when it left) and
    ``imu_known``: the last solve's IMU residuals at its solution, which the next window starts
    from (``VioProblem.known_imu_residuals``)."""

    states: dict[int, np.ndarray]
    frame_ids: list[int]
    points: dict[int, np.ndarray] = field(default_factory=dict)
    preints: dict = field(default_factory=dict)
    prior: _Prior | None = None
    anchor_refs: dict[int, np.ndarray] = field(default_factory=dict)
    final: dict[int, np.ndarray] = field(default_factory=dict)
    imu_known: dict = field(default_factory=dict)


def sliding_window(sim: VioSim, variant="prior", window=10, keyframe_every=5, method="dogleg",
                   impl="solutions", options=WINDOW_OPTIONS, loss="default", first_estimates=False,
                   keep_hessians_at: int | None = None, gauge="project") -> VioRun:
    """The sliding-window estimate of ``sim`` with ``variant`` ``"prior"`` or ``"drop"`` (module docstring);
    ``first_estimates``: first-estimate Jacobians (``course.problems.vio.problem``) for the prior's frames
    (``"frames"``), for its frames and landmarks (True) or none (False, the default).
    ``keep_hessians_at``: the index of the solve whose H (and the next window's) to keep in
    ``VioRun.hessians``, for the fill-in figure. ``gauge``: ``"project"`` (the default) takes
    the 4 unobservable directions out of every new prior and holds the window by
    :func:`anchor` on its oldest frame; ``"keep"`` leaves the first frame's prior in the chain."""
    if gauge not in ("project", "keep"):
        raise ValueError(f"gauge must be 'project' or 'keep', got {gauge!r}")
    if variant not in VARIANTS:
        raise ValueError(f"variant must be one of {VARIANTS}, got {variant!r}")
    if window < 2:
        raise ValueError(f"window must be at least 2 keyframes, got {window}")
    implementation = impl_loader.load(impl)
    imu_module = implementation.module("imu_preintegration")
    marg = implementation.module("marginalisation")
    kfs = Keyframes(sim, keyframe_every)
    loss_kw = {} if loss == "default" else {"loss": loss}
    w = _Window(states={0: kfs.truth(0)}, frame_ids=[0])
    seconds: list[float] = []
    iterations: list[int] = []
    steps: list[dict] = []
    hessians: dict = {}
    for new in range(1, len(kfs)):
        _add_keyframe(w, kfs, imu_module, new)
        extra = w.prior.landmarks if w.prior is not None else ()
        lm_ids = add_landmarks(sim, kfs, w.frame_ids, w.states, w.points, extra)
        problem, linear = _window_problem(sim, kfs, w, lm_ids, variant, gauge, first_estimates, impl, loss_kw)
        if keep_hessians_at is not None and len(steps) == keep_hessians_at + 1:  # the window after the kept one
            hessians.update(after=problem.linearize(problem.x0).H, after_frames=len(w.frame_ids))
        start = time.perf_counter()
        result = minimize(problem, method, impl, options)
        seconds.append(time.perf_counter() - start)
        w.imu_known = problem.known_imu_residuals(result.params)
        iterations.append(result.iterations)
        steps.append({"time": float(kfs.times[new]), "chi2": float(result.final_chi2), "frames": len(w.frame_ids),
                      "landmarks": len(lm_ids), "prior_dof": 0 if linear is None else int(linear.J.shape[1]),
                      "prior_rank": 0 if linear is None else int(linear.J.shape[0])})
        _update_estimates(w, problem, result.params, lm_ids)
        if len(w.frame_ids) < window or new == len(kfs) - 1:
            continue
        keep = hessians if keep_hessians_at is not None and len(steps) == keep_hessians_at + 1 else None
        _slide(w, kfs, problem, result.params, lm_ids, variant, marg, gauge, first_estimates, keep)
    for f in w.frame_ids:
        w.final[f] = w.states[f].copy()
    order = sorted(w.final)
    return VioRun(f"window {window} ({'with' if variant == 'prior' else 'without'} prior)", kfs.times[order],
                  np.array([w.final[f] for f in order]), seconds, iterations, steps, hessians)


def _add_keyframe(w: _Window, kfs: Keyframes, imu_module, new: int) -> None:
    """Step 1: keyframe ``new`` joins the window, propagated from the previous one's estimate."""
    w.preints[new - 1] = kfs.preintegrate(imu_module, new - 1, w.states[new - 1])
    w.states[new] = propagate(w.states[new - 1], w.preints[new - 1], kfs.sim.gravity)
    w.frame_ids.append(new)


def _window_problem(sim, kfs, w: _Window, lm_ids, variant, gauge, first_estimates, impl,
                    loss_kw) -> tuple[VioProblem, LinearPrior | None]:
    """The window's ``VioProblem`` at the current estimates, and the marginalisation prior in its
    local indices (None before the first): the first keyframe's prior while it is in the window,
    then the gauge's hold (``"drop"``: a prior on the oldest pose; ``"prior"`` and ``"project"``:
    :func:`anchor`)."""
    oldest = w.frame_ids[0]
    priors = []
    if oldest == 0:
        priors.append(FramePrior(0, kfs.truth(0), FIRST_SIGMAS))
    elif variant == "drop":
        priors.append(FramePrior(0, w.states[oldest].copy(), ANCHOR_SIGMAS))
    linear = None if w.prior is None else w.prior.local(w.frame_ids, lm_ids)
    data = window_data(sim, kfs, w.frame_ids, lm_ids, w.preints, priors, linear)
    if variant == "prior" and gauge == "project" and oldest != 0:
        data.anchor = anchor(w.anchor_refs.setdefault(oldest, w.states[oldest].copy()))
    if linear is not None and first_estimates:
        if first_estimates == "frames":
            data.first_estimates = (linear.frames, linear.frame_lin, np.zeros(0, dtype=np.int64), np.zeros((0, 3)))
        else:
            data.first_estimates = (linear.frames, linear.frame_lin, linear.landmarks, linear.landmark_lin)
    problem = VioProblem(np.array([w.states[f] for f in w.frame_ids]),
                         np.array([w.points[lm] for lm in lm_ids]).reshape(-1, 3), data, impl,
                         imu_known=w.imu_known, **loss_kw)
    return problem, linear


def _update_estimates(w: _Window, problem: VioProblem, x, lm_ids) -> None:
    """The window's keyframes and landmarks take their values at the solution ``x``."""
    for k, f in enumerate(w.frame_ids):
        w.states[f] = problem.frames(x)[k].copy()
    for k, lm in enumerate(lm_ids):
        w.points[lm] = problem.landmarks(x)[k].copy()


def _slide(w: _Window, kfs, problem, x, lm_ids, variant, marg, gauge, first_estimates, keep) -> None:
    """Step 4: the oldest keyframe leaves (its estimate final), with the landmarks no remaining
    keyframe sees; ``"prior"`` marginalises them into the next window's prior first. ``keep``:
    the dict to put the Hessians and the prior of this step in (``VioRun.hessians``), or None."""
    oldest = w.frame_ids[0]
    w.final[oldest] = w.states[oldest].copy()
    still_seen: set[int] = set()
    for f in w.frame_ids[1:]:
        still_seen.update(int(i) for i in kfs.obs[f][0])
    gone = [k for k, lm in enumerate(lm_ids) if lm not in still_seen]
    if variant == "prior":
        w.prior = _marginal_prior(w, problem, x, lm_ids, gone, marg, gauge, first_estimates, keep)
    w.frame_ids = w.frame_ids[1:]


def _marginal_prior(w: _Window, problem, x, lm_ids, gone, marg, gauge, first_estimates, keep) -> _Prior:
    """The prior left by marginalising the oldest keyframe and the landmarks ``gone`` (local
    indices) out of the window's system at its solution ``x``, on the kept variables it touches."""
    remove = np.r_[np.arange(FRAME_DOF), problem.split + (POINT_DOF * np.array(gone, dtype=np.int64)[:, None]
                                                          + np.arange(POINT_DOF)).ravel()].astype(np.int64)
    H_m, b_m = problem.marginal_system(x, remove)
    if keep is not None:
        keep.update(before=problem.linearize(x).H, marginalised=H_m, removed=remove, before_frames=len(w.frame_ids))
    # Jacobi scaling D = diag(H)^-1/2 first: H mixes information of 1e10 (gyro-bias walk) and
    # of order 1 (a landmark along its ray), and the relative eigenvalue threshold (eps) of
    # marginalise and prior_residual would otherwise drop the weak directions of H_mm,
    # leaving in the prior information that belongs to the removed variables
    D = 1.0 / np.sqrt(np.maximum(np.diag(H_m), 1e-300))
    H_s, b_s = marg.marginalise(D[:, None] * H_m * D[None, :], D * b_m, remove)
    D_keep = np.delete(D, remove)
    idx, tf, tl = _touched(H_s, w.frame_ids, lm_ids, gone)
    current = np.concatenate([np.array([w.states[f] for f in tf]).reshape(-1, FRAME_DOF).ravel(),
                              np.array([w.points[lm] for lm in tl]).reshape(-1, POINT_DOF).ravel()])
    old_lin: dict[tuple[str, int], np.ndarray] = {}
    if w.prior is not None and first_estimates:  # keep the first estimates of those already in
        old_lin.update({("f", f): v for f, v in zip(w.prior.frames, w.prior.frame_lin)})
        old_lin.update({("l", lm): v for lm, v in zip(w.prior.landmarks, w.prior.landmark_lin)})
    f_lin = np.array([old_lin.get(("f", f), w.states[f]) for f in tf]).reshape(-1, FRAME_DOF)
    l_lin = np.array([old_lin.get(("l", lm), w.points[lm]) for lm in tl]).reshape(-1, POINT_DOF)
    H_p, b_p = H_s[np.ix_(idx, idx)], b_s[idx]
    if gauge == "project":
        H_p, b_p = _without_gauge(H_p, b_p, gauge_directions(f_lin, l_lin) / D_keep[idx][:, None])
    J_s, e0 = marg.prior_residual(H_p, b_p)
    J = J_s / D_keep[idx][None, :]  # J^T J = D^-1 H_s D^-1 = H_prior, J^T e0 = b_prior
    if keep is not None:
        keep.update(prior_J=J, prior_frame_lin=f_lin, prior_landmark_lin=l_lin)
    n_f = FRAME_DOF * len(tf)
    shift = np.concatenate([frame_difference(current[:n_f].reshape(-1, FRAME_DOF), f_lin).ravel(),
                            current[n_f:] - l_lin.ravel()])
    # e(x) = e0 + J (x [-] x_cur) ~ e0 - J (x_cur [-] x_lin) + J (x [-] x_lin): about x_lin
    return _Prior(tf, tl, f_lin, l_lin, J, e0 - J @ shift)


def _touched(H_s, frame_ids, lm_ids, gone) -> tuple[np.ndarray, list, list]:
    """The kept variables that the reduced system ``H_s`` (over the kept keyframes, 15 each, then
    the kept landmarks, 3 each) is not zero on: ``(their indices in H_s, keyframe ids, landmark ids)``."""
    kept_frames = list(range(1, len(frame_ids)))
    kept_lms = [k for k in range(len(lm_ids)) if k not in set(gone)]
    blocks = [(k, FRAME_DOF) for k in kept_frames] + [(k, POINT_DOF) for k in kept_lms]
    offsets = np.cumsum([0] + [d for _, d in blocks])
    scale = np.abs(H_s).max()
    touched = [i for i, (_, d) in enumerate(blocks)
               if np.abs(H_s[offsets[i]:offsets[i] + d]).max() > 1e-12 * scale]
    idx = np.concatenate([np.arange(offsets[i], offsets[i + 1]) for i in touched])
    tf = [frame_ids[blocks[i][0]] for i in touched if i < len(kept_frames)]
    tl = [lm_ids[blocks[i][0]] for i in touched if i >= len(kept_frames)]
    return idx, tf, tl


def batch_problem(sim: VioSim, states, keyframe_every=5, impl="solutions", loss="default", points=None) -> VioProblem:
    """All keyframes and landmarks in one problem (first-keyframe prior, no marginalisation) at
    the keyframe ``states`` (F, 15); the IMU preintegrated at their biases; the landmarks seen by
    :data:`MIN_VIEWS` keyframes, at ``points`` (``{landmark id: (3,)}``) or triangulated."""
    imu_module = impl_loader.load(impl).module("imu_preintegration")
    kfs = Keyframes(sim, keyframe_every)
    if len(states) != len(kfs):
        raise ValueError(f"{len(states)} keyframe states for the simulation's {len(kfs)} keyframes")
    states = {k: np.asarray(states[k], dtype=float).copy() for k in range(len(kfs))}
    preints = {k: kfs.preintegrate(imu_module, k, states[k]) for k in range(len(kfs) - 1)}
    points = {} if points is None else dict(points)
    frame_ids = list(range(len(kfs)))
    lm_ids = add_landmarks(sim, kfs, frame_ids, states, points)
    data = window_data(sim, kfs, frame_ids, lm_ids, preints, [FramePrior(0, kfs.truth(0), FIRST_SIGMAS)])
    loss_kw = {} if loss == "default" else {"loss": loss}
    return VioProblem(np.array([states[k] for k in frame_ids]), np.array([points[lm] for lm in lm_ids]).reshape(-1, 3),
                      data, impl, **loss_kw)


def batch(sim: VioSim, start: VioRun, keyframe_every=5, method="dogleg", impl="solutions",
          options=BATCH_OPTIONS, loss="default") -> VioRun:
    """All keyframes and landmarks in one problem (:func:`batch_problem`), started from
    ``start``'s states; one minimize call."""
    problem = batch_problem(sim, start.states, keyframe_every, impl, loss)  # checks the number of states
    t0 = time.perf_counter()
    result = minimize(problem, method, impl, options)
    seconds = time.perf_counter() - t0
    return VioRun("batch", Keyframes(sim, keyframe_every).times, problem.frames(result.params).copy(), [seconds],
                  [result.iterations])


def true_states(sim: VioSim, keyframe_every=5) -> np.ndarray:
    """The keyframes' true states (F, 15), biases included."""
    kfs = Keyframes(sim, keyframe_every)
    return np.array([np.r_[kfs.truth(k)[:9], sim.bias_gyro[i], sim.bias_accel[i]] for k, i in enumerate(kfs.imu_index)])


def ground_truth(sim: VioSim) -> Trajectory:
    """The true trajectory at the IMU rate."""
    return Trajectory(sim.imu_times, sim.positions, _quaternions(Rotation.from_matrix(sim.rotations)))


__all__ = ["Keyframes", "VioRun", "add_landmarks", "anchor", "batch", "batch_problem", "frame_difference",
           "ground_truth", "propagate", "sliding_window", "triangulate", "true_states", "window_data"]
