"""Checks of ``pose_graph_assembly.assemble_normal_equations``, graded alone: the reference
error and Jacobians of every edge stand in for the student's ``pose_graph_edge`` (see
``autograder.tasks.pose_graph_assembly.assemble_with_reference_edges``). H blocks of the
free poses, b and chi2, and the rows and columns of the fixed poses.

Public inputs: a 6-pose, 8-edge graph (one edge from a later to an earlier pose, full
information matrices) with the first pose fixed, with poses 0 and 3 fixed, at other
poses, a 2-pose graph with a single edge, and a 3-pose graph with parallel edges (two from
pose 1 to pose 2, one back) and diagonal anisotropic information; hidden inputs: another
random graph of the same size (its own later-to-earlier edge and second fixed pose), another
one-edge graph and another graph with parallel edges.

Also the graphs the sparse-solve and vectorized checks use (:func:`small_graph`).
"""

from functools import cache

import numpy as np

from autograder.checks import Call, Verdict
from autograder.checks.common import check, failed, wrap
from autograder.checks.edges import Edge
from autograder.feedback import call_fields, compare

MODULES = ("pose_graph_assembly",)
#: the other exercise files its checks import (the edge function, replaced by the reference's blocks)
USES = ("pose_graph_edge",)
ASSEMBLY = "pose_graph_assembly.assemble_normal_equations"

# ---------------------------------------------------------------- inputs


def _information(rng, count):
    info = []
    for _ in range(count):
        L = rng.normal(size=(3, 3)) * (3.0, 3.0, 6.0)
        info.append(L @ L.T + np.diag((2.0, 2.0, 5.0)))
    return np.array(info)


def _graph_from(rng, pairs, num_poses, second_fixed):
    from course.geometry.se2 import between

    truth = np.column_stack([rng.uniform(-3, 3, num_poses), rng.uniform(-3, 3, num_poses),
                             wrap(rng.uniform(-np.pi, np.pi, num_poses))])
    ei, ej = (np.array(v) for v in zip(*pairs))
    z = between(truth[ei], truth[ej]) + rng.normal(size=(len(pairs), 3)) * (0.05, 0.05, 0.03)
    z[:, 2] = wrap(z[:, 2])
    info = _information(rng, len(pairs))
    poses = truth + rng.normal(size=truth.shape) * (0.1, 0.1, 0.05)
    poses[:, 2] = wrap(poses[:, 2])
    poses_b = poses + rng.normal(size=truth.shape) * (0.1, 0.1, 0.05)
    poses_b[:, 2] = wrap(poses_b[:, 2])
    return {"poses": poses, "edges_i": ei, "edges_j": ej, "measurements": z,
            "information": info, "fixed": np.array([0]), "poses_b": poses_b, "second_fixed": second_fixed}


@cache
def small_graph(seed=None):
    """Six poses, eight edges (one from a later to an earlier pose), full information matrices;
    ``poses_b`` other poses, ``second_fixed`` the pose held with pose 0 in the second case."""
    if seed is None:
        pairs = [(0, 1), (1, 2), (2, 3), (3, 4), (4, 5), (0, 3), (5, 2), (1, 4)]
        return _graph_from(np.random.default_rng(7), pairs, 6, 3)
    rng = np.random.default_rng([seed, 211])
    chain = [(k, k + 1) for k in range(5)]
    later = int(rng.integers(3, 6))
    earlier = int(rng.integers(0, later - 1))
    extra = [(later, earlier)]  # from a later to an earlier pose
    while len(extra) < 3:
        i, j = (int(v) for v in sorted(rng.choice(6, 2, replace=False)))
        if j - i > 1 and (i, j) not in extra and (j, i) not in extra:
            extra.append((i, j))
    pairs = chain + extra
    order = rng.permutation(len(pairs))
    return _graph_from(rng, [pairs[k] for k in order], 6, int(rng.integers(2, 6)))


@cache
def one_edge_graph(seed=None):
    """Two poses, one edge from pose 0 to pose 1, the first pose fixed."""
    rng = np.random.default_rng(17 if seed is None else [seed, 213])
    return _graph_from(rng, [(0, 1)], 2, None)


@cache
def parallel_graph(seed=None):
    """Three poses, parallel edges (1 -> 2 twice, 2 -> 1 once), diagonal anisotropic information."""
    rng = np.random.default_rng(19 if seed is None else [seed, 214])
    graph = _graph_from(rng, [(0, 1), (1, 2), (1, 2), (2, 1), (0, 2)], 3, None)
    diagonal = np.sort(rng.uniform(1.0, 20.0, (5, 3)), axis=1) * (1.0, 3.0, 9.0)  # unequal by construction
    graph["information"] = np.array([np.diag(d) for d in diagonal])
    return graph


