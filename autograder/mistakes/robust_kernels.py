# RELEASE: omit
"""Known mistakes in ``robust_kernels`` (see ``autograder.mistakes``): the kernels and the robust
weighting written plainly (one residual at a time), with one slip or none."""

import numpy as np

from autograder.checks.robust_kernels import CAUCHY, HUBER, TUKEY, WEIGHT


def _each(call, one):
    """``{"rho", "d_rho", "dd_rho"}`` (K,) of ``one(s_k, a) -> (rho, d, dd)`` over the call's s."""
    s, a = call.args
    out = np.array([one(float(v), float(a)) for v in s]).reshape(len(s), 3)
    return {"rho": out[:, 0], "d_rho": out[:, 1], "dd_rho": out[:, 2]}


def _known(call, ref, slips):
    """``{output: [(value, why), ...]}`` of the slips whose output differs from the reference's."""
    known = {name: [] for name in ("rho", "d_rho", "dd_rho")}
    for one, text in slips:
        for name, value in _each(call, one).items():
            if not np.allclose(value, ref[name], rtol=1e-9, atol=1e-12):
                known[name].append((value, text))
    return known


def huber(s, a, *, threshold="a2", beyond="sqrt", d_factor=1.0, dd_sign=-1.0, half=False, strict=False):
    t = a * a if threshold == "a2" else a
    outer = s >= t if strict else s > t
    if beyond == "s_as_e":  # Huber in |e| with s in place of |e|: e^2 below a, 2 a |e| - a^2 above
        out = (2 * a * s - a * a, 2 * a, 0.0) if s > a else (s * s, 2 * s, 2.0)
    elif not outer:
        out = (s, 1.0, 0.0)
    elif beyond == "linear":  # 2 a s - a^2: |e| written as s
        out = (2 * a * s - a * a, 2 * a, 0.0)
    else:
        r = np.sqrt(s)
        out = (2 * a * r - a * a, d_factor * a / r, dd_sign * d_factor * a / (2 * r**3))
    return tuple(0.5 * v for v in out) if half else out


def huber_mistakes(call, ref):
    return _known(call, ref, [
        (lambda s, a: huber(s, a, threshold="a"), "the threshold is s <= a^2: a is in the units of |e| = sqrt(s), s is a squared norm"),
        (lambda s, a: huber(s, a, beyond="linear"), "beyond the threshold rho = 2 a |e| - a^2 with |e| = sqrt(s): 2 a sqrt(s) - a^2, not 2 a s - a^2"),
        (lambda s, a: huber(s, a, beyond="s_as_e"), "s is the squared norm |e|^2: Huber written in |e| (e^2, then 2 a |e| - a^2) is, in s, s then 2 a sqrt(s) - a^2"),
        (lambda s, a: huber(s, a, d_factor=2.0), "d(2 a sqrt(s))/ds = a / sqrt(s): rho' is continuous at the threshold, 1 on both sides"),
        (lambda s, a: huber(s, a, dd_sign=1.0), "beyond the threshold rho'' = -a / (2 s^(3/2)) is negative (rho' = a / sqrt(s) decreases)"),
        (lambda s, a: huber(s, a, half=True), "here rho(s) ~ s near 0 (Ceres' convention, rho'(0) = 1): the textbook Huber 1/2 e^2, a |e| - a^2 / 2 is half of it"),
        (lambda s, a: huber(s, a, strict=True), "the quadratic branch includes the threshold (s <= a^2): rho'' = 0 at s = a^2"),
    ])


def cauchy(s, a, *, scale="a2", front=True, dd_sign=-1.0, dd_power=2):
    b = {"a2": a * a, "a": a, "none": 1.0}[scale]
    t = 1.0 + s / b
    c = b if front else 1.0
    return c * np.log(t), c / (b * t), dd_sign * c / (b * b * t**dd_power)


