"""3D pose graphs through GTSAM: ``Pose3``, ``BetweenFactorPose3``, Gauss-Newton and LM.

GTSAM's error is ``Logmap(Z^-1 T_i^-1 T_j)`` in its tangent order (rotation, translation);
its rotation part is ours, its translation part ``V(phi)^-1 D_t`` equals ours to first
order. Our information (translation first) is reordered to GTSAM's (``Omega_gtsam = P Omega
P^T``), so GTSAM solves our problem up to those higher-order terms; ``final_chi2`` is our
chi2 of its solution. A fixed vertex gets a ``PriorFactorPose3`` with
``noiseModel.Constrained.All(6)`` (GTSAM's idiom: its GN and LM keep it in place).
"""

import time
from typing import Any

import numpy as np

from course.backends import registry
from course.core.trace import IterationRecord, RunResult
from course.problems.posegraph3d.graph import PoseGraph3D
from course.problems.posegraph3d.problem import pack

METHODS = registry.peer_methods("posegraph3d", "gtsam")
#: our tangent (translation, rotation) -> GTSAM's (rotation, translation)
TO_GTSAM = np.r_[3:6, 0:3]


def information_for_gtsam(information) -> np.ndarray:
    """(M, 6, 6): our information matrices with rows and columns in GTSAM's order."""
    return np.asarray(information)[:, TO_GTSAM][:, :, TO_GTSAM]


#: the standard deviation of a fixed pose's prior where a hard constraint cannot be used
#: (GTSAM's GNC reweights every factor, and a constrained one then makes GN's system indeterminate)
SOFT_PRIOR_SIGMA = 1e-6


def build_factor_graph(graph: PoseGraph3D, robust=None, hard_priors=True):
    """``(factors, values)`` of ``graph`` at its poses; keys are our vertex indices.
    ``robust``: a ``gtsam.noiseModel.mEstimator`` base wrapped around every edge's model;
    ``hard_priors``: a fixed pose's prior is ``Constrained`` (else isotropic, ``SOFT_PRIOR_SIGMA``)."""
    import gtsam

    factors = gtsam.NonlinearFactorGraph()
    info = information_for_gtsam(graph.information)
    for k, (i, j) in enumerate(zip(graph.edges_i.tolist(), graph.edges_j.tolist())):
        noise = gtsam.noiseModel.Gaussian.Information(info[k])
        if robust is not None:
            noise = gtsam.noiseModel.Robust.Create(robust, noise)  # type: ignore[assignment]
        factors.add(gtsam.BetweenFactorPose3(i, j, gtsam.Pose3(gtsam.Rot3(graph.R_z[k]), graph.t_z[k]), noise))
    values = gtsam.Values()
    for k in range(graph.num_poses):
        values.insert(k, gtsam.Pose3(gtsam.Rot3(graph.R[k]), graph.t[k]))
    prior = (gtsam.noiseModel.Constrained.All(6) if hard_priors
             else gtsam.noiseModel.Isotropic.Sigma(6, SOFT_PRIOR_SIGMA))
    for k in graph.fixed.tolist():
        factors.add(gtsam.PriorFactorPose3(k, values.atPose3(k), prior))
    return factors, values


def poses_of(values, num_poses):
    """``(t (N, 3), R (N, 3, 3))`` of GTSAM ``values`` keyed 0..N-1."""
    matrices = np.array([values.atPose3(k).matrix() for k in range(num_poses)])
    return matrices[:, :3, 3].copy(), matrices[:, :3, :3].copy()


