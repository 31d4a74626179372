"""Bundle adjustment through GTSAM: ``GeneralSFMFactorCal3Bundler`` and Levenberg-Marquardt.

Cost convention: GTSAM's ``graph.error(values)`` is ``0.5 * sum |r|^2`` (unit isotropic
noise ``noiseModel.Isotropic.Sigma(2, 1.0)``, residuals in pixels), the BAL cost, plus the
priors' errors (below). Observations behind the camera: ``GeneralSFMFactor`` catches
the projection's ``CheiralityException`` and returns a zero residual with zero
Jacobians, so an observation whose point is behind its camera scores zero (and pulls on
nothing) while it stays there. On ladybug-49 (31 such observations at the start) GTSAM's
initial error is 850802.09 where ours is 850912.46; after 50 iterations one more
observation has its point just behind the camera plane (``P_z = 0.012``; in front is
``P_z < 0``): GTSAM's error 14672.57, ours (BAL's formula, no cheirality) 29968.82.

Variables: one ``PinholeCameraCal3Bundler`` per BAL camera (key ``C(c)``), one ``Point3``
per point (key ``P(j)``); one factor per observation. Conversion (BAL looks down -z, GTSAM
down +z): with ``F = diag(1, -1, -1)``, the camera's pose (camera to world) is
``Pose3(R^T F, -R^T t)``, its calibration ``Cal3Bundler(f, k1, k2, 0, 0)`` (the BAL
distortion), the measurement ``(u, -v)``; back, ``R = F wRc^T``, ``t = -R centre``.
This is the conversion of ``gtsam.SfmData.FromBalFile``: the start is the BAL start.

Gauge: ``gauge="priors"`` (the default) does what GTSAM's ``SFMExample_bal.py`` does: a
``PriorFactorPinholeCameraCal3Bundler`` on camera 0 (all 9 of its parameters, isotropic
sigma 0.1) and a ``PriorFactorPoint3`` on point 0 (sigma 0.1), both at their start
values. They are soft: they pull camera 0's calibration and point 0 towards the start,
so the minimum is not exactly ours. ``gauge="none"``: no prior; LM's damping keeps the
7-dimensional gauge freedom solvable (needed to reach a zero cost on noise-free data).
"""

from __future__ import annotations

import time

import numpy as np

from course.backends import registry
from course.backends.bal.common import (
    FLIP,
    BALRunResult,
    angle_axis,
    check_max_iterations,
    check_method,
    pack,
    rotation_matrices,
)
from course.core import peers
from course.core.trace import IterationRecord
from course.problems.bal.dataset import BALProblem, behind_camera, cost

METHODS = registry.peer_methods("bal", "gtsam")
GAUGES = ("priors", "none")
PEER_COST = ("GTSAM's error 0.5 sum |r|^2 (+ the priors'), an observation behind its camera scoring zero "
             "(CheiralityException)")


def to_gtsam(problem: BALProblem, gauge: str = "priors"):
    """``(graph, values)`` for ``problem`` at its start (see the module docstring)."""
    import gtsam
    from gtsam.symbol_shorthand import C, P

    if gauge not in GAUGES:
        raise ValueError(f"unknown gauge {gauge!r}; choose one of {GAUGES}")
    R = rotation_matrices(problem.cameras[:, :3])
    graph, values = gtsam.NonlinearFactorGraph(), gtsam.Values()
    cameras = []
    for c in range(problem.num_cameras):
        f, k1, k2 = problem.cameras[c, 6:9].tolist()
        pose = gtsam.Pose3(gtsam.Rot3(R[c].T @ FLIP), -R[c].T @ problem.cameras[c, 3:6])
        camera = gtsam.PinholeCameraCal3Bundler(pose, gtsam.Cal3Bundler(f, k1, k2, 0.0, 0.0))
        cameras.append(camera)
        values.insert(C(c), camera)
    for j in range(problem.num_points):
        values.insert(P(j), np.array(problem.points[j], dtype=float))
    noise = gtsam.noiseModel.Isotropic.Sigma(2, 1.0)
    uv = problem.observations * np.array([1.0, -1.0])
    for c, j, z in zip(problem.camera_index.tolist(), problem.point_index.tolist(), uv):
        graph.add(gtsam.GeneralSFMFactorCal3Bundler(z, noise, C(c), P(j)))
    if gauge == "priors":
        graph.add(gtsam.PriorFactorPinholeCameraCal3Bundler(C(0), cameras[0], gtsam.noiseModel.Isotropic.Sigma(9, 0.1)))
        graph.add(gtsam.PriorFactorPoint3(P(0), np.array(problem.points[0], dtype=float),
                                          gtsam.noiseModel.Isotropic.Sigma(3, 0.1)))
    return graph, values


