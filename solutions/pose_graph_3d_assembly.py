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
        # BEGIN SOLUTION
        edges_i, edges_j = np.asarray(edges_i, dtype=np.int64), np.asarray(edges_j, dtype=np.int64)
        if np.any(edges_i == edges_j):
            raise ValueError(f"self-loop edge at index {np.flatnonzero(edges_i == edges_j)[0]}")
        n, m = 6 * num_poses, len(edges_i)
        # global row and column of every entry of the three blocks ``assemble`` computes per edge, laid out as
        # it stores them, (3, M, 6, 6): A^T Omega A, A^T Omega B, B^T Omega B
        local = np.arange(6)
        dof_i, dof_j = 6 * edges_i[:, None] + local, 6 * edges_j[:, None] + local  # (M, 6)
        r = np.broadcast_to(np.stack([dof_i, dof_i, dof_j])[..., None], (3, m, 6, 6))
        c = np.broadcast_to(np.stack([dof_i, dof_j, dof_j])[..., None, :], (3, m, 6, 6))
        # H's upper triangle needs the upper 21 entries of the diagonal blocks and all 36 of A^T Omega B;
        # where pose i comes after pose j, A^T Omega B lies below H's diagonal: store its mirror
        needed = np.ones((3, 1, 6, 6), dtype=bool)
        needed[0, 0] = needed[2, 0] = local[:, None] <= local
        entries = np.flatnonzero(np.broadcast_to(needed, r.shape))  # of the 3 * 36 M computed, 78 M are summed
        rows, cols = np.minimum(r, c).ravel()[entries], np.maximum(r, c).ravel()[entries]
        diagonal = np.arange(n)
        keys = np.concatenate([cols * n + rows, diagonal * n + diagonal])  # CSC order: column, then row
        unique, inverse = unique_inverse(keys)  # np.unique(keys, return_inverse=True), faster here
        positions = inverse[: len(rows)]
        self.diagonal_positions = inverse[len(rows):]
        self._indices = (unique % n).astype(np.int32)  # the index type scipy keeps: no copy per matrix
        self._indptr = np.searchsorted(unique // n, np.arange(n + 1)).astype(np.int32)
        self._shape, self.nnz = (n, n), len(unique)
        # H.data = S @ (the computed entries, raveled): S (nnz, 3 * 36 M) holds a 1 at (position, entry)
        self._sum = sp.csr_matrix((np.ones(len(entries)), (positions, entries)), shape=(self.nnz, 3 * 36 * m))
        self._b_positions = np.concatenate([dof_i, dof_j], axis=1).ravel()
        fixed_dof = np.zeros(n, dtype=bool)
        fixed_dof[(6 * np.asarray(fixed, dtype=np.int64)[:, None] + local).ravel()] = True
        self._fixed_dof = fixed_dof
        self._dead = np.flatnonzero(fixed_dof[self._indices] | np.repeat(fixed_dof, np.diff(self._indptr)))
        self._fixed_diagonal = self.diagonal_positions[fixed_dof]
        # END SOLUTION

    def assemble(self, e, A, B, information):
        """Upper-triangular ``H`` (CSC, (6N, 6N)), ``b`` (6N,) and ``chi2`` (float).

        Args: e (M, 6), A, B (M, 6, 6) from ``pose_graph_3d.edge_errors_and_jacobians``;
        information (M, 6, 6).
        """
        # BEGIN SOLUTION
        # the three blocks H needs, not the whole J^T Omega J (12, 12): a third less to compute and move
        OA, OB = np.matmul(information, A), np.matmul(information, B)  # (M, 6, 6)
        AT, BT = A.transpose(0, 2, 1), B.transpose(0, 2, 1)
        blocks = np.empty((3,) + A.shape)  # batched products into one array: no copies to gather them
        np.matmul(AT, OA, out=blocks[0])
        np.matmul(AT, OB, out=blocks[1])
        np.matmul(BT, OB, out=blocks[2])
        data = self._sum @ blocks.ravel()  # each entry of H.data, the sum of its contributions
        data[self._dead] = 0.0
        data[self._fixed_diagonal] = 1.0
        Oe = np.einsum("mij,mj->mi", information, e)  # Omega e (M, 6)
        g_edges = np.concatenate([np.einsum("mai,ma->mi", A, Oe), np.einsum("mai,ma->mi", B, Oe)],
                                 axis=1).ravel()  # [A^T Omega e, B^T Omega e] (M * 12,)
        b = np.bincount(self._b_positions, weights=g_edges, minlength=self._shape[0])
        b[self._fixed_dof] = 0.0
        chi2 = float(np.vdot(e, Oe))
        H = sp.csc_matrix((data, self._indices, self._indptr), shape=self._shape)
        return H, b, chi2
        # END SOLUTION


#: the derived results, in three levels (``python -m autograder hint NAME LEVEL``; the release
#: prints levels 1..N into the docstrings with ``--hints N``, course.core.hints)
HINTS = {
    "SparseAssembler3D": (
        """Of the three blocks of the module docstring, list the entries H's upper triangle needs, each with
        its global row and column (pose p's dofs are ``6p .. 6p + 5``); add every diagonal entry; number the
        distinct (row, column) pairs in CSC order: that number is the position in ``H.data``. ``assemble``
        computes exactly those entries for all edges, sums them into ``H.data`` by position, and handles
        the fixed poses (zero rows and columns, unit diagonal, zero b).""",
        """The diagonal blocks ``A^T Omega A`` and ``B^T Omega B`` are symmetric: their upper 21 entries
        (``np.triu_indices(6)``) suffice. ``A^T Omega B`` is needed whole (36 entries), ``B^T Omega A`` is its
        transpose and never needed: 21 + 36 + 21 = 78 per edge. Where ``i > j`` the block ``A^T Omega B``
        lies below the diagonal: store entry ``(r, c)`` at ``(min(r, c), max(r, c))``. CSC order is the
        order of the key ``column * 6N + row``; ``np.unique(keys, return_inverse=True)`` gives the sorted
        pattern and each entry's slot. Summing the entries that share a slot is a product with a fixed
        0/1 matrix ``S`` (a row per slot, a column per computed entry), built once as a ``scipy.sparse``
        matrix (``np.bincount(slots, weights)`` sums the same).""",
        """::

            dof_i, dof_j = 6 edges_i + arange(6), 6 edges_j + arange(6)            (M, 6) each
            blocks [A^T Omega A, A^T Omega B, B^T Omega B]                         (3, M, 6, 6)
            r = [dof_i, dof_i, dof_j] down each block's rows, c = [dof_i, dof_j, dof_j] along its columns
            entries = the flat indices of the needed ones: the upper triangle of blocks 0 and 2, all of 1
            rows, cols = minimum(r, c).ravel()[entries], maximum(r, c).ravel()[entries]
            keys = concatenate([cols * 6N + rows, arange(6N) * 6N + arange(6N)])
            unique, inverse = unique_inverse(keys)
            slots, diagonal_positions = inverse[:78 M], inverse[78 M:]
            indices, indptr = unique % 6N, searchsorted(unique // 6N, arange(6N + 1))
            S = csr_matrix((ones(78 M), (slots, entries)), shape=(nnz, 3 * 36 M))
            dead = fixed_dof[indices] | repeat(fixed_dof, diff(indptr))

            assemble:  OA, OB = Omega A, Omega B
                       blocks = [A^T OA, A^T OB, B^T OB]       (matmul, each into its part of one array)
                       data = S @ blocks.ravel()
                       data[dead] = 0;  data[diagonal_positions[fixed_dof]] = 1
                       Oe = Omega e;  b = bincount([dof_i, dof_j].ravel(), [A^T Oe, B^T Oe].ravel(), minlength=6N)
                       b[fixed_dof] = 0;  chi2 = sum_k e_k . Oe_k
                       H = csc_matrix((data, indices, indptr), shape=(6N, 6N))""",
    ),
}
