"""Checks of ``jets`` (chapter 7): each derivative rule of the Jet alone, then a residual written for
arrays run on Jets.

Each rule is called through the implementation's own Jet on values and derivatives the check
chooses: a batch (5,) in k = 3 directions, a Jet against a constant on either side, a batch that
broadcasts ((4, 1) against (1, 3)), a scalar Jet (value of shape ()) and one direction (k = 1); the
values stay where the rule is defined (``log`` of positive numbers). The outputs are compared with
the reference to 1e-12 (relative); an infinite derivative must be the same infinity. The last check
runs the course's SE(2) and SE(3) edge residuals (``course.factorgraph.factors``) on Jets seeded at
the poses: every rule together, through numpy's functions. Hidden inputs: other values and
derivatives from the hidden seed (the edges of the contract kept).
"""

from functools import cache

import numpy as np

from autograder.checks import Call, Verdict
from autograder.checks.common import check, failed
from autograder.checks.edges import Edge
from autograder.feedback import call_fields, compare

MODULES = ("jets",)
TASK = "@autograder.tasks.jets:apply"
RESIDUAL_TASK = "@autograder.tasks.jets:residual_on_jets"
#: the rules' outputs agree with the reference to this (relative to the largest entry, at least 1)
RTOL = 1e-12

LABELS = {"mul": "Jet.__mul__", "truediv": "Jet.__truediv__", "pow": "Jet.__pow__", "sqrt": "jets.sqrt",
          "sin": "jets.sin", "cos": "jets.cos", "exp": "jets.exp", "log": "jets.log", "arctan2": "jets.arctan2",
          "matmul": "jets.matmul"}


def _jet(rng, shape, k, low=-2.0, high=2.0):
    return ("jet", rng.uniform(low, high, shape), rng.normal(0.0, 1.0, tuple(shape) + (k,)))


def _scaled(rng, scale):
    """A Jet (4,) in 2 directions whose values and derivatives are ``scale`` times O(1) numbers."""
    return ("jet", scale * rng.uniform(0.5, 2.0, 4) * rng.choice([-1.0, 1.0], 4), scale * rng.normal(0.0, 1.0, (4, 2)))


def _describe(spec) -> str:
    if spec[0] == "jet":
        return f"a Jet of shape {np.shape(spec[1])} in k = {np.shape(spec[2])[-1]} directions"
    if spec[0] == "array":
        return f"a constant array of shape {np.shape(spec[1])}"
    return f"the number {spec[1]:g}"


def _call(operation, operands, note=""):
    where = "on " + " and ".join(_describe(s) for s in operands) + (f" ({note})" if note else "")
    return Call(TASK, (operation, tuple(operands)), returns="dict", where=where, label=LABELS[operation])


def _rng(seed, salt):
    return np.random.default_rng(17 + salt if seed is None else [seed, 307, salt])


@cache
def arithmetic(seed=None):
    rng = _rng(seed, 1)
    calls = []
    for op in ("mul", "truediv"):
        low = 0.5 if op == "truediv" else -2.0  # divisors away from 0
        calls += [
            _call(op, [_jet(rng, (5,), 3), _jet(rng, (5,), 3, low, 2.0)]),
            _call(op, [_jet(rng, (5,), 3), ("array", rng.uniform(low, 2.0, 5))]),
            _call(op, [_jet(rng, (4, 1), 2), _jet(rng, (1, 3), 2, low, 2.0)], "broadcast to (4, 3)"),
            _call(op, [_jet(rng, (), 1), ("number", float(rng.uniform(0.5, 2.0)))]),
        ]
    calls.append(_call("truediv", [("array", rng.uniform(-2, 2, 5)), _jet(rng, (5,), 3, 0.5, 2.0)],
                       "a constant divided by a Jet"))
    calls.append(_call("mul", [("array", rng.uniform(-2, 2, 5)), _jet(rng, (5,), 3)], "a constant times a Jet"))
    return calls


