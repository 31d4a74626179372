"""The trust-region strategies the minimizer asks for steps (Ceres' ``TrustRegionStrategy``).

A strategy answers the minimizer's events and keeps its own state (lambda, nu, the
radius, the cached Gauss-Newton step):

- ``start(problem, lin)``: before the first step; returns the damping value to record;
- ``compute_step(problem, x, lin)``: a step ``h`` (n,) at the current linearization;
- ``trial(problem, x, h, lin)``: the trial point (``Trial``), after any line search;
- ``predicted_decrease(trial, lin)``: the model's decrease of chi2 (chi2 units, so the
  gain ratio is ``rho = (chi2 - chi2_new) / predicted`` for every strategy);
- ``accepts(rho)``; ``step_done(trial, lin, rho, accepted)`` (update lambda or the radius);
- ``relinearized(problem, lin)``: after an accepted step, at the new point;
- ``negligible_step(h, x, options)`` / ``exhausted(x, options)``: the step tolerance,
  tested before the trial (on the step) or after the update (on the radius).

The student's pieces stay small and are graded alone: Gavin's damping rules
(``damping.GavinType1..3``) and the dogleg functions (``dogleg.cauchy_point``,
``dogleg_step``, ``update_radius``); :class:`LevenbergMarquardtStrategy` and :class:`DoglegStrategy`
turn them into strategies.
"""

from dataclasses import dataclass, replace

import numpy as np

from course.core import impl as impl_loader
from course.core.errors import CourseError, NonFiniteError, SingularSystemError
from course.core.method_names import OUR_METHODS
from course.solver.scaled_nielsen import SCALED_NIELSEN, ScaledNielsen
from course.solver.source_nielsen import SOURCE_NIELSEN, SOURCE_TAU, SourceNielsen

GAUSS_NEWTON, DOGLEG = "gauss-newton", "dogleg"
LM_METHODS = ("lm-type1", "lm-type2", "lm-type3")
#: what a comparison runs when no method is named (``course.core.method_names.DEFAULT_METHODS``)
METHODS = (GAUSS_NEWTON, *LM_METHODS, DOGLEG)
#: every strategy :func:`make_strategy` knows, in table order, each described in
#: ``course.core.method_names.OUR_METHODS``
ALL_METHODS = tuple(OUR_METHODS)

#: the dogleg's regularization when H cannot be factorized (Ceres' dogleg strategy)
MU_MIN, MU_MAX = 1e-8, 1.0


@dataclass
class Trial:
    """A candidate point: ``x`` after the step ``h`` (as finally scaled) and its chi2; the minimizer
    linearizes an accepted point only when the run goes on."""

    x: np.ndarray
    h: np.ndarray
    chi2: float
    alpha: float = 1.0


class GaussNewtonStrategy:
    """Every step taken. The trial point's chi2 alone is evaluated (errors, no Jacobians); the minimizer
    linearizes it only when the run goes on, so the point a run stops at is never linearized (GTSAM's
    Gauss-Newton evaluates the error at the new values and linearizes at the next iteration, likewise)."""

    name = GAUSS_NEWTON

    def __init__(self):
        self.factorizations = 0

    def start(self, problem, lin) -> float:
        return float("nan")

    def damping(self) -> float:
        return float("nan")

    def compute_step(self, problem, x, lin):
        self.factorizations += 1
        return problem.solve(lin, None)

    def negligible_step(self, h, x, options) -> bool:
        return _short(h, x, options)

    def trial(self, problem, x, h, lin) -> Trial:
        x_new = problem.retract(x, h)
        return Trial(x_new, h, problem.chi2(x_new))

    def predicted_decrease(self, trial, lin) -> float:
        return float(-trial.h @ lin.b)  # the undamped model, H h = -b

    def accepts(self, rho) -> bool:
        return True

    def step_done(self, trial, lin, rho, accepted) -> None:
        pass

    def relinearized(self, problem, lin) -> None:
        pass

    def exhausted(self, x, options) -> bool:
        return False


#: how often a damping strategy raises lambda tenfold after a singular damped system
SINGULAR_RETRIES = 8


