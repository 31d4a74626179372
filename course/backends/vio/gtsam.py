"""Chapter 5's sliding window and batch through GTSAM: the same visual-inertial problem, GTSAM's factors.

The problem is ``course.problems.vio.problem``'s on the keyframes of ``course.problems.vio.window`` (every
``keyframe_every``-th camera frame), with the same landmarks and the same noise:

- keys ``X(k)`` a ``Pose3`` ``(R_wb, p)``, ``V(k)`` the world velocity (3,), ``B(k)`` an
  ``imuBias.ConstantBias(b_a, b_g)`` (GTSAM's order: accelerometer first), ``L(l)`` a ``Point3``;
  our state (15,) ``(phi, p, v, b_g, b_a)`` maps to ``Pose3(Rot3(Exp(phi)), p)``, ``v``,
  ``ConstantBias(b_a, b_g)`` and back (:func:`to_values`, :func:`states_of`);
- ``ImuFactor(X_i, V_i, X_j, V_j, B_i)``: the preintegration from keyframe i to j at B_i's
  estimate ("b hat"), corrected to first order in the bias inside the factor, as ours. Covariance
  convention: ``setGyroscopeCovariance(gyro_noise^2 I)`` (a density: GTSAM divides by dt per
  sample, as our ``Q_k = density^2 / dt``), likewise the accelerometer, integration covariance 0.
  GTSAM's ``preintMeasCov`` (9, 9) is on ``(phi, p, v)``, ours on ``(phi, v, p)`` (both in the
  frame of keyframe i); reordered, the two agree to 1.5e-3 relative or better on each 0.25-s
  interval of ``vio-sim:4:0`` (tests/test_gtsam_vio.py);
- ``BetweenFactorConstantBias(B_i, B_j, 0)`` with sigmas ``(accel_walk, gyro_walk) sqrt(dT)``: our
  bias random walk. Not ``CombinedImuFactor``: it propagates the walk inside the preintegration,
  so that its (15, 15) covariance couples the deltas with the bias change over the interval; ours
  treats the walk as a separate, independent residual, which is ``ImuFactor`` + ``BetweenFactor``;
- ``GenericProjectionFactorCal3_S2(u, X_f, L_l, K, body_P_sensor=Pose3(R_bc, t_bc))``, noise
  ``Robust(Cauchy(3), Isotropic.Sigma(2, pixel_noise))``. GTSAM's Cauchy on the whitened norm e is
  ``rho(e) = k^2 / 2 log(1 + e^2 / k^2)``, weight ``k^2 / (k^2 + e^2)``: with ``s = e^2`` exactly half
  of ours (``robust_kernels.cauchy``: ``a^2 log(1 + s / a^2)``, ``rho' = 1 / (1 + s / a^2)``), as
  GTSAM's error is ``chi2 / 2`` for every factor: the same kernel and scale (3 whitened pixels).
  GTSAM linearises it with the weight alone (IRLS), ours with Triggs' second-order correction
  where ``s < a^2``: the same minimum, a different path. A point behind its camera scores
  ``2 f_x`` pixels in each coordinate with zero Jacobians in GTSAM; ours clamps the depth;
- priors on keyframe 0 at the truth (zero biases) with ``FIRST_SIGMAS``: ``PriorFactorPose3``
  (tangent ``(rotation, translation)``, the translation in the body frame: the same as our world
  frame difference for the isotropic position sigma), ``PriorFactorVector`` on V(0),
  ``PriorFactorConstantBias`` on B(0).

IMU samples. GTSAM integrates each interval with its left sample (Euler: ``a_k``, ``omega_k``);
ours with both ends (the ``imu_preintegration`` exercise, "midpoint"). On this loop the two differ
by 0.007 to 0.017 m/s in Delta v over a 0.25-s keyframe interval, 7 to 17 times the preintegrated
velocity sigma (1e-3 m/s; Delta p likewise): not the same problem. ``imu_samples="midpoint"`` (the default) hands
GTSAM's integrator, per interval ``[t_k, t_k+1]`` of the raw samples, the rate
``w = (omega_k + omega_k+1) / 2`` and the specific force
``a = ((a_k - b_a) + Exp((w - b_g) dt) (a_k+1 - b_a)) / 2 + b_a`` (``b`` the preintegration's
b hat), whose Euler step is exactly our midpoint step: the deltas agree with ours to 3e-8 rad
and 3e-5 sigma (the bias Jacobians to O(dt): GTSAM does not see the bias inside ``Exp``).
Checked on the whole problem: at a start of ``vio-sim:12:0`` twice GTSAM's ``graph.error`` is our
chi2 to 6e-6 relative, and both batches reach the same minimum (below).
``imu_samples="raw"`` feeds the samples as measured (GTSAM's own scheme).

:func:`gtsam_batch`: all keyframes in one graph, ``LevenbergMarquardtOptimizer``.
:func:`gtsam_window`: ``BatchFixedLagSmoother`` (Levenberg-Marquardt over the whole lag at each
update, then the keys older than the lag marginalised, by elimination at the current estimate,
into ``LinearContainerFactor`` s). The variables of a marginal keep that linearisation point for
every factor afterwards (its ``enforceConsistency``, on): first estimates for the frames *and*
landmarks of the marginal, as our ``first_estimates=True``, with one difference: GTSAM evaluates
their factors' residuals there too and carries their step, where ours takes the residuals at the
current estimate. How it is made to hold our window:

- a key is marginalised when its timestamp is older than ``t_now - lag`` (``t_now`` the newest
  timestamp), after the update's optimisation. Frames carry their keyframe's time; a landmark the
  time of the latest keyframe that observes it, updated (the ``timestamps`` argument overwrites)
  at every keyframe that does: it leaves with the last keyframe that sees it, as ours;
- each step is two updates: the new keyframe's factors and values with the lag held at
  ``(window - 0.5) dT`` (nothing leaves; timed: ``solve_seconds``, ``iterations``); then, once
  ``window`` keyframes are in, the estimates are read and an empty update with the lag at
  ``(window - 1.5) dT`` marginalises the oldest keyframe and its landmarks (one more LM
  iteration on a converged window, not timed, as our marginalisation is not). A single update
  with that lag would solve the same window and marginalise in the same call, but the leaving
  keyframe's estimate could no longer be read. (With the lag ``(window - 1) dT`` the keyframe
  ``window - 1`` intervals old sits on the cut, where only "older than" marginalises: rounding
  would decide between ``window`` and ``window + 1`` keyframes per solve.)

The fixed-lag smoothers of ``gtsam`` 4.3 (``gtsam.BatchFixedLagSmoother``,
``gtsam.IncrementalFixedLagSmoother``; ``gtsam_unstable`` has none in this wheel) both work so;
the incremental one (iSAM2) does one Gauss-Newton step per update and relinearises by threshold,
without first estimates: not our window's solve-to-convergence.

Figures on ``vio-sim:12:0`` (49 keyframes; APE rmse after SE(3) alignment; seconds per
``optimize()`` or solving update, ``nice``, on a 2-core machine under a load of about 3)::

    GTSAM batch from IMU propagation   0.165 m   0.7-1.2 s     (100 LM iterations)
    GTSAM batch from our window        0.165 m   0.15 s        (28 iterations)
    GTSAM fixed-lag, window 10         0.200 m   0.012-0.019 s (4.4 iterations per update)
    the same, imu_samples="raw"        0.178 m / 0.178 m / 0.225 m

Both batches find our batch's minimum: from the same start twice GTSAM's final error is our chi2
at our solution, 1294.87, and the keyframe positions agree to 0.3 mm. The fixed-lag smoother's
0.200 m is above our window with the prior (0.124 m) and its nearest analogue among ours, the
window with first estimates on the prior's frames and landmarks and the gauge kept (0.164 m). The 0.9%
scale error of that minimum is the noise's: on noise-free data the batch is 0.4 mm off (scale
1.00003); with pixel noise alone 0.104 m (scale 1.0058); on seeds 1 and 2, 0.042 m and 0.044 m.
From the dead-reckoned start (19 m off after 12 s) LM needs 100 iterations here and 131 on
``vio-sim:12:2``, hence :data:`BATCH_ITERATIONS` well above our batch's 40.
"""

