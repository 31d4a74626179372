"""Powell's dogleg minimizer: one factorization per linearization.

A rejected step shrinks the trust region around the Gauss-Newton step and Cauchy
point already computed, so it costs a chi2 evaluation, never a factorization.
When the Gauss-Newton system cannot be factorized (or gives a non-finite step), the
loop adds ``mu D^2`` to the diagonal, ``D^2 = diag(H)`` clamped to [1e-6, 1e32],
starting at mu = 1e-8 and raising mu by 10 until it works; after an accepted step
``mu = max(1e-8, mu / 5)`` (as Ceres Solver's dogleg strategy does).
"""

import time

import numpy as np

from course import impl as impl_loader
from course.errors import CourseError, SingularSystemError
from course.solvers.options import SolverOptions
from course.trace import IterationRecord, RunResult

INITIAL_RADIUS = 1e4  # Ceres' and g2o's default
MU_MIN, MU_MAX = 1e-8, 1.0


def gauss_newton_step(problem, lin, mu):
    """``(h_gn, mu, factorizations)``: the GN step, regularized by ``mu D^2`` when needed."""
    d2 = np.clip(lin.diagonal(), 1e-6, 1e32)
    factorizations = 0
    while True:
        factorizations += 1
        try:
            return problem.solve(lin, mu * d2 if mu > 0 else None), mu, factorizations
        except (SingularSystemError, np.linalg.LinAlgError):
            mu = MU_MIN if mu == 0 else 10.0 * mu
            if mu > MU_MAX:
                raise SingularSystemError("dogleg: H + mu D^2 is not positive definite even at mu = 1")


def minimize_dogleg(problem, impl="solutions", options=None, initial_radius=INITIAL_RADIUS) -> RunResult:
    """Minimize ``problem`` with the dogleg pieces of ``impl`` (module ``dogleg``)."""
    options = options or SolverOptions()
    pieces = impl_loader.load(impl).module("dogleg")
    start = time.perf_counter()
    x = np.array(problem.x0, dtype=float)
    lin = problem.linearize(x)
    initial_chi2, radius, mu = lin.chi2, float(initial_radius), 0.0
    h_gn, mu, factorizations = gauss_newton_step(problem, lin, mu)
    h_cp, alpha = pieces.cauchy_point(lin.b, lin.matvec(lin.b))
    trace = [IterationRecord(0, lin.chi2, damping=radius)]
    reason = "max_iterations"
    for iteration in range(1, options.max_iterations + 1):
        if np.max(np.abs(lin.b)) <= options.gradient_tolerance:
            reason = "gradient_tolerance"
            break
        h, predicted, case = pieces.dogleg_step(lin.b, h_gn, alpha, radius)
        h = np.asarray(h, dtype=float)
        step_norm = float(np.linalg.norm(h))
        if not np.isfinite(predicted) or predicted <= 0:
            raise CourseError(f"dogleg.dogleg_step predicted a decrease of {predicted} ({case} case)")
        x_new = problem.retract(x, h)
        chi2_new = problem.chi2(x_new)
        rho = (lin.chi2 - chi2_new) / (2.0 * predicted)
        accepted = bool(rho > 0)
        trace.append(IterationRecord(iteration, chi2_new, radius, rho, step_norm, accepted,
                                     time.perf_counter() - start, factorizations))
        radius = float(pieces.update_radius(radius, rho, step_norm))
        if accepted:
            x, previous = x_new, lin.chi2
            lin = problem.linearize(x)
            if abs(previous - lin.chi2) <= options.cost_tolerance * previous:
                reason = "cost_tolerance"
                break
            mu = max(MU_MIN, mu / 5.0) if mu > 0 else 0.0
            h_gn, mu, count = gauss_newton_step(problem, lin, mu)
            factorizations += count
            h_cp, alpha = pieces.cauchy_point(lin.b, lin.matvec(lin.b))
        if radius <= options.step_tolerance * (np.linalg.norm(x) + options.step_tolerance):
            reason = "step_tolerance"
            break
    return RunResult(
        backend="ours", method="dogleg", params=x, initial_chi2=initial_chi2,
        final_chi2=problem.chi2(x), iterations=len(trace) - 1,
        seconds=time.perf_counter() - start, trace=trace, stop_reason=reason,
        factorizations=factorizations,
    )