def graph_at(graph, poses, fixed):
    return {"poses": poses, "edges_i": graph["edges_i"], "edges_j": graph["edges_j"],
            "measurements": graph["measurements"], "information": graph["information"],
            "fixed": np.array(fixed, dtype=np.int64)}


def reference_blocks(graph):
    """Reference (e, A, B) of every edge, stacked (instructor side: inside a calls builder)."""
    from autograder import reference

    edge = reference.solutions_module("pose_graph_edge").edge_error_and_jacobians
    out = [edge(graph["poses"][i], graph["poses"][j], z)
           for i, j, z in zip(graph["edges_i"], graph["edges_j"], graph["measurements"])]
    return tuple(np.array([o[k] for o in out]) for k in range(3))


def _assembly_call(graph, where):
    args = (graph["poses"], graph["edges_i"], graph["edges_j"], graph["measurements"], graph["information"],
            graph["fixed"], reference_blocks(graph))
    return Call("@autograder.tasks.pose_graph_assembly:assemble_with_reference_edges", args, returns="dict",
                label="pose_graph_assembly.assemble_normal_equations", where=where)


@cache
def _assembly_calls(seed=None):
    g = small_graph(seed)
    backwards = [(int(i), int(j)) for i, j in zip(g["edges_i"], g["edges_j"]) if i > j]
    k = next(n for n, (i, j) in enumerate(zip(g["edges_i"], g["edges_j"])) if i > j)
    edge_text = f"edge {k} goes from pose {backwards[0][0]} to pose {backwards[0][1]}"
    second = g["second_fixed"]
    calls = []
    for poses, fixed, what in ((g["poses"], [0], "first pose fixed"),
                               (g["poses"], [0, second], f"poses 0 and {second} fixed"),
                               (g["poses_b"], [0], "first pose fixed, other poses")):
        calls.append(_assembly_call(graph_at(g, poses, fixed), f"on a 6-pose, 8-edge graph ({what}; {edge_text})"))
    one = one_edge_graph(seed)
    calls.append(_assembly_call(graph_at(one, one["poses"], [0]),
                                "on a 2-pose graph with a single edge, from pose 0 to pose 1 (first pose fixed)"))
    par = parallel_graph(seed)
    calls.append(_assembly_call(graph_at(par, par["poses"], [0]),
                                "on a 3-pose graph with parallel edges (1 -> 2 twice, 2 -> 1 once) and diagonal "
                                "anisotropic information (first pose fixed)"))
    return calls


def _calls(seed=None):
    return list(_assembly_calls(seed))


# ---------------------------------------------------------------- judges


def _fixed_dofs(call):
    fixed = call.args[5]
    mask = np.zeros(3 * len(call.args[0]), dtype=bool)
    for k in fixed:
        mask[3 * k:3 * k + 3] = True
    return mask


def _masks(call):
    """(free-free entries of H, fixed rows/columns of H, free entries of b, fixed entries of b)."""
    fd = _fixed_dofs(call)
    free_h = np.outer(~fd, ~fd)
    return free_h, ~free_h, ~fd, fd


def _as_array(x):
    return np.asarray(x, dtype=float)


def _shape_problem(got, n, call):
    H, b = _as_array(got["H"]), _as_array(got["b"])
    if H.shape != (n, n):
        return f"H has shape {H.shape}, expected ({n}, {n}) (3 rows and columns per pose) {call.where}"
    if b.shape != (n,):
        return f"b has shape {b.shape}, expected ({n},) {call.where}"
    if _as_array(got["chi2"]).size != 1:
        return f"chi2 has shape {_as_array(got['chi2']).shape}, expected a number {call.where}"
    return None


def _failed_on(ctx, hints=None):
    """:func:`failed`, saying on which graph the call failed (one graph may break it alone)."""
    verdict = failed(ctx, hints)
    if verdict is None or verdict.not_implemented:
        return verdict
    erred = [call for call, outcome in zip(ctx.calls, ctx.student)
             if outcome.error is not None and outcome.error.kind != "Lost"]
    if erred and erred[0].where:
        verdict.message += f" [{erred[0].where}]"
    return verdict


def _masked(known, key, mask):
    """The known mistakes' full-size values under ``key``, outside ``mask`` zeroed."""
    return [(np.where(mask, np.asarray(value, dtype=float), 0.0), why) for value, why in known.get(key, ())]


