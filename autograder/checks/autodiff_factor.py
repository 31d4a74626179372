"""Checks of ``autodiff_factor`` (chapter 7): a factor's residual and its Jacobians on the tangent
spaces, obtained by seeding Jets with the retractions' derivatives at 0 (the plus-Jacobians).

The student's function is graded alone: the Jet class it is given carries the derivatives it is
told and has no rules of its own, and the residual of each check computes its derivatives in
closed form (``autograder.tasks.jets.tangent_jacobians_task``), so nothing of the student's ``jets``
is used. The residual is ``r = sum_a C_a vec(x_a) + (sum_a D_a vec(x_a))^2`` (entrywise), with random
``C_a``, ``D_a``, and the plus-Jacobians are the kinds' own (``course.factorgraph.variables``: the
identity for a vector and SE(2), ``R [e_k]_x`` for a rotation) or, for a ``linear`` variable
(``x + A delta``), a random square ``A``, neither the identity nor symmetric. Public inputs, one
variable: a linear 3-vector (M = 3, m = 2); one factor (M = 1) on a linear 4-vector (square
plus-Jacobians alone, so that a transposed one runs and is named); several: an SE(2) pose and a
2-vector (M = 4); two SE(3) poses (M = 3, m = 6); three variables of three kinds, SE(3), a 3-vector
and SO(3) (M = 2, m = 4); an SE(3) pose held fixed in two of its four factors and a linear 2-vector
(M = 4, m = 3). Hidden: other values and matrices from the hidden seed. The Jacobians are compared
with the reference's to 1e-12.
"""

from functools import cache

import numpy as np

from autograder.checks import Call, Verdict
from autograder.checks.common import check, failed
from autograder.checks.edges import Edge
from autograder.feedback import call_fields, compare

MODULES = ("autodiff_factor",)
NAME = "autodiff_factor.tangent_jacobians"
TASK = "@autograder.tasks.jets:tangent_jacobians_task"
RTOL = 1e-12


def _value(rng, kind, M, n=None):
    from course.geometry.so3 import exp_many

    if kind in ("vector", "linear"):
        return rng.uniform(-2.0, 2.0, (M, n))
    if kind == "se2":
        return np.column_stack([rng.uniform(-3, 3, (M, 2)), rng.uniform(-3, 3, M)])
    R = exp_many(rng.normal(0.0, 1.0, (M, 3)))
    if kind == "so3":
        return R
    return np.concatenate([rng.uniform(-3, 3, (M, 3)), R.reshape(M, 9)], axis=1)


def _plus_jacobian(rng, kind, x):
    """``d vec(x (+) delta) / d delta`` at 0 (M, n, d): the kind's own; a random square one for ``linear``."""
    from course.factorgraph.variables import SE2, SE3, SO3, Vector

    if kind == "linear":
        A = rng.normal(0.0, 1.0, (len(x), x.shape[1], x.shape[1]))
        return A + 2.0 * np.eye(x.shape[1])  # well away from symmetric and from the identity alike
    return {"vector": Vector(x.shape[-1]), "se2": SE2, "so3": SO3, "se3": SE3}[kind].plus_jacobian(x)


def _case(rng, kinds, M, m, note, held=None):
    """A call on variables of ``kinds`` (``(kind, n)``); ``held``: ``{slot: rows}`` where that slot's
    variable is fixed (its plus-Jacobian 0 there)."""
    xs = tuple(_value(rng, kind, M, n) for kind, n in kinds)
    plus = [_plus_jacobian(rng, kind, x) for (kind, _), x in zip(kinds, xs)]
    for slot, rows in (held or {}).items():
        plus[slot][list(rows)] = 0.0
    sizes = [int(np.prod(x.shape[1:])) for x in xs]
    C = tuple(rng.normal(0.0, 1.0, (M, m, s)) for s in sizes)
    D = tuple(rng.normal(0.0, 0.5, (M, m, s)) for s in sizes)
    names = ", ".join({"vector": f"a {n}-vector", "linear": f"a linear {n}-vector"}.get(kind, kind)
                      for kind, n in kinds)
    return Call(TASK, (tuple(kind for kind, _ in kinds), xs, tuple(plus), C, D), returns="dict", label=NAME,
                where=f"on {M} factor{'s' if M > 1 else ''} of {len(kinds)} variable{'s' if len(kinds) > 1 else ''} "
                      f"({names}), m = {m}{note}")


