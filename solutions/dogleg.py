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
    # BEGIN SOLUTION
    alpha = float(g @ g) / float(g @ Hg)
    return -alpha * g, alpha
    # END SOLUTION


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
    # BEGIN SOLUTION
    gn_decrease = -float(g @ h_gn) / 2.0
    if np.linalg.norm(h_gn) <= radius:
        return h_gn, gn_decrease, GAUSS_NEWTON
    g_norm = np.linalg.norm(g)
    a = -alpha * g
    a_norm = alpha * g_norm
    if a_norm >= radius:
        return -(radius / g_norm) * g, radius * (2.0 * a_norm - radius) / (2.0 * alpha), STEEPEST_DESCENT
    diff = h_gn - a
    c = float(a @ diff)
    diff_sq = float(diff @ diff)
    d = np.sqrt(c * c + diff_sq * (radius**2 - a_norm**2))
    beta = (d - c) / diff_sq if c <= 0 else (radius**2 - a_norm**2) / (d + c)
    decrease = alpha * (1.0 - beta) ** 2 * g_norm**2 / 2.0 + beta * (2.0 - beta) * gn_decrease
    return a + beta * diff, decrease, DOGLEG
    # END SOLUTION


def update_radius(radius, rho, step_norm):
    """The next trust-region radius (Madsen et al., algorithm 3.21).

    ``rho > 0.75``: ``max(radius, 3 |step|)``; ``rho < 0.25``: ``radius / 2``;
    otherwise unchanged.
    """
    # BEGIN SOLUTION
    if rho > 0.75:
        return max(radius, 3.0 * step_norm)
    if rho < 0.25:
        return radius / 2.0
    return radius
    # END SOLUTION


#: the derived results, in three levels (``python -m autograder hint NAME LEVEL``; the release
#: prints levels 1..N into the docstrings with ``--hints N``, course.core.hints)
HINTS = {
    "cauchy_point": (
        """Restrict the model to the line ``h = -alpha g``: ``L(-alpha g)`` is a parabola in alpha.
        Set its derivative to zero.""",
        """``L(-alpha g) = F - alpha |g|^2 + alpha^2 g^T H g / 2``.""",
        """``alpha = |g|^2 / g^T H g`` and ``h_cp = -alpha g``.""",
    ),
    "dogleg_step": (
        """For each case, put the step into ``L(0) - L(h) = -g^T h - h^T H h / 2`` and use what is
        known about it: ``H h_gn = -g``, and what makes alpha the Cauchy point's (the model's slope along
        ``-g`` is zero there). For beta, write ``|a + beta (h_gn -
        a)|^2 = radius^2`` as a quadratic in beta and take the root in (0, 1).""",
        """With ``diff = h_gn - a``, ``c = a^T diff``: ``|diff|^2 beta^2 + 2 c beta + |a|^2 - radius^2 = 0``,
        whose positive root is ``(-c + d) / |diff|^2``, ``d = sqrt(c^2 + |diff|^2 (radius^2 - |a|^2))``;
        when ``c > 0`` the numerator cancels: multiply by ``(d + c) / (d + c)``. For the decreases:
        ``L(0) - L(h_gn) = -g^T h_gn / 2``, and along ``-t g``,
        ``L(0) - L(-t g) = t |g|^2 - t^2 |g|^2 / (2 alpha)``.""",
        """::

            1. |h_gn| <= radius: L(0) - L(h) = -g^T h_gn / 2
            2. |a| >= radius:    h = -(radius / |g|) g,  L(0) - L(h) = radius (2 |a| - radius) / (2 alpha)
            3. otherwise:        h = a + beta (h_gn - a),
                                 L(0) - L(h) = alpha (1 - beta)^2 |g|^2 / 2 + beta (2 - beta) (-g^T h_gn / 2)

        with ``c = a^T (h_gn - a)``, ``d = sqrt(c^2 + |h_gn - a|^2 (radius^2 - |a|^2))``,
        ``beta = (d - c) / |h_gn - a|^2`` if ``c <= 0`` else ``(radius^2 - |a|^2) / (d + c)``.""",
    ),
}
