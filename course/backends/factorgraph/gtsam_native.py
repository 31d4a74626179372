"""A planar factor graph through GTSAM's own factors: ``gtsam.PriorFactorPose2``, ``BetweenFactorPose2``,
``RangeFactor2D`` (a ``Pose2`` to a ``Point2``) and ``PriorFactorPoint2``, in place of our library's
``prior(SE2)``, ``between(SE2)``, ``RANGE_2D`` and ``prior(Vector(2))``.

Unlike ``gtsam_custom`` (our residuals, one Python callback per factor), nothing of ours runs inside
GTSAM: its factors are C++, their errors and Jacobians GTSAM's. The errors are not all ours to the
letter: GTSAM's pose prior and between are ``Logmap(z^-1 x_i^-1 x_j)`` (SE(2)'s log, translation through
``V(theta)^-1``), ours ``[R_z^T (R_i^T (t_j - t_i) - t_z); wrap(theta_j - theta_i - theta_z)]``: the two
agree to first order at the measurement, so the minima differ by second-order terms of the residuals.
That is why ``final_chi2`` is OUR error (``FactorGraphProblem.chi2``) on GTSAM's solution: ours, which
minimises that error, ends at it or below. The range error is ``|l - t| - z`` in both.

GTSAM's keys are our variable indices; the noise model is ``noiseModel.Gaussian.Information`` of each
factor's information (GTSAM's error is half the chi2). A fixed variable, a robust loss or another factor
type is a ``ValueError`` naming it (give the graph priors in place of fixed poses).
"""

import time
from typing import Any

import numpy as np

from course.core.trace import IterationRecord, RunResult

METHODS = ("levenberg-marquardt", "gauss-newton")
BACKEND = "gtsam"


def _factor_maker(ftype):
    """``make(keys, z, model)`` of GTSAM's own factor for our factor type, or None."""
    import gtsam

    from course.factorgraph import factors
    from course.factorgraph.variables import SE2, Vector

    return {
        factors.prior(SE2): lambda k, z, m: gtsam.PriorFactorPose2(k[0], gtsam.Pose2(*z), m),
        factors.between(SE2): lambda k, z, m: gtsam.BetweenFactorPose2(k[0], k[1], gtsam.Pose2(*z), m),
        factors.RANGE_2D: lambda k, z, m: gtsam.RangeFactor2D(k[0], k[1], float(z[0]), m),
        factors.prior(Vector(2)): lambda k, z, m: gtsam.PriorFactorPoint2(k[0], np.array(z, dtype=float), m),
    }.get(ftype)


def build(graph):
    """``(factors, values)``: GTSAM's ``NonlinearFactorGraph`` and ``Values`` of ``graph`` at its values."""
    import gtsam

    where = f"gtsam (native factors): {graph.name}"
    if graph.fixed or graph.fixed_dofs:
        raise ValueError(f"{where}: variable(s) {[graph.keys[v] for v in list(graph.fixed) + list(graph.fixed_dofs)]} "
                         "are fixed; hold them by a prior factor here")
    values = gtsam.Values()
    for v, (kind, value) in enumerate(zip(graph.kinds, graph.values)):
        if kind.name == "SE2":
            values.insert(v, gtsam.Pose2(*np.asarray(value, dtype=float)))
        elif kind.name == "Vector2":
            values.insert(v, np.asarray(value, dtype=float))
        else:
            raise ValueError(f"{where}: variable {graph.keys[v]!r} is of kind {kind.name}: "
                             "the native factors here take SE2 and Vector2 variables")
    out = gtsam.NonlinearFactorGraph()
    for group in graph.groups.values():
        make = _factor_maker(group.type)
        if make is None or group.loss is not None:
            what = f"factor type {group.type.name!r}" if make is None else f"the robust loss of {group.type.name!r}"
            raise ValueError(f"{where}: {what} has no GTSAM factor here (prior and between on SE2, RANGE_2D, "
                             "prior on Vector(2), no robust loss)")
        keys, z, info = group.arrays()
        for m in range(len(keys)):
            model = gtsam.noiseModel.Unit.Create(group.type.dim) if info is None else \
                gtsam.noiseModel.Gaussian.Information(np.array(info[m]))
            out.add(make([int(v) for v in keys[m]], z[m], model))
    return out, values


def read(graph, values) -> np.ndarray:
    """Every variable's value at GTSAM's ``values``, stored as ours (flat, in variable order)."""
    out: list[np.ndarray] = []
    for v, kind in enumerate(graph.kinds):
        if kind.name == "SE2":
            pose = values.atPose2(v)
            out.append(np.array([pose.x(), pose.y(), pose.theta()]))
        else:
            out.append(np.asarray(values.atPoint2(v), dtype=float))
    return np.concatenate(out)


def solve(graph, method: str = "levenberg-marquardt", max_iterations: int = 100, *,
          relative_error_tol: float = 1e-12, absolute_error_tol: float = 1e-12) -> RunResult:
    """Optimize ``graph`` from its values with GTSAM's ``LevenbergMarquardtOptimizer`` (or
    ``GaussNewtonOptimizer``) on its own factors. ``seconds`` is ``optimize()`` alone; ``final_chi2``
    our error on the solution; the trace's chi2 twice GTSAM's error (its own, see the module doc)."""
    import gtsam

    from course.factorgraph import FactorGraphProblem

    if method not in METHODS:
        raise ValueError(f"unknown gtsam method {method!r}; choose one of {METHODS}")
    ours = FactorGraphProblem(graph)
    factors, values = build(graph)
    params: Any = gtsam.LevenbergMarquardtParams() if method == METHODS[0] else gtsam.GaussNewtonParams()
    params.setMaxIterations(int(max_iterations))
    params.setRelativeErrorTol(relative_error_tol)
    params.setAbsoluteErrorTol(absolute_error_tol)
    trace = [IterationRecord(0, ours.chi2(ours.x0))]
    start = time.perf_counter()

    def hook(iteration, error_before, error_after):
        trace.append(IterationRecord(int(iteration), 2.0 * error_after, accepted=error_after <= error_before,
                                     seconds=time.perf_counter() - start))

    params.iterationHook = hook
    optimizer = (gtsam.LevenbergMarquardtOptimizer if method == METHODS[0] else gtsam.GaussNewtonOptimizer)(
        factors, values, params)
    start = time.perf_counter()
    result = optimizer.optimize()
    seconds = time.perf_counter() - start
    final = read(graph, result)
    iterations = int(optimizer.iterations())
    stop = f"max_iterations: {max_iterations} reached" if iterations >= max_iterations else \
        f"converged: error decrease <= {relative_error_tol:g} relative or <= {absolute_error_tol:g} absolute"
    return RunResult(backend=BACKEND, method=method, params=final, initial_chi2=trace[0].chi2,
                     final_chi2=ours.chi2(final), iterations=iterations, seconds=seconds, trace=trace,
                     stop_reason=stop)
