# RELEASE: omit
"""Known mistakes in ``dogleg`` (see ``autograder.mistakes``)."""

import numpy as np


def cauchy_mistakes(call, ref):
    g, Hg = call.args
    alpha = float(ref["alpha"])
    inverse = float(g @ Hg) / float(g @ g)
    return {
        "alpha": [(np.array(inverse), "alpha = |g|^2 / (g^T H g), not its inverse"),
                  (np.array(float(np.linalg.norm(g)) / float(g @ Hg)), "alpha = |g|^2 / (g^T H g): square |g|")],
        "h_cp": [(alpha * g, "h_cp has the wrong sign: the Cauchy point goes downhill, h_cp = -alpha g"),
                 (-inverse * g, "alpha = |g|^2 / (g^T H g), not its inverse"),
                 (-g, "h_cp = -alpha g: scale the gradient by alpha")],
    }


def _beta(g, h_gn, alpha, radius, root="stable"):
    a = -alpha * g
    diff = h_gn - a
    c, dd = float(a @ diff), float(diff @ diff)
    k = radius**2 - float(a @ a)
    d = np.sqrt(c * c + dd * k)
    if root == "other":
        return (-c - d) / dd
    if root == "other_cancelled":  # the same root in the form of the stable one, (radius^2 - |a|^2) / (c - d)
        return k / (c - d)
    if root == "naive":
        return (d - c) / dd
    return (d - c) / dd if c <= 0 else k / (d + c)


def step_mistakes(call, ref):
    g, h_gn, alpha, radius = call.args
    a = -alpha * g
    g_norm = float(np.linalg.norm(g))
    a_norm = alpha * g_norm
    gn_dec = -float(g @ h_gn) / 2.0
    sd_dec = radius * (2.0 * a_norm - radius) / (2.0 * alpha)
    case = int(ref["case_code"])
    h_known = [(-ref["h"], "h has the opposite sign: it goes downhill, g^T h < 0")]
    pred = float(ref["predicted"])
    p_known = [(np.array(2 * pred), "the predicted decrease is twice too large: it is L(0) - L(h) in "
                                    "F = chi2 / 2 units (g = b = J^T W r)"),
               (np.array(-pred), "the predicted decrease has the wrong sign: L(0) - L(h) > 0")]
    if case == 0:
        p_known.append((np.array(-float(g @ h_gn)), "L(0) - L(h_gn) = -g^T h_gn / 2 (F = chi2 / 2 units)"))
    if case == 1:
        h_known += [(a, f"the Cauchy point a = -alpha g is outside the trust region (|a| = {a_norm:.6g} >= radius): "
                        "clip steepest descent to the boundary, h = -(radius / |g|) g"),
                    (-radius * g, "normalize g: h = -(radius / |g|) g"),
                    (radius * h_gn / np.linalg.norm(h_gn), "scaling the Gauss-Newton step to the boundary is not "
                                                           "the dogleg: when |a| >= radius, h = -(radius / |g|) g")]
        p_known += [(np.array(radius * g_norm), "that is only the linear term -g^T h; the model also has "
                                                "h^T H h / 2: L(0) - L(h) = radius (2 |a| - radius) / (2 alpha)"),
                    (np.array(alpha * g_norm**2 / 2.0), "that is the decrease at the Cauchy point, but h is "
                                                        "clipped: radius (2 |a| - radius) / (2 alpha)"),
                    (np.array(gn_dec), "that is the Gauss-Newton case's decrease; steepest descent clipped to the "
                                       "boundary decreases L by radius (2 |a| - radius) / (2 alpha)")]
    if case == 2:
        diff = h_gn - a
        other = a + _beta(g, h_gn, alpha, radius, "other") * diff
        other_cancelled = a + _beta(g, h_gn, alpha, radius, "other_cancelled") * diff
        naive = a + _beta(g, h_gn, alpha, radius, "naive") * diff
        why_other = ("h is the other intersection of the line through a and h_gn with the boundary "
                     "(beta < 0): take the root with beta in [0, 1], between a and h_gn")
        h_known += [(other, why_other), (other_cancelled, why_other),
                    (h_gn, f"this is the Gauss-Newton step, but |h_gn| = {np.linalg.norm(h_gn):.6g} > radius: "
                           "the Gauss-Newton step is taken only when |h_gn| <= radius"),
                    (a, "h stops at the Cauchy point a: go on along h_gn - a until |h| = radius"),
                    (-(radius / g_norm) * g, f"this is the steepest-descent case's step, but |a| = {a_norm:.6g} "
                                             "< radius: clip steepest descent only when |a| >= radius"),
                    (radius * h_gn / np.linalg.norm(h_gn), "scaling the Gauss-Newton step to the boundary is not "
                                                           "the dogleg: h = a + beta (h_gn - a)"),
                    (naive, "beta = (d - c) / |h_gn - a|^2 cancels when c > 0 (d ~ c): use the stable form "
                            "beta = (radius^2 - |a|^2) / (d + c) when c > 0")]
        beta = _beta(g, h_gn, alpha, radius)
        p_known += [(np.array(gn_dec), "that is the Gauss-Newton case's formula; in the dogleg case L(0) - L(h) = "
                                       "alpha (1 - beta)^2 |g|^2 / 2 + beta (2 - beta) (-g^T h_gn / 2)"),
                    (np.array(sd_dec), "that is the steepest-descent case's formula; in the dogleg case "
                                       "L(0) - L(h) = alpha (1 - beta)^2 |g|^2 / 2 + beta (2 - beta) (-g^T h_gn / 2)"),
                    (np.array(-float(g @ ref["h"]) / 2.0),
                     "-g^T h / 2 is L(0) - L(h) only for the Gauss-Newton step: "
                     "alpha (1 - beta)^2 |g|^2 / 2 + beta (2 - beta) (-g^T h_gn / 2)"),
                    (np.array(alpha * (1 - beta) ** 2 * g_norm**2 / 2.0 + beta * (2 - beta) * 2 * gn_dec),
                     "use -g^T h_gn / 2 (F = chi2 / 2 units) in the second term")]
    return {"h": h_known, "predicted": p_known}


