"""Chapter 3 exercise: Powell's dogleg step and its trust-region radius.

Source: K. Madsen, H. B. Nielsen, O. Tingleff, "Methods for non-linear least squares
problems" (2004), section 3.3 and algorithm 3.21; the stable root for beta as in
Ceres Solver's dogleg strategy. Notation: ``F = chi2 / 2``, gradient ``g = b = J^T W r``,
``H = J^T W J``, quadratic model ``L(h) = F + g^T h + h^T H h / 2``.

Inputs at the edges of the contract (each is a check input):
- a Gauss-Newton step inside the region (|h_gn| < radius)
- |h_gn| exactly equal to the radius: the Gauss-Newton step
- a Cauchy point beyond the radius (|a| > radius): steepest descent to the boundary
- |a| exactly equal to the radius (|h_gn| beyond it): steepest descent, not dogleg
- rho exactly 0.25: the radius stays
- rho exactly 0.75: the radius stays

Allowed imports: numpy, scipy.
"""

import numpy as np

#: the three cases of the dogleg step
GAUSS_NEWTON, STEEPEST_DESCENT, DOGLEG = "gauss-newton", "steepest-descent", "dogleg"


def cauchy_point(g, Hg):
    """The minimizer of the model ``L`` along steepest descent (the Cauchy point).

    Args: g (n,) the gradient; Hg (n,) the product ``H g`` (g^T H g > 0).
    Returns: ``(h_cp, alpha)``: ``h_cp = -alpha g`` (n,) with ``alpha > 0`` the step length that
    minimizes ``L(-alpha g)``; derive it (``python -m autograder hint cauchy_point``).
    """
    raise NotImplementedError("TODO dogleg.cauchy_point: not implemented yet")


def dogleg_step(g, h_gn, alpha, radius):
    """The dogleg step for trust-region ``radius``, its predicted decrease and its case.

    Cases (Madsen et al., algorithm 3.21), with ``a = -alpha g`` the Cauchy point:
    1. ``|h_gn| <= radius``: the Gauss-Newton step.
    2. ``|a| >= radius``: steepest descent clipped to the boundary, ``h = -(radius / |g|) g``.
    3. otherwise ``h = a + beta (h_gn - a)`` with ``0 < beta < 1`` such that ``|h| = radius``.
    In every case the predicted decrease is ``L(0) - L(h)``, exact for the quadratic model (not
    Madsen et al.'s ``F(x)`` shortcut, which holds only when the linearized residual vanishes).
    Derive the three decreases and beta, the root of a quadratic, computed without cancellation
    (``python -m autograder hint dogleg_step 1``, then 2 and 3).

    Args: g (n,), g != 0, h_gn (n,) the Gauss-Newton step (``H h_gn = -g``), alpha from
    ``cauchy_point``, radius > 0. The ties belong to the cases above: ``|h_gn| = radius`` is
    Gauss-Newton, ``|a| = radius < |h_gn|`` steepest descent.
    Returns: ``(h (n,), predicted_decrease (float, in F = chi2/2 units), case)``.
    """
    raise NotImplementedError("TODO dogleg.dogleg_step: not implemented yet")


def update_radius(radius, rho, step_norm):
    """The next trust-region radius (Madsen et al., algorithm 3.21).

    ``rho > 0.75``: ``max(radius, 3 |step|)``; ``rho < 0.25``: ``radius / 2``;
    otherwise unchanged.
    """
    raise NotImplementedError("TODO dogleg.update_radius: not implemented yet")
