"""Checks of ``pose_graph_edge.edge_error_and_jacobians``: shapes, e_t, e_theta (wrapped),
A, B, and A, B against central differences of the student's own e.

Public inputs: generic edges, raw angle errors beyond +-pi and near its ends, a measured
angle near pi, raw angle errors of exactly pi and -pi (both wrap to -pi; +pi, the same angle
with the same cost and Jacobians, keeps full marks too: ``common.same_angle``), and two seeded
random edges; hidden inputs: fresh edges of each kind (the same angle cases, other poses
and measurements).

The edges (:func:`edges`) are also those of the Ceres cost's checks.
"""

from dataclasses import replace
from functools import cache

import numpy as np

from autograder.checks import Call, Verdict
from autograder.checks.common import check, failed, same_angle, values, wrap
from autograder.checks.edges import Edge
from autograder.feedback import call_fields, compare, fmt

MODULES = ("pose_graph_edge",)
EDGE = "pose_graph_edge.edge_error_and_jacobians"

# ---------------------------------------------------------------- inputs


def pose_text(x):
    return fmt(np.asarray(x, dtype=float))


#: the angle cases of the edges: (lowest, highest raw angle error theta_j - theta_i - theta_ij, note)
#: for the hidden inputs; None: any
_ANGLE_CASES = (
    (-2.0, 2.0, ""),
    (np.pi + 0.1, 4.4, "theta_j - theta_i - theta_ij = {raw:.3g} > pi"),
    (-6.2, -np.pi - 1.0, "theta_j - theta_i - theta_ij = {raw:.3g} < -pi"),
    (None, None, "theta_ij = {z:.3g}, near pi"),
    (-np.pi + 0.01, -np.pi + 0.05, "theta_j - theta_i - theta_ij = {raw:.4g}, just above -pi"),
    (np.pi + 0.01, np.pi + 0.05, "theta_j - theta_i - theta_ij = pi + {above:.3g}, just above pi"),
)


def _fresh_edge(rng, low, high, note):
    """An edge whose raw angle error lies in [low, high] (poses' angles in (-pi, pi))."""
    while True:
        x_i = np.round(np.append(rng.uniform(-5, 5, 2), rng.uniform(-np.pi, np.pi)), 3)
        z = np.round(np.append(rng.uniform(-2.5, 2.5, 2), rng.uniform(-np.pi, np.pi)), 3)
        x_j = np.round(np.append(x_i[:2] + rng.uniform(-3, 3, 2), 0.0), 3)
        if low is None:  # the measured angle near +-pi, any raw error
            z[2] = np.round(rng.choice((-1.0, 1.0)) * rng.uniform(3.0, 3.12), 3)
            x_j[2] = np.round(rng.uniform(-np.pi, np.pi), 3)
        else:
            x_j[2] = np.round(x_i[2] + z[2] + rng.uniform(low, high), 3)
        raw = x_j[2] - x_i[2] - z[2]
        inside = -np.pi + 0.01 < x_j[2] < np.pi - 0.01
        if inside and (low is None or low - 1e-9 <= raw <= high + 1e-9):
            return x_i, x_j, z, note.format(raw=raw, z=z[2], above=raw - np.pi)


def exact_edge(rng, target):
    """An edge whose raw angle error is exactly ``target`` (+-pi) in whatever order the angles are added:
    theta_i and theta_ij are multiples of 1/16 of the same sign whose sum s keeps theta_j = target + s
    between 2 and 4 in magnitude (one binade, so every partial sum is exact); every angle in [-pi, pi)."""
    sign = 1.0 if target > 0 else -1.0
    k = int(rng.integers(2, 17))  # |s| = k / 16
    k_i = int(rng.integers(1, k))  # theta_i and theta_ij both between 0 and s
    theta_i, theta_ij = -sign * k_i / 16.0, -sign * (k - k_i) / 16.0
    x_i = np.append(np.round(rng.uniform(-5, 5, 2), 3), theta_i)
    x_j = np.append(np.round(x_i[:2] + rng.uniform(-3, 3, 2), 3), target - sign * k / 16.0)
    z = np.append(np.round(rng.uniform(-2.5, 2.5, 2), 3), theta_ij)
    return x_i, x_j, z, f"theta_j - theta_i - theta_ij = {'-' if target < 0 else ''}pi exactly"


