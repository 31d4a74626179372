"""Chapter 7 exercise: the generic linearisation, H and b of a factor graph in one block-sparse pattern.

The graph has N variables of mixed tangent sizes ``dims`` (N,); variable ``v``'s step is the slice
``offsets[v] : offsets[v] + dims[v]`` of the whole step (``offsets`` the running sum of ``dims``).
Its factors come in groups of one type: group ``g`` has ``M_g`` factors on ``s_g`` variables each,
``keys[g]`` (M_g, s_g), and at every linearisation a whitened residual ``r`` (M_g, m_g) and one
Jacobian block per slot, ``J_a`` (M_g, m_g, dims[keys[g][:, a]]) (all variables of a slot have one kind,
so one size). Then, summed over all factors,

    H = sum J^T J      b = sum J^T r      chi2 = sum r^T r

where a factor's J (m, n) is zero but for its blocks in its variables' columns. Derive which blocks
of H one factor adds to; the pattern (which entries of H can be nonzero) depends on ``keys`` only,
so find it once, in ``__init__``, and make ``assemble`` a scatter of numbers into it (chapters 2 and
6 did this for one kind of variable; here the sizes differ).
Fixed variables are held still as in chapters 2 and 6: their rows and columns of H are zero but for
the identity on their diagonal block, their entries of b zero.
``python -m autograder hint BlockSparseAssembler 1`` if you are stuck.

Inputs at the edges of the contract (each is a check input):
- one factor (M = 1) of one variable (N = 1)
- a factor of one variable (a prior)
- a factor from a later variable to an earlier one
- two factors on the same variables (their blocks add up)
- no variable fixed
- a fixed variable that is not the first

Allowed imports: numpy, scipy.
"""

import numpy as np
import scipy.sparse as sp