@cache
def powers(seed=None):
    rng = _rng(seed, 2)
    x = _jet(rng, (5,), 3, 0.5, 2.0)
    calls = [_call("pow", [x, ("number", p)]) for p in (2.0, 3.0, 0.5, -1.0, -2.5)]
    zero = ("jet", np.array([0.0, 0.0, 1.5]), rng.normal(0.0, 1.0, (3, 2)))
    calls += [_call("pow", [zero, ("number", p)], f"x ** {p:g} with x = 0 in two entries") for p in (0.0, 1.0, 2.0)]
    at_zero = rng.normal(0.0, 1.0, (4, 2))
    at_zero[0] = 0.0  # value 0, derivative 0
    at_zero[1, 0], at_zero[2, :] = 0.0, (-1.0, 2.0)
    calls.append(_call("pow", [("jet", np.array([0.0, 0.0, 0.0, 2.25]), at_zero), ("number", 0.5)],
                       "x ** 0.5 at x = 0: the first entry with a zero derivative, the next two with nonzero ones"))
    return calls


@cache
def roots(seed=None):
    rng = _rng(seed, 3)
    at_zero = rng.normal(0.0, 1.0, (4, 2))
    at_zero[0] = 0.0  # value 0, derivative 0
    at_zero[1, 0], at_zero[2, :] = 0.0, (-1.0, 2.0)
    return [_call("sqrt", [_jet(rng, (5,), 3, 0.1, 4.0)]),
            _call("sqrt", [_jet(rng, (), 1, 0.1, 4.0)]),
            _call("sqrt", [("jet", np.array([0.0, 0.0, 0.0, 2.25]), at_zero)],
                  "sqrt at 0: the first entry with a zero derivative, the next two with nonzero ones")]


def elementary(operation):
    """The calls of one elementary function: a batch (5,) in 3 directions and (2, 3) or () in fewer."""
    low, high = {"sin": (-4.0, 4.0), "cos": (-4.0, 4.0), "exp": (-2.0, 2.0), "log": (0.05, 5.0)}[operation]
    salt = ("sin", "cos", "exp", "log").index(operation)

    @cache
    def calls(seed=None):
        rng = _rng(seed, 40 + salt)
        return [_call(operation, [_jet(rng, (5,), 3, low, high)]), _call(operation, [_jet(rng, (2, 3), 1, low, high)]),
                _call(operation, [_jet(rng, (), 2, low, high)])]

    return calls


@cache
def angles(seed=None):
    rng = _rng(seed, 6)
    quadrants = ("jet", np.array([0.7, 0.7, -0.7, -0.7, 0.0, 0.0, 1.2, -1.2]), rng.normal(0.0, 1.0, (8, 3)))
    xs = ("jet", np.array([0.9, -0.9, -0.9, 0.9, -1.1, 1.1, 0.0, 0.0]), rng.normal(0.0, 1.0, (8, 3)))
    return [_call("arctan2", [quadrants, xs], "a point in each quadrant and on each axis: (0, -1.1) gives pi"),
            _call("arctan2", [_scaled(rng, 1e200), _scaled(rng, 1e200)],
                  "values and derivatives ~ 1e200: x^2 + y^2 overflows"),
            _call("arctan2", [_scaled(rng, 1e-200), _scaled(rng, 1e-200)],
                  "values and derivatives ~ 1e-200: x^2 + y^2 underflows to 0"),
            _call("arctan2", [_jet(rng, (5,), 2), ("array", rng.uniform(-2, 2, 5))], "x a constant"),
            _call("arctan2", [("array", rng.uniform(-2, 2, 5)), _jet(rng, (5,), 2)], "y a constant")]


@cache
def products(seed=None):
    rng = _rng(seed, 7)
    return [_call("matmul", [_jet(rng, (4, 3, 3), 2), _jet(rng, (4, 3, 2), 2)], "a batch of 4 products"),
            _call("matmul", [("array", rng.uniform(-2, 2, (3, 3))), _jet(rng, (4, 3, 3), 3)],
                  "a constant matrix on the left"),
            _call("matmul", [_jet(rng, (4, 2, 3), 3), ("array", rng.uniform(-2, 2, (4, 3, 3)))],
                  "a constant on the right"),
            _call("matmul", [_jet(rng, (3, 3), 2), ("array", rng.uniform(-2, 2, 3))], "a vector on the right")]