@cache
def edges(seed=None):
    """(x_i, x_j, z_ij, where): generic edges, raw angle errors outside [-pi, pi) and near its ends,
    a measured angle near pi, and two random edges."""
    if seed is None:
        cases = [
            ((1.2, -0.7, 0.4), (2.5, 0.3, 1.1), (1.1, 0.6, 0.5), ""),
            ((-3.1, 2.0, -2.2), (-1.0, -0.5, 2.9), (-1.5, -2.0, 1.8), "theta_j - theta_i - theta_ij = 3.3 > pi"),
            ((0.5, 0.5, 3.0), (1.5, -0.2, -3.0), (-0.9, 0.4, 0.2), "theta_j - theta_i - theta_ij = -6.2 < -pi"),
            ((2.0, 1.0, -1.0), (2.3, 1.8, 2.1), (0.8, 0.1, 3.05), "theta_ij = 3.05, near pi"),
            ((0.0, 0.0, 1.6), (1.0, 1.0, -1.6), (1.0, -1.0, -0.1),
             "theta_j - theta_i - theta_ij = -3.1, just above -pi"),
            ((0.3, -1.2, -1.5), (-0.4, 0.9, 1.0), (0.7, 1.9, 2.5 - np.pi - 0.02),
             "theta_j - theta_i - theta_ij = pi + 0.02, just above pi"),
        ]
        rng = np.random.default_rng(3)
    else:
        rng = np.random.default_rng([seed, 201])
        cases = [_fresh_edge(rng, *case) for case in _ANGLE_CASES]
    exact = np.random.default_rng(11 if seed is None else [seed, 202])
    cases += [exact_edge(exact, np.pi), exact_edge(exact, -np.pi)]
    for _ in range(2):  # two random edges
        x_i, x_j, z = (np.round(np.append(rng.uniform(-5, 5, 2), rng.uniform(-np.pi, np.pi)), 3) for _ in range(3))
        cases.append((tuple(x_i), tuple(x_j), tuple(z), "random"))
    out = []
    for x_i, x_j, z, note in cases:
        x_i, x_j, z = (np.array(v, dtype=float) for v in (x_i, x_j, z))
        where = (f"for x_i = {pose_text(x_i)}, x_j = {pose_text(x_j)}, z_ij = {pose_text(z)}"
                 + (f" ({note})" if note else ""))
        out.append((x_i, x_j, z, where))
    return out


def edge_call(x_i, x_j, z, where):
    return Call("pose_graph_edge:edge_error_and_jacobians", (x_i, x_j, z), returns=("e", "A", "B"), where=where)


def _edge_calls(seed=None):
    return [edge_call(*edge) for edge in edges(seed)]


# finite differences: the student's own e, perturbed one coordinate at a time
FD_EDGES = (0, 1, 3)  # indices into edges()
FD_STEP = 1e-6
FD_CALLS = 13  # per edge: the edge itself, then +/- a step in each of the 6 coordinates
FD_HINTS = {
    ("A", 0): "d e / d t_i: A's top-left block is -R_ij^T R_i^T",
    ("A", 1): "d e / d t_i: A's top-left block is -R_ij^T R_i^T",
    ("A", 2): "d e / d theta_i = (R_ij^T dR_i^T/dtheta_i (t_j - t_i), -1), dR^T/dtheta = [[-sin, cos], [-cos, -sin]]",
    ("B", 0): "d e / d t_j: B's top-left block is R_ij^T R_i^T",
    ("B", 1): "d e / d t_j: B's top-left block is R_ij^T R_i^T",
    ("B", 2): "d e / d theta_j = (0, 0, 1)",
}


