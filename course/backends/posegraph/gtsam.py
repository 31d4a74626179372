"""2D pose graphs through GTSAM's nonlinear optimizers.

Factors: ``BetweenFactorPose2`` per edge with ``noiseModel.Gaussian.Information``.
GTSAM's Pose2 error is the SE(2) log map ``Log(z^-1 x_i^-1 x_j)``, not our error
(``course.geometry.se2.edge_errors``): the rotation parts agree, the translation parts
differ by ``O(|theta error| |t error|)``. Near a good optimum the two chi2 agree to
~1e-6 relative or better (intel: 65.402444 GTSAM's, 65.402048 ours at GTSAM's
solution); where some edge keeps a large error they do not, and GTSAM's minimum is
not ours (mit from the Levenberg-Marquardt run: 770.24 GTSAM's, 2956.8 ours).

Fixed vertices (``fix="eliminate"``, the default) are not variables, as in g2o and
Ceres: an edge from a fixed ``x_i`` to a free ``x_j`` becomes the exactly equivalent
``PriorFactorPose2(j, x_i z, Omega)``, an edge from a free ``x_i`` to a fixed ``x_j``
becomes ``PriorFactorPose2(i, x_j z^-1, A^T Omega A)`` with ``A = Ad(z^-1)`` (since
``Log(z^-1 x_i^-1 x_j) = -Ad(z^-1) Log((x_j z^-1)^-1 x_i)``), and an edge between two
fixed vertices is a constant and is left out. A fixed pose then stays bit-for-bit at
its start. ``fix="prior"`` is GTSAM's usual idiom instead: every vertex a variable and
a ``PriorFactorPose2`` with ``noiseModel.Constrained.All(3)`` on each fixed one. Its
Gauss-Newton and LM keep the fixed pose, but its dogleg moves it (by 2e-17 on intel,
by 0.32 m on w100, where it then stops after 2 iterations with "error increased").

Failures: from a bad start (intel-g2o, mit) Gauss-Newton and dogleg throw
``IndeterminantLinearSystemException`` (a ``RuntimeError`` in Python: "Indeterminate
linear system detected while working near variable ..."). ``solve`` catches it and returns a ``RunResult`` whose
``stop_reason`` starts with ``failed:`` and whose ``params`` are the last values the
optimizer held (exactly the start when it fails in its first iteration, as on those);
``raise_on_failure=True`` re-raises instead.
"""

import time
from typing import Any

import numpy as np

from course.backends import registry
from course.core.trace import IterationRecord, RunResult
from course.problems.posegraph.graph import PoseGraph

METHODS = registry.peer_methods("posegraph", "gtsam")
FIX_MODES = ("eliminate", "prior")


def build_factor_graph(graph: PoseGraph, fix: str = "eliminate"):
    """``(factor_graph, values, free)`` for ``graph`` at ``graph.poses``.

    Keys are our vertex indices; ``free`` (K,) lists the vertices in ``values`` (all of
    them with ``fix="prior"``).
    """
    import gtsam

    if fix not in FIX_MODES:
        raise ValueError(f"unknown fix mode {fix!r}; choose one of {FIX_MODES}")
    n = graph.num_poses
    is_fixed = np.zeros(n, dtype=bool)
    is_fixed[graph.fixed] = True
    if fix == "prior":
        is_fixed[:] = False
    pose = [gtsam.Pose2(*p) for p in graph.poses.tolist()]
    factors = gtsam.NonlinearFactorGraph()
    edges = zip(graph.edges_i.tolist(), graph.edges_j.tolist(), graph.measurements.tolist(),
                graph.information)
    for i, j, z, info in edges:
        z = gtsam.Pose2(*z)
        if not is_fixed[i] and not is_fixed[j]:
            noise = gtsam.noiseModel.Gaussian.Information(info)
            factors.add(gtsam.BetweenFactorPose2(i, j, z, noise))
        elif not is_fixed[j]:
            noise = gtsam.noiseModel.Gaussian.Information(info)
            factors.add(gtsam.PriorFactorPose2(j, pose[i].compose(z), noise))
        elif not is_fixed[i]:
            z_inv = z.inverse()
            adj = z_inv.AdjointMap()
            noise = gtsam.noiseModel.Gaussian.Information(adj.T @ info @ adj)
            factors.add(gtsam.PriorFactorPose2(i, pose[j].compose(z_inv), noise))
    if fix == "prior":
        for k in graph.fixed.tolist():
            factors.add(gtsam.PriorFactorPose2(k, pose[k], gtsam.noiseModel.Constrained.All(3)))
    free = np.flatnonzero(~is_fixed)
    values = gtsam.Values()
    for k in free.tolist():
        values.insert(k, pose[k])
    return factors, values, free


