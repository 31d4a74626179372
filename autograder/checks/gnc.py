"""Checks of ``gnc``: the TLS and Geman-McClure weights, and GNC's outer loop, on a stand-in
problem.

Public inputs: squared residuals spanning the three TLS regions (inside, between and beyond
the bounds) at three values of mu; the loop on a robust mean of 30 values, 8 of them wrong,
the first 4 known inliers (one of them 4.5 sigma away: the surrogate alone would reject it),
for each surrogate; and the same without the wrong values, where only the known inlier's s
exceeds c2 (GNC still runs: least squares may hide a wrong edge's error in its neighbours);
without that one too, where no s exceeds c2 (nothing to do: the weights stay 1, no mu); and the
TLS loop stopped by ``max_iterations = 3`` before it converges. Hidden: the same kind from the
hidden seed.
The loop uses the student's own weights: a wrong weight function costs the loop's check too.
"""

import numpy as np

from autograder.checks import Call
from autograder.checks.common import check, values
from autograder.checks.edges import Edge

MODULES = ("gnc",)
TLS = "gnc.tls_weights"
GM = "gnc.gm_weights"
LOOP = "gnc.gnc"
C2 = 9.0


def _s(seed):
    rng = np.random.default_rng(91 if seed is None else [seed, 291])
    return np.concatenate([rng.uniform(0.0, 30.0, 20), [0.0, C2, 1e-12], rng.uniform(100.0, 1e4, 5)])


def _weight_calls(function, mus):
    """At each mu, the squared residuals of :func:`_s` (for TLS with that mu's two bounds appended), then
    one edge (M = 1) at the middle mu."""
    def calls(seed=None):
        out = []
        for mu in mus:
            s = _s(seed)
            where = f"at mu = {mu:g}, c2 = {C2:g}, s from 0 to {s.max():.4g}"
            if function == "tls_weights":
                s = np.concatenate([s, [mu / (mu + 1.0) * C2, (mu + 1.0) / mu * C2]])
                where += ", the last two exactly on the bounds mu/(mu+1) c2 and (mu+1)/mu c2"
            out.append(Call(f"gnc:{function}", (s, mu, C2), where=where))
        one = np.array([_s(seed)[0]])
        out.append(Call(f"gnc:{function}", (one, mus[1], C2), where=f"at mu = {mus[1]:g}, c2 = {C2:g}, one edge "
                                                                     f"(s of shape (1,): s = {one[0]:.4g})"))
        return out
    return calls


def problem(seed=None) -> dict:
    """30 values: 22 near 10 (sigma 1), 8 wrong ones far away; the first 4 known inliers, the first of
    them 4.5 sigma away."""
    rng = np.random.default_rng(93 if seed is None else [seed, 293])
    y = 10.0 + rng.normal(0.0, 1.0, 30)
    y[22:] = 10.0 + rng.choice([-1.0, 1.0], 8) * rng.uniform(6.0, 40.0, 8)
    y[0] = 10.0 + 4.5
    known = np.zeros(30, dtype=bool)
    known[:4] = True
    return {"y": y, "known": known}


def _loop_calls(seed=None):
    p = problem(seed)
    calls = [Call("@autograder.tasks.gnc:robust_mean", (p["y"], 1.0, C2, surrogate, p["known"]), returns="dict",
                  label=LOOP, where=f"with the {surrogate.upper()} surrogate on a robust mean of 30 values, 8 wrong, "
                                    "the first 4 known inliers (value 0 4.5 sigma away), c2 = 9")
             for surrogate in ("tls", "gm")]
    clean = p["y"][:22]  # no wrong value: only the known inlier 4.5 sigma away exceeds c2
    calls.append(Call("@autograder.tasks.gnc:robust_mean", (clean, 1.0, C2, "tls", p["known"][:22]), returns="dict",
                      label=LOOP, where="with the TLS surrogate on a robust mean of 22 right values, the first 4 "
                                        "known inliers (value 0 4.5 sigma away, the only s above c2 = 9)"))
    tight = 10.0 + np.clip(clean[1:] - 10.0, -1.5, 1.5)  # |y - mean| <= 3: every s <= c2 whatever the seed
    calls.append(Call("@autograder.tasks.gnc:robust_mean", (tight, 1.0, C2, "tls", p["known"][1:22]),
                      returns="dict", label=LOOP, where="with the TLS surrogate on a robust mean of 21 right values "
                                                        "(every s below c2 = 9 at the start)"))
    calls.append(Call("@autograder.tasks.gnc:robust_mean", (p["y"], 1.0, C2, "tls", p["known"]),
                      {"max_iterations": 3}, returns="dict", label=LOOP,
                      where="with the TLS surrogate on a robust mean of 30 values, 8 wrong, max_iterations = 3"))
    calls.append(Call("@autograder.tasks.gnc:robust_mean", (p["y"], 1.0, C2, "gm", None), returns="dict",
                      label=LOOP, where="with the GM surrogate on a robust mean of 30 values, 8 wrong, "
                                        "known_inliers=None (no edge known)"))
    return calls


