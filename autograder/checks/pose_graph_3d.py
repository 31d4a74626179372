"""Checks of ``pose_graph_3d``: the SE(3) edge error, its Jacobians on the manifold, and the
retraction, each graded alone.

Public inputs: 6 poses turned far from each other and 11 edges (some written from the
larger index to the smaller), one edge whose residual rotation is 2.9 rad, one whose residual
is 1e-9 rad (the small-angle branch), then one edge alone (M = 1) whose residual rotation is
exactly 0 and one whose residual rotation is pi - 1e-4; the retraction with steps of about 0.4,
one zero and one of 1e-10 rad, and on one pose alone; hidden inputs: the same kind from the
hidden seed.

The edge function is also called on the same edges split apart (every edge its own two
poses) with every first pose, then every second pose, moved by ``+-h`` along each of the
six tangent directions (the right perturbation ``T (Exp(phi), rho)``): a wrong Jacobian's
feedback then says whether it agrees with central differences of the student's own e (the
model is wrong) or not (the derivative is wrong), and which of its blocks differ.
"""

from functools import cache

import numpy as np

from autograder.checks import Call
from autograder.checks.common import check, residual_or_jacobian, values
from autograder.checks.edges import Edge
from autograder.feedback import fields_of
from course.geometry import se3
from course.geometry.so3 import exp_many

MODULES = ("pose_graph_3d",)
EDGE_ERRORS = "pose_graph_3d.edge_errors_and_jacobians"
RETRACT = "pose_graph_3d.retract"
#: what the moved calls' ``where`` ends with (feedback names the first call's causes only)
DIFFERENCES = "(for central differences of e)"
STEP = 1e-6
#: the four 3x3 blocks of A and B, as feedback names them
BLOCKS = (("d e_t / d rho (translation rows, translation columns)", slice(0, 3), slice(0, 3)),
          ("d e_t / d phi (translation rows, rotation columns)", slice(0, 3), slice(3, 6)),
          ("d e_phi / d rho (rotation rows, translation columns)", slice(3, 6), slice(0, 3)),
          ("d e_phi / d phi (rotation rows, rotation columns)", slice(3, 6), slice(3, 6)))


@cache
def graph(seed=None) -> dict:
    """``t`` (6, 3), ``R`` (6, 3, 3), ``edges_i``, ``edges_j`` (11,), ``t_z`` (11, 3), ``R_z``
    (11, 3, 3); the measurements near the truth except the chosen large residuals."""
    rng = np.random.default_rng(71 if seed is None else [seed, 271])
    n = 6
    t = rng.normal(0, 2.0, (n, 3))
    R = exp_many(rng.normal(0, 1.0, (n, 3)))
    pairs = [(0, 1), (1, 2), (2, 3), (3, 4), (4, 5), (5, 0), (2, 0), (4, 1), (1, 3), (5, 2), (3, 5)]
    ei, ej = (np.array(v) for v in zip(*pairs))
    t_rel, R_rel = se3.between(t[ei], R[ei], t[ej], R[ej])
    # the measurements: the relative poses moved by small noise, then three chosen residuals
    noise = rng.normal(0, 0.05, (len(ei), 6))
    noise[3, 3:] = 1e-9 * rng.normal(size=3)  # the small-angle case
    axis = rng.normal(size=3)
    noise[7, 3:] = 2.9 * axis / np.linalg.norm(axis)  # a residual rotation near pi
    R_z = np.matmul(R_rel, exp_many(-noise[:, 3:]))
    t_z = t_rel + noise[:, :3]
    return {"t": t, "R": R, "edges_i": ei, "edges_j": ej, "t_z": t_z, "R_z": R_z}


def _where(g) -> str:
    return (f"on a graph of {len(g['t'])} poses and {len(g['edges_i'])} edges (edge 3's residual rotation "
            "1e-9 rad, edge 7's 2.9 rad)")


def split(g) -> dict:
    """The same edges, each with its own two poses: edge k joins pose k and pose M + k."""
    m = len(g["edges_i"])
    return {"t": np.concatenate([g["t"][g["edges_i"]], g["t"][g["edges_j"]]]),
            "R": np.concatenate([g["R"][g["edges_i"]], g["R"][g["edges_j"]]]),
            "edges_i": np.arange(m), "edges_j": np.arange(m, 2 * m), "t_z": g["t_z"], "R_z": g["R_z"]}


def _args(g):
    return (g["t"], g["R"], g["edges_i"], g["edges_j"], g["t_z"], g["R_z"])


