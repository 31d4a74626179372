"""The Gauss-Newton / Levenberg-Marquardt loop, with the damping strategy as a plug-in.

The loop owns iteration, acceptance, termination and the trace; the strategy (from
the chosen implementation's ``damping`` module) owns lambda. One iteration is one
step attempt, accepted or rejected, as in Gavin's lm.m and in Ceres.
"""

import time

import numpy as np

from course import impl as impl_loader
from course.errors import NonFiniteError
from course.solvers.options import SolverOptions
from course.trace import IterationRecord, RunResult

GAUSS_NEWTON = "gauss-newton"
METHODS = (GAUSS_NEWTON, "lm-type1", "lm-type2", "lm-type3", "dogleg")


def make_strategy(method: str, impl="solutions"):
    """The damping strategy object for ``method`` (None for Gauss-Newton)."""
    if method == GAUSS_NEWTON:
        return None
    strategies = impl_loader.load(impl).module("damping").STRATEGIES
    if method not in strategies:
        raise ValueError(f"unknown method {method!r}; choose one of {METHODS}")
    return strategies[method]()


def minimize(problem, method="gauss-newton", impl="solutions", options=None) -> RunResult:
    """Minimize ``problem`` from ``problem.x0`` with ``method`` (one of ``METHODS``).

    ``problem`` provides ``x0``, ``linearize(x) -> Linearization``, ``chi2(x)``,
    ``solve(lin, damping) -> h`` and ``retract(x, h)``.
    """
    if method == "dogleg":
        from course.solvers.dogleg import minimize_dogleg

        return minimize_dogleg(problem, impl=impl, options=options)
    options = options or SolverOptions()
    strategy = make_strategy(method, impl)
    start = time.perf_counter()
    x = np.array(problem.x0, dtype=float)
    lin = problem.linearize(x)
    initial_chi2 = lin.chi2
    diag_H = lin.diagonal()
    state = strategy.initial_state(diag_H) if strategy else None
    trace = [IterationRecord(0, lin.chi2, damping=state.lam if state else np.nan)]
    factorizations, reason = 0, "max_iterations"

    for iteration in range(1, options.max_iterations + 1):
        if np.max(np.abs(lin.b)) <= options.gradient_tolerance:
            reason = "gradient_tolerance"
            break
        damping = strategy.damping_diagonal(diag_H, state.lam) if strategy else None
        h = problem.solve(lin, damping)
        factorizations += 1
        if np.linalg.norm(h) <= options.step_tolerance * (np.linalg.norm(x) + options.step_tolerance):
            reason = "step_tolerance"  # no step taken: nothing to record
            break
        if strategy is None:
            # Gauss-Newton takes every step; linearizing there gives its chi2 too
            predicted = float(-h @ lin.b)  # decrease of the undamped model, H h = -b
            x, previous = problem.retract(x, h), lin.chi2
            lin = problem.linearize(x)
            rho = (previous - lin.chi2) / predicted if predicted != 0 else np.nan
            trace.append(_record(iteration, lin.chi2, None, rho, h, True, start, factorizations))
            if abs(previous - lin.chi2) <= options.cost_tolerance * previous:
                reason = "cost_tolerance"
                break
            continue
        x_new, h, chi2_new, alpha = _trial_point(problem, strategy, x, h, lin)
        dchi2 = chi2_new - lin.chi2
        denominator = strategy.gain_denominator(h, lin.b, diag_H, state.lam)
        rho = -dchi2 / denominator if denominator != 0 else np.nan
        accepted = bool(strategy.accepts(rho)) if np.isfinite(rho) else False
        trace.append(_record(iteration, chi2_new, state, rho, h, accepted, start, factorizations))
        state = strategy.update(state, rho, accepted, alpha=alpha, dchi2=dchi2)
        if not np.isfinite(state.lam) or state.lam <= 0:
            raise NonFiniteError(f"damping.{type(strategy).__name__}.update returned lambda = {state.lam}")
        if accepted:
            x, previous = x_new, lin.chi2
            lin = problem.linearize(x)
            diag_H = lin.diagonal()
            if abs(previous - lin.chi2) <= options.cost_tolerance * previous:
                reason = "cost_tolerance"
                break
    final_chi2 = problem.chi2(x)
    return RunResult(
        backend="ours",
        method=method,
        params=x,
        initial_chi2=initial_chi2,
        final_chi2=final_chi2,
        iterations=len(trace) - 1,
        seconds=time.perf_counter() - start,
        trace=trace,
        stop_reason=reason,
        factorizations=factorizations,
    )


def _trial_point(problem, strategy, x, h, lin):
    """``(x_new, h, chi2_new, alpha)``: the trial point, after the strategy's line search."""
    x_new = problem.retract(x, h)
    chi2_new = problem.chi2(x_new)
    alpha = float(strategy.step_scale(h, lin.b, lin.chi2, chi2_new))
    if not np.isfinite(alpha) or alpha <= 0:
        raise NonFiniteError(f"damping.{type(strategy).__name__}.step_scale returned {alpha}")
    if alpha != 1.0:
        h = alpha * h
        x_new = problem.retract(x, h)
        chi2_new = problem.chi2(x_new)
    return x_new, h, chi2_new, alpha


def _record(iteration, chi2, state, rho, h, accepted, start, factorizations):
    return IterationRecord(
        iteration=iteration,
        chi2=float(chi2),
        damping=float(state.lam) if state is not None else float("nan"),
        rho=float(rho),
        step_norm=float(np.linalg.norm(h)),
        accepted=bool(accepted),
        seconds=time.perf_counter() - start,
        factorizations=factorizations,
    )
