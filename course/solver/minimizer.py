"""The one minimizer: Gauss-Newton, Levenberg-Marquardt (Gavin's types 1-3) and dogleg.

It owns the linearization, the gain ratio ``rho = (chi2 - chi2_new) / predicted`` (chi2
units for every method), acceptance, termination and the trace; a strategy
(:mod:`course.solver.strategies`) computes the steps and keeps lambda or the radius.
One iteration is one step attempt, accepted or rejected, as in Gavin's lm.m and Ceres.
"""

import time
from collections.abc import Callable
from enum import Enum
from typing import Protocol

import numpy as np

from course.core.trace import IterationRecord, RunResult
from course.solver.linearization import Linearization
from course.solver.options import SolverOptions
from course.solver.strategies import make_strategy


class StopReason(str, Enum):
    """Why the minimizer stopped; the value is what ``RunResult.stop_reason`` holds."""

    MAX_ITERATIONS = "max_iterations"
    GRADIENT_TOLERANCE = "gradient_tolerance"
    COST_TOLERANCE = "cost_tolerance"
    STEP_TOLERANCE = "step_tolerance"
    CALLBACK = "callback"

    @property
    def message(self) -> str:
        return _MESSAGES[self]


_MESSAGES = {
    StopReason.MAX_ITERATIONS: "the maximum number of step attempts was reached",
    StopReason.GRADIENT_TOLERANCE: "max |b| fell below gradient_tolerance (b = J^T W r)",
    StopReason.COST_TOLERANCE: "a step changed chi2 by less than cost_tolerance, relative",
    StopReason.STEP_TOLERANCE: "the step (or the trust radius) fell below step_tolerance (|x| + step_tolerance)",
    StopReason.CALLBACK: "the callback asked to stop",
}


class Problem(Protocol):
    """What the minimizer needs of a problem (curve fit, pose graph, ...).

    ``x0`` (n,) the start; ``linearize(x)`` H, b and chi2 at x; ``chi2(x)``;
    ``solve(lin, damping)`` the step h (n,) of ``(H + diag(damping)) h = -b`` (damping
    (n,) or None); ``retract(x, h)`` the point x moved by h.
    """

    x0: np.ndarray

    def linearize(self, x) -> Linearization: ...

    def chi2(self, x) -> float: ...

    def solve(self, lin: Linearization, damping=None) -> np.ndarray: ...

    def retract(self, x, h) -> np.ndarray: ...


def minimize(problem: Problem, method="gauss-newton", impl="solutions", options: SolverOptions | None = None,
             callback: Callable[[IterationRecord], bool | None] | None = None) -> RunResult:
    """Minimize ``problem`` from ``problem.x0`` with ``method`` (``course.solver.METHODS``, or a damping
    rule object: Levenberg-Marquardt with it, named by its ``name``).

    The strategy's pieces come from ``impl`` (``solutions``, ``exercises`` or a path).
    ``callback(record)`` is called after every step attempt with its
    :class:`~course.core.trace.IterationRecord`; returning True stops the run.
    """
    options = options or SolverOptions()
    strategy = make_strategy(method, impl, options)
    start = time.perf_counter()
    x = np.array(problem.x0, dtype=float)
    lin = problem.linearize(x)
    initial_chi2 = lin.chi2
    trace = [IterationRecord(0, lin.chi2, damping=strategy.start(problem, lin))]
    reason = StopReason.MAX_ITERATIONS
    x_chi2 = None  # problem.chi2(x) once a step is accepted: every strategy's trial chi2 is that of its point
    for iteration in range(1, options.max_iterations + 1):
        if np.max(np.abs(lin.b)) <= options.gradient_tolerance:
            reason = StopReason.GRADIENT_TOLERANCE
            break
        h = strategy.compute_step(problem, x, lin)
        if strategy.negligible_step(h, x, options):
            reason = StopReason.STEP_TOLERANCE  # no step taken: nothing to record
            break
        trial = strategy.trial(problem, x, h, lin)
        predicted = strategy.predicted_decrease(trial, lin)
        rho = (lin.chi2 - trial.chi2) / predicted if predicted != 0 else float("nan")
        accepted = strategy.accepts(rho)
        record = IterationRecord(iteration, float(trial.chi2), strategy.damping(), float(rho),
                                 float(np.linalg.norm(trial.h)), accepted, time.perf_counter() - start,
                                 strategy.factorizations)
        trace.append(record)
        strategy.step_done(trial, lin, rho, accepted)
        if accepted:
            # judged on the trial's chi2: a run that stops here never linearizes at its last point
            x, previous, x_chi2 = trial.x, lin.chi2, trial.chi2
            converged = abs(previous - trial.chi2) <= options.cost_tolerance * previous
            if not converged:
                lin = problem.linearize(x)
                strategy.relinearized(problem, lin)
        else:  # a rejected step that changes chi2 by less than cost_tolerance: the optimum, to rounding
            # (rho is noise there; going on would only shrink the step to the step tolerance, as
            # Ceres' function tolerance also stops)
            converged = abs(lin.chi2 - trial.chi2) <= options.cost_tolerance * lin.chi2
        if converged:
            reason = StopReason.COST_TOLERANCE
        elif strategy.exhausted(x, options):
            reason = StopReason.STEP_TOLERANCE
        if callback is not None and callback(record) and reason is StopReason.MAX_ITERATIONS:
            reason = StopReason.CALLBACK
        if reason is not StopReason.MAX_ITERATIONS:
            break
    return RunResult(
        backend="ours", method=method if isinstance(method, str) else strategy.name, params=x,
        initial_chi2=initial_chi2, final_chi2=problem.chi2(x) if x_chi2 is None else float(x_chi2),
        iterations=len(trace) - 1, seconds=time.perf_counter() - start, trace=trace,
        stop_reason=reason, factorizations=strategy.factorizations,
        linear_solve=str(getattr(problem, "linear_solve", "")),
    )
