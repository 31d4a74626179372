# RELEASE: omit
"""Known mistakes in ``gnc`` (see ``autograder.mistakes``): the weights with one slip, and the
outer loop with one slip, on the same stand-in problem."""

import numpy as np

from autograder.checks.gnc import GM, LOOP, TLS


def tls(s, mu, c2, *, slip=None):
    s = np.asarray(s, dtype=float)
    lower, upper = mu / (mu + 1.0) * c2, (mu + 1.0) / mu * c2
    if slip == "bounds":
        lower, upper = upper, lower
    middle = {None: np.sqrt(c2 * mu * (mu + 1.0) / np.maximum(s, 1e-300)) - mu,
              "bounds": np.sqrt(c2 * mu * (mu + 1.0) / np.maximum(s, 1e-300)) - mu,
              "no_sqrt": c2 * mu * (mu + 1.0) / np.maximum(s, 1e-300) - mu,
              "r_for_s": np.sqrt(c2 * mu * (mu + 1.0)) / np.maximum(s, 1e-300) - mu}[slip]
    return np.where(s <= lower, 1.0, np.where(s >= upper, 0.0, middle))


def gm(s, mu, c2, *, slip=None):
    s = np.asarray(s, dtype=float)
    return {None: (mu * c2 / (s + mu * c2)) ** 2, "not_squared": mu * c2 / (s + mu * c2),
            "mu_below": (mu * c2 / (s + c2)) ** 2}[slip]


def tls_mistakes(call, ref):
    s, mu, c2 = call.args
    return {"value": [
        (tls(s, mu, c2, slip="bounds"), "the bounds are swapped: w = 1 below mu/(mu+1) c2, 0 above (mu+1)/mu c2"),
        (tls(s, mu, c2, slip="no_sqrt"), "in between, w = sqrt(c2 mu (mu+1) / s) - mu: the square root is missing"),
        (tls(s, mu, c2, slip="r_for_s"), "s is already squared: w = sqrt(c2 mu (mu+1) / s) - mu, not "
                                         "sqrt(c2 mu (mu+1)) / s - mu"),
    ]}


def gm_mistakes(call, ref):
    s, mu, c2 = call.args
    return {"value": [(gm(s, mu, c2, slip="not_squared"), "the Geman-McClure weight is squared: (mu c2 / (s + mu c2))^2"),
                      (gm(s, mu, c2, slip="mu_below"), "mu scales c2 in the denominator too: (mu c2 / (s + mu c2))^2")]}


def loop(call, *, slip=None):
    y, sigma2, c2, surrogate, known = call.args
    raw = known
    y = np.asarray(y, float)
    known = np.zeros(len(y), dtype=bool) if known is None else np.asarray(known, bool)
    calls = [0]
    last = [np.nan]

    def solve(w):
        calls[0] += 1
        last[0] = float(w @ y / w.sum())
        return (y - last[0]) ** 2 / sigma2

    weights = np.ones(len(y))
    s = solve(weights)
    s_max = float(np.max(s if slip != "unknown_only" else s[~known]))
    if s_max <= c2 and slip != "no_early_return":
        return {"weights": weights, "mus": np.zeros(0), "x": last[0], "calls": float(calls[0])}
    mu = c2 / (2 * s_max - c2) if surrogate == "tls" else 2 * s_max / c2
    mus = []
    for _ in range(100 if slip == "unlimited" else call.kwargs.get("max_iterations", 100)):
        weights = tls(s, mu, c2) if surrogate == "tls" else gm(s, mu, c2)
        if slip == "raw_known":  # the argument itself: weights[None] = 1 sets every weight
            weights[raw] = 1.0
        elif slip != "known":
            weights[known] = 1.0
        if slip != "no_resolve":
            s = solve(weights)
        mus.append(mu)
        if surrogate == "tls":
            if np.sum(weights * (1 - weights)) < 1e-6:
                break
            mu *= 1.4
        else:
            if mu == 1.0:
                break
            mu = max(mu / 1.4, 1.0) if slip != "gm_up" else mu * 1.4
    return {"weights": weights, "mus": np.array(mus), "x": last[0], "calls": float(calls[0])}


def loop_mistakes(call, ref):
    known = {"mus": [], "weights": [], "x": [], "calls": []}
    for slip, text in (("raw_known", "known_inliers may be None (no edge known), and weights[None] = 1.0 sets "
                                     "every weight to 1: index with the mask built from it"),
                       ("unknown_only", "s_max is the largest s of every edge, known inliers included (least "
                                        "squares spreads a wrong edge's error over its neighbours)"),
                       ("known", "known inliers keep weight 1 whatever their residual"),
                       ("no_resolve", "solve again after every new set of weights (s must come from the new "
                                      "solution)"),
                       ("gm_up", "for Geman-McClure mu shrinks toward 1: mu = max(mu / factor, 1)"),
                       ("no_early_return", "when no s exceeds c2 at the start there is nothing to reject: return "
                                           "the unit weights and no mu at once"),
                       ("unlimited", "stop after max_iterations new sets of weights even if they have not "
                                     "settled")):
        if slip == "raw_known" and call.args[4] is not None:
            continue
        try:
            out = loop(call, slip=slip)
        except (ValueError, FloatingPointError):
            continue
        for name in known:
            known[name].append((out[name], text))
    return known


MISTAKES = {
    f"{TLS}: the truncated-least-squares weights": tls_mistakes,
    f"{GM}: the Geman-McClure weights": gm_mistakes,
    f"{LOOP}: the outer loop: mu schedule, weights": loop_mistakes,
}