def radius_mistakes(call, ref):
    radius, rho, step = call.args
    known = []
    if rho > 0.75:
        known += [(radius * 2.0, "a good step (rho > 0.75) sets the radius to max(radius, 3 |step|), not 2 radius"),
                  (3.0 * step, "use max(radius, 3 |step|): a short good step must not shrink the trust region"),
                  (radius * 3.0, "a good step gives max(radius, 3 |step|): three times the step's length, "
                                 "not the radius"),
                  (radius, f"rho = {rho:g} > 0.75 is a good step: the radius becomes max(radius, 3 |step|)")]
    elif rho < 0.25:
        known += [(radius * 2.0, "the radius grew on a poor step (rho < 0.25): halve it, radius / 2"),
                  (max(radius, 3.0 * step), "the radius grew on a poor step (rho < 0.25): halve it, radius / 2"),
                  (radius, f"rho = {rho:g} < 0.25 is a poor step: the radius halves"),
                  (step / 2.0, "halve the radius, not the step length")]
    else:
        known += [(radius / 2.0, f"rho = {rho:g} is not < 0.25: the radius stays (0.25 <= rho <= 0.75)"),
                  (max(radius, 3.0 * step), f"rho = {rho:g} is not > 0.75: the radius stays (0.25 <= rho <= 0.75)")]
    return {"value": [(np.array(v), why) for v, why in known]}


MISTAKES = {
    "dogleg.cauchy_point: h_cp and alpha": cauchy_mistakes,
    "dogleg.dogleg_step: Gauss-Newton case (|h_gn| <= radius)": step_mistakes,
    "dogleg.dogleg_step: steepest-descent case (|a| >= radius)": step_mistakes,
    "dogleg.dogleg_step: dogleg case (|a| < radius < |h_gn|)": step_mistakes,
    "dogleg.dogleg_step: stable beta (Cauchy point almost on the boundary)": step_mistakes,
    "dogleg.update_radius: good step (rho > 0.75)": radius_mistakes,
    "dogleg.update_radius: poor step (rho < 0.25)": radius_mistakes,
    "dogleg.update_radius: in between (0.25 <= rho <= 0.75)": radius_mistakes,
}
