"""Chapter 6 exercise: the normal equations of a 3D pose graph, assembled in 6x6 blocks into
a sparsity pattern computed once.

Edge k (``i -> j``) contributes, with ``J_k = [A_k  B_k]`` (6, 12) and ``Omega_k`` (6, 6)::

    H[i, i] += A^T Omega A    H[i, j] += A^T Omega B    H[j, j] += B^T Omega B
    b[i]    += A^T Omega e    b[j]    += B^T Omega e    chi2    += e^T Omega e

(blocks of 6 rows and columns: pose p's are ``6p .. 6p + 5``, translation then rotation).
Only H's upper triangle is stored (CSC, diagonal included), as in chapter 2. A fixed pose
keeps an identity diagonal block and zero rows, columns and b, so its step is zero.
"""

import numpy as np
import scipy.sparse as sp


class SparseAssembler3D:
    """Scatter-add edge blocks into the upper triangle of a sparse H whose pattern is fixed.

    ``__init__`` finds, once, where each edge's entries go: for every edge, the position in
    ``H.data`` of each of the 144 entries of ``J^T Omega J`` (12, 12) that lands in the
    upper triangle (78 of them: 21 + 21 on the two diagonal blocks, 36 off it), and the
    pattern itself. ``assemble`` then costs batched products and one ``np.bincount``.

    Attribute ``diagonal_positions`` (6N,): where H's diagonal entries sit in ``H.data``
    (the LM loop adds its damping there).
    """

    def __init__(self, num_poses, edges_i, edges_j, fixed):
        # BEGIN SOLUTION
        edges_i, edges_j = np.asarray(edges_i, dtype=np.int64), np.asarray(edges_j, dtype=np.int64)
        if np.any(edges_i == edges_j):
            raise ValueError(f"self-loop edge at index {np.flatnonzero(edges_i == edges_j)[0]}")
        n = 6 * num_poses
        # global row and column of the 12 x 12 entries of every edge
        local = np.arange(6)
        dof = np.concatenate([6 * edges_i[:, None] + local, 6 * edges_j[:, None] + local], axis=1)  # (M, 12)
        # (M, 144): entry (a, b) at a * 12 + b, put at row dof[b] and column dof[a] (the block is
        # symmetric), so that an edge's entries come column by column, nearly in CSC order
        rows = np.tile(dof, (1, 12))
        cols = np.repeat(dof, 12, axis=1)
        upper = rows <= cols  # 78 per edge
        self._take = np.flatnonzero(upper)  # where in the flattened (M * 144) products
        diagonal = np.arange(n)
        keys = np.concatenate([(cols * n + rows).ravel()[self._take], diagonal * n + diagonal])  # CSC order
        # np.unique(keys, return_inverse=True), written out: on keys that come nearly in order,
        # numpy's stable sort is several times faster than the sort np.unique uses
        order = np.argsort(keys, kind="stable")
        first = np.concatenate([[True], np.diff(keys[order]) != 0])
        unique, inverse = keys[order][first], np.empty(len(keys), dtype=np.int64)
        inverse[order] = np.cumsum(first) - 1
        self._positions = inverse[: len(self._take)]
        self.diagonal_positions = inverse[len(self._take):]
        self._indices = unique % n
        self._indptr = np.searchsorted(unique // n, np.arange(n + 1))
        self._shape, self.nnz = (n, n), len(unique)
        self._b_positions = dof.ravel()
        fixed_dof = np.zeros(n, dtype=bool)
        fixed_dof[(6 * np.asarray(fixed, dtype=np.int64)[:, None] + local).ravel()] = True
        self._fixed_dof = fixed_dof
        self._dead = fixed_dof[self._indices] | np.repeat(fixed_dof, np.diff(self._indptr))
        self._fixed_diagonal = self.diagonal_positions[fixed_dof]
        # END SOLUTION

    def assemble(self, e, A, B, information):
        """Upper-triangular ``H`` (CSC, (6N, 6N)), ``b`` (6N,) and ``chi2`` (float).

        Args: e (M, 6), A, B (M, 6, 6) from ``pose_graph_3d.edge_errors_and_jacobians``;
        information (M, 6, 6).
        """
        # BEGIN SOLUTION
        J = np.concatenate([A, B], axis=2)  # (M, 6, 12)
        OJ = np.matmul(information, J)  # (M, 6, 12); Omega symmetric: J^T Omega = (Omega J)^T
        H_edges = np.einsum("mai,maj->mij", J, OJ, optimize=True).ravel()[self._take]  # J^T Omega J (M, 12, 12)
        g_edges = np.einsum("mai,ma->mi", OJ, e).ravel()  # J^T Omega e (M, 12)
        data = np.bincount(self._positions, weights=H_edges, minlength=self.nnz)
        data[self._dead] = 0.0
        data[self._fixed_diagonal] = 1.0
        b = np.bincount(self._b_positions, weights=g_edges, minlength=self._shape[0])
        b[self._fixed_dof] = 0.0
        chi2 = float(np.einsum("mi,mij,mj->", e, information, e))
        H = sp.csc_matrix((data, self._indices, self._indptr), shape=self._shape)
        return H, b, chi2
        # END SOLUTION
