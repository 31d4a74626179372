"""Chapter 3 checks: Powell's dogleg (Cauchy point, dogleg step, radius update) and the
dogleg minimizer with the student's pieces.

``dogleg_step`` is graded in each of its three cases, with radii chosen around the
lengths of the Cauchy point ``a = -alpha g`` and of the Gauss-Newton step, and on a
case where the Cauchy point is almost on the boundary and the Gauss-Newton step is
1e8 times longer: there the naive root of the quadratic for beta loses most of its
digits. The case comes back from the child as character codes (see
``autograder.tasks.dogleg_step``). The end-to-end checks run
``course.solvers.dogleg.minimize_dogleg`` (framework) with the student's pieces on the
reference curve model and on a pose graph, compare where it ends with the reference
Gauss-Newton minimum, and check from the trace that no rejected step was followed by a
factorization before the retry.
"""

from functools import lru_cache

import numpy as np

from autograder.checks import Call, Check, Verdict
from autograder.compare import call_fields, compare, fmt, values

MODULES = ("dogleg",)

CAUCHY = "dogleg.cauchy_point"
STEP = "dogleg.dogleg_step"
RADIUS = "dogleg.update_radius"
END = "dogleg.end_to_end"

CASES = ("gauss-newton", "steepest-descent", "dogleg")
CASE_NAMES = ("GAUSS_NEWTON", "STEEPEST_DESCENT", "DOGLEG")

# ---------------------------------------------------------------- inputs


def _quadratic(n, seed, scales):
    """g, H, the Gauss-Newton step and the Cauchy alpha of a random convex model."""
    rng = np.random.default_rng(seed)
    J = rng.normal(size=(3 * n, n)) * np.asarray(scales, dtype=float)
    H = J.T @ J + 0.05 * np.eye(n)
    g = rng.normal(size=n) * 2.0
    h_gn = np.linalg.solve(H, -g)
    alpha = float(g @ g) / float(g @ H @ g)
    return g, H, h_gn, alpha


@lru_cache(maxsize=None)
def _models():
    return [_quadratic(5, 1, [1.0, 4.0, 0.3, 2.0, 1.0]), _quadratic(3, 2, [3.0, 0.2, 1.0])]


def _lengths(model):
    g, _, h_gn, alpha = model
    return alpha * float(np.linalg.norm(g)), float(np.linalg.norm(h_gn))


# ---------------------------------------------------------------- Cauchy point


def _cauchy_calls():
    return [Call("dogleg:cauchy_point", (g, H @ g), returns=("h_cp", "alpha"),
                 where=f"for g of size {len(g)} (H g given)") for g, H, _, _ in _models()]


def _cauchy_mistakes(call, ref):
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


# ---------------------------------------------------------------- dogleg step


def _step_call(g, h_gn, alpha, radius, where):
    return Call("@autograder.tasks:dogleg_step", (g, h_gn, alpha, float(radius)), returns="dict",
                label="dogleg.dogleg_step", where=where)


def _case_calls(case):
    def build():
        calls = []
        for g, H, h_gn, alpha in _models():
            a_norm, gn_norm = _lengths((g, H, h_gn, alpha))
            if case == "gauss-newton":
                radii = ((1.5 * gn_norm, "radius = 1.5 |h_gn|"), (10 * gn_norm, "radius = 10 |h_gn|"))
            elif case == "steepest-descent":
                radii = ((0.5 * a_norm, "radius = |a| / 2"), (0.9 * a_norm, "radius = 0.9 |a|"))
            else:
                radii = ((a_norm + t * (gn_norm - a_norm), f"radius {int(100 * t)}% of the way from |a| to |h_gn|")
                         for t in (0.3, 0.8))
            for radius, how in radii:
                where = (f"for g of size {len(g)}, |a| = alpha |g| = {a_norm:.6g}, |h_gn| = {gn_norm:.6g}, "
                         f"radius = {radius:.6g} ({how})")
                calls.append(_step_call(g, h_gn, alpha, radius, where))
        return calls

    return build


def _stable_calls():
    # H = [[1, x], [x, 1e4 x]] with x = 1e4 - 1e-4 gives alpha = 1 and h_gn = (-1e8, 1e4): the Cauchy
    # point (-1, 0) sits 2^-40 inside the boundary and c = a^T (h_gn - a) ~ 1e8 dominates d.
    g, h_gn, radius = np.array([1.0, 0.0]), np.array([-1e8, 1e4]), 1.0 + 2.0**-40
    where = ("for g = (1, 0), h_gn = (-1e8, 1e4), alpha = 1, radius = 1 + 2^-40 (the Cauchy point is almost on "
             "the boundary and the Gauss-Newton step is 1e8 times longer)")
    return [_step_call(g, h_gn, 1.0, radius, where)]


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


