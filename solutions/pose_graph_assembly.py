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
    # BEGIN SOLUTION
    n = 3 * len(poses)
    H = np.zeros((n, n))
    b = np.zeros(n)
    chi2 = 0.0
    for i, j, z, omega in zip(edges_i, edges_j, measurements, information):
        e, A, B = pose_graph_edge.edge_error_and_jacobians(poses[i], poses[j], z)
        si, sj = slice(3 * i, 3 * i + 3), slice(3 * j, 3 * j + 3)
        H[si, si] += A.T @ omega @ A
        H[si, sj] += A.T @ omega @ B
        H[sj, si] += B.T @ omega @ A
        H[sj, sj] += B.T @ omega @ B
        b[si] += A.T @ omega @ e
        b[sj] += B.T @ omega @ e
        chi2 += e @ omega @ e
    for k in fixed:
        sk = slice(3 * k, 3 * k + 3)
        H[sk, :] = 0.0
        H[:, sk] = 0.0
        H[sk, sk] = np.eye(3)
        b[sk] = 0.0
    return H, b, float(chi2)
    # END SOLUTION


#: the derived results, in three levels (``python -m autograder hint NAME LEVEL``; the release
#: prints levels 1..N into the docstrings with ``--hints N``, course.core.hints)
HINTS = {
    "assemble_normal_equations": (
        """Write one edge's rows of J as a block row ``J_k = [0 ... A ... B ... 0]`` (A at pose i, B at
        pose j) and multiply out ``J_k^T Omega J_k`` and ``J_k^T Omega e`` block by block; H and b are
        the sums over the edges.""",
        """``(J_k^T Omega J_k)[p, q] = J_k[:, p]^T Omega J_k[:, q]``, nonzero only for p, q in {i, j}.""",
        """::

            H[i,i] += A^T Omega A    H[i,j] += A^T Omega B
            H[j,i] += B^T Omega A    H[j,j] += B^T Omega B
            b[i]   += A^T Omega e    b[j]   += B^T Omega e       chi2 += e^T Omega e""",
    ),
}
