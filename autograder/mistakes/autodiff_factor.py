# RELEASE: omit
"""Known mistakes in ``autodiff_factor`` (see ``autograder.mistakes``): the seeding written with one
slip, run through the same task as the student's code (its Jet carries closed-form derivatives)."""

from types import SimpleNamespace

import numpy as np

from autograder.checks.autodiff_factor import NAME
from autograder.tasks.jets import tangent_jacobians_task


def _variant(offsets="sum", read="offsets", order="forward", sign=1.0, ambient=False):
    def tangent_jacobians(residual, retractions, dims, xs, jet):
        if ambient:  # the stored coordinates seeded, no retraction
            sizes = [int(np.prod(np.shape(x)[1:])) for x in xs]
            starts = np.concatenate([[0], np.cumsum(sizes)])
            points = []
            for x, s, o in zip(xs, sizes, starts):
                seeded = jet.seed(np.reshape(x, (len(x), s)), int(o), int(starts[-1]))
                points.append(jet(seeded.value.reshape(np.shape(x)), seeded.grad.reshape(np.shape(x) + (-1,))))
            r = residual(*points)
            return r.value, [r.grad[..., starts[a]:starts[a + 1]] for a in range(len(xs))]
        k = int(sum(dims))
        start = {"sum": np.concatenate([[0], np.cumsum(dims)])[:-1],
                 "zero": [0] * len(dims),
                 "equal": [a * d for a, d in enumerate(dims)]}[offsets]
        moved = []
        for retract, d, o, x in zip(retractions, dims, start, xs):
            seeded = jet.seed(np.zeros((len(x), d)), int(o), k)
            moved.append(retract(x, jet(seeded.value, sign * seeded.grad)))
        r = residual(*moved)
        where = start if read == "offsets" else [0] * len(dims)
        ends = [int(o) + d for o, d in zip(where, dims)]
        if offsets == "equal":  # the one wrong offsets array, read as it was seeded: up to the next offset
            ends = [int(o) for o in start[1:]] + [k]
        blocks = [r.grad[..., int(o):e] for o, e in zip(where, ends)]
        return r.value, blocks[::-1] if order == "reversed" else blocks

    return SimpleNamespace(module=lambda name: SimpleNamespace(tangent_jacobians=tangent_jacobians))


SLIPS = [
    ({"offsets": "zero"}, "every variable's step seeded in the same directions 0 .. d_a - 1: their derivatives add "
                          "up in one block; give each its own directions, offset by the sizes before it"),
    ({"offsets": "equal"}, "the offsets are the running sum of the tangent sizes (0, d_1, d_1 + d_2, ...), not "
                           "a d_a: the sizes differ"),
    ({"read": "first"}, "each block is read from its own columns of r's derivative, offset_a .. offset_a + d_a, "
                        "not from the first d_a"),
    ({"order": "reversed"}, "the blocks come back in the order of the variables"),
    ({"sign": -1.0}, "the step is x (+) delta, seeded with +1: the derivative of x (+) (-delta) has the "
                     "opposite sign"),
    ({"ambient": True}, "that is the derivative by the stored numbers (e.g. the 9 entries of R), not by the "
                        "tangent step: seed delta = 0 and move x by the retraction, x (+) delta"),
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