@cache
def residuals(seed=None):
    """The course's SE(2) and SE(3) edge residuals on Jets seeded at the poses (k = 6 and 24)."""
    from course.factorgraph.variables import se3_value
    from course.geometry.so3 import exp_many

    rng = _rng(seed, 8)
    poses = [rng.uniform(-3.0, 3.0, (5, 3)) for _ in range(2)]
    z = rng.uniform(-1.0, 1.0, (5, 3))
    rot = [exp_many(rng.normal(0.0, 1.0, (4, 3))) for _ in range(3)]
    t = [rng.uniform(-3.0, 3.0, (4, 3)) for _ in range(3)]
    return [Call(RESIDUAL_TASK, ("BETWEEN_SE2", z, tuple(poses)), returns="dict",
                 where="on 5 SE(2) edges, Jets seeded at both poses (k = 6)", label="the SE(2) edge on Jets"),
            Call(RESIDUAL_TASK, ("BETWEEN_SE3", se3_value(t[0], rot[0]),
                                 (se3_value(t[1], rot[1]), se3_value(t[2], rot[2]))), returns="dict",
                 where="on 4 SE(3) edges, Jets seeded at both poses (k = 24)", label="the SE(3) edge on Jets")]


def _same_infinities(got, want):
    """``(got, want)`` with the entries where both are the same infinity set to 0."""
    got, want = np.array(got, dtype=float), np.array(want, dtype=float)
    if got.shape == want.shape:
        same = np.isinf(want) & (got == want)
        got[same] = want[same] = 0.0
    return got, want


def judge(cause, nan_cause=""):
    """Value and derivative against the reference (:data:`RTOL`); ``nan_cause`` is what a nan where the
    reference is finite means (a 0 * inf the rule should not compute)."""

    def judged(ctx):
        triples, failure = call_fields(ctx, failed=failed)
        if failure:
            return failure
        for index, (call, got, want) in enumerate(triples):
            known = ctx.known(index)
            for name, label in (("value", "value"), ("grad", "grad")):
                g, w = _same_infinities(got[name], want[name])
                finite = w[np.isfinite(w)]
                atol = 1e-14 * max(1.0, float(np.max(np.abs(finite)))) if finite.size else 1e-14
                # a nan where a known slip has it too: say which slip
                if g.shape == w.shape and not np.all(np.isfinite(g)):
                    for value, why in known.get(name, ()):
                        value = _same_infinities(value, want[name])[0]
                        if value.shape == g.shape and np.allclose(g, value, rtol=RTOL, atol=atol, equal_nan=True):
                            bad = tuple(int(i) for i in np.argwhere(~np.isfinite(g))[0])
                            return Verdict(0.0, f"{call.function}: {label}{list(bad)} = {g[bad]} (not a finite "
                                                f"number), expected {w[bad]:g} {call.where}: {why}")
                if nan_cause and g.shape == w.shape and np.any(np.isnan(g) & np.isfinite(w)):
                    bad = tuple(int(i) for i in np.argwhere(np.isnan(g) & np.isfinite(w))[0])
                    return Verdict(0.0, f"{call.function}: {label}{list(bad)} = nan, expected {w[bad]:g} "
                                        f"{call.where}: {nan_cause}")
                mistakes = [_same_infinities(v, want[name])[0] for v, _ in known.get(name, ())]
                text = compare(g, w, label, RTOL, atol, call.where,
                               list(zip(mistakes, (why for _, why in known.get(name, ())))), cause)
                if text:
                    return Verdict(0.0, f"{call.function}: {text}")
        return Verdict(1.0, "ok")

    return judged


RULES = "d f(a) = f'(a) da, with da the operand's grad (value's shape + (k,))"

