"""Checks of ``robust_kernels``: Huber, Cauchy and Tukey (value, first and second derivative
in s, each its own check) and the robust weighting of a residual's information.

Public inputs: for each kernel, two scales a (binary fractions, so that a^2 is exact and
s = a^2 is exactly on the threshold), with squared norms s = x a^2 for x from 0 through
tiny, below, exactly at and just above the threshold to far beyond; for the weighting,
residuals (n = 3, one Omega per residual; n = 2, one Omega shared) whose rho', rho'' are
Huber's, Cauchy's and Tukey's at chosen s / a^2, either all where the corrected form
``rho' Omega + 2 rho'' (Omega e)(Omega e)^T`` is positive definite (Tukey's just above the margin
among them), or all where it is not (Tukey's just below the margin among them), or a mix, and one
residual alone (K = 1). Each kernel also gets one residual alone, on the threshold. Hidden inputs:
other scales, other s / a^2 in the same regions (x = 0 and x = 1 kept), other residuals and
information matrices, from the hidden seed (Tukey next to the margin and K = 1 kept).
"""

from functools import cache

import numpy as np

from autograder.checks import Call
from autograder.checks.common import check, values
from autograder.checks.edges import Edge

MODULES = ("robust_kernels",)
HUBER = "robust_kernels.huber"
CAUCHY = "robust_kernels.cauchy"
TUKEY = "robust_kernels.tukey"
WEIGHT = "robust_kernels.robust_information"
KERNELS = {"huber": HUBER, "cauchy": CAUCHY, "tukey": TUKEY}

# ---------------------------------------------------------------- kernel inputs

#: public scales per kernel (binary fractions: a^2 exact)
_SCALES = {"huber": (1.0, 2.5), "cauchy": (0.5, 3.0), "tukey": (1.5, 4.5)}
#: public s / a^2: zero, tiny, below, at and just above the threshold, beyond, far beyond
_RATIOS = (0.0, 1e-3, 0.25, 0.8, 1.0, 1.0 + 2.0**-20, 1.5, 4.0, 40.0)


def _ratio_text(x) -> str:
    return ", ".join("1 + 2^-20" if v == 1.0 + 2.0**-20 else f"{v:.4g}" for v in x)


def _hidden_scale(rng) -> float:
    while True:  # a multiple of 1/16 (a^2 exact), never 1 (where a and a^2 agree)
        a = round(float(rng.uniform(0.3, 5.0)) * 16) / 16
        if a != 1.0:
            return a


@cache
def kernel_inputs(kernel, seed=None):
    """``[(s (K,), a, where)]``: two scales, s = x a^2 over the regions of the kernel."""
    if seed is None:
        cases = [(a, np.array(_RATIOS)) for a in _SCALES[kernel]]
    else:
        rng = np.random.default_rng([seed, 281, list(KERNELS).index(kernel)])
        cases = []
        for _ in range(2):
            x = np.concatenate([[0.0, 1.0], 10.0 ** rng.uniform(-3, -1, 1), rng.uniform(0.1, 0.95, 2),
                                1.0 + rng.uniform(1e-7, 1e-3, 1), rng.uniform(1.05, 3, 1),
                                10.0 ** rng.uniform(0.5, 2, 2)])
            cases.append((_hidden_scale(rng), x[rng.permutation(len(x))]))
    out = [(x * (a * a), a, f"for s = x a^2 with scale a = {a:g}, x = ({_ratio_text(x)})") for a, x in cases]
    a = cases[0][0]  # one residual (K = 1), on the threshold
    return out + [(np.array([a * a]), a, f"for one residual (K = 1), s = a^2 with scale a = {a:g}")]


def _kernel_calls(kernel):
    def build(seed=None):
        return [Call(f"robust_kernels:{kernel}", (s, a), returns=("rho", "d_rho", "dd_rho"), where=where)
                for s, a, where in kernel_inputs(kernel, seed)]

    return build


# ---------------------------------------------------------------- weighting inputs

#: (kernel, s / a^2) per residual: where the corrected form is positive definite (the first
#: entry has e = 0), where it is not, and a mix
_DEFINITE: tuple = (("cauchy", 0.0), ("cauchy", 0.05), ("cauchy", 0.5), ("cauchy", 0.9), ("huber", 0.5),
                    ("tukey", 0.05), ("tukey", 0.15))
_NOT_DEFINITE: tuple = (("cauchy", 1.0), ("cauchy", 1.5), ("cauchy", 30.0), ("huber", 1.5), ("huber", 10.0),
                        ("tukey", 0.25), ("tukey", 0.7), ("tukey", 1.0), ("tukey", 3.0))
_MIXED = (("cauchy", 0.3), ("cauchy", 2.0), ("huber", 0.9), ("huber", 4.0), ("tukey", 0.1), ("tukey", 0.5),
          ("cauchy", 0.0))


def _margin_ratio(m: float) -> float:
    """The s / a^2 where Tukey's rho' + 2 rho'' s is ``m`` rho' (``(1 - 5x) / (1 - x) = m``)."""
    return (1.0 - m) / (5.0 - m)