CHECKS = [
    check(TLS, "the truncated-least-squares weights", 2, _weight_calls("tls_weights", (0.05, 1.0, 20.0)), values(
        ("value",), 1e-10, 1e-12, "w = 1 for s <= mu/(mu+1) c2, 0 for s >= (mu+1)/mu c2, "
                                  "sqrt(c2 mu (mu+1) / s) - mu in between", {"value": "w[{}]"}),
        exact_inputs=True),  # s exactly on mu's bounds, as the contract writes them: moving it changes the case
    check(GM, "the Geman-McClure weights", 1, _weight_calls("gm_weights", (1.0, 4.0, 300.0)), values(
        ("value",), 1e-10, 1e-12, "w = (mu c2 / (s + mu c2))^2", {"value": "w[{}]"})),
    check(LOOP, "the outer loop: mu schedule, weights", 3, _loop_calls, values(
        ("mus", "weights", "x", "calls"), 1e-8, 1e-10,
        {"mus": "mu from the largest s of all edges (TLS c2/(2 s_max - c2), GM 2 s_max/c2), "
                "then times (TLS) or over (GM, down to 1) the factor after each solve",
         "weights": "new weights from the last solve's s at the current mu; known inliers keep weight 1",
         "x": "solve again after every new set of weights", "calls": "one solve to start, then one per mu"},
        {"mus": "mus[{}]", "weights": "weights[{}]", "x": "x", "calls": "solves"}, scalar=True)),
]


def _tls_on_bounds(call) -> bool:
    s, mu, c2 = call.args
    return bool(np.any(s == mu / (mu + 1.0) * c2) and np.any(s == (mu + 1.0) / mu * c2))


def _loop_s_max(call) -> float:
    y = np.asarray(call.args[0], dtype=float)
    return float(np.max((y - y.mean()) ** 2 / call.args[1]))


def _stops_early(call) -> bool:
    """The TLS loop stopped by max_iterations before its weights settle (the reference takes more rounds)."""
    return call.args[3] == "tls" and call.kwargs.get("max_iterations", 100) < 5 and _loop_s_max(call) > call.args[2]


EDGES = (
    Edge("tls_weights: s = 0 (no division by zero: w = 1)", "gnc:tls_weights", lambda c: bool(np.any(c.args[0] == 0))),
    Edge("tls_weights: s exactly on the bounds mu/(mu+1) c2 and (mu+1)/mu c2 (w = 1 and 0: continuous)",
         "gnc:tls_weights", _tls_on_bounds),
    Edge("tls_weights: mu far below 1 and far above it (0.05, 20)", "gnc:tls_weights",
         lambda c: c.args[1] <= 0.05 or c.args[1] >= 20),
    Edge("tls_weights: one edge (M = 1)", "gnc:tls_weights", lambda c: np.shape(c.args[0]) == (1,)),
    Edge("gm_weights: mu = 1, its lower bound", "gnc:gm_weights", lambda c: c.args[1] == 1.0),
    Edge("gm_weights: one edge (M = 1)", "gnc:gm_weights", lambda c: np.shape(c.args[0]) == (1,)),
    Edge("gnc: no s above c2 at the start (the unit weights, no mu)", "@autograder.tasks.gnc:robust_mean",
         lambda c: _loop_s_max(c) <= c.args[2]),
    Edge("gnc: known_inliers None (no edge known)", "@autograder.tasks.gnc:robust_mean", lambda c: c.args[4] is None),
    Edge("gnc: max_iterations reached before the weights settle", "@autograder.tasks.gnc:robust_mean", _stops_early),
)