def cauchy_mistakes(call, ref):
    return _known(call, ref, [
        (lambda s, a: cauchy(s, a, scale="none"), "with the scale a, Cauchy is a^2 log(1 + s / a^2) (log(1 + s) is the unit kernel, a = 1)"),
        (lambda s, a: cauchy(s, a, scale="a"), "a is in the units of |e| = sqrt(s): the kernel is a^2 log(1 + s / a^2), not a log(1 + s / a)"),
        (lambda s, a: cauchy(s, a, front=False), "the factor a^2 in front of log(1 + s / a^2) keeps rho'(0) = 1 (rho ~ s near 0)"),
        (lambda s, a: cauchy(s, a, dd_sign=1.0), "Cauchy's rho'' = -1 / (a^2 (1 + s / a^2)^2) is negative: rho' = 1 / (1 + s / a^2) decreases"),
        (lambda s, a: cauchy(s, a, dd_power=1), "rho'' = d/ds (1 + s / a^2)^-1 = -1 / (a^2 (1 + s / a^2)^2): the square is missing"),
        (lambda s, a: (a * a * np.log1p(s / (a * a)), 1 / (1 + s / (a * a)), -1 / (1 + s / (a * a)) ** 2), "rho'' = -1 / (a^2 (1 + s / a^2)^2): the chain rule's 1 / a^2 is missing"),
    ])


def tukey(s, a, *, front=3.0, threshold="a2", cutoff="all", beyond_rho=True, dd_sign=-1.0, dd_factor=2.0, dd_a2=True,
          d_power=2):
    a2 = a * a
    t = a2 if threshold == "a2" else a
    u = 1.0 - s / a2
    inside = s <= t
    rho = a2 / front * (1 - u**3) if inside or cutoff == "none" else (a2 / front if beyond_rho else 0.0)
    if not inside and cutoff == "all":
        return rho, 0.0, 0.0
    scale = 3.0 / front  # Ceres' a^2 / 6 halves every output
    return rho, scale * u**d_power, scale * dd_sign * dd_factor * u / (a2 if dd_a2 else 1.0)


def tukey_mistakes(call, ref):
    return _known(call, ref, [
        (lambda s, a: tukey(s, a, front=6.0), "that is Ceres' TukeyLoss, a^2 / 6 (1 - (1 - s / a^2)^3) with rho'(0) = 1/2: here rho ~ s near 0, so a^2 / 3"),
        (lambda s, a: tukey(s, a, cutoff="none"), "beyond s = a^2 Tukey's rho is the constant a^2 / 3: rho' = rho'' = 0 there (u = 1 - s / a^2 is not used beyond)"),
        (lambda s, a: tukey(s, a, cutoff="derivatives"), "beyond s = a^2 Tukey's rho is constant: rho' = rho'' = 0 there, not (1 - s / a^2)^2 and -2 (1 - s / a^2) / a^2"),
        (lambda s, a: tukey(s, a, beyond_rho=False), "rho is continuous at s = a^2: a^2 / 3 beyond the threshold, not 0"),
        (lambda s, a: tukey(s, a, threshold="a"), "the threshold is s <= a^2: a is in the units of |e| = sqrt(s), s is a squared norm"),
        (lambda s, a: tukey(s, a, dd_sign=1.0), "rho'' = -2 (1 - s / a^2) / a^2 is negative below the threshold (rho' = (1 - s / a^2)^2 decreases)"),
        (lambda s, a: tukey(s, a, dd_factor=1.0), "rho'' = d/ds (1 - s / a^2)^2 = -2 (1 - s / a^2) / a^2: the factor 2 is missing"),
        (lambda s, a: tukey(s, a, dd_a2=False), "rho'' = -2 (1 - s / a^2) / a^2: the chain rule's 1 / a^2 is missing"),
        (lambda s, a: tukey(s, a, d_power=1), "rho' = (1 - s / a^2)^2, squared"),
    ])


