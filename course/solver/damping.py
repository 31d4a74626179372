"""The seam between the Levenberg-Marquardt loop and a damping strategy.

A strategy keeps together the four things that must agree (H. P. Gavin, "The
Levenberg-Marquardt algorithm for nonlinear least squares curve-fitting problems",
section 4.1.1): the initial lambda, the damped system, the denominator of the gain
ratio rho, and the lambda update after an accepted or rejected step.

Notation (shared by every chapter): residuals ``r = y_hat(p) - y`` (m,), Jacobian
``J = dr/dp`` (m, n), weights ``W`` (m,), ``H = J^T W J`` (n, n), ``b = J^T W r`` (n,),
``chi2 = r^T W r``. Gavin writes ``J^T W (y - y_hat)``, which is ``-b`` here.
The damped system is ``(H + diag(d)) h = -b`` with the damping diagonal ``d`` (n,).
"""

from dataclasses import dataclass


@dataclass(frozen=True)
class DampingState:
    """lambda and Nielsen's nu; every update returns a new state."""

    lam: float
    nu: float = 2.0


class DampingStrategy:
    """Interface the loop calls; the exercises implement it (see ``exercises/damping.py``)."""

    name = "damping"
    #: step acceptance threshold on rho (Gavin's eps_4 = 1e-1, lm.m default)
    epsilon_4 = 1e-1

    def initial_state(self, diag_H) -> DampingState:
        """State before the first step, from ``diag(H)`` (n,)."""
        raise NotImplementedError

    def damping_diagonal(self, diag_H, lam):
        """``d`` (n,) so that the damped system is ``(H + diag(d)) h = -b``."""
        raise NotImplementedError

    def gain_denominator(self, h, b, diag_H, lam) -> float:
        """Denominator of rho = (chi2(p) - chi2(p + h)) / denominator."""
        raise NotImplementedError

    def step_scale(self, h, b, chi2, chi2_full_step) -> float:
        """Multiplier alpha of the step (a line search); 1 unless the strategy has one."""
        return 1.0

    def accepts(self, rho) -> bool:
        """Whether a step with gain ratio ``rho`` is taken (Gavin: rho > eps_4)."""
        return bool(rho > self.epsilon_4)

    def update(self, state: DampingState, rho, accepted, alpha=1.0, dchi2=0.0) -> DampingState:
        """The state for the next step.

        ``dchi2 = chi2(p + alpha h) - chi2(p)``; ``alpha`` from :meth:`step_scale`.
        """
        raise NotImplementedError
