"""Chapter 6 exercise: the normal equations of a 3D pose graph, assembled in 6x6 blocks into
a sparsity pattern computed once.

Edge k (``i -> j``) contributes, with ``J_k = [A_k  B_k]`` (6, 12) and ``Omega_k`` (6, 6)::

    H[i, i] += A^T Omega A    H[i, j] += A^T Omega B    H[j, j] += B^T Omega B
    b[i]    += A^T Omega e    b[j]    += B^T Omega e    chi2    += e^T Omega e

(blocks of 6 rows and columns: pose p's are ``6p .. 6p + 5``, translation then rotation).
Only H's upper triangle is stored (CSC, diagonal included), as in chapter 2. A fixed pose
keeps an identity diagonal block and zero rows, columns and b, so its step is zero.

Inputs at the edges of the contract (each is a check input):
- one edge (M = 1)
- no pose fixed (fixed = [])
- information diagonal but anisotropic
- information full (correlated, positive definite)
- edges from the larger pose index to the smaller (A^T Omega B stored mirrored)

Allowed imports: numpy, scipy, course.solver.unique.
"""

import numpy as np
import scipy.sparse as sp

from course.solver.unique import unique_inverse


class SparseAssembler3D:
    """Scatter-add edge blocks into the upper triangle of a sparse H whose pattern is fixed.

    ``__init__`` finds, once, the pattern of H's upper triangle (every diagonal entry present) and
    where in ``H.data`` each entry of each edge's blocks that the upper triangle needs goes;
    ``assemble`` then costs batched products and one sum into those places (a sparse product). Which entries of
    ``J^T Omega J`` (12, 12) are needed, and where do they go? Derive it from the edges' indices
    (``python -m autograder hint SparseAssembler3D 1``, then 2 and 3).

    Args of ``__init__``: ``num_poses``, ``edges_i``, ``edges_j`` (M,) int, ``fixed`` the indices of the
    fixed poses (a sequence of ints, possibly empty).

    Attribute ``diagonal_positions`` (6N,): where H's diagonal entries sit in ``H.data``
    (the LM loop adds its damping there).

    ``course.solver.unique.unique_inverse(keys)`` is ``np.unique(keys, return_inverse=True)``,
    faster on keys that come nearly in order.
    """

    #: row and column of the 21 upper-triangle entries of a 6x6 block
    UPPER = np.triu_indices(6)

    def __init__(self, num_poses, edges_i, edges_j, fixed):
        raise NotImplementedError("TODO pose_graph_3d_assembly.SparseAssembler3D.__init__: not implemented yet")

    def assemble(self, e, A, B, information):
        """Upper-triangular ``H`` (CSC, (6N, 6N)), ``b`` (6N,) and ``chi2`` (float).

        Args: e (M, 6), A, B (M, 6, 6) from ``pose_graph_3d.edge_errors_and_jacobians``;
        information (M, 6, 6).
        """
        raise NotImplementedError("TODO pose_graph_3d_assembly.SparseAssembler3D.assemble: not implemented yet")
