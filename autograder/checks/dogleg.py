"""Checks of Powell's dogleg (``dogleg``: Cauchy point, dogleg step, radius update) and the
dogleg minimizer with the student's own pieces.

``dogleg_step`` is graded in each of its three cases, with radii chosen around the
lengths of the Cauchy point ``a = -alpha g`` and of the Gauss-Newton step, and on a
case where the Cauchy point is almost on the boundary and the Gauss-Newton step is
1e8 times longer: there the naive root of the quadratic for beta loses most of its
digits. The case comes back from the child as character codes (see
``autograder.tasks.dogleg.dogleg_step``). The end-to-end checks run ``course.solver.minimize``
with ``"dogleg"`` on the curve and on a pose graph with every piece from the student
(model, normal equations or pose-graph pieces, and the dogleg), compare where it ends with
the reference run, and check from the trace that no rejected step was followed by a
factorization before the retry.

Public inputs: two seeded quadratic models, fixed radii, the curve's default data and
``manhattan(100, seed=0)``; at the edges, a radius exactly |h_gn| and one exactly |a| (lengths
exact in any order of summation: integer vectors of integer length, alpha a power of two);
hidden inputs: other models and sizes, radii elsewhere in the same case, another noise seed
and another Manhattan graph, and the ties scaled by powers of two with the axes permuted.
"""

import numpy as np

from autograder.checks import Call, Verdict
from autograder.checks.common import check
from autograder.checks.edges import Edge
from autograder.feedback import call_fields, compare, fmt, values

MODULES = ("dogleg",)
#: the other exercise files the end-to-end runs use (given solved in an assignment: course_config)
USES = ("curve_model", "gauss_newton", "pose_graph_edge", "pose_graph_assembly", "sparse_solve", "pose_graph_fast")

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


def _models(seed=None):
    if seed is None:
        return [_quadratic(5, 1, [1.0, 4.0, 0.3, 2.0, 1.0]), _quadratic(3, 2, [3.0, 0.2, 1.0])]
    rng = np.random.default_rng([seed, 501])
    return [_quadratic(n, int(rng.integers(1 << 30)), np.exp(rng.uniform(np.log(0.2), np.log(4.0), n)))
            for n in (int(rng.integers(4, 8)), int(rng.integers(2, 4)))]


def _lengths(model):
    g, _, h_gn, alpha = model
    return alpha * float(np.linalg.norm(g)), float(np.linalg.norm(h_gn))


# ---------------------------------------------------------------- Cauchy point


def _cauchy_calls(seed=None):
    return [Call("dogleg:cauchy_point", (g, H @ g), returns=("h_cp", "alpha"),
                 where=f"for g of size {len(g)} (H g given)") for g, H, _, _ in _models(seed)]


# ---------------------------------------------------------------- dogleg step


def _step_call(g, h_gn, alpha, radius, where):
    return Call("@autograder.tasks.dogleg:dogleg_step", (g, h_gn, alpha, float(radius)), returns="dict",
                label="dogleg.dogleg_step", where=where)


#: where the radius sits in each case: (low, high) factors, and the public ones
RADIUS_FACTORS = {"gauss-newton": ((1.2, 10.0), (1.5, 10.0)), "steepest-descent": ((0.3, 0.95), (0.5, 0.9)),
                  "dogleg": ((0.1, 0.9), (0.3, 0.8))}


def _tie_call(case, seed=None):
    """A radius exactly |h_gn| (``case`` "gauss-newton") or exactly |a| = alpha |g| ("steepest-descent"):
    g = -(1, 2, 2) (|g| = 3), alpha = 1/2 (|a| = 3/2) and h_gn = (2, 3, 6) / 4 or / 2 (|h_gn| = 7/4 or 7/2),
    every length exact whatever the order of the sums; -g^T h_gn >= alpha |g|^2, so an H > 0 with
    H h_gn = -g and alpha = |g|^2 / g^T H g exists. Hidden: lengths scaled by powers of two, axes permuted."""
    g, alpha = -np.array([1.0, 2.0, 2.0]), 0.5
    h_gn = np.array([2.0, 3.0, 6.0]) / (4.0 if case == "gauss-newton" else 2.0)
    if seed is not None:
        rng = np.random.default_rng([seed, 507, CASES.index(case)])
        order, p, q = rng.permutation(3), int(rng.integers(-3, 4)), int(rng.integers(-3, 4))
        g, h_gn, alpha = g[order] * 2.0**p, h_gn[order] * 2.0**q, alpha * 2.0 ** (q - p)
    a_norm, gn_norm = alpha * float(np.linalg.norm(g)), float(np.linalg.norm(h_gn))
    radius, how = (gn_norm, "radius = |h_gn| exactly") if case == "gauss-newton" else (a_norm, "radius = |a| exactly")
    where = (f"for g = {fmt(g)}, h_gn = {fmt(h_gn)}, alpha = {alpha:g}: |a| = alpha |g| = {a_norm:g}, "
             f"|h_gn| = {gn_norm:g}, radius = {radius:g} ({how})")
    return _step_call(g, h_gn, alpha, radius, where)