def _step_mistakes(call, ref):
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
    return h_known, p_known


def _case_rule(call, expected):
    g, h_gn, alpha, radius = call.args
    a_norm, gn_norm = alpha * float(np.linalg.norm(g)), float(np.linalg.norm(h_gn))
    short = [f"{x:.6g}" for x in (a_norm, radius, gn_norm)]
    digits = ".17g" if len(set(short)) < 3 else ".6g"  # show the digits that tell them apart
    a, r, gn = (format(x, digits) for x in (a_norm, radius, gn_norm))
    return {0: f"|h_gn| = {gn} <= radius = {r}, so the case is Gauss-Newton",
            1: f"|h_gn| = {gn} > radius = {r} and |a| = {a} >= radius, so the case is steepest descent",
            2: f"|a| = {a} < radius = {r} < |h_gn| = {gn}, so the case is dogleg"}[expected]


def _judge_step(ctx, predicted=True):
    """The case, h and (unless ``predicted`` is False) the predicted decrease of every call."""
    from autograder.tasks import decode_text

    triples, failure = call_fields(ctx)
    for call, got, want in triples:
        expected = int(want["case_code"])
        code, text = int(got["case_code"]), decode_text(got["case_text"])
        if code != expected and code >= 0:
            return Verdict(0.0, f"the case is {text!r}, expected {CASES[expected]!r} {call.where}: "
                                f"{_case_rule(call, expected)}")
        h_known, p_known = _step_mistakes(call, want)
        scale = float(np.linalg.norm(want["h"]))
        text_h = compare(got["h"], want["h"], "h[{}]", 1e-9, 0.0 if expected == 2 else 1e-14 * scale, call.where,
                         h_known, _case_rule(call, expected))
        if text_h:
            return Verdict(0.0, text_h)
        text_p = predicted and compare(got["predicted"], want["predicted"], "predicted decrease", 1e-9, 0.0,
                                       call.where, p_known, "the decrease L(0) - L(h) of the quadratic model for "
                                       "this case", scalar=True)
        if text_p:
            return Verdict(0.0, text_p)
        if code < 0:
            return Verdict(0.0, f"the step is right but the case is {text!r} {call.where}: "
                                f"return the module's constant {CASE_NAMES[expected]} = {CASES[expected]!r}")
    return failure or Verdict(1.0, "ok")


# ---------------------------------------------------------------- radius update


def _radius_calls(cases):
    def build():
        return [Call("dogleg:update_radius", (radius, rho, step), where=f"for radius = {radius:g}, rho = {rho:g}, "
                                                                        f"|step| = {step:g}")
                for radius, rho, step in cases]

    return build


def _radius_mistakes(call, ref):
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


def _radius_judge(hint):
    return values(("value",), 1e-12, 0.0, _radius_mistakes, hint, labels={"value": "the new radius"}, scalar=True)


# ---------------------------------------------------------------- end to end


@lru_cache(maxsize=None)
def _e2e_graph():
    from course.datasets import manhattan

    g = manhattan(100, seed=0)
    return {"poses": g.poses, "edges_i": g.edges_i, "edges_j": g.edges_j, "measurements": g.measurements,
            "information": g.information, "fixed": g.fixed, "name": g.name}


def _end_calls(on):
    def build():
        if on == "curve":
            run = ("@autograder.tasks:minimize_curve_run", (), {"problem_impl": "solutions"})
            label = "minimize(curve problem, {!r}) on the reference model"
        else:
            run = ("@autograder.tasks:minimize_pose_graph", (_e2e_graph(),),
                   {"problem_impl": "solutions", "vectorized": None})
            label = "minimize(pose graph, {!r}) on the reference pose-graph pieces"
        target, args, kwargs = run
        return [Call(target, ("dogleg",) if on == "curve" else args + ("dogleg",), kwargs, returns="dict",
                     label=label.format("dogleg") + " with your dogleg pieces"),
                Call(target, ("gauss-newton",) if on == "curve" else args + ("gauss-newton",), kwargs,
                     returns="dict", label=label.format("gauss-newton") + " (the minimum to reach)")]

    return build