def weighting(call, *, rule="definite", factor=2.0, outer="v", sign=1.0, test_factor=2.0):
    e, Omega, d_rho, dd_rho = call.args
    K, n = e.shape
    out = np.zeros((K, n, n))
    for k in range(K):
        om = Omega if Omega.ndim == 2 else Omega[k]
        v = om @ e[k]
        s = float(e[k] @ v)
        first = d_rho[k] * om
        w = v if outer == "v" else e[k]
        rank_one = np.outer(v, w) if outer == "one_sided" else np.outer(w, w)
        corrected = first + sign * factor * dd_rho[k] * rank_one
        use = {"definite": d_rho[k] + test_factor * dd_rho[k] * s > 1e-6 * d_rho[k],
               "absolute": d_rho[k] + 2 * dd_rho[k] * s > 1e-6,
               "tiny_margin": d_rho[k] + 2 * dd_rho[k] * s > 1e-9 * d_rho[k],
               "psd": d_rho[k] + 2 * dd_rho[k] * s >= -1e-12 * d_rho[k],
               "always": True, "never": False, "ceres": dd_rho[k] > 0}[rule]
        out[k] = corrected if use else first
    return out


def weighting_mistakes(call, ref):
    known = []
    for slip, text in (({"rule": "always"}, "the corrected form is used only where it is positive definite (rho' + 2 rho'' s > 1e-6 rho'), "
                                            "else the first-order rho' Omega: an indefinite weight can make H indefinite"),
                       ({"rule": "never"}, "where rho' + 2 rho'' s > 1e-6 rho' the corrected form rho' Omega + 2 rho'' (Omega e)(Omega e)^T is used, "
                                           "not rho' Omega (nor only where rho'' > 0, Ceres' choice)"),
                       ({"factor": 1.0}, "the rank-one term is 2 rho'' (Omega e)(Omega e)^T: the factor 2 is missing"),
                       ({"outer": "e"}, "the rank-one term is 2 rho'' (Omega e)(Omega e)^T, not 2 rho'' e e^T"),
                       ({"outer": "one_sided"}, "the rank-one term is 2 rho'' (Omega e)(Omega e)^T, symmetric, not (Omega e) e^T"),
                       ({"sign": -1.0}, "the corrected form adds 2 rho'' (Omega e)(Omega e)^T (rho'' < 0 lowers the curvature)"),
                       ({"test_factor": 1.0}, "the corrected form is positive definite where rho' + 2 rho'' s > 0 (with the factor 2), "
                                              "s = e^T Omega e"),
                       ({"rule": "absolute"}, "the margin is relative: rho' + 2 rho'' s > 1e-6 rho' (an absolute 1e-6 "
                                              "takes the first-order form where rho' < 1 puts it between the two)"),
                       ({"rule": "tiny_margin"}, "the margin is 1e-6 rho', not a rounding-sized one: just above 0, the "
                                                 "corrected form is nearly singular along Omega e; first-order there"),
                       ({"rule": "psd"}, "at rho' + 2 rho'' s = 0 (Huber beyond its threshold) the corrected form is singular: "
                                         "the test is rho' + 2 rho'' s > 1e-6 rho', strict with a margin, first-order there")):
        value = weighting(call, **slip)
        if not np.allclose(value, ref["value"], rtol=1e-9, atol=1e-12):
            known.append((value, text))
    return {"value": known}


MISTAKES = {
    **{f"{HUBER}: {title}": huber_mistakes for title in ("rho(s)", "rho'(s)", "rho''(s)")},
    **{f"{CAUCHY}: {title}": cauchy_mistakes for title in ("rho(s)", "rho'(s)", "rho''(s)")},
    **{f"{TUKEY}: {title}": tukey_mistakes for title in ("rho(s)", "rho'(s)", "rho''(s)")},
    f"{WEIGHT}: corrected form where it is positive definite": weighting_mistakes,
    f"{WEIGHT}: first-order form where the corrected one is not positive definite": weighting_mistakes,
    f"{WEIGHT}: a mix of both, one Omega for all residuals": weighting_mistakes,
}