def _case_calls(case):
    def build(seed=None):
        (low, high), public = RADIUS_FACTORS[case]
        rng = None if seed is None else np.random.default_rng([seed, 502, CASES.index(case)])
        calls = []
        for model in _models(seed):
            g, _, h_gn, alpha = model
            a_norm, gn_norm = _lengths(model)
            factors = public if rng is None else tuple(np.round(np.sort(rng.uniform(low, high, 2)), 3))
            for t in factors:
                if case == "gauss-newton":
                    radius, how = t * gn_norm, f"radius = {t:g} |h_gn|"
                elif case == "steepest-descent":
                    radius, how = t * a_norm, f"radius = {t:g} |a|"
                else:
                    radius, how = a_norm + t * (gn_norm - a_norm), f"radius {100 * t:g}% of the way from |a| to |h_gn|"
                where = (f"for g of size {len(g)}, |a| = alpha |g| = {a_norm:.6g}, |h_gn| = {gn_norm:.6g}, "
                         f"radius = {radius:.6g} ({how})")
                calls.append(_step_call(g, h_gn, alpha, radius, where))
        if case != "dogleg":  # the tie that still belongs to this case
            calls.append(_tie_call(case, seed))
        return calls

    return build


def _stable_calls(seed=None):
    # H = [[1, x], [x, 1e4 x]] with x = 1e4 - 1e-4 gives alpha = 1 and h_gn = (-1e8, 1e4): the Cauchy
    # point (-1, 0) sits 2^-40 inside the boundary and c = a^T (h_gn - a) ~ 1e8 dominates d. Hidden
    # inputs scale every length by a power of two and may swap the axes, which keeps all of it exact.
    g, h_gn, alpha, radius = np.array([1.0, 0.0]), np.array([-1e8, 1e4]), 1.0, 1.0 + 2.0**-40
    scale, swap = 1.0, False
    if seed is not None:
        rng = np.random.default_rng([seed, 503])
        scale, swap = 2.0 ** int(rng.integers(-3, 4)), bool(rng.integers(2))
    order = [1, 0] if swap else [0, 1]
    g, h_gn = g[order], scale * h_gn[order]
    alpha, radius = scale * alpha, scale * radius
    where = (f"for g = {fmt(g)}, h_gn = {fmt(h_gn)}, alpha = {alpha:g}, radius = {scale:g} (1 + 2^-40) (the Cauchy "
             "point is almost on the boundary and the Gauss-Newton step is 1e8 times longer)")
    return [_step_call(g, h_gn, alpha, radius, where)]


# ---------------------------------------------------------------- judging the step


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
    from autograder.tasks.common import decode_text

    triples, failure = call_fields(ctx)
    for index, (call, got, want) in enumerate(triples):
        expected = int(want["case_code"])
        code, text = int(got["case_code"]), decode_text(got["case_text"])
        if code != expected and code >= 0:
            return Verdict(0.0, f"the case is {text!r}, expected {CASES[expected]!r} {call.where}: "
                                f"{_case_rule(call, expected)}")
        known = ctx.known(index)
        h_known, p_known = known.get("h", ()), known.get("predicted", ())
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
    """Public: ``cases`` (radius, rho, |step|); hidden: radius and |step| scaled alike, rho
    moved within its branch (the boundary values 0.25 and 0.75 and those near them stay)."""

    def build(seed=None):
        rng = None if seed is None else np.random.default_rng([seed, 504, int(1000 * cases[0][1])])
        calls = []
        for radius, rho, step in cases:
            if rng is not None:
                scale = float(np.round(rng.uniform(0.5, 2.0), 3))
                radius, step = radius * scale, step * scale
                if abs(rho - 0.25) > 0.02 and abs(rho - 0.75) > 0.02:
                    rho = float(np.round(rho + rng.uniform(-0.01, 0.01), 4))
            calls.append(Call("dogleg:update_radius", (radius, rho, step),
                              where=f"for radius = {radius:g}, rho = {rho:g}, |step| = {step:g}"))
        return calls

    return build