from __future__ import annotations

import time

import numpy as np

from course.geometry.so3 import so3_exp, so3_log
from course.problems.vio.sim import VioSim
from course.problems.vio.window import FIRST_SIGMAS, Keyframes, VioRun, add_landmarks

#: the reprojections' Cauchy scale, in whitened units (as ``course.problems.vio.problem.DEFAULT_LOSS``)
CAUCHY_SCALE = 3.0
IMU_SAMPLES = ("midpoint", "raw")
#: Levenberg-Marquardt stops when an iteration lowers the error by less than this, relative
#: (``relativeErrorTol``; ours ``cost_tolerance``), or after the iterations (ours: BATCH_OPTIONS, WINDOW_OPTIONS)
BATCH_TOLERANCE, BATCH_ITERATIONS = 1e-8, 300
WINDOW_TOLERANCE, WINDOW_ITERATIONS = 1e-6, 20


def imu_params(sim: VioSim):
    """``gtsam.PreintegrationParams`` with the sim's gravity and noise densities (module docstring)."""
    import gtsam

    params = gtsam.PreintegrationParams(np.asarray(sim.gravity, dtype=float))
    params.setGyroscopeCovariance(sim.gyro_noise**2 * np.eye(3))
    params.setAccelerometerCovariance(sim.accel_noise**2 * np.eye(3))
    params.setIntegrationCovariance(np.zeros((3, 3)))
    return params


