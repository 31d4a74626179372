"""2D pose graphs through Ceres (``pyceres``), with the edge cost written in Python.

One ``SE2EdgeCost`` residual block per edge, one C-contiguous float64 ``(3,)`` array
per pose as a parameter block (a non-contiguous row of an ``(N, 3)`` array would make
Ceres write into its neighbours), ``SetParameterBlockConstant`` on ``graph.fixed``,
``SPARSE_NORMAL_CHOLESKY``. The residual is the edge error whitened by the upper
Cholesky factor ``U`` of the information (``Omega = U^T U``), so
``2 * cost = sum e^T Omega e``: Ceres minimizes exactly our chi2.

About 90% of the time goes to the Python ``Evaluate`` callbacks (a few microseconds per
call): that is the price of a Python cost function, not of Ceres.

pyceres 2.6 traps met here: a ``CostFunction`` subclass must call
``pyceres.CostFunction.__init__(self)``; ``Problem.evaluate_residuals`` (every overload)
and a residual block whose parameter blocks are all constant segfault with a Python
cost function (so edges between two fixed vertices stay out of the problem, see
``build_problem``); ``CostFunction.evaluate(*blocks)`` works.

The cost class is the chapter 2 exercise ``ceres_edge_cost.SE2EdgeCost``:
``solve(..., impl="exercises")`` uses the student's, ``cost_class=`` any class built as
``Cost(measurement (3,), sqrt_information (3, 3))``.
"""

import math
import time

import numpy as np
import pyceres

from course.backends import registry
from course.core import impl as impl_loader
from course.core.trace import IterationRecord, RunResult
from course.problems.posegraph.graph import PoseGraph

METHODS = registry.peer_methods("posegraph", "ceres")
_TWO_PI = 2.0 * math.pi


def sqrt_information(information) -> np.ndarray:
    """Upper Cholesky factors ``U`` (..., 3, 3) with ``U^T U = information``."""
    lower = np.linalg.cholesky(np.asarray(information, dtype=float))
    return np.ascontiguousarray(np.swapaxes(lower, -1, -2))


def build_problem(graph: PoseGraph, cost_class=None, poses=None, impl="solutions"):
    """The Ceres problem for ``graph`` at ``poses`` (default ``graph.poses``).

    Returns ``(problem, blocks, costs, constant_chi2)``: ``blocks`` the N parameter
    arrays (each its own C-contiguous ``(3,)`` float64 array, updated in place by
    Ceres), ``costs`` the M cost functions (keep them alive as long as the problem).
    Fixed vertices are constant blocks; a vertex without edges is not in the problem
    and keeps its value. An edge between two fixed vertices is left out of the problem
    (pyceres 2.6 segfaults on a residual block whose parameter blocks are all
    constant): ``constant_chi2`` is the sum of its ``|r|^2``, evaluated through the
    cost function's C++ ``evaluate``.
    """
    if cost_class is None:
        cost_class = impl_loader.load(impl).module("ceres_edge_cost").SE2EdgeCost
    poses = graph.poses if poses is None else np.asarray(poses, dtype=float)
    blocks = [np.array(p, dtype=np.float64, order="C", copy=True) for p in poses]
    roots = sqrt_information(graph.information)
    is_fixed = np.zeros(len(blocks), dtype=bool)
    is_fixed[graph.fixed] = True
    problem = pyceres.Problem()
    costs, constant_chi2 = [], 0.0
    edges = zip(graph.edges_i.tolist(), graph.edges_j.tolist(), graph.measurements, roots)
    for i, j, z, u in edges:
        cost = cost_class(z.copy(), u.copy())
        costs.append(cost)
        if is_fixed[i] and is_fixed[j]:
            residuals = np.asarray(cost.evaluate(blocks[i], blocks[j])[0], dtype=float)
            constant_chi2 += float(residuals.ravel() @ residuals.ravel())
        else:
            problem.add_residual_block(cost, None, [blocks[i], blocks[j]])
    for k in graph.fixed.tolist():
        if problem.has_parameter_block(blocks[k]):
            problem.set_parameter_block_constant(blocks[k])
    return problem, blocks, costs, constant_chi2


class _TraceCallback(pyceres.IterationCallback):
    """Records one ``IterationRecord`` per Ceres iteration (0 = the start)."""

    def __init__(self, damping_is_inverse_radius: bool, constant_chi2: float = 0.0):
        pyceres.IterationCallback.__init__(self)
        self.inverse = damping_is_inverse_radius
        self.constant_chi2 = constant_chi2
        self.records: list = []
        self.start = time.perf_counter()

    def __call__(self, summary):
        radius = summary.trust_region_radius
        self.records.append(
            IterationRecord(
                iteration=int(summary.iteration),
                chi2=2.0 * summary.cost + self.constant_chi2,
                damping=(1.0 / radius if self.inverse else radius) if radius > 0 else float("nan"),
                rho=float(summary.relative_decrease) if summary.iteration > 0 else float("nan"),
                step_norm=float(summary.step_norm) if summary.iteration > 0 else float("nan"),
                accepted=bool(summary.step_is_successful),
                seconds=time.perf_counter() - self.start,
            )
        )
        return pyceres.CallbackReturnType.SOLVER_CONTINUE