def _radius_judge(hint):
    return values(("value",), 1e-12, 0.0, hint, labels={"value": "the new radius"}, scalar=True)


# ---------------------------------------------------------------- end to end


def _e2e_graph(seed=None):
    from course.problems.posegraph.dataset import manhattan

    g = manhattan(100, seed=0 if seed is None else int(np.random.default_rng([seed, 505]).integers(1, 1 << 30)))
    return {"poses": g.poses, "edges_i": g.edges_i, "edges_j": g.edges_j, "measurements": g.measurements,
            "information": g.information, "fixed": g.fixed, "name": g.name}


def _pieces(on) -> str:
    return ("your curve_model, gauss_newton and dogleg pieces" if on == "curve"
            else "your pose-graph pieces and dogleg pieces")


#: which modules the pose-graph run uses, for the feedback of a run that ends elsewhere
_POSE_GRAPH_MODULES = ("pose_graph_fast when it is written, else pose_graph_edge and pose_graph_assembly; "
                       "sparse_solve; dogleg")


def _end_calls(on):
    def build(seed=None):
        label = f"minimize({'curve problem' if on == 'curve' else 'pose graph'}, 'dogleg') with {_pieces(on)}"
        if on == "curve":
            noise = 0 if seed is None else int(np.random.default_rng([seed, 506]).integers(1, 1 << 30))
            return [Call("@autograder.tasks.dogleg:minimize_curve_run", ("dogleg",), {"seed": noise},
                         returns="dict", label=label)]
        return [Call("@autograder.tasks.pose_graph:minimize_pose_graph", (_e2e_graph(seed), "dogleg"),
                     {"vectorized": None, "cost_tolerance": 1e-9}, returns="dict", label=label)]

    return build


def _judge_end(on):
    def judge(ctx):
        from autograder.tasks.common import stop_reason
        from course.solver import StopReason

        triples, failure = call_fields(ctx)
        if failure:
            return failure
        call, got, want = triples[0]
        if got["refactorized_after_rejection"] > 0:
            return Verdict(0.0, f"{int(got['refactorized_after_rejection'])} rejected step(s) were followed by a "
                                "factorization before the retry: a rejection must only shrink the radius and reuse "
                                "h_gn and the Cauchy point")
        chi2 = compare(got["final_chi2"], want["final_chi2"], "final chi2", 1e-6, 0.0)
        params = compare(got["params"], want["params"], "params", 1e-6, 1e-9) if on == "curve" else None
        summary = (f"{int(got['iterations'])} step attempts, {int(got['rejected'])} rejected, "
                   f"{int(got['factorizations'])} factorizations")
        reason, reference_reason = stop_reason(got["stop"]), stop_reason(want["stop"])
        # a run that only reaches the minimum by exhausting its iterations has not converged
        spun = reason == StopReason.MAX_ITERATIONS and reference_reason != StopReason.MAX_ITERATIONS
        if chi2 is None and params is None and not spun:
            return Verdict(1.0, f"ok (chi2 {float(got['final_chi2']):.6g}; {summary}, none after a rejection)")
        what = "the curve from (0, 0, 0)" if on == "curve" else f"the pose graph {call.args[0]['name']}"
        text = (f"dogleg on {what} ends at chi2 {fmt(got['final_chi2'])} ({summary}; stopped by {reason}); the "
                f"reference ends at {fmt(want['final_chi2'])} (rtol 1e-6)")
        if chi2 is None and params:
            text += f"; {params}"
        elif chi2 is None and params is None:
            text += (f", reached, but the run never converged (the reference stops after "
                     f"{int(want['iterations'])} step attempts, by {reference_reason})")
        if reason == StopReason.MAX_ITERATIONS and got["trailing_rejections"] >= 10:
            text += (f": the last {int(got['trailing_rejections'])} steps were all rejected, so the radius never "
                     "became small enough: a poor step (rho < 0.25) must halve it (update_radius)")
        elif reason == StopReason.STEP_TOLERANCE:
            text += ": the radius shrank to nothing before the minimum: check update_radius and the predicted decrease"
        modules = "" if on == "curve" else f" ({_POSE_GRAPH_MODULES})"
        text += (f". This run uses {_pieces(on)}{modules}: a unit check of theirs that fails points "
                 "at the part that differs; if their unit checks pass, look for state kept between calls or arrays "
                 "modified in place")
        return Verdict(0.0, text)

    return judge