class LevenbergMarquardtStrategy:
    """Levenberg-Marquardt with one of Gavin's damping rules (``impl``'s ``damping`` module).

    The damped system is ``(H + diag(d)) h = -b`` with ``d = rule.damping_diagonal(diag(H),
    lambda)``; a rejected step solves again with the new lambda.
    """

    def __init__(self, rule):
        self.rule = rule
        self.name = getattr(rule, "name", type(rule).__name__)
        self.factorizations = 0
        self.state = None
        self.diag_H = None

    def start(self, problem, lin) -> float:
        self.diag_H = lin.diagonal()
        self.state = self.rule.initial_state(self.diag_H)
        return float(self.state.lam)

    def damping(self) -> float:
        return float(self.state.lam)

    def compute_step(self, problem, x, lin):
        """The damped step; a numerically singular damped system (lambda I too small for a
        rank-deficient H, e.g. bundle adjustment's gauge) raises lambda tenfold and solves
        again, at most ``SINGULAR_RETRIES`` times, as a failed linear solve shrinks the trust
        region in Ceres."""
        for attempt in range(SINGULAR_RETRIES + 1):
            self.factorizations += 1
            try:
                return problem.solve(lin, self.rule.damping_diagonal(self.diag_H, self.state.lam))
            except SingularSystemError:
                if attempt == SINGULAR_RETRIES:
                    raise
                self.state = replace(self.state, lam=10.0 * self.state.lam)
        raise AssertionError("unreachable")

    def negligible_step(self, h, x, options) -> bool:
        return _short(h, x, options)

    def trial(self, problem, x, h, lin) -> Trial:
        x_new = problem.retract(x, h)
        chi2_new = problem.chi2(x_new)
        alpha = float(self.rule.step_scale(h, lin.b, lin.chi2, chi2_new))
        if not np.isfinite(alpha) or alpha <= 0:
            raise NonFiniteError(f"damping.{type(self.rule).__name__}.step_scale returned {alpha}")
        if alpha != 1.0:
            h = alpha * h
            x_new = problem.retract(x, h)
            chi2_new = problem.chi2(x_new)
        return Trial(x_new, h, chi2_new, alpha=alpha)

    def predicted_decrease(self, trial, lin) -> float:
        return float(self.rule.gain_denominator(trial.h, lin.b, self.diag_H, self.state.lam))

    def accepts(self, rho) -> bool:
        return bool(np.isfinite(rho) and self.rule.accepts(rho))

    def step_done(self, trial, lin, rho, accepted) -> None:
        dchi2 = trial.chi2 - lin.chi2
        self.state = self.rule.update(self.state, rho, accepted, alpha=trial.alpha, dchi2=dchi2)
        if not np.isfinite(self.state.lam) or self.state.lam <= 0:
            raise NonFiniteError(f"damping.{type(self.rule).__name__}.update returned lambda = {self.state.lam}")

    def relinearized(self, problem, lin) -> None:
        self.diag_H = lin.diagonal()

    def exhausted(self, x, options) -> bool:
        return False