def _edge_calls(seed=None):
    """The edges, then the split edges with every first (then second) pose moved by +-h along
    each tangent direction: 1 + 2 * 2 * 6 calls."""
    g = graph(seed)
    target = "pose_graph_3d:edge_errors_and_jacobians"
    backwards = tuple(int(k) for k in np.flatnonzero(g["edges_i"] > g["edges_j"]))
    groups = {"whose residual rotation is 2.9 rad, near pi (edge 7)": (7,),
              "whose residual rotation is 1e-9 rad, the small-angle case (edge 3)": (3,),
              f"written from the larger pose index to the smaller (edges {', '.join(map(str, backwards))})": backwards}
    calls = [Call(target, _args(g), returns=("e", "A", "B"), where=_where(g), groups=groups)]
    s, m = split(g), len(g["edges_i"])
    for side, poses in (("first", slice(0, m)), ("second", slice(m, 2 * m))):
        for direction in range(6):
            for sign in (1.0, -1.0):
                delta = np.zeros((2 * m, 6))
                delta[poses, direction] = sign * STEP
                t, R = se3.retract(s["t"], s["R"], delta)
                name = ("rho_x", "rho_y", "rho_z", "phi_x", "phi_y", "phi_z")[direction]
                calls.append(Call(target, (t, R, *_args(s)[2:]), returns=("e", "A", "B"),
                                  where=_where(g) + f", every edge's {side} pose moved by {name} "
                                                    f"{'+' if sign > 0 else '-'}{STEP:g} {DIFFERENCES}"))
    for kind, text in (("zero", "whose residual rotation is exactly 0 (R_i = R_j = R_z = I)"),
                       ("pi", "whose residual rotation is pi - 1e-4 rad")):
        calls.append(Call(target, _args(one_edge(seed, kind)), returns=("e", "A", "B"),
                          where=f"on one edge (M = 1) {text}"))
    return calls


#: the residual rotation of the near-pi edge: within 1e-3 of pi, where Log takes the symmetric part
NEAR_PI = np.pi - 1e-4


@cache
def one_edge(seed=None, kind="zero") -> dict:
    """Two poses and one edge (M = 1): ``kind = "zero"``, every rotation I (the residual rotation exactly
    0: J_r^-1 at 0); ``"pi"``, turned poses and a measurement that leaves a residual rotation of pi - 1e-4."""
    rng = np.random.default_rng(75 if seed is None else [seed, 275])
    t = rng.normal(0, 2.0, (2, 3))
    t_z = rng.normal(0, 2.0, (1, 3))
    if kind == "zero":
        R = np.tile(np.eye(3), (2, 1, 1))
        R_z = np.eye(3)[None]
    else:
        R = exp_many(rng.normal(0, 1.0, (2, 3)))
        axis = rng.normal(size=3)
        residual = exp_many((NEAR_PI * axis / np.linalg.norm(axis))[None])
        R_z = np.matmul(np.matmul(R[:1].transpose(0, 2, 1), R[1:]), residual.transpose(0, 2, 1))
    return {"t": t, "R": R, "edges_i": np.array([0]), "edges_j": np.array([1]), "t_z": t_z, "R_z": R_z}


def _retract_calls(seed=None):
    g = graph(seed)
    rng = np.random.default_rng(7 if seed is None else [seed, 272])
    delta = rng.normal(0, 0.4, (len(g["t"]), 6))
    delta[0] = 0.0
    delta[1, 3:] = [1e-10, 0.0, 0.0]  # the small-angle case
    one = rng.normal(0, 0.4, (1, 6))
    return [Call("pose_graph_3d:retract", (g["t"], g["R"], delta), returns=("t", "R"),
                 where=f"on {len(g['t'])} poses, pose 0's step zero, pose 1's rotation 1e-10 rad"),
            Call("pose_graph_3d:retract", (g["t"][:1], g["R"][:1], one), returns=("t", "R"),
                 where="on one pose (N = 1)")]


def own_differences(ctx, name: str):
    """(M, 6, 6): central differences of the student's own e along each tangent direction of
    the first (``name == "A"``) or second pose; None when a call failed."""
    first = 1 if name == "A" else 13
    columns = []
    for direction in range(6):
        k = first + 2 * direction
        (plus, bad_plus), (minus, bad_minus) = (fields_of(ctx.student[k], ctx.calls[k]),
                                                fields_of(ctx.student[k + 1], ctx.calls[k + 1]))
        if bad_plus or bad_minus or "e" not in plus or "e" not in minus:
            return None
        e_plus, e_minus = np.asarray(plus["e"], float), np.asarray(minus["e"], float)
        if e_plus.shape != e_minus.shape or e_plus.ndim != 2 or e_plus.shape[1] != 6:
            return None
        difference = e_plus - e_minus
        difference[:, 3:] = (difference[:, 3:] + np.pi) % (2 * np.pi) - np.pi  # a Log that jumps at pi
        columns.append(difference / (2 * STEP))
    return np.stack(columns, axis=-1)


