"""Checks of ``gauge`` (chapter 4, going further): the 7 directions in which a bundle
adjustment's cost does not change.

The columns are compared as subspaces, not entry by entry, each group alone: the
translations' span must be the reference's; the rotations, joined with the reference's
translations, must span the reference's six; the scale column, joined with the reference's
six, the reference's seven. So a rotation about another centre (a rotation plus a
translation), another basis of the same span or a scaled column keep full marks, and a
slip in one group costs that group's check only. Public inputs: the problem of the ``bundle_adjustment``
checks (4 cameras, camera 0 rotated by 1e-9 rad, 12 points), the cameras and points of their edge
problem (a camera not rotated at all, one rotated by pi - 1e-3 rad) and one camera with one point;
hidden: others from the hidden seed.
"""

import numpy as np

from autograder.checks import Call, Verdict
from autograder.checks.bundle_adjustment import NEAR_PI, edge_problem, problem
from autograder.checks.common import check, failed
from autograder.checks.edges import Edge
from autograder.feedback import call_fields

MODULES = ("gauge",)
DIRECTIONS = "gauge.gauge_directions"
#: a column is "in" a span when its part outside it is below this, relative to its norm
SPAN_TOL = 1e-7
#: columns are independent when the smallest singular value exceeds this, relative to the largest
RANK_TOL = 1e-6

#: the column groups: (the student's columns, the reference's columns joined to them, what they are)
GROUPS = {
    "translations": ([3, 4, 5], [], "columns 3-5: dX = u_a, dt = -R(w) u_a, dw = 0"),
    "rotations": ([0, 1, 2], [3, 4, 5], "columns 0-2: dX = u_a x X, dw = -J_r(w)^-1 u_a, dt = 0"),
    "scale": ([6], [0, 1, 2, 3, 4, 5], "column 6: dX = X, dt = t"),
}


def _calls(seed=None):
    """The bundle-adjustment checks' problem, then the edges: the cameras and points of their edge problem
    (camera 0 not rotated at all, camera 1 by pi - 1e-3 rad), and one camera with one point."""
    g = problem(seed)
    where = (f"on a problem of {len(g['cameras'])} cameras (camera 0 rotated by 1e-9 rad) and "
             f"{len(g['points'])} points")
    calls = [Call(TARGET, (g["cameras"], g["points"]), where=where)]
    e, one = edge_problem(seed), edge_problem(seed, one=True)
    calls.append(Call(TARGET, (e["cameras"], e["points"]),
                      where=f"on a problem of {len(e['cameras'])} cameras (camera 0 not rotated at all, w = 0 exactly; "
                            f"camera 1 rotated by pi - 1e-3 rad) and {len(e['points'])} points"))
    calls.append(Call(TARGET, (one["cameras"], one["points"]), where="on one camera and one point"))
    return calls


TARGET = f"gauge:{DIRECTIONS.split('.')[1]}"


def outside(columns, reference) -> float:
    """The largest part of a column of ``columns`` (n, m) outside span(``reference``) (n, k),
    relative to that column's norm."""
    Q, _ = np.linalg.qr(reference)
    rest = columns - Q @ (Q.T @ columns)
    norms = np.maximum(np.linalg.norm(columns, axis=0), np.finfo(float).tiny)
    return float(np.max(np.linalg.norm(rest, axis=0) / norms))


def independent(columns) -> bool:
    s = np.linalg.svd(columns, compute_uv=False)
    return bool(s[-1] > RANK_TOL * s[0])


def same_span(columns, reference) -> bool:
    return (columns.shape == reference.shape and independent(columns)
            and outside(columns, reference) <= SPAN_TOL)


def _judge(group):
    mine, joined, what = GROUPS[group]

    def spans(N, ref) -> bool:
        return same_span(np.column_stack([N[:, mine], ref[:, joined]]), ref[:, mine + joined])

    def judge(ctx):
        triples, failure = call_fields(ctx, failed=failed)
        if failure:
            return failure
        for index, (call, got, want) in enumerate(triples):
            N, ref = np.asarray(got["value"], dtype=float), np.asarray(want["value"], dtype=float)
            if N.shape != ref.shape:
                return Verdict(0.0, f"N has shape {N.shape}, expected {ref.shape} (9C + 3P rows, 7 columns) "
                                    f"{call.where}")
            if not np.all(np.isfinite(N[:, mine])):  # this group's columns: a slip elsewhere costs its own check
                return Verdict(0.0, f"{what}: N has entries that are not finite {call.where}")
            if spans(N, ref):
                continue
            columns = np.column_stack([N[:, mine], ref[:, joined]])
            text = (f"{what}: not a direction of the gauge {call.where} (part outside the gauge's span: "
                    f"{outside(N[:, mine], ref[:, mine + joined]):.3g} of a column's norm"
                    f"{'' if independent(columns) else '; the columns are not independent'})")
            for value, why in ctx.known(index).get("value", ()):
                theirs = np.asarray(value, dtype=float)[:, mine]
                if max(outside(N[:, mine], theirs), outside(theirs, N[:, mine])) <= SPAN_TOL:
                    return Verdict(0.0, f"{text}: {why}")
            return Verdict(0.0, text)
        return Verdict(1.0, "ok")

    return judge


CHECKS = [
    check(DIRECTIONS, "translation directions", 2, _calls, _judge("translations")),
    check(DIRECTIONS, "rotation directions", 3, _calls, _judge("rotations")),
    check(DIRECTIONS, "scale direction", 2, _calls, _judge("scale")),
]


def _norms(call):
    return np.linalg.norm(np.asarray(call.args[0], dtype=float)[:, :3], axis=1)


EDGES = (
    Edge("a camera not rotated at all (w = 0 exactly)", TARGET, lambda c: bool(np.any(_norms(c) == 0.0))),
    Edge("a camera rotated by nearly pi (|w| = pi - 1e-3)", TARGET,
         lambda c: bool(np.any(np.abs(_norms(c) - NEAR_PI) <= 1e-9))),
    Edge("one camera and one point (C = P = 1)", TARGET, lambda c: len(c.args[0]) == 1 and len(c.args[1]) == 1),
)