def preintegrate(sim: VioSim, a: int, b: int, bias_gyro, bias_accel, imu_samples="midpoint"):
    """``gtsam.PreintegratedImuMeasurements`` of IMU samples ``a .. b`` (b - a intervals) at the
    biases ``bias_gyro``, ``bias_accel`` (3,), the samples fed as ``imu_samples`` says."""
    import gtsam

    if imu_samples not in IMU_SAMPLES:
        raise ValueError(f"imu_samples must be one of {IMU_SAMPLES}, got {imu_samples!r}")
    bg, ba = np.asarray(bias_gyro, dtype=float), np.asarray(bias_accel, dtype=float)
    gyro, accel = sim.gyro[a:b + 1], sim.accel[a:b + 1]
    if imu_samples == "raw":
        rates, forces = gyro[:-1], accel[:-1]
    else:
        rates = (gyro[:-1] + gyro[1:]) / 2.0
        turned = np.stack([so3_exp((w - bg) * sim.dt) @ (f - ba) for w, f in zip(rates, accel[1:])])
        forces = (accel[:-1] - ba + turned) / 2.0 + ba
    pim = gtsam.PreintegratedImuMeasurements(imu_params(sim), gtsam.imuBias.ConstantBias(ba, bg))
    for w, f in zip(rates, forces):
        pim.integrateMeasurement(f, w, sim.dt)
    return pim


def to_values(states: dict, points: dict):
    """``gtsam.Values`` of frame states ``{k: (15,)}`` and landmarks ``{l: (3,)}``."""
    import gtsam
    from gtsam.symbol_shorthand import B, L, V, X

    values = gtsam.Values()
    for k, s in states.items():
        values.insert(X(k), gtsam.Pose3(gtsam.Rot3(so3_exp(s[0:3])), np.asarray(s[3:6], dtype=float)))
        values.insert(V(k), np.asarray(s[6:9], dtype=float))
        values.insert(B(k), gtsam.imuBias.ConstantBias(np.asarray(s[12:15], dtype=float),
                                                       np.asarray(s[9:12], dtype=float)))
    for lm, X_l in points.items():
        values.insert(L(lm), np.asarray(X_l, dtype=float))
    return values