def _judge_assembly(part):
    """``part``: "H" (free-free blocks), "b" (b and chi2 of free poses), "fixed" (fixed rows, columns, b).

    The known mistakes (``ctx.known``) are whole H (key ``"H"``), b (``"b"``), chi2
    (``"chi2"``) and, for the fixed poses, ``"fixed_H"`` and ``"fixed_b"``; each part
    compares the entries it grades only.
    """

    def judge(ctx):
        triples, failure = call_fields(ctx, failed=_failed_on)
        if failure:
            return failure
        for index, (call, got, want) in enumerate(triples):
            n = 3 * len(call.args[0])
            problem = _shape_problem(got, n, call)
            if problem:
                return Verdict(0.0, problem)
            H, b, chi2 = _as_array(got["H"]), _as_array(got["b"]), _as_array(got["chi2"]).reshape(())
            free_h, fixed_h, free_b, fixed_b = _masks(call)
            scale_h = float(np.max(np.abs(want["H"])))
            scale_b = float(np.max(np.abs(want["b"])))
            known = ctx.known(index)
            if part == "H":
                text = compare(np.where(free_h, H, 0.0), np.where(free_h, want["H"], 0.0), "H[{}]", 1e-9,
                               1e-10 * scale_h, call.where, _masked(known, "H", free_h),
                               "H[i,i] += A^T Omega A, H[i,j] += A^T Omega B, H[j,i] += B^T Omega A, "
                               "H[j,j] += B^T Omega B over all edges")
                if text:
                    return Verdict(0.0, text)
            elif part == "b":
                text = compare(np.where(free_b, b, 0.0), np.where(free_b, want["b"], 0.0), "b[{}]", 1e-9,
                               1e-10 * scale_b, call.where, _masked(known, "b", free_b),
                               "b[i] += A^T Omega e, b[j] += B^T Omega e")
                if text:
                    return Verdict(0.0, text)
                text = compare(chi2, want["chi2"], "chi2", 1e-9, 0.0, call.where, known.get("chi2", ()),
                               "chi2 = sum e^T Omega e")
                if text:
                    return Verdict(0.0, text)
            else:
                for name, actual, expected, mask, index_text, scale in (
                        ("H", H, want["H"], fixed_h, "H[{}]", scale_h), ("b", b, want["b"], fixed_b, "b[{}]", scale_b)):
                    text = compare(np.where(mask, actual, 0.0), np.where(mask, expected, 0.0), index_text, 1e-9,
                                   1e-10 * scale, f"{call.where}, rows and columns of the fixed poses",
                                   _masked(known, f"fixed_{name}", mask),
                                   "a fixed pose has zero rows and columns in H except an identity diagonal "
                                   "block, and zero b")
                    if text:
                        return Verdict(0.0, text)
        return Verdict(1.0, "ok")

    return judge


CHECKS = [
    check(ASSEMBLY, "H blocks of the free poses", 3, _calls, _judge_assembly("H")),
    check(ASSEMBLY, "b and chi2", 2, _calls, _judge_assembly("b")),
    check(ASSEMBLY, "fixed poses (first pose, and poses 0 and 3)", 2, _calls, _judge_assembly("fixed")),
]


TARGET = "@autograder.tasks.pose_graph_assembly:assemble_with_reference_edges"


def _off_diagonal(information):
    return information - information * np.eye(3)


EDGES = (
    Edge("a 2-pose graph with a single edge (M = 1), the first pose fixed", TARGET,
         lambda call: len(call.args[1]) == 1 and len(call.args[0]) == 2),
    Edge("an edge from a later to an earlier pose (i > j)", TARGET,
         lambda call: bool(np.any(call.args[1] > call.args[2]))),
    Edge("two edges between the same two poses (their blocks add up)", TARGET,
         lambda call: len({frozenset((int(i), int(j))) for i, j in zip(*call.args[1:3])}) < len(call.args[1])),
    Edge("information diagonal but anisotropic", TARGET,
         lambda call: not np.any(_off_diagonal(call.args[4]))
         and bool(np.any(np.ptp(np.diagonal(call.args[4], axis1=1, axis2=2), axis=1) > 0))),
    Edge("information full (not diagonal)", TARGET,
         lambda call: bool(np.all(np.any(_off_diagonal(call.args[4]), axis=(1, 2))))),
    Edge("a fixed pose other than the first", TARGET, lambda call: bool(np.any(np.asarray(call.args[5]) != 0))),
)
