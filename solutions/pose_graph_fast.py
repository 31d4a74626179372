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
        # scipy keeps 32-bit indices where they fit: given them, csc_matrix neither scans nor copies
        index = np.int32 if max(n, len(unique)) < np.iinfo(np.int32).max else np.int64
        self._indices = (unique % n).astype(index)
        self._indptr = np.searchsorted(unique // n, np.arange(n + 1)).astype(index)
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
        # one product gives all three: with K = [A B e] (M, 3, 7), K^T Omega K = [[J^T Omega J, J^T Omega e],
        # [e^T Omega J, e^T Omega e]] (fr079: 0.22 against 0.26 ms for J^T Omega J and J^T (Omega e) apart)
        K = np.concatenate([A, B, e[:, :, None]], axis=2)
        KOK = np.matmul(K.transpose(0, 2, 1), np.matmul(information, K))  # (M, 7, 7)
        # the 21 upper entries of J^T Omega J, taken from the flat 7x7 blocks: a contiguous (M, 21), which
        # KOK[:, UPPER[0], UPPER[1]] is not (its ravel below would copy it: fr079 0.02 against 0.06 ms)
        H_edges = KOK.reshape(-1, 49).take(7 * self.UPPER[0] + self.UPPER[1], axis=1)
        g_edges = KOK[:, :6, 6]
        data = np.bincount(self._positions, weights=H_edges.ravel(), minlength=self.nnz)
        data[self._dead] = 0.0
        data[self._fixed_diagonal] = 1.0
        b = np.bincount(self._b_positions, weights=g_edges.ravel(), minlength=self._shape[0])
        b[self._fixed_dof] = 0.0
        chi2 = float(KOK[:, 6, 6].sum())
        H = sp.csc_matrix((data, self._indices, self._indptr), shape=self._shape)
        return H, b, chi2
        # END SOLUTION


#: the derived results, in three levels (``python -m autograder hint NAME LEVEL``; the release
#: prints levels 1..N into the docstrings with ``--hints N``, course.core.hints)
HINTS = {
    "edge_errors_and_jacobians": (
        """Gather the two poses of every edge (``poses[edges_i]``, ``poses[edges_j]``, (M, 3)), compute the
        cosines and sines once as (M,) arrays, and fill the (M, 3) and (M, 3, 3) outputs entry by entry
        (``A[:, 0, 2] = ...``). Products of 2x2 rotations collapse to one rotation of the summed angle.""",
        """``R_ij^T R_i^T = R(theta_i + theta_ij)^T = [[c, s], [-s, c]]`` with ``c, s`` the cosine and sine of
        ``theta_i + theta_ij``: the translation blocks of A and B are its negative and itself. With
        ``(u, v) = R_i^T (t_j - t_i)``, ``d (u, v) / d theta_i = (v, -u)``.""",
        """With ``c, s = cos, sin(theta_i + theta_ij)``, ``(u, v) = R_i^T (t_j - t_i)`` and
        ``cz, sz = cos, sin(theta_ij)``::

            e[:, :2] = R_ij^T ((u, v) - t_ij)          e[:, 2] = wrap(theta_j - theta_i - theta_ij)
            B = [[ c, s, 0], [-s, c, 0], [0, 0, 1]]    per edge, (M, 3, 3)
            A = -B, then A[:, :2, 2] = R_ij^T (v, -u) = (cz v - sz u, -sz v - cz u)""",
    ),
    "SparseAssembler": (
        """In ``__init__``: for every edge, the global row and column of each of the 21 upper entries of its
        6x6 block (the pose dofs ``[3i, 3i + 1, 3i + 2, 3j, 3j + 1, 3j + 2]``), moved above H's diagonal
        where they fall below it; add every diagonal entry; then number the distinct (row, column) pairs in
        CSC order: that numbering is the position in ``H.data``. In ``assemble``: the 21 entries of every
        edge's ``J^T Omega J``, summed into ``H.data`` by position; the fixed poses' rows and columns
        zeroed and their diagonal set to 1.""",
        """H is symmetric: an entry ``(r, c)`` with ``r > c`` is stored at ``(c, r)``, so use
        ``(min(r, c), max(r, c))``. CSC stores column by column, rows ascending within a column: that is
        the order of the key ``column * 3N + row``. ``np.unique(keys, return_inverse=True)`` sorts the
        distinct keys (the pattern: ``indices = key % 3N``, ``indptr = np.searchsorted(key // 3N,
        arange(3N + 1))``) and gives each entry its slot; entries of several edges that share a slot are
        summed by ``np.bincount(slot, weights, minlength=nnz)``.""",
        """::

            dof = [3 edges_i + (0, 1, 2), 3 edges_j + (0, 1, 2)]               (M, 6)
            r, c = dof[:, UPPER[0]], dof[:, UPPER[1]]                        (M, 21)
            rows, cols = minimum(r, c).ravel(), maximum(r, c).ravel()
            keys = concatenate([cols * 3N + rows, arange(3N) * 3N + arange(3N)])   (edges, then diagonal)
            unique, inverse = unique_inverse(keys)
            positions, diagonal_positions = inverse[:21 M], inverse[21 M:]
            indices, indptr = unique % 3N, searchsorted(unique // 3N, arange(3N + 1))
            dead = fixed_dof[indices] | repeat(fixed_dof, diff(indptr))     (row or column fixed)

            assemble:  J = [A B] (M, 3, 6);  H_edges = (J^T Omega J)[:, UPPER[0], UPPER[1]]   (M, 21)
                       data = bincount(positions, H_edges.ravel(), minlength=nnz)
                       data[dead] = 0;  data[diagonal_positions[fixed_dof]] = 1
                       b = bincount(dof.ravel(), (J^T Omega e).ravel(), minlength=3N);  b[fixed_dof] = 0
                       chi2 = sum_k e_k^T Omega_k e_k;  H = csc_matrix((data, indices, indptr), (3N, 3N))

        (The reference gets ``J^T Omega J``, ``J^T Omega e`` and ``e^T Omega e`` from one batched product
        ``[A B e]^T Omega [A B e]`` (M, 7, 7): fewer calls, each over all the edges.)""",
    ),
}
