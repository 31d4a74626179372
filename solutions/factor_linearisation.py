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
        rows, cols, weights, entries = [], [], [], []
        # per group, per slot pair (a, c) with a <= c: where in ``assemble``'s values its blocks go, their shape,
        # and the variables' grouping (below); the values are every pair's blocks, one pair after the other
        self._plan = []
        size = 0
        # a variable's own block of H is summed variable by variable (one product of its factors' rows
        # stacked) where the variables of a slot are in at least this many factors each, on average
        many = 8
        for key in keys:
            key = np.asarray(key, dtype=np.int64)
            pairs = []
            for a in range(key.shape[1]):
                for c in range(a, key.shape[1]):
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
                    # J_c^T J_a is the transpose of J_a^T J_c: an entry of the pair below H's diagonal is stored
                    # at its mirror; a variable's own block (a == c) is symmetric, its upper triangle suffices;
                    # two slots on one variable put a diagonal entry there twice (J_a^T J_c and J_c^T J_a)
                    used = r <= q if a == c else np.ones(r.shape, dtype=bool)
                    rows.append(np.minimum(r, q)[used])
                    cols.append(np.maximum(r, q)[used])
                    weights.append(np.where((a != c) & (r == q), 2.0, 1.0)[used])
                    entries.append(size + np.flatnonzero(used))
                    pairs.append((a, c, slice(size, size + r.size), r.shape, groups))
                    size += r.size
            self._plan.append(pairs)
        rows.append(np.arange(n))  # every diagonal entry is in the pattern (the damping adds to it)
        cols.append(np.arange(n))
        rows, cols = np.concatenate(rows), np.concatenate(cols)
        linear = cols * n + rows  # column-major order: CSC
        unique, inverse = np.unique(linear, return_inverse=True)
        self._indices = (unique % n).astype(np.int32)
        self._indptr = np.searchsorted(unique // n, np.arange(n + 1)).astype(np.int32)
        self.nnz = len(unique)
        self.diagonal_positions = inverse[len(linear) - n:]
        # H.data = S @ values: S (nnz, size) holds each value's weight at (its position in H.data, its index)
        self._size = size
        self._sum = sp.csr_matrix((np.concatenate(weights), (inverse[: len(linear) - n], np.concatenate(entries))),
                                  shape=(self.nnz, size))
        fixed_dof = np.zeros(n, dtype=bool)
        for v in np.asarray(fixed, dtype=np.int64):
            fixed_dof[offsets[v]:offsets[v + 1]] = True
        self._fixed_dof = fixed_dof
        column = np.repeat(np.arange(n), np.diff(self._indptr))
        self._dead = np.flatnonzero(fixed_dof[self._indices] | fixed_dof[column])
        self._offsets = offsets
        self._keys = [np.asarray(key, dtype=np.int64) for key in keys]
        # per group, per slot: the entries of b its factors' J_a^T r go to (M * d_a,)
        self._b_index = [[(offsets[key[:, a]][:, None] + np.arange(int(dims[key[0, a]]))).ravel()
                          for a in range(key.shape[1])] for key in self._keys]
        # END SOLUTION

    def assemble(self, blocks):
        """``(H, b, chi2)`` from ``blocks``: per group ``(r (M_g, m_g), [J_a (M_g, m_g, d_a)])``, whitened.

        H is the upper triangle (n, n) as a scipy CSC matrix, b (n,), chi2 a float.
        """
        # BEGIN SOLUTION
        n = self._shape[0]
        values = np.empty(self._size)  # every pair's blocks, written in place by the products
        b = np.zeros(n)
        chi2 = 0.0
        for b_index, pairs, (r, J) in zip(self._b_index, self._plan, blocks):
            for a, c, where, shape, groups in pairs:
                out = values[where].reshape(shape)
                if groups is None:  # one block per factor; J_a^T J_a of a copy: numpy hands a product of an
                    # array with its own transpose to BLAS (syrk) one small block at a time, 3x slower here
                    np.matmul(J[a].transpose(0, 2, 1), J[c] if c != a else J[c].copy(), out=out)
                else:  # one per variable: the rows of its factors stacked, J^T J in one product
                    order, bounds = groups
                    stacked = J[a][order].reshape(-1, J[a].shape[2])
                    m = J[a].shape[1]
                    for k, (lo, hi) in enumerate(zip(bounds[:-1], bounds[1:])):
                        np.matmul(stacked[m * lo:m * hi].T, stacked[m * lo:m * hi], out=out[k])
            for a, index in enumerate(b_index):
                g = np.einsum("mra,mr->ma", J[a], r)
                b += np.bincount(index, weights=g.ravel(), minlength=n)
            chi2 += float(np.vdot(r, r))
        data = self._sum @ values  # each entry of H.data, the sum of its contributions
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
        gives the pattern (sorted) and every contribution's position. The sums are one product with a
        fixed sparse matrix ``S`` (a row per position, a column per computed value, 1 where the value goes;
        ``np.bincount(positions, weights)`` sums the same). ``J_c^T J_a`` is the transpose of ``J_a^T J_c``:
        compute the pairs ``a <= c`` only; where a factor's variables come in the other order, an entry
        lands below the diagonal: store it at its mirror ``(column, row)``. Of a variable's own block
        (``a == c``) the upper triangle suffices.""",
        """``__init__``: for each group and each slot pair (a, c) with ``a <= c``, the (M, d_a, d_c) arrays of
        rows and columns; ``used = rows <= cols`` where ``a == c``, every entry where ``a < c``; concatenate
        ``minimum(rows, cols)[used]``, ``maximum(rows, cols)[used]`` and the diagonal (every diagonal entry
        in the pattern, for the damping); ``unique, inverse = np.unique(cols * n + rows, return_inverse=True)``;
        ``indices = unique % n``, ``indptr = searchsorted(unique // n, arange(n + 1))``;
        ``S = csr_matrix((1s, (inverse of the used entries, their index among all values)))``, with 2 for a
        diagonal entry of a pair ``a < c`` whose two slots hold one variable (``J_a^T J_c`` and its transpose
        both put it there). ``assemble``: ``J_a^T J_c`` of each pair into its part of one array of values
        (``matmul``'s ``out=``), ``data = S @ values``; ``b`` by ``bincount`` of ``J_a^T r`` at slot a's
        offsets; ``chi2 = sum r^T r``; then the fixed rows and columns zeroed, their diagonal set to 1,
        their entries of b zeroed.""",
    ),
}
