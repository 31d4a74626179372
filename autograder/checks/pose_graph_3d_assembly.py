"""Checks of ``pose_graph_3d_assembly``: ``SparseAssembler3D`` (H's upper triangle as CSC, b,
chi2 in 6x6 blocks) built once and called twice on the same pattern.

Public inputs: the graph of the ``pose_graph_3d`` checks with poses 0 and 3 fixed, full
(anisotropic, correlated) 6x6 information matrices, and the reference e, A, B at two sets
of poses; hidden inputs: the same kind from the hidden seed.
"""

from functools import cache

import numpy as np

from autograder.checks import Call
from autograder.checks.common import assembler_judge, check
from autograder.checks.pose_graph_3d import graph as edge_graph
from course.geometry import se3

MODULES = ("pose_graph_3d_assembly",)
ASSEMBLER = "pose_graph_3d_assembly.SparseAssembler3D"
FIXED = (0, 3)


@cache
def inputs(seed=None):
    """``(graph, blocks)``: the assembly's graph (plain arrays) and the reference ``(e, A, B)``
    at two sets of poses (instructor side: inside a calls builder)."""
    from autograder import reference

    g = edge_graph(seed)
    rng = np.random.default_rng(73 if seed is None else [seed, 273])
    m = len(g["edges_i"])
    L = rng.normal(0, 1.0, (m, 6, 6)) + np.eye(6) * rng.uniform(1.0, 4.0, (m, 6, 1))
    information = np.matmul(L, L.transpose(0, 2, 1))  # full, correlated, positive definite
    f = reference.solutions_module("pose_graph_3d").edge_errors_and_jacobians
    rest = (g["edges_i"], g["edges_j"], g["t_z"], g["R_z"])
    moved = se3.retract(g["t"], g["R"], rng.normal(0, 0.1, (len(g["t"]), 6)))
    blocks = [f(g["t"], g["R"], *rest), f(*moved, *rest)]
    data = {"num_poses": len(g["t"]), "edges_i": g["edges_i"], "edges_j": g["edges_j"],
            "information": information, "fixed": np.array(FIXED)}
    return data, blocks


def _calls(seed=None):
    data, blocks = inputs(seed)
    return [Call("@autograder.tasks.pose_graph_3d_assembly:assemble_twice", (data, blocks), returns="dict",
                 label=ASSEMBLER, where=f"on {len(data['edges_i'])} edges of {data['num_poses']} poses (poses "
                                        f"{FIXED[0]} and {FIXED[1]} fixed, full 6x6 information), assemble called "
                                        "twice with new blocks")]


CHECKS = [check(ASSEMBLER, "H (upper, CSC), b, chi2 in 6x6 blocks", 3, _calls, assembler_judge(
    "H[i, i] += A^T Omega A, H[i, j] += A^T Omega B, H[j, j] += B^T Omega B (upper triangle only), "
    "b[i] += A^T Omega e, b[j] += B^T Omega e, fixed poses: identity block, zero b", "PoseGraph3DProblem"))]