def _residual_or_jacobian(name, judge):
    """``common.residual_or_jacobian`` for the edge: its 3x3 blocks, differences of the student's e."""
    return residual_or_jacobian(name, [(text, (slice(None), rows, cols)) for text, rows, cols in BLOCKS], judge,
                                own_differences, "e", "the error check", "error")


_LABELS = {"e": "e[{}]", "A": "A[{}]", "B": "B[{}]", "t": "t[{}]", "R": "R[{}]"}

CHECKS = [
    check(EDGE_ERRORS, "error e", 2, _edge_calls, values(("e",), 1e-8, 1e-10, "e = [R_z^T (R_i^T (t_j - t_i) - t_z); "
                                                                "Log(R_z^T R_i^T R_j)]", _LABELS)),
    check(EDGE_ERRORS, "Jacobian A = de/d delta_i", 3, _edge_calls, _residual_or_jacobian("A", values(
        ("A",), 1e-6, 1e-8, "A = [[-R_z^T, R_z^T [d]x], [0, -J_r^-1(e_phi) R_j^T R_i]] for the right "
                            "perturbation T (Exp(phi), rho)", _LABELS))),
    check(EDGE_ERRORS, "Jacobian B = de/d delta_j", 2, _edge_calls, _residual_or_jacobian("B", values(
        ("B",), 1e-6, 1e-8, "B = [[R_z^T R_i^T R_j, 0], [0, J_r^-1(e_phi)]] for the right perturbation "
                            "T (Exp(phi), rho)", _LABELS))),
    check(RETRACT, "the retraction T (+) delta", 1, _retract_calls, values(
        ("t", "R"), 1e-10, 1e-12, "T (+) (rho, phi) = (R Exp(phi), t + R rho): the step is in the pose's own frame",
        _LABELS)),
]


def _residual_angles(call):
    """The residual rotation angle of each edge of an edge call (from its inputs)."""
    t, R, ei, ej, t_z, R_z = (np.asarray(a) for a in call.args)
    D = np.matmul(R_z.transpose(0, 2, 1), np.matmul(R[ei].transpose(0, 2, 1), R[ej]))
    cos = (np.trace(D, axis1=1, axis2=2) - 1.0) / 2.0
    sin = np.linalg.norm(np.stack([D[:, 2, 1] - D[:, 1, 2], D[:, 0, 2] - D[:, 2, 0], D[:, 1, 0] - D[:, 0, 1]], axis=1),
                         axis=1) / 2.0
    return np.arctan2(sin, cos), D


_E_TARGET = "pose_graph_3d:edge_errors_and_jacobians"
_R_TARGET = "pose_graph_3d:retract"

EDGES = (
    Edge("edge_errors_and_jacobians: one edge (M = 1)", _E_TARGET, lambda c: len(c.args[2]) == 1),
    Edge("edge_errors_and_jacobians: a residual rotation exactly 0 (J_r^-1 at 0)", _E_TARGET,
         lambda c: bool(np.any(np.all(_residual_angles(c)[1] == np.eye(3), axis=(1, 2))))),
    Edge("edge_errors_and_jacobians: a residual rotation of 1e-9 rad (the small-angle branch)", _E_TARGET,
         lambda c: bool(np.any((_residual_angles(c)[0] < 1e-6) & (_residual_angles(c)[0] > 0)))
         if not c.where.endswith(DIFFERENCES) else False),
    Edge("edge_errors_and_jacobians: a residual rotation within 1e-3 of pi (pi - 1e-4)", _E_TARGET,
         lambda c: bool(np.any(_residual_angles(c)[0] > np.pi - 1e-3))),
    Edge("edge_errors_and_jacobians: edges from the larger pose index to the smaller", _E_TARGET,
         lambda c: bool(np.any(np.asarray(c.args[2]) > np.asarray(c.args[3])))),
    Edge("retract: one pose (N = 1)", _R_TARGET, lambda c: len(c.args[0]) == 1),
    Edge("retract: a zero step", _R_TARGET, lambda c: bool(np.any(np.all(np.asarray(c.args[2]) == 0, axis=1)))),
    Edge("retract: a rotation step of 1e-10 rad (the small-angle branch)", _R_TARGET,
         lambda c: bool(np.any((np.linalg.norm(np.asarray(c.args[2])[:, 3:], axis=1) < 1e-6)
                               & (np.linalg.norm(np.asarray(c.args[2])[:, 3:], axis=1) > 0)))),
)
