"""Chapter 2, going further: the pose-graph linearization vectorized over edges.

The reference solver uses this module; an implementation that leaves it unwritten
falls back to the per-edge loop of ``pose_graph_assembly`` (fine for small graphs).

Inputs at the edges of the contract (each is a check input):
- edge_errors_and_jacobians on a single edge (M = 1)
- a raw angle error theta_j - theta_i - theta_ij exactly pi: e_theta = -pi
- SparseAssembler on a single edge (M = 1)
- SparseAssembler with two edges between the same two poses
- SparseAssembler with information diagonal but anisotropic
- SparseAssembler with an edge from a later to an earlier pose (entries mirrored above the diagonal)

Allowed imports: numpy, scipy, course.solver.unique.
"""

import numpy as np
import scipy.sparse as sp

from course.solver.unique import unique_inverse


def edge_errors_and_jacobians(poses, edges_i, edges_j, measurements):
    """All edges at once: ``e`` (M, 3), ``A`` (M, 3, 3), ``B`` (M, 3, 3).

    The error and Jacobians of ``pose_graph_edge.edge_error_and_jacobians`` (its docstring has the
    definitions) for every edge k between ``poses[edges_i[k]]`` and ``poses[edges_j[k]]`` with
    ``measurements[k]``, with no Python loop over edges: write the entries as arrays over the edges
    (``python -m autograder hint pose_graph_fast.edge_errors_and_jacobians 1``, then 2 and 3).
    M >= 1: keep the (M, ...) shapes for a single edge too.
    """
    raise NotImplementedError("TODO pose_graph_fast.edge_errors_and_jacobians: not implemented yet")


class SparseAssembler:
    """Scatter-add edge blocks into the upper triangle of a sparse H, pattern fixed.

    Each edge k contributes ``J_k^T Omega_k J_k`` with ``J_k = [A_k B_k]`` (3, 6) to
    the rows and columns of its two poses; only the 21 entries of the upper triangle
    of that 6x6 matrix are needed. The pattern (upper triangle, CSC, every diagonal
    entry present) and the position in ``H.data`` of every one of those 21 entries
    of every edge are computed once here; ``assemble`` then costs two batched
    products and two ``np.bincount``. Fixed poses get identity blocks and zero rows,
    columns and b.

    Optional attribute ``diagonal_positions`` (3N,): where H's diagonal entries sit in
    ``H.data``, so the LM loop adds its damping in place instead of building H + D.

    Pose p's rows and columns are ``3p .. 3p + 2``. Work out the pattern and the positions from the
    edges' indices alone (``python -m autograder hint SparseAssembler 1``, then 2 and 3);
    ``course.solver.unique.unique_inverse(keys)`` is ``np.unique(keys, return_inverse=True)``, faster
    on keys that come nearly in order.
    """

    #: row and column of the 21 upper-triangle entries of a 6x6 edge block
    UPPER = np.triu_indices(6)

    def __init__(self, num_poses, edges_i, edges_j, fixed):
        raise NotImplementedError("TODO pose_graph_fast.SparseAssembler.__init__: not implemented yet")

    def assemble(self, e, A, B, information):
        """Upper-triangular ``H`` (CSC, (3N, 3N)), ``b`` (3N,) and ``chi2`` from the blocks.

        Args: e (M, 3), A, B (M, 3, 3) from ``edge_errors_and_jacobians``;
        information (M, 3, 3).
        """
        raise NotImplementedError("TODO pose_graph_fast.SparseAssembler.assemble: not implemented yet")
