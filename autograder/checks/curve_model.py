"""Checks of ``curve_model.residuals_and_jacobian``: shapes, r, J, and J against central
differences of the student's own r.

Public inputs: the default data (100 points) at the start, the truth and another point,
a 20-point data set, and a single point of it (m = 1); hidden inputs: data of another size,
truth and noise seed, at random parameters in the same ranges, and one point of the small set.
"""

import numpy as np

from autograder.checks import Call, Check, Verdict
from autograder.checks.edges import Edge
from autograder.feedback import call_fields, compare, fmt, values

MODULES = ("curve_model",)
NAME = "curve_model.residuals_and_jacobian"

COLUMN_HINTS = (
    "check d y_hat / d a = x^2 y_hat",
    "check d y_hat / d b = x y_hat",
    "check d y_hat / d c = y_hat",
)

# ---------------------------------------------------------------- inputs


def _curve_points(seed=None):
    """(x, y, params, where): the start, the truth, another point, a small data set, and a single
    point of it (m = 1)."""
    from course.problems.curve.problem import generate

    if seed is None:
        big, small = generate(), generate(num_points=20, seed=5, truth=(0.5, -1.0, 0.3))
        points = [(0.0, 0.0, 0.0), (1.0, 2.0, 1.0), (0.3, -0.7, 0.2)]
        last = (0.8, 1.5, 0.9)
    else:
        rng = np.random.default_rng([seed, 101])
        truth = tuple(np.round(rng.uniform([0.5, 1.0, 0.5], [1.5, 2.5, 1.5]), 3))
        big = generate(num_points=int(rng.integers(60, 140)), seed=int(rng.integers(1 << 30)), truth=truth)
        small = generate(num_points=int(rng.integers(12, 30)), seed=int(rng.integers(1 << 30)),
                         truth=tuple(np.round(rng.uniform(-1.0, 1.0, 3), 3)))
        points = [(0.0, 0.0, 0.0), truth, tuple(np.round(rng.uniform(-1.0, 1.0, 3), 3))]
        last = tuple(np.round(rng.uniform(0.2, 1.5, 3), 3))

    def where(p, x):
        text = f"at params ({', '.join(f'{v:g}' for v in p)})"
        return text if x is big.x else f"{text} on {len(x)} point{'s' if len(x) > 1 else ''}"

    out = [(big.x, big.y, np.array(p, dtype=float), where(p, big.x)) for p in points]
    out.append((small.x, small.y, np.array(last, dtype=float), where(last, small.x)))
    k = len(small.x) // 2  # a single point (m = 1), away from x = 0
    one = small.x[k:k + 1].copy()
    out.append((one, small.y[k:k + 1].copy(), np.array(last, dtype=float), where(last, one) + f" (x = {one[0]:g})"))
    return out


def _curve_call(x, y, p, where):
    return Call("curve_model:residuals_and_jacobian", (p, x, y), returns=("r", "J"), where=where)


def _curve_calls(seed=None):
    return [_curve_call(*point) for point in _curve_points(seed)]


FD_POINTS = (1, 2, 3)  # indices into _curve_points(): truth, another point, small data
FD_CALLS = 7  # per point: the point itself, then +/- a step in each parameter


def _fd_step(value):
    return 1e-6 * max(1.0, abs(value))


def _fd_calls(seed=None):
    calls = []
    points = _curve_points(seed)
    for k in FD_POINTS:
        x, y, p, where = points[k]
        calls.append(_curve_call(x, y, p, where))
        for j in range(3):
            step = _fd_step(p[j])
            for sign in (1.0, -1.0):
                q = p.copy()
                q[j] += sign * step
                calls.append(_curve_call(x, y, q, f"{where}, param {j} {'+' if sign > 0 else '-'} {step:g}"))
    return calls


# ---------------------------------------------------------------- judges


def _judge_shapes(ctx):
    triples, failure = call_fields(ctx)
    for call, got, _ in triples:
        m = len(call.args[1])
        for name, shape in (("r", (m,)), ("J", (m, 3))):
            if got[name].shape != shape:
                text = f"{name} has shape {got[name].shape}, expected {shape} {call.where}"
                if name == "J" and got[name].shape == shape[::-1]:
                    text += ": J is transposed (one row per point, columns d/da, d/db, d/dc)"
                return Verdict(0.0, text)
    return failure or Verdict(1.0, "ok")