def states_of(values, frames) -> np.ndarray:
    """(len(frames), 15) our states ``(phi, p, v, b_g, b_a)`` of keyframes ``frames`` in ``values``."""
    from gtsam.symbol_shorthand import B, V, X

    out = np.empty((len(frames), 15))
    for row, k in enumerate(frames):
        pose, bias = values.atPose3(X(k)), values.atConstantBias(B(k))
        out[row] = np.r_[so3_log(pose.rotation().matrix()), pose.translation(), values.atVector(V(k)),
                         bias.gyroscope(), bias.accelerometer()]
    return out


def _stamps(k: int, t) -> dict:
    """``{key: t}`` for keyframe k's pose, velocity and bias keys."""
    from gtsam.symbol_shorthand import B, V, X

    return {X(k): float(t), V(k): float(t), B(k): float(t)}


def _predict(pim, state) -> np.ndarray:
    """The state (15,) at the end of ``pim`` from ``state`` (biases carried over)."""
    import gtsam

    nav = pim.predict(gtsam.NavState(gtsam.Rot3(so3_exp(state[0:3])), state[3:6], state[6:9]),
                      gtsam.imuBias.ConstantBias(state[12:15], state[9:12]))
    return np.r_[so3_log(nav.attitude().matrix()), nav.position(), nav.velocity(), state[9:15]]


def first_priors(truth0):
    """The priors on keyframe 0 at ``truth0`` (15,) with :data:`FIRST_SIGMAS` (a ``NonlinearFactorGraph``)."""
    import gtsam
    from gtsam.symbol_shorthand import B, V, X

    sig, graph = FIRST_SIGMAS, gtsam.NonlinearFactorGraph()
    pose = gtsam.Pose3(gtsam.Rot3(so3_exp(truth0[0:3])), np.asarray(truth0[3:6], dtype=float))
    graph.add(gtsam.PriorFactorPose3(X(0), pose, gtsam.noiseModel.Diagonal.Sigmas(sig[0:6])))
    graph.add(gtsam.PriorFactorVector(V(0), np.asarray(truth0[6:9], dtype=float),
                                      gtsam.noiseModel.Diagonal.Sigmas(sig[6:9])))
    graph.add(gtsam.PriorFactorConstantBias(B(0), gtsam.imuBias.ConstantBias(truth0[12:15], truth0[9:12]),
                                            gtsam.noiseModel.Diagonal.Sigmas(np.r_[sig[12:15], sig[9:12]])))
    return graph


def imu_factors(sim: VioSim, i: int, j: int, pim):
    """``[ImuFactor, BetweenFactorConstantBias]`` between keyframes i and j."""
    import gtsam
    from gtsam.symbol_shorthand import B, V, X

    root_t = np.sqrt(pim.deltaTij())
    walk = gtsam.noiseModel.Diagonal.Sigmas(np.r_[np.full(3, sim.accel_walk), np.full(3, sim.gyro_walk)] * root_t)
    return [gtsam.ImuFactor(X(i), V(i), X(j), V(j), B(i), pim),
            gtsam.BetweenFactorConstantBias(B(i), B(j), gtsam.imuBias.ConstantBias(), walk)]


class _Camera:
    """Makes the projection factors of one simulation (calibration, extrinsics and noise built once)."""

    def __init__(self, sim: VioSim):
        import gtsam

        K = sim.K
        self.K = gtsam.Cal3_S2(K[0, 0], K[1, 1], K[0, 1], K[0, 2], K[1, 2])
        self.body_P_sensor = gtsam.Pose3(gtsam.Rot3(sim.R_bc), np.asarray(sim.t_bc, dtype=float))
        self.noise = gtsam.noiseModel.Robust.Create(gtsam.noiseModel.mEstimator.Cauchy(CAUCHY_SCALE),
                                                    gtsam.noiseModel.Isotropic.Sigma(2, sim.pixel_noise))

    def factor(self, frame: int, landmark: int, uv):
        import gtsam
        from gtsam.symbol_shorthand import L, X

        return gtsam.GenericProjectionFactorCal3_S2(np.asarray(uv, dtype=float), self.noise, X(frame), L(landmark),
                                                    self.K, self.body_P_sensor)


