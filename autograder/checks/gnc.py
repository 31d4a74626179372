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

MODULES = ("gnc",)
TLS = "gnc.tls_weights"
GM = "gnc.gm_weights"
LOOP = "gnc.gnc"
C2 = 9.0


def _s(seed):
    rng = np.random.default_rng(91 if seed is None else [seed, 291])
    return np.concatenate([rng.uniform(0.0, 30.0, 20), [0.0, C2, 1e-12], rng.uniform(100.0, 1e4, 5)])


def _weight_calls(function, mus):
    def calls(seed=None):
        s = _s(seed)
        return [Call(f"gnc:{function}", (s, mu, C2), where=f"at mu = {mu:g}, c2 = {C2:g}, s from 0 to {s.max():.4g}")
                for mu in mus]
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
    return calls


CHECKS = [
    check(TLS, "the truncated-least-squares weights", 2, _weight_calls("tls_weights", (0.05, 1.0, 20.0)), values(
        ("value",), 1e-10, 1e-12, "w = 1 for s <= mu/(mu+1) c2, 0 for s >= (mu+1)/mu c2, "
                                  "sqrt(c2 mu (mu+1) / s) - mu in between", {"value": "w[{}]"})),
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
