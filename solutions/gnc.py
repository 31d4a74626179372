"""Chapter 6 exercise: graduated non-convexity (GNC) against wrong loop closures.

A wrong loop closure (perceptual aliasing) pulls a least-squares solution as hard as it is
wrong. A robust cost ``rho(s_k)`` of each edge's ``s_k = e_k^T Omega_k e_k`` ignores large
residuals, but is not convex: a solver started far away falls in a local minimum. GNC (Yang,
Antonante, Tzoumas, Carlone, "Graduated non-convexity for robust spatial perception", RA-L
2020) solves a sequence of weighted least-squares problems, from a convex surrogate
``rho_mu`` of the robust cost (control ``mu``) to the robust cost itself.

Truncated least squares (TLS), ``rho(s) = min(s, c2)`` with threshold ``c2`` on s; its surrogate
at ``mu`` > 0 (the robust cost as mu -> infinity), with mu growing from ``c2 / (2 s_max - c2)`` by
``factor`` each round (``s_max`` the largest s of the least-squares solution)::

    rho_mu(s) = s                                       for s <= mu / (mu + 1) c2
    rho_mu(s) = 2 sqrt(c2 mu (mu + 1) s) - mu (c2 + s)  in between
    rho_mu(s) = c2                                      for s >= (mu + 1) / mu c2

Geman-McClure (GM), ``rho(s) = c2 s / (c2 + s)``; its surrogate ``rho_mu(s) = mu c2 s / (mu c2 +
s)`` (plain least squares as mu -> infinity, GM at mu = 1), mu shrinking from ``2 s_max / c2`` by
``factor`` down to 1.

Each round replaces ``sum_k rho_mu(s_k)`` by the weighted least squares ``sum_k w_k s_k`` whose
minimizer is a stationary point of the surrogate when the weights are computed at the solution
(iteratively reweighted least squares): derive the weights ``w(s)`` of each surrogate in closed
form (``python -m autograder hint tls_weights 1``, ``gm_weights``; then 2 and 3).

The outer loop (``gnc``) is problem-agnostic: it sees the problem only through
``solve(weights) -> s``, the minimizer of ``sum_k w_k s_k`` (every solve warm-started by the
caller from the last).

Inputs at the edges of the contract (each is a check input):
- tls_weights: s = 0 (no division by zero: w = 1)
- tls_weights: s exactly on the bounds mu/(mu+1) c2 and (mu+1)/mu c2 (w = 1 and 0: continuous)
- tls_weights: mu far below 1 and far above it (0.05, 20)
- tls_weights: one edge (M = 1)
- gm_weights: mu = 1, its lower bound
- gm_weights: one edge (M = 1)
- gnc: no s above c2 at the start (the unit weights, no mu)
- gnc: known_inliers None (no edge known)
- gnc: max_iterations reached before the weights settle

Allowed imports: numpy, scipy.
"""

import numpy as np

SURROGATES = ("tls", "gm")


def tls_weights(s, mu, c2):
    """The TLS surrogate's weights (M,) in [0, 1] at control ``mu`` > 0 for squared residuals s (M,).

    Derive them from ``rho_mu`` (module docstring): continuous in s, 1 up to ``mu / (mu + 1) c2``
    and 0 from ``(mu + 1) / mu c2`` on; ``s = 0`` gives 1 (no division by zero).
    """
    # BEGIN SOLUTION
    s = np.asarray(s, dtype=float)
    lower, upper = mu / (mu + 1.0) * c2, (mu + 1.0) / mu * c2
    w = np.sqrt(c2 * mu * (mu + 1.0) / np.maximum(s, 1e-300)) - mu
    return np.where(s <= lower, 1.0, np.where(s >= upper, 0.0, w))
    # END SOLUTION


def gm_weights(s, mu, c2):
    """The Geman-McClure surrogate's weights (M,) in (0, 1] at control ``mu`` >= 1 for squared
    residuals s (M,): derive them from ``rho_mu`` (module docstring); ``s = 0`` gives 1."""
    # BEGIN SOLUTION
    return (mu * c2 / (np.asarray(s, dtype=float) + mu * c2)) ** 2
    # END SOLUTION


