"""GNC's outer loop on a stand-in problem: a robust mean (``checks/gnc.py``)."""

import numpy as np

from autograder.tasks.common import OutputError


def robust_mean(y, sigma2, c2, surrogate, known, impl, max_iterations=None):
    """The student's ``gnc.gnc`` on the weighted mean of ``y`` (M,) (``known``: a mask (M,), or None as
    ``known_inliers``): ``solve(w)`` returns
    ``s_k = (y_k - x)^2 / sigma2`` at ``x = sum w y / sum w`` (``max_iterations``: passed on
    when given, else gnc's default).

    Fields: ``weights`` (M,), ``mus``, ``x`` (the last solve's mean), ``calls`` (how many solves).
    """
    y = np.asarray(y, dtype=float)
    state = {"x": float("nan"), "calls": 0}

    def solve(weights):
        weights = np.asarray(weights, dtype=float)
        if weights.shape != y.shape or not np.all(np.isfinite(weights)) or weights.sum() <= 0:
            raise OutputError(f"solve() was called with weights of shape {weights.shape} that are not {len(y)} "
                              "finite numbers >= 0 with a positive sum")
        state["calls"] += 1
        state["x"] = float(weights @ y / weights.sum())
        return (y - state["x"]) ** 2 / sigma2

    limit = {} if max_iterations is None else {"max_iterations": int(max_iterations)}
    known = None if known is None else np.asarray(known, dtype=bool)
    out = impl.module("gnc").gnc(solve, len(y), c2, surrogate, known_inliers=known, **limit)
    if not isinstance(out, tuple) or len(out) != 2:
        raise OutputError(f"gnc returned {type(out).__name__}, expected a tuple (weights, mus)")
    weights, mus = out
    return {"weights": np.asarray(weights, dtype=float), "mus": np.asarray(mus, dtype=float),
            "x": state["x"], "calls": float(state["calls"])}
