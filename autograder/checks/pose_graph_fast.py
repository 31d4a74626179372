"""Checks of the optional vectorized linearization ``pose_graph_fast``: the errors and
Jacobians of all edges at once, and ``SparseAssembler`` (H's upper triangle as CSC, b,
chi2) called twice on the same pattern.

Public inputs: the 6-pose graph of the assembly checks with poses 0 and 3 fixed, and its
second set of poses; hidden inputs: the hidden graph of the assembly checks. For the edges,
one edge's theta_j - theta_i - theta_ij leaves [-pi, pi) (where none does, the last edge's
measured angle is written 2 pi larger).
"""

import numpy as np

from autograder.checks import Call
from autograder.checks.common import assembler_judge, check, values
from autograder.checks.pose_graph_assembly import graph_at, reference_blocks, small_graph

MODULES = ("pose_graph_fast",)
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
    return [Call("@autograder.tasks.pose_graph_fast:fast_edges", (graph,), returns="dict",
                 label="pose_graph_fast.edge_errors_and_jacobians", where=_where(seed), groups=groups)]


def _fast_assembler_calls(seed=None):
    graph = _fast_graph(seed)
    blocks = [reference_blocks(graph), reference_blocks(_fast_graph(seed, "poses_b"))]
    return [Call("@autograder.tasks.pose_graph_fast:fast_assemble", (graph, blocks), returns="dict",
                 label="pose_graph_fast.SparseAssembler",
                 where=_where(seed, ", assemble called twice with new blocks"))]


CHECKS = [
    check(FAST_EDGES, "e, A, B of all edges (optional)", 1, _fast_edge_calls,
          values(("e", "A", "B"), 1e-9, 1e-12, "the same e, A, B as pose_graph_edge, edge by edge")),
    check(FAST_ASSEMBLER, "H (upper, CSC), b, chi2 (optional)", 1, _fast_assembler_calls,
          assembler_judge("the same H (upper triangle), b and chi2 as the per-edge loop", "PoseGraphProblem")),
]
