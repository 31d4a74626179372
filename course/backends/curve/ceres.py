"""The chapter 1 curve fit through Ceres (``pyceres``), with the model in Python.

``y = exp(a x^2 + b x + c)``. Ceres minimizes ``1/2 sum f_k^2`` with the whitened
residuals ``f = sqrt(w) r`` and their Jacobian ``sqrt(w) J``, ``r`` and ``J`` the implementation's
``curve_model.residuals_and_jacobian`` (chapter 1's exercise: the peer runs the student's model, as
our solvers do), so ``chi2 = 2 * cost`` is our chi2. Same data, same start (``data.start``) and
same weights as our solvers.

Layout (measured, see ``solve(per_point=...)``): by default ONE residual block holds
all m points (``CurveCost``, m residuals, vectorized with numpy); the alternative,
one block per point (a ``CurveCost`` of one point each, as the source's C++ does), makes
Ceres call Python m times per evaluation. Measured on the default data (m = 100, LM, median
of 5): one block 0.7 ms for the whole solve (26 iterations), one block per point 11 ms
(25 iterations), about 15x: the Python call, not the arithmetic, is what a Python cost
function costs.
The parameter block is one C-contiguous ``(3,)`` float64 array, updated in place.

Methods: ``levenberg-marquardt`` (Ceres' LM strategy) and ``dogleg`` (traditional
dogleg), both with ``DENSE_QR`` (3 parameters).
"""

import time

import numpy as np
import pyceres

from course.backends import registry
from course.core import impl as impl_loader
from course.core.errors import NonFiniteError
from course.core.trace import IterationRecord, RunResult
from course.problems.curve.problem import curve_chi2

METHODS = registry.peer_methods("curve", "ceres")

#: Ceres' defaults are 1e-6 / 1e-10 / 1e-8 (it stops early); these make the minimum
#: agree with ours to 1e-6 relative.
TOLERANCES = {"function_tolerance": 1e-15, "gradient_tolerance": 1e-15, "parameter_tolerance": 1e-15}


class CurveCost(pyceres.CostFunction):
    """Points in one residual block: ``f = sqrt(w) r`` (m,), ``(r, J) = model(params, x, y)`` the
    implementation's ``residuals_and_jacobian``.

    ``Evaluate(parameters, residuals, jacobians)``: ``parameters[0]`` is the (3,) block;
    ``residuals`` (m,) and ``jacobians[0]`` (3 m,), the row-major (m, 3) Jacobian, are
    written in place; ``jacobians`` or ``jacobians[0]`` may be None. Returns False
    (Ceres then rejects the step) when the model is not finite there.
    """

    def __init__(self, x, y, weights, model):
        pyceres.CostFunction.__init__(self)  # without it pyceres segfaults
        self.x = np.ascontiguousarray(np.atleast_1d(x), dtype=float)
        self.y = np.ascontiguousarray(np.atleast_1d(y), dtype=float)
        self.sqrt_w = np.sqrt(np.atleast_1d(np.asarray(weights, dtype=float)))
        self.model = model
        self.set_num_residuals(len(self.x))
        self.set_parameter_block_sizes([3])

    def Evaluate(self, parameters, residuals, jacobians):  # noqa: N802 (the pyceres name)
        with np.errstate(over="ignore", invalid="ignore"):  # an error of the model leaves pyceres.solve
            r, J = self.model(np.array(parameters[0], dtype=float), self.x.copy(), self.y.copy())
            f = self.sqrt_w * np.asarray(r, dtype=float)
            J = self.sqrt_w[:, None] * np.asarray(J, dtype=float)
        if not np.all(np.isfinite(f)):
            return False
        residuals[:] = f
        if jacobians is not None and jacobians[0] is not None:
            jacobians[0][:] = J.ravel()
        return True


def build_problem(data, per_point=False, impl="solutions"):
    """``(problem, block, costs)``: ``block`` the (3,) parameter array (starts at
    ``data.start``, updated in place), ``costs`` the cost functions (keep them alive): one
    :class:`CurveCost` of every point, or one per point (``per_point``), on the model of ``impl``."""
    model = impl_loader.load(impl).module("curve_model").residuals_and_jacobian
    model(np.array(data.start, dtype=float), np.asarray(data.x, dtype=float)[:1].copy(),
          np.asarray(data.y, dtype=float)[:1].copy())  # a TODO raises here, before Ceres runs
    block = np.array(data.start, dtype=np.float64, order="C", copy=True)
    problem = pyceres.Problem()
    if per_point:
        costs = [CurveCost(x, y, w, model) for x, y, w in zip(data.x, data.y, data.weights)]
    else:
        costs = [CurveCost(data.x, data.y, data.weights, model)]
    for cost in costs:
        problem.add_residual_block(cost, None, [block])
    return problem, block, costs


