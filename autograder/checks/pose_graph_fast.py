"""Checks of the optional vectorized linearization ``pose_graph_fast``: the errors and
Jacobians of all edges at once, and ``SparseAssembler`` (H's upper triangle as CSC, b,
chi2) called twice on the same pattern.

Public inputs: the 6-pose graph of the assembly checks with poses 0 and 3 fixed, and its
second set of poses; at the edges, the one-edge graph of the assembly checks (M = 1; for the
edges, with theta_j - theta_i - theta_ij exactly pi) and its graph with parallel edges and
diagonal anisotropic information (the assembler); hidden inputs: the hidden graphs of the
assembly checks. For the edges, one edge's theta_j - theta_i - theta_ij leaves [-pi, pi)
(where none does, the last edge's measured angle is written 2 pi larger).
"""

import numpy as np

from autograder.checks import Call
from autograder.checks.common import angles_as_reference, assembler_judge, check, values
from autograder.checks.edges import Edge
from autograder.checks.pose_graph_assembly import (
    graph_at,
    one_edge_graph,
    parallel_graph,
    reference_blocks,
    small_graph,
)
from autograder.checks.pose_graph_edge import exact_edge

MODULES = ("pose_graph_fast",)
#: the other exercise files its checks run (the per-edge loop, named in a stub's feedback)
USES = ("pose_graph_assembly",)
FAST_EDGES = "pose_graph_fast.edge_errors_and_jacobians"
FAST_ASSEMBLER = "pose_graph_fast.SparseAssembler"


def _fast_graph(seed=None, poses="poses"):
    g = small_graph(seed)
    return graph_at(g, g[poses], [0, g["second_fixed"]])


def _where(seed, text=""):
    g = small_graph(seed)
    return f"on the {len(g['edges_i'])} edges of the 6-pose graph (poses 0 and {g['second_fixed']} fixed){text}"


def _fast_edge_calls(seed=None):
    graph = dict(_fast_graph(seed))
    poses, z = graph["poses"], graph["measurements"].copy()
    raw = poses[graph["edges_j"], 2] - poses[graph["edges_i"], 2] - z[:, 2]
    if not np.any(np.abs(raw) >= np.pi):  # the last edge's angle written 2 pi larger: the same measurement
        z[-1, 2] += 2.0 * np.pi
        raw[-1] -= 2.0 * np.pi
    graph["measurements"] = z
    wrapped = tuple(int(k) for k in np.flatnonzero(np.abs(raw) >= np.pi))
    groups = {"whose theta_j - theta_i - theta_ij leaves [-pi, pi), so e_theta must be wrapped": wrapped}
    calls = [Call("@autograder.tasks.pose_graph_fast:fast_edges", (graph,), returns="dict",
                  label="pose_graph_fast.edge_errors_and_jacobians", where=_where(seed), groups=groups)]
    one = one_edge_graph(seed)  # M = 1, its angles those of an edge whose raw angle error is exactly pi
    rng = np.random.default_rng(23 if seed is None else [seed, 221])
    theta_i, theta_j, theta_ij = (v[2] for v in exact_edge(rng, np.pi)[:3])
    single = dict(graph_at(one, one["poses"].copy(), [0]))
    single["poses"][:, 2] = (theta_i, theta_j)
    single["measurements"] = one["measurements"].copy()
    single["measurements"][0, 2] = theta_ij
    calls.append(Call("@autograder.tasks.pose_graph_fast:fast_edges", (single,), returns="dict",
                      label="pose_graph_fast.edge_errors_and_jacobians",
                      where="on the single edge of a 2-pose graph (M = 1), theta_j - theta_i - theta_ij = pi exactly",
                      groups={"whose theta_j - theta_i - theta_ij is exactly pi, so e_theta = -pi": (0,)}))
    return calls


def _fast_assembler_calls(seed=None):
    graph = _fast_graph(seed)
    blocks = [reference_blocks(graph), reference_blocks(_fast_graph(seed, "poses_b"))]
    calls = [Call("@autograder.tasks.pose_graph_fast:fast_assemble", (graph, blocks), returns="dict",
                  label="pose_graph_fast.SparseAssembler",
                  where=_where(seed, ", assemble called twice with new blocks"))]
    for g, text in ((one_edge_graph(seed), "a 2-pose graph with a single edge (M = 1)"),
                    (parallel_graph(seed), "a 3-pose graph with parallel edges (1 -> 2 twice, 2 -> 1 once) and "
                                           "diagonal anisotropic information")):
        graph = graph_at(g, g["poses"], [0])
        blocks = [reference_blocks(graph), reference_blocks(graph_at(g, g["poses_b"], [0]))]
        calls.append(Call("@autograder.tasks.pose_graph_fast:fast_assemble", (graph, blocks), returns="dict",
                          label="pose_graph_fast.SparseAssembler",
                          where=f"on {text} (first pose fixed), assemble called twice with new blocks"))
    return calls


CHECKS = [
    check(FAST_EDGES, "e, A, B of all edges", 1, _fast_edge_calls,
          values(("e", "A", "B"), 1e-9, 1e-12, "the same e, A, B as pose_graph_edge, edge by edge",
                 equivalent={"e": angles_as_reference(2)}),  # at pi: -pi or +pi, the same angle
          exact_inputs=True),  # an edge at exactly +-pi, written to be exact (autograder.rounding)
    check(FAST_ASSEMBLER, "H (upper, CSC), b, chi2", 1, _fast_assembler_calls,
          assembler_judge("the same H (upper triangle), b and chi2 as the per-edge loop", "PoseGraphProblem")),
]


EDGES_TASK = "@autograder.tasks.pose_graph_fast:fast_edges"
ASSEMBLER_TASK = "@autograder.tasks.pose_graph_fast:fast_assemble"


def _graph(call):
    return call.args[0]


def _raw(graph):
    poses, z = graph["poses"], graph["measurements"]
    return poses[graph["edges_j"], 2] - poses[graph["edges_i"], 2] - z[:, 2]


def _pairs(graph):
    return {frozenset((int(i), int(j))) for i, j in zip(graph["edges_i"], graph["edges_j"])}


EDGES = (
    Edge("edge_errors_and_jacobians on a single edge (M = 1)", EDGES_TASK,
         lambda call: len(_graph(call)["edges_i"]) == 1),
    Edge("a raw angle error theta_j - theta_i - theta_ij exactly pi: e_theta = -pi", EDGES_TASK,
         lambda call: bool(np.any(_raw(_graph(call)) == np.pi))),
    Edge("SparseAssembler on a single edge (M = 1)", ASSEMBLER_TASK, lambda call: len(_graph(call)["edges_i"]) == 1),
    Edge("SparseAssembler with two edges between the same two poses", ASSEMBLER_TASK,
         lambda call: len(_pairs(_graph(call))) < len(_graph(call)["edges_i"])),
    Edge("SparseAssembler with information diagonal but anisotropic", ASSEMBLER_TASK,
         lambda call: not np.any(_graph(call)["information"] * (1 - np.eye(3)))
         and bool(np.any(np.ptp(np.diagonal(_graph(call)["information"], axis1=1, axis2=2), axis=1) > 0))),
    Edge("SparseAssembler with an edge from a later to an earlier pose (entries mirrored above the diagonal)",
         ASSEMBLER_TASK, lambda call: bool(np.any(_graph(call)["edges_i"] > _graph(call)["edges_j"]))),
)