def _judge_end(on):
    from autograder.tasks import STOP_REASONS

    def judge(ctx):
        triples, failure = call_fields(ctx)
        if failure:
            return failure
        (_, got, want), (_, _, gn) = triples  # gn: the minimum, computed here with the reference
        if got["refactorized_after_rejection"] > 0:
            return Verdict(0.0, f"{int(got['refactorized_after_rejection'])} rejected step(s) were followed by a "
                                "factorization before the retry: a rejection must only shrink the radius and reuse "
                                "h_gn and the Cauchy point")
        chi2 = compare(got["final_chi2"], gn["final_chi2"], "final chi2", 1e-6, 0.0)
        params = compare(got["params"], gn["params"], "params", 1e-6, 1e-9) if on == "curve" else None
        summary = (f"{int(got['iterations'])} step attempts, {int(got['rejected'])} rejected, "
                   f"{int(got['factorizations'])} factorizations")
        stop = int(got["stop"])
        reason = STOP_REASONS[stop] if 0 <= stop < len(STOP_REASONS) else "?"
        # a run that only reaches the minimum by exhausting its iterations has not converged
        spun = reason == "max_iterations" and int(want["stop"]) != STOP_REASONS.index("max_iterations")
        if chi2 is None and params is None and not spun:
            return Verdict(1.0, f"ok (chi2 {float(got['final_chi2']):.6g}; {summary}, none after a rejection)")
        what = "the curve from (0, 0, 0)" if on == "curve" else f"the pose graph {_e2e_graph()['name']}"
        text = (f"dogleg on {what} ends at chi2 {fmt(got['final_chi2'])} ({summary}; stopped by {reason}); the "
                f"Gauss-Newton minimum is {fmt(gn['final_chi2'])} (rtol 1e-6)")
        if chi2 is None and params:
            text += f"; {params}"
        elif chi2 is None and params is None:
            text += (f", reached, but the run never converged (the reference stops after "
                     f"{int(want['iterations'])} step attempts, by {STOP_REASONS[int(want['stop'])]})")
        if reason == "max_iterations" and got["trailing_rejections"] >= 10:
            text += (f": the last {int(got['trailing_rejections'])} steps were all rejected, so the radius never "
                     "became small enough: a poor step (rho < 0.25) must halve it (update_radius)")
        elif reason == "step_tolerance":
            text += ": the radius shrank to nothing before the minimum: check update_radius and the predicted decrease"
        text += (". This run uses your cauchy_point, dogleg_step and update_radius on reference problem pieces; "
                 "their unit checks say which part differs")
        return Verdict(0.0, text)

    return judge


# ---------------------------------------------------------------- registry


def _check(exercise, title, points, calls, judge, **kwargs):
    return Check(f"{exercise}: {title}", exercise, points, calls, judge, **kwargs)


CHECKS = [
    _check(CAUCHY, "h_cp and alpha", 2, _cauchy_calls,
           values(("alpha", "h_cp"), 1e-9, 1e-12, _cauchy_mistakes,
                  {"alpha": "alpha = |g|^2 / (g^T H g)", "h_cp": "h_cp = -alpha g"}, scalar=True)),
    _check(STEP, "Gauss-Newton case (|h_gn| <= radius)", 1, _case_calls("gauss-newton"), _judge_step),
    _check(STEP, "steepest-descent case (|a| >= radius)", 2, _case_calls("steepest-descent"), _judge_step),
    _check(STEP, "dogleg case (|a| < radius < |h_gn|)", 3, _case_calls("dogleg"), _judge_step),
    _check(STEP, "stable beta (Cauchy point almost on the boundary)", 1, _stable_calls,
           lambda ctx: _judge_step(ctx, predicted=False)),
    _check(RADIUS, "good step (rho > 0.75)", 1,
           _radius_calls([(1.0, 0.9, 0.5), (2.0, 0.9, 0.5), (0.4, 0.99, 0.4)]),
           _radius_judge("rho > 0.75: max(radius, 3 |step|)")),
    _check(RADIUS, "poor step (rho < 0.25)", 1,
           _radius_calls([(1.0, 0.1, 0.5), (3.0, -2.0, 3.0), (1.0, 0.2499, 1.0)]),
           _radius_judge("rho < 0.25: radius / 2")),
    _check(RADIUS, "in between (0.25 <= rho <= 0.75)", 1,
           _radius_calls([(1.0, 0.5, 0.5), (2.0, 0.25, 2.0), (2.0, 0.75, 2.0)]),
           _radius_judge("0.25 <= rho <= 0.75: the radius stays")),
    _check(END, "curve", 2, _end_calls("curve"), _judge_end("curve")),
    _check(END, "pose graph", 2, _end_calls("pose graph"), _judge_end("pose graph")),
]
