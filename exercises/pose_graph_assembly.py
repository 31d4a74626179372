"""Chapter 2 exercise: assemble H and b over all edges, one edge at a time.

Inputs at the edges of the contract (each is a check input):
- a 2-pose graph with a single edge (M = 1), the first pose fixed
- an edge from a later to an earlier pose (i > j)
- two edges between the same two poses (their blocks add up)
- information diagonal but anisotropic
- information full (not diagonal)
- a fixed pose other than the first

Allowed imports: numpy, scipy, .pose_graph_edge.
"""

import numpy as np

from . import pose_graph_edge


def assemble_normal_equations(poses, edges_i, edges_j, measurements, information, fixed):
    """Dense ``H`` (3N, 3N), ``b`` (3N,) and ``chi2`` of a pose graph, edge by edge.

    ``H = J^T Omega J``, ``b = J^T Omega e`` and ``chi2 = e^T Omega e`` summed over the edges, where edge
    k from pose i to pose j has ``e, A, B`` from ``pose_graph_edge.edge_error_and_jacobians`` and
    ``Omega = information[k]``: its rows of the Jacobian J are zero but for A in pose i's three
    columns and B in pose j's. Derive which 3x3 blocks of H and 3-blocks of b one edge adds to, and
    what (``python -m autograder hint assemble_normal_equations``); ``H[i,j]`` is the 3x3 block at
    rows ``3i:3i+3``, columns ``3j:3j+3``.
    Then hold every pose in ``fixed`` still: zero its rows and columns of H and its
    entries of b, and put the identity on its diagonal block, so that its step is 0.

    Args:
        poses: (N, 3), N >= 2; edges_i, edges_j: (M,) int, M >= 1, i != j, in either order, two
        edges may join the same poses; measurements: (M, 3); information: (M, 3, 3) symmetric
        positive definite; fixed: (K,) int indices of fixed poses.
    """
    raise NotImplementedError("TODO pose_graph_assembly.assemble_normal_equations: not implemented yet")
