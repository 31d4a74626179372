"""Checks of ``pose_graph_3d_assembly``: ``SparseAssembler3D`` (H's upper triangle as CSC, b,
chi2 in 6x6 blocks) built once and called twice on the same pattern.

Public inputs: the graph of the ``pose_graph_3d`` checks with poses 0 and 3 fixed, full
(anisotropic, correlated) 6x6 information matrices, and the reference e, A, B at two sets
of poses; then one edge alone, no pose fixed, a diagonal anisotropic information; hidden
inputs: the same kind from the hidden seed.
"""

import dataclasses
from functools import cache

import numpy as np

from autograder.checks import Call
from autograder.checks.common import assembler_judge, check
from autograder.checks.edges import Edge
from autograder.checks.pose_graph_3d import graph as edge_graph
from autograder.checks.pose_graph_3d import one_edge
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


@cache
def one_edge_inputs(seed=None):
    """``(graph, blocks)`` of one edge (M = 1) between two poses, no pose fixed (``fixed = []``), a diagonal
    but anisotropic information (instructor side: inside a calls builder)."""
    from autograder import reference

    g = one_edge(seed, "pi")
    rng = np.random.default_rng(77 if seed is None else [seed, 277])
    information = np.diag(10.0 ** rng.uniform(-1.0, 3.0, 6))[None]
    f = reference.solutions_module("pose_graph_3d").edge_errors_and_jacobians
    rest = (g["edges_i"], g["edges_j"], g["t_z"], g["R_z"])
    moved = se3.retract(g["t"], g["R"], rng.normal(0, 0.1, (2, 6)))
    data = {"num_poses": 2, "edges_i": g["edges_i"], "edges_j": g["edges_j"], "information": information,
            "fixed": []}
    return data, [f(g["t"], g["R"], *rest), f(*moved, *rest)]


TASK = "@autograder.tasks.pose_graph_3d_assembly:assemble_twice"


def _calls(seed=None):
    data, blocks = inputs(seed)
    one, one_blocks = one_edge_inputs(seed)
    return [Call(TASK, (data, blocks), returns="dict",
                 label=ASSEMBLER, where=f"on {len(data['edges_i'])} edges of {data['num_poses']} poses (poses "
                                        f"{FIXED[0]} and {FIXED[1]} fixed, full 6x6 information), assemble called "
                                        "twice with new blocks"),
            Call(TASK, (one, one_blocks), returns="dict", label=ASSEMBLER,
                 where="on one edge (M = 1) between two poses, no pose fixed (fixed = []), a diagonal but anisotropic "
                       "information (1e-1 to 1e3), assemble called twice with new blocks")]


_ONE_CALL = assembler_judge(
    "H[i, i] += A^T Omega A, H[i, j] += A^T Omega B, H[j, j] += B^T Omega B (upper triangle only), "
    "b[i] += A^T Omega e, b[j] += B^T Omega e, fixed poses: identity block, zero b", "PoseGraph3DProblem")


def _judge(ctx):
    """``assembler_judge`` (which judges one call) on each call in turn: the first that loses points."""
    verdict = None
    for k in range(len(ctx.calls)):
        alone = dataclasses.replace(ctx, calls=ctx.calls[k:k + 1], student=ctx.student[k:k + 1],
                                    reference=ctx.reference[k:k + 1], mistakes=ctx.mistakes[k:k + 1])
        verdict = _ONE_CALL(alone)
        if verdict.fraction < 1.0:
            return verdict
    return verdict


CHECKS = [check(ASSEMBLER, "H (upper, CSC), b, chi2 in 6x6 blocks", 3, _calls, _judge)]


def _information(call):
    return np.asarray(call.args[0]["information"], dtype=float)


def _diagonal_anisotropic(call) -> bool:
    info = _information(call)
    diagonal = np.einsum("mii->mi", info)
    off = info - diagonal[:, :, None] * np.eye(6)
    return bool(np.all(off == 0) and np.any(diagonal.max(axis=1) > diagonal.min(axis=1)))


def _full(call) -> bool:
    info = _information(call)
    return bool(np.any(info - np.einsum("mii->mi", info)[:, :, None] * np.eye(6) != 0))


EDGES = (
    Edge("one edge (M = 1)", TASK, lambda c: len(c.args[0]["edges_i"]) == 1),
    Edge("no pose fixed (fixed = [])", TASK, lambda c: len(c.args[0]["fixed"]) == 0),
    Edge("information diagonal but anisotropic", TASK, _diagonal_anisotropic),
    Edge("information full (correlated, positive definite)", TASK, _full),
    Edge("edges from the larger pose index to the smaller (A^T Omega B stored mirrored)", TASK,
         lambda c: bool(np.any(np.asarray(c.args[0]["edges_i"]) > np.asarray(c.args[0]["edges_j"])))),
)
