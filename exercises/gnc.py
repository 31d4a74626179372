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
    raise NotImplementedError("TODO gnc.tls_weights: not implemented yet")


def gm_weights(s, mu, c2):
    """The Geman-McClure surrogate's weights (M,) in (0, 1] at control ``mu`` >= 1 for squared
    residuals s (M,): derive them from ``rho_mu`` (module docstring); ``s = 0`` gives 1."""
    raise NotImplementedError("TODO gnc.gm_weights: not implemented yet")


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
    raise NotImplementedError("TODO gnc.gnc: not implemented yet")