def gnc(solve, num_edges, c2, surrogate="tls", known_inliers=None, factor=1.4, max_iterations=100):
    """``(weights (M,), mus)``: GNC's outer loop.

    1. ``s = solve(ones)``: plain least squares. If ``s_max = max s <= c2`` (over every edge:
       least squares spreads a wrong edge's error over its neighbours, known inliers
       included), every edge is an inlier: return the ones and ``[]``.
    2. ``mu`` from ``s_max`` (module docstring: its starting value for each surrogate).
    3. Repeat at most ``max_iterations`` times: weights from ``s`` and ``mu`` (``known_inliers``,
       a boolean mask (M,) or None, keep weight 1); ``s = solve(weights)``; record mu in
       ``mus``; then stop when converged, else update mu:
       TLS: converged when every weight is 0 or 1 to 1e-6 (``sum w (1 - w) < 1e-6``), else
       ``mu *= factor``; GM: converged when ``mu == 1``, else ``mu = max(mu / factor, 1)``.
    """
    if surrogate not in SURROGATES:
        raise ValueError(f"unknown surrogate {surrogate!r}; choose one of {SURROGATES}")
    known = np.zeros(num_edges, dtype=bool) if known_inliers is None else np.asarray(known_inliers, dtype=bool)
    # BEGIN SOLUTION
    weights = np.ones(num_edges)
    s = np.asarray(solve(weights), dtype=float)
    s_max = float(np.max(s, initial=0.0))
    if s_max <= c2:
        return weights, []
    mu = c2 / (2.0 * s_max - c2) if surrogate == "tls" else 2.0 * s_max / c2
    mus = []
    for _ in range(max_iterations):
        weights = tls_weights(s, mu, c2) if surrogate == "tls" else gm_weights(s, mu, c2)
        weights[known] = 1.0
        s = np.asarray(solve(weights), dtype=float)
        mus.append(mu)
        if surrogate == "tls":
            if np.sum(weights * (1.0 - weights)) < 1e-6:
                break
            mu *= factor
        else:
            if mu == 1.0:
                break
            mu = max(mu / factor, 1.0)
    return weights, mus
    # END SOLUTION


#: the derived results, in three levels (``python -m autograder hint NAME LEVEL``; the release
#: prints levels 1..N into the docstrings with ``--hints N``, course.core.hints)
HINTS = {
    "tls_weights": (
        """Compare the gradients (in the unknowns x) of the two costs: ``sum_k rho_mu(s_k(x))`` and
        ``sum_k w_k s_k(x)`` with the weights held fixed. They agree at the current x when each
        ``w_k`` is the slope of ``rho_mu`` at ``s_k``; differentiate each of the three pieces in s.""",
        """By the chain rule, ``grad sum_k rho_mu(s_k) = sum_k rho_mu'(s_k) grad s_k``: the weight is
        ``w = d rho_mu / d s``. The middle piece has ``d/ds 2 sqrt(c2 mu (mu + 1) s) = sqrt(c2 mu (mu + 1) / s)``;
        at the two bounds it gives ``(mu + 1) - mu = 1`` and ``mu - mu = 0``, so w is continuous.""",
        """::

            w = 1                               if s <= mu / (mu + 1) c2
            w = 0                               if s >= (mu + 1) / mu c2
            w = sqrt(c2 mu (mu + 1) / s) - mu   otherwise

        evaluated with ``np.where`` over all s at once (floor s at a tiny positive number inside the
        square root: s = 0 falls in the first case, but ``np.where`` evaluates every branch).""",
    ),
    "gm_weights": (
        """As for ``tls_weights``: the weight is the slope ``d rho_mu / d s`` of the surrogate at ``s``
        (iteratively reweighted least squares). Differentiate the quotient.""",
        """With ``a = mu c2``: ``d/ds (a s / (a + s)) = a ((a + s) - s) / (a + s)^2 = a^2 / (a + s)^2``.""",
        """``w = (mu c2 / (s + mu c2))^2``, in (0, 1], 1 at s = 0.""",
    ),
    "gnc": (
        """One plain solve to see whether any edge is an outlier at all; then alternate: weights from
        the last ``s`` at the current ``mu``, a weighted solve, the stopping test, the next ``mu``. Each
        round is one reweighting step of a surrogate a little closer to the robust cost, warm-started
        from the last (``solve`` does the warm start).""",
        """The starting mu keeps every edge in play: for TLS, ``mu = c2 / (2 s_max - c2)`` gives
        ``(mu + 1) / mu c2 = 2 s_max``, so no weight starts at 0; for GM, ``mu c2 = 2 s_max`` gives every
        weight at least ``(2/3)^2 = 4/9``. Record ``mu`` after the solve and before updating it; the
        known inliers' weights are reset to 1 after the weights are computed, every round. TLS has
        converged when no weight is strictly between 0 and 1 (``w (1 - w)`` vanishes only at 0 and 1);
        GM when mu has reached 1.""",
        """::

            w = ones(M);  s = solve(w);  s_max = max(s)
            if s_max <= c2: return w, []
            mu = c2 / (2 s_max - c2)   (TLS)   or   2 s_max / c2   (GM)
            repeat max_iterations times:
                w = tls_weights(s, mu, c2) or gm_weights(s, mu, c2);  w[known] = 1
                s = solve(w);  mus.append(mu)
                TLS: stop if sum(w (1 - w)) < 1e-6, else mu = mu * factor
                GM:  stop if mu == 1, else mu = max(mu / factor, 1)
            return w, mus""",
    ),
}