def _fd_calls(seed=None):
    calls = []
    cases = edges(seed)
    for k in FD_EDGES:
        x_i, x_j, z, where = cases[k]
        calls.append(edge_call(x_i, x_j, z, where))
        for p in range(6):
            for sign in (1.0, -1.0):
                xs = [x_i.copy(), x_j.copy()]
                xs[p // 3][p % 3] += sign * FD_STEP
                name = ("x_i", "x_j")[p // 3]
                moved = f"{name}[{p % 3}] {'+' if sign > 0 else '-'} {FD_STEP:g}"
                calls.append(edge_call(xs[0], xs[1], z, f"{where}, {moved}"))
    return calls


# ---------------------------------------------------------------- judges


def _judge_shapes(ctx):
    triples, failure = call_fields(ctx, failed=failed)
    if failure:
        return failure
    for call, got, _ in triples:
        for name, shape in (("e", (3,)), ("A", (3, 3)), ("B", (3, 3))):
            if got[name].shape != shape:
                text = f"{name} has shape {got[name].shape}, expected {shape} {call.where}"
                if got[name].size == int(np.prod(shape)):
                    text += ": same numbers, wrong shape (reshape it)"
                return Verdict(0.0, text)
    return Verdict(1.0, "ok")


def _judge_e(part):
    hint = {"e_t": "e_t = R_ij^T (R_i^T (t_j - t_i) - t_ij)",
            "e_theta": "e_theta = wrap(theta_j - theta_i - theta_ij) in [-pi, pi)"}[part]
    label = {"e_t": "e[{}]", "e_theta": "e[2]"}[part]

    def judge(ctx):
        triples, failure = call_fields(ctx, failed=failed)
        if failure:
            return failure
        for index, (call, got, want) in enumerate(triples):
            if got["e"].shape != (3,):
                return Verdict(0.0, f"e has shape {got['e'].shape}, expected (3,) {call.where}")
            split = {"e_t": (got["e"][:2], want["e"][:2]), "e_theta": (got["e"][2], want["e"][2])}
            actual, expected = split[part]
            if part == "e_theta" and same_angle(actual, expected):
                continue  # at the end of the range: -pi or +pi, the same angle, or either less a rounding
            text = compare(actual, expected, label, 1e-9, 1e-12, call.where, ctx.known(index).get(part, ()), hint)
            if text:
                return Verdict(0.0, text)
        return Verdict(1.0, "ok")

    return judge


def _wrong_e(got_e, want_e, where):
    """Feedback when the student's e differs from the reference's at a point (the angle
    error compared modulo 2 pi: its wrapping is graded by the e_theta check), else None."""
    got_e, want_e = np.asarray(got_e, float), np.asarray(want_e, float)
    text = compare(got_e[:2], want_e[:2], "e[{}]", 1e-9, 1e-12, where)
    if text is None:
        turned = np.asarray(want_e[2] + wrap(got_e[2] - want_e[2]), dtype=float)
        text = compare(turned, want_e[2], "e[2]", 1e-9, 1e-12, where)
    return text


def _judge_fd(ctx):
    """A and B against central differences of the student's own e (angle differences wrapped).

    Consistency earns credit only where e itself is right at the edge (up to the angle's
    multiple of 2 pi): A and B consistent with a wrong e (all zeros, say) earn nothing.
    """
    triples, failure = call_fields(ctx, failed=failed)
    fields = []
    for call, got, _ in triples:
        if got["e"].shape != (3,) or got["A"].shape != (3, 3) or got["B"].shape != (3, 3):
            return Verdict(0.0, f"e, A or B has the wrong shape {call.where} (see the shapes check)")
        fields.append(got)
    if failure:
        return failure
    for block in range(len(FD_EDGES)):
        base = FD_CALLS * block
        call, _, want = triples[base]
        wrong = _wrong_e(fields[base]["e"], want["e"], call.where)
        if wrong:
            return Verdict(0.0, f"{wrong}: your e is wrong (see the e_t/e_theta checks), so consistency with "
                                "it earns nothing")
    good, messages, minus = {}, {}, set()
    for block in range(len(FD_EDGES)):
        base = FD_CALLS * block
        call = ctx.calls[base]
        for p in range(6):
            plus, minus_e = fields[base + 1 + 2 * p]["e"], fields[base + 2 + 2 * p]["e"]
            diff = plus - minus_e
            diff[2] = wrap(diff[2])
            fd = diff / (2 * FD_STEP)
            name, column = ("A", "B")[p // 3], p % 3
            key = (name, column)
            if not good.get(key, True):
                continue
            good[key] = True
            jac = fields[base][name][:, column]
            if not np.all(np.isfinite(fd)):
                good[key] = False
                messages[key] = (f"your e is not finite near {call.where}, so {name}[:, {column}] cannot be "
                                 "checked by finite differences (see the e checks)")
                continue
            atol = 1e-6 * max(1.0, float(np.max(np.abs(fd))))
            if compare(jac, fd, "", 1e-6, atol) is None:
                continue
            good[key] = False
            row = int(np.argmax(np.abs(jac - fd)))
            text = (f"{name}[:, {column}] disagrees with finite differences of your e {call.where}: "
                    f"{name}[{row}, {column}] = {fmt(jac[row])}, central difference {fmt(fd[row])} "
                    f"(rtol=1e-06, atol={atol:.2g})")
            if np.all(np.isfinite(jac)) and compare(jac, -fd, "", 1e-6, atol) is None:
                minus.add(key)
                text += f": {name} is minus the derivative of your e"
            else:
                text += f": {FD_HINTS[key]}"
            messages[key] = text
    score = sum(good.values()) / len(good)
    if score == 1.0:
        return Verdict(1.0, "ok")
    for name in ("A", "B"):
        keys = [k for k in messages if k[0] == name]
        if keys and set(keys) <= minus:
            first = messages[keys[0]].split(f": {name} is minus")[0]
            for k in keys:
                del messages[k]
            messages[(name, -1)] = (f"{first}: {name} is minus the derivative of your e in every column that "
                                    f"differs; {name} must be de/dx_{'i' if name == 'A' else 'j'} of the same e")
    return Verdict(score, "; ".join(messages[k] for k in sorted(messages)))


CHECKS = [
    check(EDGE, "shapes", 1, _edge_calls, _judge_shapes),
    check(EDGE, "e_t (translation error)", 2, _edge_calls, _judge_e("e_t")),
    check(EDGE, "e_theta wrapped to [-pi, pi)", 2, _edge_calls, _judge_e("e_theta")),
    check(EDGE, "A values", 3, _edge_calls,
          values(("A",), 1e-9, 1e-12, "A = [[-R_ij^T R_i^T, R_ij^T dR_i^T/dtheta_i (t_j - t_i)], [0, 0, -1]]")),
    check(EDGE, "B values", 2, _edge_calls, values(("B",), 1e-9, 1e-12, "B = [[R_ij^T R_i^T, 0], [0, 0, 1]]")),
    check(EDGE, "A, B vs finite differences of e", 2, _fd_calls, _judge_fd),
]


def _raw_angle_error(call):
    x_i, x_j, z = call.args[:3]
    return x_j[2] - x_i[2] - z[2]


EDGES = (
    Edge("raw angle error theta_j - theta_i - theta_ij exactly pi: e_theta = -pi",
         "pose_graph_edge:edge_error_and_jacobians", lambda call: _raw_angle_error(call) == np.pi),
    Edge("raw angle error exactly -pi: e_theta = -pi", "pose_graph_edge:edge_error_and_jacobians",
         lambda call: _raw_angle_error(call) == -np.pi),
)

# the edges whose raw angle error is exactly +-pi are written to be exact (angles multiples of 1/16 beside
# pi itself): moving them by an ulp would change the question (autograder.rounding)
CHECKS = [replace(c, exact_inputs=True) for c in CHECKS]
