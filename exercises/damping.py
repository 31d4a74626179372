"""Chapter 1 exercise: H. P. Gavin's three Levenberg-Marquardt damping update types.

Source: H. P. Gavin, "The Levenberg-Marquardt algorithm for nonlinear least squares
curve-fitting problems" (Duke University), section 4.1.1, eqs. 12-16, and the
defaults of its ``lm.m``. Notation in ``course/solver/damping.py``: ``b = J^T W r`` is minus
Gavin's ``J^T W (y - y_hat)``, and the damped system is ``(H + diag(d)) h = -b``.

Only type 1 clamps lambda to [1e-7, 1e7]; type 2 bounds it below only, type 3 not at all.

Inputs at the edges of the contract (each is a check input):
- type 1: lambda at 1e-7 and the step accepted: it stays 1e-7
- type 1: lambda at 1e7 and the step rejected: it stays 1e7
- type 2: a rejected step takes lambda past 1e7 (type 2 has no upper bound)
- type 2: alpha above 1 (chi2 fell by more than 2 g^T h; no upper bound)
- type 2: alpha's denominator negative (chi2 fell by more than 4 g^T h): alpha = 0.1
- type 3: an accepted step takes lambda below 1e-7 (type 3 has no lower bound)
- type 3: a rejected step takes lambda past 1e7 (type 3 has no upper bound)

Allowed imports: numpy, scipy, course.solver.damping.
"""

import numpy as np

from course.solver.damping import DampingState, DampingStrategy

#: lambda bounds of lm.m (Gavin, section 4.1.1)
LAMBDA_MIN = 1e-7
LAMBDA_MAX = 1e7
#: lower bound on type 2's line-search alpha (this course's safeguard, see step_scale)
ALPHA_MIN = 1e-1


class GavinType1(DampingStrategy):
    """Type 1 (Marquardt): ``[H + lambda diag(H)] h = -b``.

    Constants (Gavin section 4.1.1 and lm.m defaults): lambda_0 = 1e-2,
    L_down = 9, L_up = 11, eps_4 = 1e-1, lambda clamped to [1e-7, 1e7].
    """

    name = "lm-type1"

    def __init__(self, lambda_0=1e-2, l_down=9.0, l_up=11.0):
        self.lambda_0, self.l_down, self.l_up = lambda_0, l_down, l_up

    def initial_state(self, diag_H):
        """lambda_0 as given (default 1e-2), independent of H."""
        raise NotImplementedError("TODO damping.GavinType1.initial_state: not implemented yet")

    def damping_diagonal(self, diag_H, lam):
        """``d = lambda diag(H)`` (n,), Gavin eq. 13."""
        raise NotImplementedError("TODO damping.GavinType1.damping_diagonal: not implemented yet")

    def gain_denominator(self, h, b, diag_H, lam):
        """The decrease of chi2 that the quadratic model ``chi2(p) + 2 b^T h + h^T H h`` predicts for
        the step ``h``, which solves this type's damped system (Gavin eq. 16). Derive it in terms of
        ``h``, ``b``, ``lambda`` and ``diag(H)`` (no H: the strategy is not given it);
        ``python -m autograder hint GavinType1.gain_denominator``.
        """
        raise NotImplementedError("TODO damping.GavinType1.gain_denominator: not implemented yet")

    def update(self, state, rho, accepted, alpha=1.0, dchi2=0.0):
        """Accepted: ``lambda = max(lambda / L_down, 1e-7)``; rejected: ``min(lambda L_up, 1e7)``."""
        raise NotImplementedError("TODO damping.GavinType1.update: not implemented yet")


class GavinType2(DampingStrategy):
    """Type 2: ``[H + lambda I] h = -b`` with Gavin's line search on the step length.

    Constants: lambda_0 = tau max diag(H) with tau = lambda_0 of lm.m (1e-2),
    eps_4 = 1e-1, lambda clamped below at 1e-7 (Gavin section 4.1.1).
    """

    name = "lm-type2"

    def __init__(self, tau=1e-2):
        self.tau = tau

    def initial_state(self, diag_H):
        """``lambda_0 = tau max diag(H)`` (Gavin eq. 14 start)."""
        raise NotImplementedError("TODO damping.GavinType2.initial_state: not implemented yet")

    def damping_diagonal(self, diag_H, lam):
        """``d = lambda (1, ..., 1)`` (n,), i.e. lambda I."""
        raise NotImplementedError("TODO damping.GavinType2.damping_diagonal: not implemented yet")

    def step_scale(self, h, b, chi2, chi2_full_step):
        """Gavin's alpha: ``(g^T h) / ((chi2(p+h) - chi2(p)) / 2 + 2 g^T h)`` with ``g = -b``,
        as printed in section 4.1.1 and coded in lm.m, bounded below by ``ALPHA_MIN``.

        The bound is this course's: from a far start (the default (0, 0, 0)) the full
        step overflows the exponential, alpha underflows to ~1e-27, chi2(p + alpha h)
        rounds to chi2(p), and lambda never grows again.
        """
        raise NotImplementedError("TODO damping.GavinType2.step_scale: not implemented yet")

    def gain_denominator(self, h, b, diag_H, lam):
        """The decrease of chi2 the quadratic model predicts for ``h`` (Gavin eq. 15), in ``h``, ``b``
        and ``lambda``, as for type 1 but with this type's system (h is already the scaled step alpha h);
        ``python -m autograder hint GavinType2.gain_denominator``."""
        raise NotImplementedError("TODO damping.GavinType2.gain_denominator: not implemented yet")

    def update(self, state, rho, accepted, alpha=1.0, dchi2=0.0):
        """Accepted: ``max(lambda / (1 + alpha), 1e-7)``; rejected: ``lambda + |dchi2| / (2 alpha)`` (no upper
        bound)."""
        raise NotImplementedError("TODO damping.GavinType2.update: not implemented yet")


class GavinType3(DampingStrategy):
    """Type 3 (Nielsen): system and lambda_0 as type 2, nu_0 = 2.

    Constants: tau = 1e-2 (lm.m lambda_0), eps_4 = 1e-1, nu_0 = 2 (Gavin section 4.1.1;
    Madsen, Nielsen and Tingleff 2004, algorithm 3.16).
    """

    name = "lm-type3"

    def __init__(self, tau=1e-2):
        self.tau = tau

    def initial_state(self, diag_H):
        """``lambda_0 = tau max diag(H)``, ``nu = 2``."""
        raise NotImplementedError("TODO damping.GavinType3.initial_state: not implemented yet")

    def damping_diagonal(self, diag_H, lam):
        """``d = lambda (1, ..., 1)`` (n,), i.e. lambda I."""
        raise NotImplementedError("TODO damping.GavinType3.damping_diagonal: not implemented yet")

    def gain_denominator(self, h, b, diag_H, lam):
        """The decrease of chi2 the quadratic model predicts for ``h`` (Gavin eq. 15), in ``h``, ``b``
        and ``lambda`` (this type's system is type 2's); ``python -m autograder hint GavinType3.gain_denominator``."""
        raise NotImplementedError("TODO damping.GavinType3.gain_denominator: not implemented yet")

    def update(self, state, rho, accepted, alpha=1.0, dchi2=0.0):
        """Accepted: ``lambda max(1/3, 1 - (2 rho - 1)^3)``, ``nu = 2``; rejected: ``lambda nu``, ``nu = 2 nu``;
        lambda unclamped."""
        raise NotImplementedError("TODO damping.GavinType3.update: not implemented yet")


STRATEGIES = {cls.name: cls for cls in (GavinType1, GavinType2, GavinType3)}