def from_gtsam(problem: BALProblem, values) -> tuple[np.ndarray, np.ndarray]:
    """``(cameras (C, 9), points (P, 3))``: the BAL state of GTSAM ``values``."""
    import gtsam
    from gtsam.symbol_shorthand import C

    cameras = np.empty((problem.num_cameras, 9))
    R = np.empty((problem.num_cameras, 3, 3))
    for c in range(problem.num_cameras):
        camera = values.atPinholeCameraCal3Bundler(C(c))
        pose, K = camera.pose(), camera.calibration()
        R[c] = FLIP @ pose.rotation().matrix().T
        cameras[c, 3:6] = -R[c] @ np.asarray(pose.translation())
        cameras[c, 6:9] = K.fx(), K.k1(), K.k2()
    cameras[:, :3] = angle_axis(R, near=problem.cameras[:, :3])
    # every Point3 in key order; P(j) = ('p' << 56) + j, so row j is point j
    points = np.asarray(gtsam.utilities.extractPoint3(values), dtype=float).reshape(-1, 3)
    if points.shape != (problem.num_points, 3):
        raise ValueError(f"GTSAM values hold {len(points)} points, the problem {problem.num_points}")
    return cameras, points


def solve(
    problem: BALProblem,
    method: str = "levenberg-marquardt",
    max_iterations: int = 100,
    *,
    relative_error_tol: float = 1e-12,
    absolute_error_tol: float = 1e-12,
    gauge: str = "priors",
) -> BALRunResult:
    """Bundle-adjust ``problem`` from its own start with GTSAM's Levenberg-Marquardt.

    GTSAM stops when an iteration lowers its error by at most ``relative_error_tol``
    relative AND ``absolute_error_tol`` absolute, when LM finds no decreasing step with
    lambda up to its bound, or after ``max_iterations``. ``gauge``: see the module docstring.

    Returns a ``BALRunResult(backend="gtsam")``: ``params`` the BAL state at the solution;
    ``initial_chi2`` / ``final_chi2`` OUR ``sum |r|^2`` over all observations;
    ``peer_initial_cost`` / ``peer_final_cost`` GTSAM's ``graph.error`` at the start and at
    the end (priors included); ``seconds`` ``optimize()`` alone minus our hook's time;
    ``iterations`` GTSAM's ``optimizer.iterations()`` (lambda retries inside one iteration
    count once). The trace: record 0 the start, then one record per ``iterationHook``
    call, ``chi2`` OUR chi2 of the optimizer's values then (computed in the hook, its time
    excluded), ``damping`` LM's lambda; ``peer_costs`` GTSAM's error alongside.
    """
    peers.require("gtsam")
    import gtsam

    check_method(method, METHODS, "gtsam")
    max_iterations = check_max_iterations(max_iterations)
    graph, values = to_gtsam(problem, gauge)
    params = gtsam.LevenbergMarquardtParams()
    params.setMaxIterations(max_iterations)
    params.setRelativeErrorTol(relative_error_tol)
    params.setAbsoluteErrorTol(absolute_error_tol)

    initial_chi2 = 2.0 * cost(problem)
    peer_initial = float(graph.error(values))
    trace = [IterationRecord(0, initial_chi2)]
    peer_costs = [peer_initial]
    errors = []  # GTSAM's (error before, error after) per hook call
    clock = {"start": 0.0, "hook": 0.0}

    def hook(iteration, error_before, error_after):
        entered = time.perf_counter()
        errors.append((error_before, error_after))
        if iteration > trace[-1].iteration:
            cameras, points = from_gtsam(problem, optimizer.values())
            trace.append(IterationRecord(
                iteration=int(iteration), chi2=2.0 * cost(problem, cameras, points),
                damping=float(optimizer.lambda_()), accepted=error_after <= error_before,
                seconds=entered - clock["start"] - clock["hook"]))
            peer_costs.append(float(error_after))
        clock["hook"] += time.perf_counter() - entered

    params.iterationHook = hook
    optimizer = gtsam.LevenbergMarquardtOptimizer(graph, values, params)
    clock["start"] = time.perf_counter()
    optimizer.optimize()
    seconds = time.perf_counter() - clock["start"] - clock["hook"]

    iterations = int(optimizer.iterations())
    final_values = optimizer.values()
    cameras, points = from_gtsam(problem, final_values)
    if iterations >= max_iterations:
        reason = f"max_iterations: {max_iterations} reached"
    elif optimizer.lambda_() >= params.getlambdaUpperBound():  # type: ignore[attr-defined]
        reason = f"lambda_upper_bound: no decreasing step with lambda up to {params.getlambdaUpperBound():g}"  # type: ignore[attr-defined]
    else:
        reason = (f"converged: error decrease <= {relative_error_tol:g} relative and "
                  f"<= {absolute_error_tol:g} absolute")
    final_cost = cost(problem, cameras, points)
    return BALRunResult(
        backend="gtsam", method=method, params=pack(cameras, points),
        initial_chi2=initial_chi2, final_chi2=2.0 * final_cost, iterations=iterations, seconds=seconds,
        trace=trace, stop_reason=f"{reason}; gauge: {gauge}",
        initial_cost=0.5 * initial_chi2, final_cost=final_cost,
        peer_initial_cost=peer_initial, peer_final_cost=float(graph.error(final_values)),
        peer_costs=peer_costs, peer_cost=PEER_COST,
        behind_camera_start=behind_camera(problem), behind_camera_final=behind_camera(problem, cameras, points),
    )