def batch_graph(sim: VioSim, states: dict, points: dict | None = None, keyframe_every=5, imu_samples="midpoint"):
    """``(graph, values, landmark ids)`` of all keyframes: IMU factors preintegrated at ``states``'
    biases, the landmarks seen by two keyframes or more (``points`` ``{l: (3,)}``, triangulated from
    ``states`` as ``course.problems.vio.window`` does when None), the first-keyframe priors; values at ``states``."""
    import gtsam

    kfs = Keyframes(sim, keyframe_every)
    frames = list(range(len(kfs)))
    graph = gtsam.NonlinearFactorGraph()
    graph.push_back(first_priors(kfs.truth(0)))
    for k in frames[:-1]:
        pim = preintegrate(sim, kfs.imu_index[k], kfs.imu_index[k + 1], states[k][9:12], states[k][12:15], imu_samples)
        for factor in imu_factors(sim, k, k + 1, pim):
            graph.add(factor)
    if points is None:
        points = {}
        lm_ids = add_landmarks(sim, kfs, frames, states, points)
    else:
        lm_ids = sorted(points)
    camera, wanted = _Camera(sim), set(lm_ids)
    for f in frames:
        for lm, uv in zip(*kfs.obs[f]):
            if int(lm) in wanted:
                graph.add(camera.factor(f, int(lm), uv))
    return graph, to_values({k: states[k] for k in frames}, {lm: points[lm] for lm in lm_ids}), lm_ids


def gtsam_batch(sim: VioSim, start: VioRun | None = None, keyframe_every=5, imu_samples="midpoint") -> VioRun:
    """All keyframes at once with GTSAM's Levenberg-Marquardt, started from ``start``'s states (as our
    ``batch``) or, when None, from IMU propagation (at zero biases) of the truth at keyframe 0; the
    landmarks triangulated from that start. ``solve_seconds`` times ``optimize()`` alone."""
    import gtsam

    kfs = Keyframes(sim, keyframe_every)
    if start is not None:
        if len(start.states) != len(kfs):
            raise ValueError(f"start has {len(start.states)} keyframes, the simulation {len(kfs)}")
        states = {k: np.array(start.states[k], dtype=float) for k in range(len(kfs))}
    else:
        states = {0: kfs.truth(0)}
        for k in range(len(kfs) - 1):
            pim = preintegrate(sim, kfs.imu_index[k], kfs.imu_index[k + 1], states[k][9:12], states[k][12:15],
                               imu_samples)
            states[k + 1] = _predict(pim, states[k])
    graph, values, _ = batch_graph(sim, states, None, keyframe_every, imu_samples)
    params = gtsam.LevenbergMarquardtParams()
    params.setMaxIterations(BATCH_ITERATIONS)
    params.setRelativeErrorTol(BATCH_TOLERANCE)
    params.setAbsoluteErrorTol(0.0)
    optimizer = gtsam.LevenbergMarquardtOptimizer(graph, values, params)
    t0 = time.perf_counter()
    result = optimizer.optimize()
    seconds = time.perf_counter() - t0
    return VioRun("GTSAM batch", kfs.times, states_of(result, range(len(kfs))), [seconds],
                  [int(optimizer.iterations())])


