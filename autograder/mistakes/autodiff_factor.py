# RELEASE: omit
"""Known mistakes in ``autodiff_factor`` (see ``autograder.mistakes``): the seeding written with one
slip, run through the same task as the student's code (its Jet carries closed-form derivatives)."""

from types import SimpleNamespace

import numpy as np

from autograder.checks.autodiff_factor import NAME
from autograder.tasks.jets import tangent_jacobians_task


def _variant(offsets="sum", read="offsets", order="forward", sign=1.0, seed="plus"):
    def tangent_jacobians(residual, plus_jacobians, xs, jet):
        M = len(xs[0])
        sizes = [int(np.prod(np.shape(x)[1:])) for x in xs]
        if seed == "ambient":  # the stored coordinates seeded with the identity, dr/d vec(x) returned
            dims = sizes
            plus_jacobians = [np.broadcast_to(np.eye(n), (M, n, n)) for n in sizes]
        else:
            dims = [int(np.shape(P)[-1]) for P in plus_jacobians]
        k = int(sum(dims))
        start = {"sum": np.concatenate([[0], np.cumsum(dims)])[:-1],
                 "zero": [0] * len(dims),
                 "equal": [a * d for a, d in enumerate(dims)]}[offsets]
        points = []
        for P, x, n, d, o in zip(plus_jacobians, xs, sizes, dims, start):
            if seed == "identity":  # the first d stored numbers seeded, as if P were the identity
                P = np.broadcast_to(np.eye(n, d), (M, n, d))
            elif seed == "transposed":
                if np.shape(P)[1] != d:
                    raise ValueError("a transpose of a non-square plus-Jacobian does not fit")
                P = np.swapaxes(P, 1, 2)
            grad = np.zeros((M, n, k))
            grad[:, :, int(o):int(o) + d] = sign * np.asarray(P)
            points.append(jet(np.reshape(x, (M, n)), grad).reshape(np.shape(x)))
        r = residual(*points)
        where = start if read == "offsets" else [0] * len(dims)
        ends = [int(o) + d for o, d in zip(where, dims)]
        if offsets == "equal":  # the one wrong offsets array, read as it was seeded: up to the next offset
            ends = [int(o) for o in start[1:]] + [k]
        blocks = [r.grad[..., int(o):e] for o, e in zip(where, ends)]
        return r.value, blocks[::-1] if order == "reversed" else blocks

    return SimpleNamespace(module=lambda name: SimpleNamespace(tangent_jacobians=tangent_jacobians))


SLIPS = [
    ({"offsets": "zero"}, "every variable seeded in the same directions 0 .. d_a - 1: their derivatives add "
                          "up in one block; give each its own directions, offset by the sizes before it"),
    ({"offsets": "equal"}, "the offsets are the running sum of the tangent sizes (0, d_1, d_1 + d_2, ...), not "
                           "a d_a: the sizes differ"),
    ({"read": "first"}, "each block is read from its own columns of r's derivative, offset_a .. offset_a + d_a, "
                        "not from the first d_a"),
    ({"order": "reversed"}, "the blocks come back in the order of the variables"),
    ({"sign": -1.0}, "the Jet of x_a is seeded with +P_a (x (+) delta moves by +P_a delta): seeded with -P_a "
                     "every derivative has the opposite sign"),
    ({"seed": "identity"}, "x_a's Jet is seeded with the identity, as if the step moved the first d_a stored "
                           "numbers: seed it with the plus-Jacobian P_a = d vec(x_a (+) delta) / d delta"),
    ({"seed": "transposed"}, "the plus-Jacobian is transposed: grad[:, i, offset_a + j] = P_a[:, i, j], row i "
                             "the stored number, column j the step's direction"),
    ({"seed": "ambient"}, "that is the derivative by the stored numbers (e.g. the 9 entries of R), not by the "
                          "tangent step: seed x_a's Jet with P_a, so that the chain rule gives dr/d vec(x_a) P_a"),
]


def _known(call, ref):
    known: dict = {}
    for slip, why in SLIPS:
        try:
            out = tangent_jacobians_task(*call.args, impl=_variant(**slip))
        except (ValueError, IndexError):  # a slip that cannot run on these shapes says nothing here
            continue
        for name, value in out.items():
            if name == "count":
                continue
            want = ref.get(name)
            value = np.asarray(value, dtype=float)
            if want is None or (value.shape == np.shape(want) and np.allclose(value, want, rtol=1e-12, atol=1e-14)):
                continue
            known.setdefault(name, []).append((value, why))
    return known


MISTAKES = {f"{NAME}: {title}": _known for title in (
    "the residual at delta = 0", "the Jacobian of one variable",
    "the Jacobians of several variables of different sizes")}