# ---------------------------------------------------------------- registry


CHECKS = [
    check(CAUCHY, "h_cp and alpha", 2, _cauchy_calls,
           values(("alpha", "h_cp"), 1e-9, 1e-12, {"alpha": "alpha = |g|^2 / (g^T H g)", "h_cp": "h_cp = -alpha g"},
                  scalar=True)),
    check(STEP, "Gauss-Newton case (|h_gn| <= radius)", 1, _case_calls("gauss-newton"), _judge_step),
    check(STEP, "steepest-descent case (|a| >= radius)", 2, _case_calls("steepest-descent"), _judge_step),
    check(STEP, "dogleg case (|a| < radius < |h_gn|)", 3, _case_calls("dogleg"), _judge_step),
    # the radius 1 + 2^-40 is chosen to make the unstable beta cancel: moving it changes the question
    check(STEP, "stable beta (Cauchy point almost on the boundary)", 1, _stable_calls,
           lambda ctx: _judge_step(ctx, predicted=False), exact_inputs=True),
    # rho exactly at 0.25 and 0.75 (exact in binary): which side of the threshold is the contract's
    check(RADIUS, "good step (rho > 0.75)", 1,
           _radius_calls([(1.0, 0.9, 0.5), (2.0, 0.9, 0.5), (0.4, 0.99, 0.4)]),
           _radius_judge("rho > 0.75: max(radius, 3 |step|)"), exact_inputs=True),
    check(RADIUS, "poor step (rho < 0.25)", 1,
           _radius_calls([(1.0, 0.1, 0.5), (3.0, -2.0, 3.0), (1.0, 0.2499, 1.0)]),
           _radius_judge("rho < 0.25: radius / 2"), exact_inputs=True),
    check(RADIUS, "in between (0.25 <= rho <= 0.75)", 1,
           _radius_calls([(1.0, 0.5, 0.5), (2.0, 0.25, 2.0), (2.0, 0.75, 2.0)]),
           _radius_judge("0.25 <= rho <= 0.75: the radius stays"), exact_inputs=True),
    check(END, "curve", 2, _end_calls("curve"), _judge_end("curve")),
    check(END, "pose graph", 2, _end_calls("pose graph"), _judge_end("pose graph")),
]


STEP_TASK = "@autograder.tasks.dogleg:dogleg_step"


def _step_lengths(call):
    """(|a|, radius, |h_gn|) of a dogleg_step call."""
    g, h_gn, alpha, radius = call.args
    return alpha * float(np.linalg.norm(g)), radius, float(np.linalg.norm(h_gn))


EDGES = (
    Edge("a Gauss-Newton step inside the region (|h_gn| < radius)", STEP_TASK,
         lambda call: _step_lengths(call)[2] < _step_lengths(call)[1]),
    Edge("|h_gn| exactly equal to the radius: the Gauss-Newton step", STEP_TASK,
         lambda call: _step_lengths(call)[2] == _step_lengths(call)[1]),
    Edge("a Cauchy point beyond the radius (|a| > radius): steepest descent to the boundary", STEP_TASK,
         lambda call: _step_lengths(call)[0] > _step_lengths(call)[1] < _step_lengths(call)[2]),
    Edge("|a| exactly equal to the radius (|h_gn| beyond it): steepest descent, not dogleg", STEP_TASK,
         lambda call: _step_lengths(call)[0] == _step_lengths(call)[1] < _step_lengths(call)[2]),
    Edge("rho exactly 0.25: the radius stays", "dogleg:update_radius", lambda call: call.args[1] == 0.25),
    Edge("rho exactly 0.75: the radius stays", "dogleg:update_radius", lambda call: call.args[1] == 0.75),
)
