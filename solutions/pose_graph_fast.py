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
"""

import numpy as np
import scipy.sparse as sp

from course.solver.unique import unique_inverse


def edge_errors_and_jacobians(poses, edges_i, edges_j, measurements):
    """All edges at once: ``e`` (M, 3), ``A`` (M, 3, 3), ``B`` (M, 3, 3).

    Same formulas as ``pose_graph_edge.edge_error_and_jacobians``, with no Python
    loop over edges. Note ``R_ij^T R_i^T = R(theta_i + theta_ij)^T``.
    M >= 1: keep the (M, ...) shapes for a single edge too.
    """
    # BEGIN SOLUTION
    xi, xj = poses[edges_i], poses[edges_j]
    ci, si = np.cos(xi[:, 2]), np.sin(xi[:, 2])
    cz, sz = np.cos(measurements[:, 2]), np.sin(measurements[:, 2])
    dx, dy = xj[:, 0] - xi[:, 0], xj[:, 1] - xi[:, 1]
    # R_i^T dt and its derivative in theta_i
    u, v = ci * dx + si * dy, -si * dx + ci * dy
    du, dv = v, -u
    m = len(edges_i)
    e = np.empty((m, 3))
    tx, ty = u - measurements[:, 0], v - measurements[:, 1]
    e[:, 0] = cz * tx + sz * ty
    e[:, 1] = -sz * tx + cz * ty
    e[:, 2] = (xj[:, 2] - xi[:, 2] - measurements[:, 2] + np.pi) % (2.0 * np.pi) - np.pi
    c, s = np.cos(xi[:, 2] + measurements[:, 2]), np.sin(xi[:, 2] + measurements[:, 2])
    B = np.zeros((m, 3, 3))
    B[:, 0, 0], B[:, 0, 1], B[:, 1, 0], B[:, 1, 1], B[:, 2, 2] = c, s, -s, c, 1.0
    A = -B
    A[:, 0, 2] = cz * du + sz * dv
    A[:, 1, 2] = -sz * du + cz * dv
    return e, A, B
    # END SOLUTION


class SparseAssembler:
    """Scatter-add edge blocks into the upper triangle of a sparse H, pattern fixed.

    Each edge k contributes ``J_k^T Omega_k J_k`` with ``J_k = [A_k B_k]`` (3, 6) to
    the rows and columns of its two poses; only the 21 entries of the upper triangle
    of that 6x6 matrix are needed. The pattern (upper triangle, CSC, every diagonal
    entry present) and the position in ``H.data`` of every one of those 21 entries
    of every edge are computed once here; ``assemble`` then costs two batched
    products and one ``np.bincount``. Fixed poses get identity blocks and zero rows,
    columns and b.

    Optional attribute ``diagonal_positions`` (3N,): where H's diagonal entries sit in
    ``H.data``, so the LM loop adds its damping in place instead of building H + D.

    Hint: give every entry a CSC key (column * 3N + row) and keep the distinct keys with
    ``np.unique(keys, return_inverse=True)``, or ``course.solver.unique.unique_inverse(keys)``,
    the same and faster on keys that come nearly in order.
    """

    #: row and column of the 21 upper-triangle entries of a 6x6 edge block
    UPPER = np.triu_indices(6)

    def __init__(self, num_poses, edges_i, edges_j, fixed):
        # BEGIN SOLUTION
        edges_i, edges_j = np.asarray(edges_i, dtype=np.int64), np.asarray(edges_j, dtype=np.int64)
        if np.any(edges_i == edges_j):
            raise ValueError(f"self-loop edge at index {np.flatnonzero(edges_i == edges_j)[0]}")
        n = 3 * num_poses
        # global row and column of the 21 upper entries (a, b), a <= b, of every edge's 6x6 block;
        # where pose i comes after pose j the entry lies below H's diagonal: store its mirror
        dof = np.concatenate([3 * edges_i[:, None] + np.arange(3), 3 * edges_j[:, None] + np.arange(3)], axis=1)
        r, c = dof[:, self.UPPER[0]], dof[:, self.UPPER[1]]  # (M, 21)
        rows, cols = np.minimum(r, c).ravel(), np.maximum(r, c).ravel()
        diagonal = np.arange(n)
        keys = np.concatenate([cols * n + rows, diagonal * n + diagonal])  # CSC order: column, then row
        unique, inverse = unique_inverse(keys)  # np.unique(keys, return_inverse=True), faster here
        self._positions = inverse[: len(rows)]
        self.diagonal_positions = inverse[len(rows):]
        self._indices = unique % n
        self._indptr = np.searchsorted(unique // n, np.arange(n + 1))
        self._shape, self.nnz = (n, n), len(unique)
        self._b_positions = dof.ravel()
        fixed_dof = np.zeros(n, dtype=bool)
        fixed_dof[(3 * np.asarray(fixed, dtype=np.int64)[:, None] + np.arange(3)).ravel()] = True
        self._fixed_dof = fixed_dof
        self._dead = fixed_dof[self._indices] | np.repeat(fixed_dof, np.diff(self._indptr))
        self._fixed_diagonal = self.diagonal_positions[fixed_dof]
        # END SOLUTION

    def assemble(self, e, A, B, information):
        """Upper-triangular ``H`` (CSC, (3N, 3N)), ``b`` (3N,) and ``chi2`` from the blocks.

        Args: e (M, 3), A, B (M, 3, 3) from ``edge_errors_and_jacobians``;
        information (M, 3, 3).
        """
        # BEGIN SOLUTION
        J = np.concatenate([A, B], axis=2)
        JT = J.transpose(0, 2, 1)
        H_edges = np.matmul(np.matmul(JT, information), J)[:, self.UPPER[0], self.UPPER[1]]
        Oe = np.matmul(information, e[:, :, None])  # (M, 3, 1)
        g_edges = np.matmul(JT, Oe)
        data = np.bincount(self._positions, weights=H_edges.ravel(), minlength=self.nnz)
        data[self._dead] = 0.0
        data[self._fixed_diagonal] = 1.0
        b = np.bincount(self._b_positions, weights=g_edges.ravel(), minlength=self._shape[0])
        b[self._fixed_dof] = 0.0
        chi2 = float(np.vdot(e, Oe))
        H = sp.csc_matrix((data, self._indices, self._indptr), shape=self._shape)
        return H, b, chi2
        # END SOLUTION