def gtsam_window(sim: VioSim, window=10, keyframe_every=5, imu_samples="midpoint") -> VioRun:
    """GTSAM's ``BatchFixedLagSmoother`` holding our window of ``window`` keyframes (module docstring):
    a keyframe per step (IMU factor at the previous keyframe's current biases, its value by IMU
    prediction from that keyframe's estimate), landmarks triangulated when two keyframes in the
    window see them (``course.problems.vio.window.add_landmarks``); a keyframe's estimate is the one it has
    when it leaves (or at the end). ``solve_seconds``, ``iterations``: one per optimising update."""
    import gtsam
    from gtsam.symbol_shorthand import L

    if window < 2:
        raise ValueError(f"window must be at least 2 keyframes, got {window}")
    kfs = Keyframes(sim, keyframe_every)
    dT = float(kfs.times[1] - kfs.times[0])
    hold, release = (window - 0.5) * dT, (window - 1.5) * dT
    params = gtsam.LevenbergMarquardtParams()
    params.setMaxIterations(WINDOW_ITERATIONS)
    params.setRelativeErrorTol(WINDOW_TOLERANCE)
    params.setAbsoluteErrorTol(0.0)
    smoother = gtsam.BatchFixedLagSmoother(hold, params)
    camera = _Camera(sim)
    states = {0: kfs.truth(0)}
    points: dict[int, np.ndarray] = {}
    final: dict[int, np.ndarray] = {}
    frame_ids = [0]
    live: set[int] = set()  # the landmarks in the smoother
    seconds, iterations = [], []
    # keyframe 0 (its priors and values) goes in with keyframe 1, as ours solves first with two keyframes
    graph, values, stamps = first_priors(kfs.truth(0)), to_values({0: states[0]}, {}), _stamps(0, kfs.times[0])
    for new in range(1, len(kfs)):
        prev = states[new - 1]
        pim = preintegrate(sim, kfs.imu_index[new - 1], kfs.imu_index[new], prev[9:12], prev[12:15], imu_samples)
        states[new] = _predict(pim, prev)
        for factor in imu_factors(sim, new - 1, new, pim):
            graph.add(factor)
        frame_ids.append(new)
        t_new = float(kfs.times[new])
        stamps.update(_stamps(new, t_new))
        in_window = set(add_landmarks(sim, kfs, frame_ids, states, points, live))
        for lm in sorted(in_window - live):  # new ones: every observation in the window
            for f in frame_ids:
                lms, pixels = kfs.obs[f]
                for hit in np.flatnonzero(lms == lm):
                    graph.add(camera.factor(f, lm, pixels[hit]))
            latest = max(f for f in frame_ids if np.any(kfs.obs[f][0] == lm))
            stamps[L(lm)] = float(kfs.times[latest])
        for lm, uv in zip(*kfs.obs[new]):  # the new keyframe's view of the landmarks already in
            if int(lm) in live:
                graph.add(camera.factor(new, int(lm), uv))
                stamps[L(int(lm))] = t_new
        values.insert(to_values({new: states[new]}, {lm: points[lm] for lm in sorted(in_window - live)}))
        smoother.setSmootherLag(hold)
        t0 = time.perf_counter()
        result = smoother.update(graph, values, stamps)
        seconds.append(time.perf_counter() - t0)
        iterations.append(int(result.getIterations()))
        graph, values, stamps = gtsam.NonlinearFactorGraph(), gtsam.Values(), {}
        live |= in_window
        estimate = smoother.calculateEstimate()
        for f, s in zip(frame_ids, states_of(estimate, frame_ids)):
            states[f] = s
        for lm in live:
            points[lm] = np.asarray(estimate.atPoint3(L(lm)), dtype=float)
        if len(frame_ids) < window or new == len(kfs) - 1:
            continue
        final[frame_ids[0]] = states[frame_ids[0]].copy()
        smoother.setSmootherLag(release)
        smoother.update()
        frame_ids = frame_ids[1:]
        kept = set(smoother.timestamps().keys())
        live = {lm for lm in live if L(lm) in kept}
    for f in frame_ids:
        final[f] = states[f].copy()
    order = sorted(final)
    return VioRun(f"GTSAM fixed-lag (window {window})", kfs.times[order], np.array([final[f] for f in order]),
                  seconds, iterations)


__all__ = ["batch_graph", "gtsam_batch", "gtsam_window", "imu_params", "preintegrate", "states_of", "to_values"]