class BlockSparseAssembler:
    """``assemble`` H (upper triangle, CSC), b and chi2 of whitened factor blocks, into a pattern found once.

    Args of ``__init__``: ``dims`` (N,) int tangent sizes; ``keys``: one (M_g, s_g) int array per group;
    ``fixed``: (K,) int indices of fixed variables.
    ``diagonal_positions`` (n,): where ``H``'s diagonal entries sit in the returned matrix's ``data``.
    """

    def __init__(self, dims, keys, fixed):
        # BEGIN SOLUTION
        dims = np.asarray(dims, dtype=np.int64)
        offsets = np.concatenate([[0], np.cumsum(dims)])
        n = int(offsets[-1])
        self._shape = (n, n)
        rows, cols = [], []
        self._plan = []  # per group, per (a, c) slot pair with a <= c: which entries of the block are kept
        # a variable's own block of H is summed variable by variable (one product of its factors' rows
        # stacked) where the variables of a slot are in at least this many factors each, on average
        many = 8
        for key in keys:
            key = np.asarray(key, dtype=np.int64)
            pairs = []
            for a in range(key.shape[1]):
                for c in range(key.shape[1]):
                    da, dc = int(dims[key[0, a]]), int(dims[key[0, c]])
                    variables, groups = key[:, a], None
                    if a == c:  # a variable's own block: by variable where each is in many factors
                        shared, count = np.unique(variables, return_counts=True)
                        if len(variables) >= many * len(shared):
                            order = np.argsort(variables, kind="stable")
                            groups = (order, np.concatenate([[0], np.cumsum(count)]))
                            variables = shared
                    r = offsets[variables][:, None, None] + np.arange(da)[None, :, None]
                    q = offsets[variables if a == c else key[:, c]][:, None, None] + np.arange(dc)[None, None, :]
                    r, q = np.broadcast_arrays(r, q)
                    keep = r <= q  # the upper triangle of H
                    if not keep.any():  # the pair (c, a) holds this block's transpose
                        continue
                    rows.append(r[keep])
                    cols.append(q[keep])
                    pairs.append((a, c, None if keep.all() else np.flatnonzero(keep), groups))
            self._plan.append(pairs)
        rows.append(np.arange(n))  # every diagonal entry is in the pattern (the damping adds to it)
        cols.append(np.arange(n))
        rows, cols = np.concatenate(rows), np.concatenate(cols)
        linear = cols * n + rows  # column-major order: CSC
        unique, inverse = np.unique(linear, return_inverse=True)
        self._positions = inverse[: len(linear) - n]
        self._indices = (unique % n).astype(np.int32)
        self._indptr = np.searchsorted(unique // n, np.arange(n + 1)).astype(np.int32)
        self.nnz = len(unique)
        self.diagonal_positions = inverse[len(linear) - n:]
        fixed_dof = np.zeros(n, dtype=bool)
        for v in np.asarray(fixed, dtype=np.int64):
            fixed_dof[offsets[v]:offsets[v + 1]] = True
        self._fixed_dof = fixed_dof
        column = np.repeat(np.arange(n), np.diff(self._indptr))
        self._dead = np.flatnonzero(fixed_dof[self._indices] | fixed_dof[column])
        self._offsets = offsets
        self._keys = [np.asarray(key, dtype=np.int64) for key in keys]
        # END SOLUTION

    def assemble(self, blocks):
        """``(H, b, chi2)`` from ``blocks``: per group ``(r (M_g, m_g), [J_a (M_g, m_g, d_a)])``, whitened.

        H is the upper triangle (n, n) as a scipy CSC matrix, b (n,), chi2 a float.
        """
        # BEGIN SOLUTION
        n = self._shape[0]
        values = []
        b = np.zeros(n)
        chi2 = 0.0
        for key, pairs, (r, J) in zip(self._keys, self._plan, blocks):
            for a, c, keep, groups in pairs:
                if groups is None:  # one block per factor
                    block = np.matmul(J[a].transpose(0, 2, 1), J[c]).ravel()
                else:  # one per variable: the rows of its factors stacked, J^T J in one product
                    order, bounds = groups
                    stacked = J[a][order].reshape(-1, J[a].shape[2])
                    m = J[a].shape[1]
                    block = np.stack([stacked[m * lo:m * hi].T @ stacked[m * lo:m * hi]
                                      for lo, hi in zip(bounds[:-1], bounds[1:])]).ravel()
                values.append(block if keep is None else block[keep])
            for a in range(len(J)):
                g = np.einsum("mra,mr->ma", J[a], r)
                idx = self._offsets[key[:, a]][:, None] + np.arange(J[a].shape[2])
                b += np.bincount(idx.ravel(), weights=g.ravel(), minlength=n)
            chi2 += float(np.vdot(r, r))
        data = np.bincount(self._positions, weights=np.concatenate(values) if values else None, minlength=self.nnz)
        data[self._dead] = 0.0
        data[self.diagonal_positions[self._fixed_dof]] = 1.0
        b[self._fixed_dof] = 0.0
        return sp.csc_matrix((data, self._indices, self._indptr), shape=self._shape), b, chi2
        # END SOLUTION


#: the derived results, in three levels (``python -m autograder hint NAME LEVEL``; the release
#: prints levels 1..N into the docstrings with ``--hints N``, course.core.hints)
HINTS = {
    "BlockSparseAssembler": (
        """A factor's J has nonzero blocks only in its variables' columns, so ``J^T J`` has nonzero blocks
        only at (variable of slot a, variable of slot c). List, once, every entry (row, column) each slot
        pair of each factor adds to, keep the upper triangle, find the distinct positions in CSC order,
        and remember where each contribution goes; then ``assemble`` only computes the block values and
        sums them into those positions.""",
        """Row ``offsets[key[f, a]] + i``, column ``offsets[key[f, c]] + j`` gets ``(J_a^T J_c)[i, j]``; in
        CSC order an entry's key is ``column * n + row``, so ``np.unique(keys, return_inverse=True)``
        gives the pattern (sorted) and every contribution's position; ``np.bincount(positions, weights)``
        sums them. A pair (a, c) whose variables come in the other order lands below the diagonal:
        its transpose, from the pair (c, a), is the one above.""",
        """``__init__``: for each group and each slot pair (a, c), the (M, d_a, d_c) arrays of rows and
        columns; ``keep = rows <= cols``; concatenate the kept ones and the diagonal (every diagonal entry
        in the pattern, for the damping); ``unique, inverse = np.unique(cols * n + rows, return_inverse=True)``;
        ``indices = unique % n``, ``indptr = searchsorted(unique // n, arange(n + 1))``. ``assemble``:
        ``values = (J_a^T J_c)[keep]`` per pair, ``data = bincount(positions, values)``; ``b`` by
        ``bincount`` of ``J_a^T r`` at slot a's offsets; ``chi2 = sum r^T r``; then the fixed rows and
        columns zeroed, their diagonal set to 1, their entries of b zeroed.""",
    ),
}