class _TraceCallback(pyceres.IterationCallback):
    """One ``IterationRecord`` per Ceres iteration (0 = the start)."""

    def __init__(self, inverse_radius: bool):
        pyceres.IterationCallback.__init__(self)  # as for CostFunction
        self.inverse = inverse_radius
        self.records: list = []
        self.start = time.perf_counter()

    def __call__(self, summary):
        radius = summary.trust_region_radius
        first = summary.iteration == 0
        self.records.append(
            IterationRecord(
                iteration=int(summary.iteration),
                chi2=2.0 * summary.cost,
                damping=(1.0 / radius if self.inverse else radius) if radius > 0 else float("nan"),
                rho=float("nan") if first else float(summary.relative_decrease),
                # Ceres reports step_norm 0 for an unsuccessful step: write NaN (unknown)
                step_norm=float("nan") if first or not summary.step_is_successful else float(summary.step_norm),
                accepted=True if first else bool(summary.step_is_successful),
                seconds=time.perf_counter() - self.start,
            )
        )
        return pyceres.CallbackReturnType.SOLVER_CONTINUE


def solve(data, method="levenberg-marquardt", max_iterations=100, per_point=False, impl="solutions",
          **options) -> RunResult:
    """Fit ``data`` (a ``CurveData``) with Ceres' ``method`` (one of ``METHODS``).

    Args:
        data: ``course.problems.curve.problem.CurveData``; starts from ``data.start``.
        method: ``"levenberg-marquardt"`` or ``"dogleg"``.
        max_iterations: ``SolverOptions.max_num_iterations``.
        per_point: one residual block per point instead of one for all (slower).
        impl: the implementation whose ``curve_model`` gives the residuals and the Jacobian.
        **options: any ``pyceres.SolverOptions`` attribute (e.g. ``function_tolerance``,
            ``initial_trust_region_radius``); the defaults are ``TOLERANCES``.

    Returns:
        ``RunResult(backend="ceres")``. ``seconds`` is ``pyceres.solve`` alone (building
        the problem excluded). ``iterations`` counts the step attempts, successful or
        not: ``num_successful_steps + num_unsuccessful_steps - 1`` (Ceres counts its
        iteration 0, the start, as a successful step). The trace comes from an
        ``IterationCallback`` (``options.callbacks``; ``update_state_every_iteration``
        stays False because the callback reads no parameter): ``chi2 = 2 * cost`` as
        Ceres reports it, which for an unsuccessful step is the cost of the rejected
        candidate (as in our trace); ``damping`` is ``1 / radius`` for LM (Ceres'
        mu, its lambda) and the radius for dogleg; ``rho`` is Ceres' relative decrease.
        ``initial_chi2`` and ``final_chi2`` are evaluated with our error.
    """
    if method not in METHODS:
        raise ValueError(f"ceres: unknown method {method!r}; choose one of {METHODS}")
    initial_chi2 = curve_chi2(data, data.start)
    if not np.isfinite(initial_chi2):
        raise NonFiniteError(f"ceres_curve: the model is not finite at the start {list(data.start)}")
    problem, block, costs = build_problem(data, per_point=per_point, impl=impl)
    solver_options = pyceres.SolverOptions()
    solver_options.max_num_iterations = int(max_iterations)
    solver_options.linear_solver_type = pyceres.LinearSolverType.DENSE_QR
    solver_options.minimizer_progress_to_stdout = False
    solver_options.logging_type = pyceres.LoggingType.SILENT
    if method == "dogleg":
        solver_options.trust_region_strategy_type = pyceres.TrustRegionStrategyType.DOGLEG
        solver_options.dogleg_type = pyceres.DoglegType.TRADITIONAL_DOGLEG
    else:
        solver_options.trust_region_strategy_type = pyceres.TrustRegionStrategyType.LEVENBERG_MARQUARDT
    settings = dict(TOLERANCES)
    settings.update(options)
    for name, value in settings.items():
        if name.startswith("_") or not hasattr(solver_options, name):
            raise ValueError(f"ceres: pyceres.SolverOptions has no option {name!r}")
        setattr(solver_options, name, value)
    callback = _TraceCallback(inverse_radius=(method == "levenberg-marquardt"))
    solver_options.callbacks = [callback]
    summary = pyceres.SolverSummary()
    t0 = time.perf_counter()
    callback.start = t0
    pyceres.solve(solver_options, problem, summary)
    seconds = time.perf_counter() - t0
    params = block.copy()
    del costs  # alive until here
    return RunResult(
        backend="ceres",
        method=method,
        params=params,
        initial_chi2=initial_chi2,
        final_chi2=curve_chi2(data, params),
        iterations=int(summary.num_successful_steps + summary.num_unsuccessful_steps) - 1,
        seconds=seconds,
        trace=callback.records,
        stop_reason=f"{summary.termination_type.name.lower()}: {summary.message}",
    )