def solve(graph: PoseGraph3D, method: str, max_iterations: int = 100, *, relative_error_tol: float = 1e-12,
          absolute_error_tol: float = 1e-12) -> RunResult:
    """Optimize ``graph`` with GTSAM's ``method`` (``METHODS``); ``seconds`` is ``optimize()``
    minus the iteration hook, which records our chi2 after every iteration."""
    import gtsam

    kinds = {"gauss-newton": (gtsam.GaussNewtonParams, gtsam.GaussNewtonOptimizer),
             "levenberg-marquardt": (gtsam.LevenbergMarquardtParams, gtsam.LevenbergMarquardtOptimizer)}
    if method not in kinds:
        raise ValueError(f"unknown GTSAM method {method!r}; choose one of {METHODS}")
    factors, values = build_factor_graph(graph)
    params_class, optimizer_class = kinds[method]
    params = params_class()
    params.setMaxIterations(int(max_iterations))
    params.setRelativeErrorTol(relative_error_tol)
    params.setAbsoluteErrorTol(absolute_error_tol)
    initial_chi2 = graph.chi2()
    trace = [IterationRecord(0, initial_chi2, seconds=0.0)]
    clock = {"hook": 0.0, "start": 0.0}
    holder: dict = {}

    def hook(iteration, before, after):
        entered = time.perf_counter()
        if iteration > trace[-1].iteration:
            t, R = poses_of(holder["optimizer"].values(), graph.num_poses)
            trace.append(IterationRecord(int(iteration), graph.chi2(t, R), accepted=after <= before,
                                         seconds=entered - clock["start"] - clock["hook"]))
        clock["hook"] += time.perf_counter() - entered

    params.iterationHook = hook
    optimizer = holder["optimizer"] = optimizer_class(factors, values, params)
    failure = None
    clock["start"] = time.perf_counter()
    try:
        optimizer.optimize()
    except RuntimeError as exc:
        failure = " ".join(str(exc).split())
    seconds = time.perf_counter() - clock["start"] - clock["hook"]
    iterations = int(optimizer.iterations())
    t, R = poses_of(optimizer.values(), graph.num_poses)
    if failure is not None:
        reason = f"failed: {failure}"
    elif iterations >= max_iterations:
        reason = f"max_iterations: {max_iterations} reached"
    else:
        reason = f"converged: error decrease <= {relative_error_tol:g} relative and <= {absolute_error_tol:g} absolute"
    return RunResult(backend="gtsam", method=method, params=pack(t, R), initial_chi2=initial_chi2,
                     final_chi2=graph.chi2(t, R), iterations=iterations, seconds=seconds, trace=trace,
                     stop_reason=reason)


def solve_gnc(graph: PoseGraph3D, surrogate: str = "tls", c2: float = 16.811893829770927, known_inliers=None,
              inner_iterations: int | None = 30, inner: str = "gauss-newton"):
    """GTSAM's GNC on ``graph`` from its poses: ``(t, R, weights (M,), seconds)``.

    ``surrogate`` "tls" or "gm"; ``c2`` our threshold on ``s = e^T Omega e`` (GTSAM's factor
    error is ``s / 2``, so its inlier cost threshold is ``c2 / 2``); ``known_inliers`` (M,) bool,
    e.g. the odometry. The prior factors that fix poses are known inliers too.
    ``inner``: the inner solver, ``gauss-newton`` (``GncGaussNewtonOptimizer``, as ours) or
    ``levenberg-marquardt`` (``GncLMOptimizer``: on sphere2500 with 20% wrong closures, one of its
    LM iterations took 3.7 s, and the whole did not finish in 12 minutes);
    ``inner_iterations``: the cap on each inner solve (ours: 30,
    ``course.problems.posegraph3d.robust.INNER``); None keeps GTSAM's (100).
    """
    import gtsam

    if inner not in ("gauss-newton", "levenberg-marquardt"):
        raise ValueError(f"GTSAM's GNC runs gauss-newton or levenberg-marquardt inside, not {inner!r}")
    factors, values = build_factor_graph(graph, hard_priors=False)
    lm = inner == "levenberg-marquardt"
    params: Any
    if lm:
        base_lm = gtsam.LevenbergMarquardtParams()
        if inner_iterations is not None:
            base_lm.setMaxIterations(int(inner_iterations))
        params = gtsam.GncLMParams(base_lm)
    else:
        base_gn = gtsam.GaussNewtonParams()
        if inner_iterations is not None:
            base_gn.setMaxIterations(int(inner_iterations))
        params = gtsam.GncGaussNewtonParams(base_gn)
    params.setLossType(gtsam.GncLossType.TLS if surrogate == "tls" else gtsam.GncLossType.GM)
    known = [] if known_inliers is None else np.flatnonzero(known_inliers).tolist()
    params.setKnownInliers(known + list(range(graph.num_edges, factors.size())))
    optimizer = (gtsam.GncLMOptimizer if lm else gtsam.GncGaussNewtonOptimizer)(factors, values, params)
    optimizer.setInlierCostThresholds(c2 / 2.0)
    start = time.perf_counter()
    result = optimizer.optimize()
    seconds = time.perf_counter() - start
    t, R = poses_of(result, graph.num_poses)
    return t, R, np.asarray(optimizer.getWeights())[:graph.num_edges], seconds
