"""Chapter 1 problem: fit ``y = exp(a x^2 + b x + c)`` to noisy samples."""

from dataclasses import dataclass

import numpy as np

from course.core import impl as impl_loader
from course.core.errors import SingularSystemError, check_array
from course.solver.linearization import Linearization

TRUTH = (1.0, 2.0, 1.0)
START = (0.0, 0.0, 0.0)


@dataclass
class CurveData:
    """Samples ``x, y, weights`` (m,), the true parameters and the start (3,)."""

    x: np.ndarray
    y: np.ndarray
    weights: np.ndarray
    truth: np.ndarray
    start: np.ndarray
    sigma: float
    seed: int


def generate(num_points=100, sigma=1.0, truth=TRUTH, start=START, seed=0, weights=None):
    """Seeded data: ``x_k = k / num_points``, ``y_k = exp(a x_k^2 + b x_k + c) + N(0, sigma^2)``.

    ``weights`` (m,) defaults to ones (W = I), as in the source experiment.
    """
    if num_points < 3:
        raise ValueError(f"num_points must be at least 3 (three parameters), got {num_points}")
    rng = np.random.default_rng(seed)
    x = np.arange(num_points) / num_points
    a, b, c = truth
    y = np.exp(a * x**2 + b * x + c) + rng.normal(0.0, sigma, num_points)
    w = np.ones(num_points) if weights is None else np.asarray(weights, dtype=float)
    if w.shape != (num_points,) or np.any(w < 0) or not np.all(np.isfinite(w)):
        raise ValueError(f"weights must be {num_points} finite non-negative numbers")
    return CurveData(x, y, w, np.array(truth, float), np.array(start, float), sigma, seed)


def curve_chi2(data, params) -> float:
    """Our chi2 ``sum w (y_hat - y)^2`` at ``params`` (3,), independent of any impl.

    The framework's trusted evaluation, used to score every back end alike.
    """
    a, b, c = np.asarray(params, dtype=float)
    with np.errstate(over="ignore", invalid="ignore"):
        r = np.exp(a * data.x**2 + b * data.x + c) - data.y
        return float(r @ (data.weights * r))


class CurveProblem:
    """The curve fit as the loop sees it, with the student's pieces from ``impl``.

    Parameters ``p`` (3,); ``linearize`` uses ``curve_model.residuals_and_jacobian``
    and ``gauss_newton.normal_equations``; ``solve`` uses ``gauss_newton.solve_step``.
    """

    #: the solve of ``H h = -b`` (``compare``'s ``solve`` column): the implementation's dense 3 x 3 one
    linear_solve = "dense"

    def __init__(self, data: CurveData, impl="solutions"):
        self.data = data
        self.impl = impl_loader.load(impl)
        self._model = self.impl.module("curve_model")
        self._gn = self.impl.module("gauss_newton")
        self.x0 = data.start.copy()

    def residuals_and_jacobian(self, p):
        m = len(self.data.x)
        r, J = self._model.residuals_and_jacobian(np.asarray(p, float), self.data.x, self.data.y)
        where = "curve_model.residuals_and_jacobian"
        return check_array(r, (m,), where, "r"), check_array(J, (m, 3), where, "J")

    def chi2(self, p) -> float:
        r, _ = self.residuals_and_jacobian(p)
        return float(r @ (self.data.weights * r))

    def linearize(self, p) -> Linearization:
        r, J = self.residuals_and_jacobian(p)
        H, b = self._gn.normal_equations(J, r, self.data.weights)
        where = "gauss_newton.normal_equations"
        H, b = check_array(H, (3, 3), where, "H"), check_array(b, (3,), where, "b")
        return Linearization(H=H, b=b, chi2=float(r @ (self.data.weights * r)))

    def solve(self, lin: Linearization, damping=None):
        """Step h (3,) of ``(H + diag(damping)) h = -b``."""
        try:
            h = self._gn.solve_step(lin.H, lin.b, damping)
        except np.linalg.LinAlgError as exc:
            raise SingularSystemError(
                f"gauss_newton.solve_step: H + diag(damping) is not positive definite ({exc})"
            ) from exc
        return check_array(h, (3,), "gauss_newton.solve_step", "h")

    def retract(self, p, h):
        return p + h