#: Tukey next to the margin DEFINITE_MARGIN = 1e-6 (rho' = 0.64 there): at 1.1e-6 rho' (corrected; below an
#: absolute 1e-6) and at 0.5e-6 rho' (first-order; above 0), by far more than rounding
TUKEY_ABOVE, TUKEY_BELOW = ("tukey", _margin_ratio(1.1e-6)), ("tukey", _margin_ratio(0.5e-6))
_DEFINITE = (*_DEFINITE, TUKEY_ABOVE)
_NOT_DEFINITE = (*_NOT_DEFINITE, TUKEY_BELOW)


def _hidden_cases(rng, kind):
    """Fresh (kernel, x) in the regions of ``kind``: corrected form definite, not, or both."""
    definite = [("cauchy", 0.0), ("cauchy", float(rng.uniform(0.01, 0.2))), ("cauchy", float(rng.uniform(0.2, 0.95))),
                ("huber", float(rng.uniform(0.05, 0.95))), ("tukey", float(rng.uniform(0.01, 0.18)))]
    other = [("cauchy", 1.0), ("cauchy", float(rng.uniform(1.05, 3.0))), ("cauchy", float(10 ** rng.uniform(0.5, 2))),
             ("huber", float(rng.uniform(1.05, 20.0))), ("tukey", float(rng.uniform(0.22, 0.95))),
             ("tukey", float(rng.uniform(1.05, 5.0)))]
    if kind == "definite":
        return [*definite, TUKEY_ABOVE]
    if kind == "not":
        return [*other, TUKEY_BELOW]
    return [definite[1], definite[3], other[1], other[3], definite[4], other[4]]


def _information(rng, K, n):
    """(K, n, n) symmetric positive definite matrices with off-diagonal terms that matter."""
    L = rng.normal(size=(K, n, n))
    return np.matmul(L, L.transpose(0, 2, 1)) + 0.5 * np.eye(n)


@cache
def weight_inputs(kind, seed=None):
    """``[(e (K, n), Omega, d_rho (K,), dd_rho (K,), where)]`` for ``kind`` in ("definite", "not",
    "mixed"): the kernels' rho', rho'' at s_k = e_k^T Omega_k e_k = x_k a_k^2 (instructor side)."""
    from autograder import reference

    kernels = reference.solutions_module("robust_kernels")
    index = ("definite", "not", "mixed").index(kind)
    rng = np.random.default_rng(91 + index if seed is None else [seed, 283, index])
    if seed is None:
        cases = {"definite": _DEFINITE, "not": _NOT_DEFINITE, "mixed": _MIXED}[kind]
    else:
        cases = _hidden_cases(rng, kind)
    out = []
    for n, shared in ((3, False), (2, True)) if kind != "mixed" else ((2, True), (3, True)):
        if n == 3 and kind == "mixed":  # one residual (K = 1) with one Omega (3, 3)
            cases = cases[:1]
        K = len(cases)
        e = rng.normal(0.0, 2.0, (K, n))
        Omega = _information(rng, 1, n)[0] if shared else _information(rng, K, n)
        d_rho, dd_rho = np.zeros(K), np.zeros(K)
        for k, (kernel, x) in enumerate(cases):
            if x == 0.0:
                e[k] = 0.0
            om = Omega if shared else Omega[k]
            s = float(e[k] @ om @ e[k])
            a = float(np.sqrt(s / x)) if x > 0 else 1.5
            _, d1, d2 = getattr(kernels, kernel)(np.array([s]), a)
            d_rho[k], dd_rho[k] = d1[0], d2[0]
        listing = ", ".join(f"{kernel} at s/a^2 = {x:.3g}" for kernel, x in cases)
        omega = f"one Omega ({n}, {n}) for all" if shared else f"Omega ({K}, {n}, {n}), one per residual"
        where = f"for K = {K} residuals e of dimension {n}, {omega}; rho', rho'' of {listing}"
        out.append((e, Omega, d_rho, dd_rho, where))
    return out


def _weight_calls(kind):
    def build(seed=None):
        return [Call(f"robust_kernels:{WEIGHT.split('.')[1]}", (e, Omega, d1, d2), returns="value", where=where)
                for e, Omega, d1, d2, where in weight_inputs(kind, seed)]

    return build


# ---------------------------------------------------------------- judges