def solve(
    graph: PoseGraph,
    method: str,
    max_iterations: int = 100,
    *,
    relative_error_tol: float = 1e-12,
    absolute_error_tol: float = 1e-12,
    fix: str = "eliminate",
    raise_on_failure: bool = False,
) -> RunResult:
    """Optimize ``graph`` from ``graph.poses`` with GTSAM's ``method`` (one of ``METHODS``).

    GTSAM stops when an iteration lowers its error by at most ``relative_error_tol``
    relative AND ``absolute_error_tol`` absolute, or raises it (its Gauss-Newton keeps
    that last, worse, iterate), or after ``max_iterations``.

    Returns a ``RunResult``: ``final_chi2 = graph.chi2(params)`` (our error);
    ``iterations`` is GTSAM's ``optimizer.iterations()`` (the damping or radius retries
    inside one LM or dogleg iteration count once); ``seconds`` is ``optimize()`` alone,
    minus the time of our iteration hook. The trace: one record per iteration from
    ``params.iterationHook``, whose ``chi2`` is OUR chi2 of the optimizer's values after
    that iteration (computed in the hook, the time excluded), so that the trace compares
    with the other back ends; GTSAM's own ``2 * error`` differs (see the module doc).

    ``stop_reason``: ``converged``, ``error_increased``, ``max_iterations``,
    ``lambda_upper_bound`` (LM found no decreasing step with lambda up to its bound) or
    ``failed`` (an exception: message follows), then ``: `` and details.
    """
    import gtsam

    kinds = {
        "gauss-newton": (gtsam.GaussNewtonParams, gtsam.GaussNewtonOptimizer),
        "levenberg-marquardt": (gtsam.LevenbergMarquardtParams, gtsam.LevenbergMarquardtOptimizer),
        "dogleg": (gtsam.DoglegParams, gtsam.DoglegOptimizer),
    }
    if method not in kinds:
        raise ValueError(f"unknown GTSAM method {method!r}; choose one of {METHODS}")
    if max_iterations < 1:
        raise ValueError(f"max_iterations must be >= 1, got {max_iterations}")
    factors, values, free = build_factor_graph(graph, fix)
    params_class, optimizer_class = kinds[method]
    params = params_class()
    params.setMaxIterations(int(max_iterations))
    params.setRelativeErrorTol(relative_error_tol)
    params.setAbsoluteErrorTol(absolute_error_tol)

    initial_chi2 = graph.chi2()
    recorder = _Recorder(graph, free, method, initial_chi2)
    params.iterationHook = recorder.hook
    optimizer = recorder.optimizer = optimizer_class(factors, values, params)
    failure = None
    recorder.start = time.perf_counter()
    try:
        optimizer.optimize()
    except RuntimeError as exc:
        if raise_on_failure:
            raise
        failure = " ".join(str(exc).split())
    seconds = recorder.elapsed()

    iterations = int(optimizer.iterations())
    # Pose2 keeps (cos, sin): theta() may differ from the start in the last bit.
    final = recorder.start_poses.copy() if iterations == 0 else recorder.poses(optimizer.values())
    return RunResult(
        backend="gtsam",
        method=method,
        params=final,
        initial_chi2=initial_chi2,
        final_chi2=graph.chi2(final),
        iterations=iterations,
        seconds=seconds,
        trace=recorder.trace,
        stop_reason=_stop_reason(method, optimizer, params, iterations, max_iterations, failure, recorder.errors,
                                 relative_error_tol, absolute_error_tol),
    )


class _Recorder:
    """GTSAM's iteration hook for :func:`solve`: one ``IterationRecord`` per iteration, with OUR
    chi2 of the optimizer's values; the time spent in the hook is kept apart (``elapsed``)."""

    def __init__(self, graph: PoseGraph, free, method: str, initial_chi2: float):
        self.graph, self.free, self.method = graph, free, method
        self.start_poses = graph.poses.copy()
        self.trace = [IterationRecord(0, initial_chi2)]
        self.errors: list = []  # GTSAM's (error before, error after) per hook call
        self.optimizer: Any = None  # set once built: the hook reads its values and its lambda or radius
        self.start = 0.0
        self.hook_seconds = 0.0

    def poses(self, optimizer_values) -> np.ndarray:
        """(N, 3) poses: the optimizer's for the free vertices, the start's for the fixed ones."""
        import gtsam

        out = self.start_poses.copy()
        out[self.free] = gtsam.utilities.extractPose2(optimizer_values)  # rows in key order
        return out

    def hook(self, iteration, error_before, error_after) -> None:
        entered = time.perf_counter()
        self.errors.append((error_before, error_after))
        if iteration > self.trace[-1].iteration:
            optimizer, method = self.optimizer, self.method
            self.trace.append(
                IterationRecord(
                    iteration=int(iteration),
                    chi2=self.graph.chi2(self.poses(optimizer.values())),
                    damping=float(optimizer.lambda_()) if method == "levenberg-marquardt"
                    else float(optimizer.getDelta()) if method == "dogleg" else float("nan"),
                    accepted=error_after <= error_before,
                    seconds=entered - self.start - self.hook_seconds,
                )
            )
        self.hook_seconds += time.perf_counter() - entered

    def elapsed(self) -> float:
        """Seconds since ``start``, the hook's own excluded."""
        return time.perf_counter() - self.start - self.hook_seconds


def _stop_reason(method, optimizer, params, iterations, max_iterations, failure, errors,
                 relative_error_tol, absolute_error_tol) -> str:
    """Why GTSAM stopped (``solve``'s ``stop_reason``)."""
    if failure is not None:
        return f"failed: {failure}"
    if iterations >= max_iterations:
        return f"max_iterations: {max_iterations} reached"
    if method == "levenberg-marquardt" and optimizer.lambda_() >= params.getlambdaUpperBound():
        return f"lambda_upper_bound: no decreasing step with lambda up to {params.getlambdaUpperBound():g}"
    if errors and errors[-1][1] > errors[-1][0]:
        before, after = errors[-1]
        return f"error_increased: GTSAM's 2 * error {2 * before:.17g} -> {2 * after:.17g}"
    return (f"converged: error decrease <= {relative_error_tol:g} relative and "
            f"<= {absolute_error_tol:g} absolute")