CHECKS = [
    check("jets.Jet", "product and quotient", 3, arithmetic, judge(f"the product and quotient rules ({RULES})")),
    check("jets.Jet", "powers", 2, powers, judge(
        "d(x^p) = p x^(p-1) dx", "at x = 0, p x^(p-1) dx meets 0 * inf = nan: x ** 0 is the constant 1 and x ** 1 "
        "is x; for 0 < p < 1, where dx is 0 nothing depends on the seeds there, so the derivative is 0 (as "
        "sqrt's); keep +-inf where dx is not 0")),
    check("jets.sqrt", "sqrt, also at 0", 2, roots, judge(
        "d sqrt(x) = dx / (2 sqrt(x)); at 0 see the docstring",
        "at x = 0 with a zero derivative, dx / (2 sqrt(x)) is 0 * inf = nan: nothing depends on the seeds there, "
        "so the derivative is 0 (the contract); keep +-inf where the derivative is not 0")),
    check("jets.sin", "sin", 1, elementary("sin"), judge("d sin(x) = cos(x) dx")),
    check("jets.cos", "cos", 1, elementary("cos"), judge("d cos(x) = -sin(x) dx")),
    check("jets.exp", "exp", 1, elementary("exp"), judge("d exp(x) = exp(x) dx")),
    check("jets.log", "log", 1, elementary("log"), judge("d log(x) = dx / x")),
    check("jets.arctan2", "arctan2", 2, angles, judge(
        "d atan2(y, x) = (x dy - y dx) / (x^2 + y^2); at large or tiny magnitudes x^2 + y^2 overflows or "
        "underflows: divide x and y by max(|x|, |y|) first")),
    check("jets.matmul", "matrix products", 2, products, judge("d(A B) = dA B + A dB")),
    check("jets.Jet", "a residual written for arrays runs on Jets", 2, residuals,
          judge("every rule together through numpy's functions: if the checks above pass, look at how the "
                "results broadcast against (..., k)")),
]


def _operands(call):
    return call.args[1] if call.target == TASK else ()


EDGES = (
    Edge("sqrt at 0 with a zero derivative: value 0, derivative 0", TASK,
         lambda c: bool(c.args[0] == "sqrt" and np.any((np.asarray(c.args[1][0][1]) == 0)
                                                  & np.all(np.asarray(c.args[1][0][2]) == 0, axis=-1)))),
    Edge("sqrt at 0 with a nonzero derivative: value 0, derivative +-inf in the sign of the derivative", TASK,
         lambda c: bool(c.args[0] == "sqrt" and np.any((np.asarray(c.args[1][0][1]) == 0)
                                                  & np.any(np.asarray(c.args[1][0][2]) != 0, axis=-1)))),
    Edge("x ** 0: value 1, derivative 0 (also at x = 0)", TASK,
         lambda c: bool(c.args[0] == "pow" and c.args[1][1][1] == 0.0 and np.any(np.asarray(c.args[1][0][1]) == 0))),
    Edge("x ** 1 at x = 0 and x ** 2 at x = 0: derivative 1 * dx and 0", TASK,
         lambda c: bool(c.args[0] == "pow" and c.args[1][1][1] in (1.0, 2.0)
                        and np.any(np.asarray(c.args[1][0][1]) == 0))),
    Edge("x ** p with 0 < p < 1 at x = 0: value 0, derivative 0 where x's derivative is 0, else +-inf in its sign",
         TASK, lambda c: bool(c.args[0] == "pow" and 0.0 < c.args[1][1][1] < 1.0
                              and np.any((np.asarray(c.args[1][0][1]) == 0)
                                         & np.all(np.asarray(c.args[1][0][2]) == 0, axis=-1))
                              and np.any((np.asarray(c.args[1][0][1]) == 0)
                                         & np.any(np.asarray(c.args[1][0][2]) != 0, axis=-1)))),
    Edge("arctan2 at magnitudes whose squares overflow or underflow (x, y ~ 1e200 and ~ 1e-200): finite derivatives",
         TASK, lambda c: bool(c.args[0] == "arctan2" and all(s[0] == "jet" for s in c.args[1])
                              and (np.max(np.abs(c.args[1][0][1])) > 1e155
                                   or 0 < np.max(np.abs(c.args[1][0][1])) < 1e-155))),
    Edge("arctan2 on each axis (y = 0 with x < 0 gives pi)", TASK,
         lambda c: bool(c.args[0] == "arctan2" and c.args[1][0][0] == "jet" and c.args[1][1][0] == "jet"
         and np.any((np.asarray(c.args[1][0][1]) == 0) & (np.asarray(c.args[1][1][1]) < 0)))),
    Edge("one direction (k = 1) and a scalar Jet (value of shape ())", TASK,
         lambda c: any(s[0] == "jet" and np.ndim(s[1]) == 0 for s in _operands(c))),
)