def _short_reason(summary) -> str:
    message = summary.message
    for key, short in (
        ("Function tolerance", "function_tolerance"),
        ("Gradient tolerance", "gradient_tolerance"),
        ("Parameter tolerance", "parameter_tolerance"),
        ("Maximum number of iterations", "max_iterations"),
    ):
        if key in message:
            return f"{short}: {message}"
    return f"{summary.termination_type.name.lower()}: {message}"


def solve(
    graph: PoseGraph,
    method: str,
    max_iterations: int = 100,
    *,
    cost_class=None,
    impl="solutions",
    function_tolerance: float = 1e-12,
    parameter_tolerance: float = 1e-12,
    gradient_tolerance: float = 1e-14,
    num_threads: int = 1,
    verbose: bool = False,
) -> RunResult:
    """Optimize ``graph`` from ``graph.poses`` with Ceres' ``method`` (one of ``METHODS``).

    ``levenberg-marquardt`` is Ceres' LM trust-region strategy, ``dogleg`` its
    traditional dogleg; both solve with ``SPARSE_NORMAL_CHOLESKY``. The tolerances
    default far below Ceres' own (1e-6, 1e-8, 1e-10) so that the result agrees with
    Gauss-Newton to 1e-6 relative. ``cost_class`` replaces ``SE2EdgeCost`` (same
    constructor: ``(measurement (3,), sqrt_information (3, 3))``).

    Returns a ``RunResult``: ``params`` (N, 3) with the angles that left ``[-pi, pi)``
    wrapped back; ``final_chi2 = graph.chi2(params)`` (our error, whatever
    ``cost_class`` computes); ``seconds`` is ``pyceres.solve`` alone (building the
    problem excluded); ``iterations`` the step attempts, successful or not, i.e.
    ``num_successful_steps + num_unsuccessful_steps - 1`` (Ceres counts its
    iteration 0, the start, as a successful step). The trace comes from an
    ``IterationCallback``: ``chi2 = 2 * cost`` as Ceres reports it (for a rejected
    step, the cost of the rejected candidate, as in our own traces; plus ``constant_chi2`` of the edges between
    fixed vertices, see ``build_problem``), ``damping`` is ``1 / radius`` for LM
    (Ceres' mu) and the radius for dogleg, ``rho`` Ceres' relative decrease,
    ``seconds`` since the solve started. ``stop_reason`` is ``function_tolerance``,
    ``gradient_tolerance``, ``parameter_tolerance``, ``max_iterations`` or Ceres'
    termination type, then ``: `` and Ceres' message.
    """
    if method not in METHODS:
        raise ValueError(f"unknown Ceres method {method!r}; choose one of {METHODS}")
    if max_iterations < 1:
        raise ValueError(f"max_iterations must be >= 1, got {max_iterations}")
    problem, blocks, costs, constant_chi2 = build_problem(graph, cost_class, impl=impl)

    options = pyceres.SolverOptions()
    options.linear_solver_type = pyceres.LinearSolverType.SPARSE_NORMAL_CHOLESKY
    if method == "dogleg":
        options.trust_region_strategy_type = pyceres.TrustRegionStrategyType.DOGLEG
        options.dogleg_type = pyceres.DoglegType.TRADITIONAL_DOGLEG
    else:
        options.trust_region_strategy_type = pyceres.TrustRegionStrategyType.LEVENBERG_MARQUARDT
    options.max_num_iterations = int(max_iterations)
    options.function_tolerance = function_tolerance
    options.parameter_tolerance = parameter_tolerance
    options.gradient_tolerance = gradient_tolerance
    options.num_threads = num_threads
    options.minimizer_progress_to_stdout = verbose
    callback = _TraceCallback(method != "dogleg", constant_chi2)
    options.callbacks = [callback]
    summary = pyceres.SolverSummary()

    callback.start = start = time.perf_counter()
    pyceres.solve(options, problem, summary)
    seconds = time.perf_counter() - start

    poses = np.array(blocks, dtype=float).reshape(-1, 3)
    # Ceres' angles live in R: wrap those that left [-pi, pi), as g2o and GTSAM do
    # (only those: wrapping an angle already in range may change its last bit).
    outside = (poses[:, 2] < -math.pi) | (poses[:, 2] >= math.pi)
    outside[graph.fixed] = False
    poses[outside, 2] = (poses[outside, 2] + math.pi) % _TWO_PI - math.pi
    trace = callback.records
    if not trace or trace[0].iteration != 0:
        raise RuntimeError("Ceres did not report its starting point to the iteration callback")
    iterations = summary.num_successful_steps + summary.num_unsuccessful_steps - 1
    return RunResult(
        backend="ceres",
        method=method,
        params=poses,
        initial_chi2=graph.chi2(),
        final_chi2=graph.chi2(poses),
        iterations=int(iterations),
        seconds=seconds,
        trace=trace,
        stop_reason=_short_reason(summary),
        factorizations=int(summary.num_linear_solves),
    )
