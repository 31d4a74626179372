"""Chapter 6 exercise: graduated non-convexity (GNC) against wrong loop closures.

A wrong loop closure (perceptual aliasing) pulls a least-squares solution as hard as it is
wrong. A robust cost ``rho(s_k)`` of each edge's ``s_k = e_k^T Omega_k e_k`` ignores large
residuals, but is not convex: a solver started far away falls in a local minimum. GNC (Yang,
Antonante, Tzoumas, Carlone, "Graduated non-convexity for robust spatial perception", RA-L
2020) solves a sequence of weighted least-squares problems, from a convex surrogate of the
robust cost (control ``mu``) to the robust cost itself, each one's weights in closed form:

Truncated least squares (TLS) with threshold ``c2`` on s, mu growing from ``c2 / (2 s_max -
c2)`` by ``factor`` each round (``s_max`` the largest s of the least-squares solution)::

    w = 1                               for s <= mu / (mu + 1) c2
    w = sqrt(c2 mu (mu + 1) / s) - mu   in between
    w = 0                               for s >= (mu + 1) / mu c2

Geman-McClure (GM), mu shrinking from ``2 s_max / c2`` by ``factor`` down to 1::

    w = (mu c2 / (s + mu c2))^2

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
"""

import numpy as np

SURROGATES = ("tls", "gm")


def tls_weights(s, mu, c2):
    """The TLS surrogate's weights (M,) in [0, 1] at control ``mu`` > 0 for squared residuals s (M,)."""
    raise NotImplementedError("TODO gnc.tls_weights: not implemented yet")


def gm_weights(s, mu, c2):
    """The Geman-McClure surrogate's weights (M,) in (0, 1] at control ``mu`` >= 1."""
    raise NotImplementedError("TODO gnc.gm_weights: not implemented yet")


def gnc(solve, num_edges, c2, surrogate="tls", known_inliers=None, factor=1.4, max_iterations=100):
    """``(weights (M,), mus)``: GNC's outer loop.

    1. ``s = solve(ones)``: plain least squares. If ``s_max = max s <= c2`` (over every edge:
       least squares spreads a wrong edge's error over its neighbours, known inliers
       included), every edge is an inlier: return the ones and ``[]``.
    2. ``mu`` from ``s_max`` (module docstring).
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