_LABELS = {"rho": "rho[{}]", "d_rho": "rho'[{}]", "dd_rho": "rho''[{}]", "value": "weighted[{}]"}
_CAUSES = {
    "huber": {"rho": "rho = s for s <= a^2, 2 a sqrt(s) - a^2 beyond",
              "d_rho": "rho' = 1 for s <= a^2, a / sqrt(s) beyond",
              "dd_rho": "rho'' = 0 for s <= a^2, -a / (2 s^(3/2)) beyond"},
    "cauchy": {"rho": "rho = a^2 log(1 + s / a^2)", "d_rho": "rho' = 1 / (1 + s / a^2)",
               "dd_rho": "rho'' = -1 / (a^2 (1 + s / a^2)^2)"},
    "tukey": {"rho": "rho = a^2 / 3 (1 - (1 - s / a^2)^3) for s <= a^2, a^2 / 3 beyond",
              "d_rho": "rho' = (1 - s / a^2)^2 for s <= a^2, 0 beyond",
              "dd_rho": "rho'' = -2 (1 - s / a^2) / a^2 for s <= a^2, 0 beyond"},
}
_TITLES = {"rho": "rho(s)", "d_rho": "rho'(s)", "dd_rho": "rho''(s)"}
_WEIGHT_CAUSE = ("weighted = rho' Omega + 2 rho'' (Omega e)(Omega e)^T where rho' + 2 rho'' s > 1e-6 rho' "
                 "(s = e^T Omega e), else rho' Omega")
_NOT_DEFINITE_CAUSE = (_WEIGHT_CAUSE + "; Huber beyond its threshold sits exactly on rho' + 2 rho'' s = 0 "
                       "(not above the margin): first-order there")


def _kernel_checks(kernel):
    name = KERNELS[kernel]
    return [check(name, _TITLES[out], 1, _kernel_calls(kernel),
                  values((out,), 1e-10, 1e-12, _CAUSES[kernel][out], _LABELS, atol_scaled=True),
                  exact_inputs=True)  # s = a^2 exactly (x = 1): which side of the threshold is the contract's
            for out in ("rho", "d_rho", "dd_rho")]


CHECKS = [
    *_kernel_checks("huber"),
    *_kernel_checks("cauchy"),
    *_kernel_checks("tukey"),
    check(WEIGHT, "corrected form where it is positive definite", 2, _weight_calls("definite"),
          values(("value",), 1e-9, 1e-12, _WEIGHT_CAUSE, _LABELS, atol_scaled=True)),
    check(WEIGHT, "first-order form where the corrected one is not positive definite", 2, _weight_calls("not"),
          values(("value",), 1e-9, 1e-12, _NOT_DEFINITE_CAUSE, _LABELS, atol_scaled=True)),
    check(WEIGHT, "a mix of both, one Omega for all residuals", 1, _weight_calls("mixed"),
          values(("value",), 1e-9, 1e-12, _WEIGHT_CAUSE, _LABELS, atol_scaled=True)),
]


def _ratios(call) -> np.ndarray:
    """``(rho' + 2 rho'' s) / rho'`` of each residual of a weighting call (``s = e^T Omega e``)."""
    e, Omega, d_rho, dd_rho = (np.asarray(v, dtype=float) for v in call.args)
    Om = np.broadcast_to(Omega, (len(e), e.shape[1], e.shape[1]))
    s = np.einsum("ka,kab,kb->k", e, Om, e)
    with np.errstate(divide="ignore", invalid="ignore"):
        return (d_rho + 2.0 * dd_rho * s) / d_rho


def _kernel_edges(kernel):
    target = f"robust_kernels:{kernel}"

    def x(call):
        s, a = call.args
        return np.asarray(s, dtype=float) / (a * a)

    edges = [Edge(f"{kernel}: s = 0", target, lambda c: bool(np.any(x(c) == 0.0))),
             Edge(f"{kernel}: one residual (K = 1)", target, lambda c: np.shape(c.args[0]) == (1,))]
    if kernel != "cauchy":
        edges += [Edge(f"{kernel}: s exactly at the threshold a^2 (a binary fraction: a^2 exact)", target,
                       lambda c: bool(np.any(x(c) == 1.0))),
                  Edge(f"{kernel}: s just above the threshold (a^2 (1 + 2^-20); hidden 1e-7 to 1e-3 above)", target,
                       lambda c: bool(np.any((x(c) > 1.0) & (x(c) <= 1.0 + 1e-3))))]
    return edges


_WEIGHT_TARGET = f"robust_kernels:{WEIGHT.split('.')[1]}"

EDGES = (
    *_kernel_edges("huber"), *_kernel_edges("cauchy"), *_kernel_edges("tukey"),
    Edge("robust_information: one residual (K = 1)", _WEIGHT_TARGET, lambda c: len(c.args[0]) == 1),
    Edge("robust_information: one Omega (n, n) shared by all residuals", _WEIGHT_TARGET,
         lambda c: np.ndim(c.args[1]) == 2),
    Edge("robust_information: exactly on rho' + 2 rho'' s = 0 (Huber's robust branch: first-order)", _WEIGHT_TARGET,
         lambda c: bool(np.any(np.abs(_ratios(c)) < 1e-12))),
    Edge("robust_information: just above the margin, rho' + 2 rho'' s = 1.1e-6 rho' (corrected)", _WEIGHT_TARGET,
         lambda c: bool(np.any(np.abs(_ratios(c) - 1.1e-6) < 1e-8))),
    Edge("robust_information: just below the margin, rho' + 2 rho'' s = 0.5e-6 rho' (first-order)", _WEIGHT_TARGET,
         lambda c: bool(np.any(np.abs(_ratios(c) - 0.5e-6) < 1e-8))),
)