class DoglegStrategy:
    """Powell's dogleg with ``impl``'s ``dogleg`` pieces: one factorization per point.

    A rejected step shrinks the radius around the Gauss-Newton step and Cauchy point
    already computed, so it costs a chi2 evaluation, never a factorization. When the
    Gauss-Newton system cannot be factorized (or gives a non-finite step), ``mu D^2`` is
    added to the diagonal, ``D^2 = diag(H)`` clamped to [1e-6, 1e32], from mu = 1e-8 up
    by 10 until it works; after an accepted step ``mu = max(1e-8, mu / 5)`` (as Ceres
    Solver's dogleg strategy does).
    """

    name = DOGLEG

    def __init__(self, pieces, initial_radius):
        self.pieces = pieces
        self.radius = float(initial_radius)
        self.factorizations = 0
        self.mu = 0.0
        self.h_gn = self.alpha = None

    def start(self, problem, lin) -> float:
        self._linearized(problem, lin)
        return self.radius

    def damping(self) -> float:
        return self.radius

    def _linearized(self, problem, lin) -> None:
        d2 = np.clip(lin.diagonal(), 1e-6, 1e32)
        while True:
            self.factorizations += 1
            try:
                self.h_gn = problem.solve(lin, self.mu * d2 if self.mu > 0 else None)
                break
            except (SingularSystemError, np.linalg.LinAlgError):
                self.mu = MU_MIN if self.mu == 0 else 10.0 * self.mu
                if self.mu > MU_MAX:
                    raise SingularSystemError("dogleg: H + mu D^2 is not positive definite even at mu = 1") from None
        if not np.any(lin.b):  # at a stationary point: no steepest-descent direction (the loop stops)
            self.alpha = 0.0
            return
        _, self.alpha = self.pieces.cauchy_point(lin.b, lin.matvec(lin.b))

    def compute_step(self, problem, x, lin):
        h, predicted, case = self.pieces.dogleg_step(lin.b, self.h_gn, self.alpha, self.radius)
        if not np.isfinite(predicted) or predicted <= 0:
            raise CourseError(f"dogleg.dogleg_step predicted a decrease of {predicted} ({case} case)")
        self._predicted = 2.0 * float(predicted)  # the pieces work in F = chi2 / 2
        return np.asarray(h, dtype=float)

    def negligible_step(self, h, x, options) -> bool:
        return False  # the radius decides (``exhausted``)

    def trial(self, problem, x, h, lin) -> Trial:
        x_new = problem.retract(x, h)
        return Trial(x_new, h, problem.chi2(x_new))

    def predicted_decrease(self, trial, lin) -> float:
        return self._predicted

    def accepts(self, rho) -> bool:
        return bool(rho > 0)

    def step_done(self, trial, lin, rho, accepted) -> None:
        self.radius = float(self.pieces.update_radius(self.radius, rho, float(np.linalg.norm(trial.h))))

    def relinearized(self, problem, lin) -> None:
        self.mu = max(MU_MIN, self.mu / 5.0) if self.mu > 0 else 0.0
        self._linearized(problem, lin)

    def exhausted(self, x, options) -> bool:
        return self.radius <= options.step_tolerance * (np.linalg.norm(x) + options.step_tolerance)


def _short(h, x, options) -> bool:
    return bool(np.linalg.norm(h) <= options.step_tolerance * (np.linalg.norm(x) + options.step_tolerance))


def make_strategy(method: str, impl="solutions", options=None):
    """A fresh strategy for ``method`` (one of :data:`ALL_METHODS`: :data:`METHODS`, and
    ``lm-scaled-nielsen``, Gavin's types 1 and 3 put together, :mod:`course.solver.scaled_nielsen`,
    and ``lm-source``, type 3 with the constants and cap of chapter 1's source,
    :mod:`course.solver.source_nielsen`) from ``impl``'s pieces; or, for ``method`` a damping rule
    object (``course.solver.damping.DampingStrategy``), Levenberg-Marquardt with that rule."""
    if not isinstance(method, str):  # a damping rule object (e.g. SourceNielsen with other constants)
        return LevenbergMarquardtStrategy(method)
    if method == GAUSS_NEWTON:
        return GaussNewtonStrategy()
    if method == DOGLEG:
        from course.solver.options import SolverOptions

        radius = (options or SolverOptions()).initial_radius
        return DoglegStrategy(impl_loader.load(impl).module("dogleg"), radius)
    if method in LM_METHODS:
        rules = impl_loader.load(impl).module("damping").STRATEGIES
        return LevenbergMarquardtStrategy(rules[method]())
    if method == SOURCE_NIELSEN:
        rules = impl_loader.load(impl).module("damping").STRATEGIES
        return LevenbergMarquardtStrategy(SourceNielsen(rules["lm-type3"](tau=SOURCE_TAU)))
    if method == SCALED_NIELSEN:
        rules = impl_loader.load(impl).module("damping").STRATEGIES
        return LevenbergMarquardtStrategy(ScaledNielsen(rules["lm-type1"](), rules["lm-type3"]()))
    raise ValueError(f"unknown method {method!r}; choose one of {', '.join(ALL_METHODS)}")