@cache
def one_variable(seed=None):
    rng = np.random.default_rng(61 if seed is None else [seed, 311, 1])
    return [_case(rng, [("linear", 3)], 3, 2, ": a plus-Jacobian neither the identity nor symmetric"),
            _case(rng, [("linear", 4)], 1, 3, ": one factor (M = 1)")]


@cache
def several_variables(seed=None):
    rng = np.random.default_rng(62 if seed is None else [seed, 311, 2])
    return [_case(rng, [("se2", None), ("vector", 2)], 4, 2, ""),
            _case(rng, [("se3", None), ("se3", None)], 3, 6, ": the same kind in two slots"),
            _case(rng, [("se3", None), ("vector", 3), ("so3", None)], 2, 4, ": three sizes"),
            _case(rng, [("se3", None), ("linear", 2)], 4, 3,
                  ": the pose held fixed in factors 1 and 3 (its plus-Jacobian 0 there)", held={0: (1, 3)})]


def _judge(fields):
    def judged(ctx):
        triples, failure = call_fields(ctx, failed=failed)
        if failure:
            return failure
        for index, (call, got, want) in enumerate(triples):
            known = ctx.known(index)
            if "r" in fields:
                text = compare(got["r"], want["r"], "r", RTOL, 1e-12 * max(1.0, float(np.max(np.abs(want["r"])))),
                               call.where, known.get("r", ()),
                               "r is the residual of the values themselves: the Jets' values are the x_a")
                if text:
                    return Verdict(0.0, f"{NAME}: {text}")
            if "J" not in fields:
                continue
            count = int(want["count"])
            if int(got["count"]) != count:
                return Verdict(0.0, f"{NAME}: returned {int(got['count'])} Jacobian blocks, expected {count} "
                                    f"(one per variable) {call.where}")
            for a in range(count):
                scale = max(1.0, float(np.max(np.abs(want[f"J{a}"]))))
                text = compare(got[f"J{a}"], want[f"J{a}"], f"J[{a}]", RTOL, 1e-12 * scale, call.where,
                               known.get(f"J{a}", ()),
                               "J_a is dr/d delta_a at delta = 0, in the tangent space: by the chain rule "
                               "dr/d vec(x_a) P_a, with x_a's Jet seeded with P_a in its own directions")
                if text:
                    return Verdict(0.0, f"{NAME}: {text}")
        return Verdict(1.0, "ok")

    return judged


CHECKS = [
    check(NAME, "the residual at delta = 0", 1, several_variables, _judge(("r",))),
    check(NAME, "the Jacobian of one variable", 2, one_variable, _judge(("r", "J"))),
    check(NAME, "the Jacobians of several variables of different sizes", 3, several_variables, _judge(("r", "J"))),
]


EDGES = (
    Edge("one factor (M = 1)", TASK, lambda c: len(c.args[1][0]) == 1),
    Edge("one variable (s = 1)", TASK, lambda c: len(c.args[0]) == 1),
    Edge("a variable stored in another shape than its tangent size (SO(3): 3x3 stored, 3 tangent)", TASK,
         lambda c: "so3" in c.args[0]),
    Edge("the same kind in two slots", TASK, lambda c: len(set(c.args[0])) < len(c.args[0])),
    Edge("a plus-Jacobian that is neither the identity nor symmetric (a square one)", TASK,
         lambda c: any(np.shape(P)[1] == np.shape(P)[2] and not np.allclose(P, np.swapaxes(P, 1, 2))
                       for P in c.args[2])),
    Edge("a variable held fixed in some factors: its plus-Jacobian is 0 there", TASK,
         lambda c: any(np.any(~np.any(np.reshape(P, (len(P), -1)), axis=1)) for P in c.args[2])),
)