def _judge_jacobian(ctx):
    triples, failure = call_fields(ctx)
    for index, (call, got, want) in enumerate(triples):
        if got["J"].shape != want["J"].shape:
            return Verdict(0.0, compare(got["J"], want["J"], "J", 0, 0, call.where))
        known = ctx.known(index)
        for j in range(3):
            text = compare(got["J"][:, j], want["J"][:, j], f"J[{{}}, {j}]", 1e-8, 1e-10, call.where,
                           known.get(f"J{j}", ()), COLUMN_HINTS[j])
            if text:
                return Verdict(0.0, text)
    return failure or Verdict(1.0, "ok")


def _judge_finite_differences(ctx):
    """J of the student against central differences of the student's own r, per column.

    A column earns credit only where r itself is right at the point: J consistent with a
    wrong r (all zeros, say) earns nothing.
    """
    triples, failure = call_fields(ctx)
    if failure:
        return failure
    fields = [got for _, got, _ in triples]
    good = [True, True, True]
    messages, minus = {}, []
    for block in range(len(FD_POINTS)):
        base = FD_CALLS * block
        call, J = ctx.calls[base], fields[base]["J"]
        m = len(call.args[1])
        if J.shape != (m, 3) or any(fields[base + i]["r"].shape != (m,) for i in range(FD_CALLS)):
            return Verdict(0.0, f"r or J has the wrong shape {call.where} (see the shapes check)")
        wrong_r = compare(fields[base]["r"], triples[base][2]["r"], "r", 1e-8, 1e-10, call.where)
        if wrong_r:
            return Verdict(0.0, f"{wrong_r}: your r is wrong (see the r values check), so J's agreement "
                                "with finite differences of it earns nothing")
        p = call.args[0]
        for j in range(3):
            step = _fd_step(p[j])
            fd = (fields[base + 1 + 2 * j]["r"] - fields[base + 2 + 2 * j]["r"]) / (2 * step)
            if not good[j]:
                continue
            if not np.all(np.isfinite(fd)):
                good[j] = False
                messages[j] = (f"your r is not finite near {call.where} (perturbing param {j}), so J[:, {j}] "
                               "cannot be checked by finite differences (see the r values check)")
                continue
            atol = 1e-6 * max(1.0, float(np.max(np.abs(fd))))
            if compare(J[:, j], fd, "", 1e-6, atol) is None:
                continue
            good[j] = False
            excess = np.abs(J[:, j] - fd) - (atol + 1e-6 * np.abs(fd))
            k = int(np.nanargmax(np.where(np.isfinite(excess), excess, np.inf)))
            text = (f"J[:, {j}] disagrees with finite differences of your r {call.where}: "
                    f"J[{k}, {j}] = {fmt(J[k, j])}, central difference {fmt(fd[k])} "
                    f"(rtol=1e-06, atol={atol:.2g})")
            if np.all(np.isfinite(J[:, j])) and compare(J[:, j], -fd, "", 1e-6, atol) is None:
                text += ": J is minus the derivative of your r"
                minus.append(j)
            else:
                text += f": {COLUMN_HINTS[j]}"
            messages[j] = text
    if minus and len(minus) == len(messages):
        columns = ", ".join(f"J[:, {j}]" for j in minus)
        first = messages[minus[0]].split(": J is minus")[0]
        messages = {0: (f"{first}: J is minus the derivative of your r in {columns}; J must be dr/dp "
                        "of the same r (r = y_hat - y gives J = +y_hat (x^2, x, 1))")}
    score = sum(good) / 3.0
    if score == 1.0:
        return Verdict(1.0, "ok")
    return Verdict(score, "; ".join(messages[j] for j in sorted(messages)))


def _check(title, points, calls, judge):
    return Check(f"{NAME}: {title}", NAME, points, calls, judge)


CHECKS = [
    _check("shapes", 1, _curve_calls, _judge_shapes),
    _check("r values", 3, _curve_calls,
           values(("r",), 1e-8, 1e-10, "check y_hat = exp(a x^2 + b x + c) and r = y_hat - y")),
    _check("J values", 3, _curve_calls, _judge_jacobian),
    _check("J vs finite differences of r", 3, _fd_calls, _judge_finite_differences),
]

EDGES = (
    Edge("a single data point (m = 1): r has shape (1,) and J shape (1, 3)",
         "curve_model:residuals_and_jacobian", lambda call: len(call.args[1]) == 1),
)
