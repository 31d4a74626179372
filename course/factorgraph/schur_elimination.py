"""The damped step of a block-sparse H with a set of variables eliminated first (the Schur complement).

Order the unknowns as kept ``k`` and eliminated ``e``; with the damping added,

    [A    B] [h_k]     [b_k]        S = A - B D^-1 B^T              (the reduced system)
    [B^T  D] [h_e] = - [b_e]        S h_k = -b_k + B D^-1 b_e
                                    h_e = -D^-1 (b_e + B^T h_k)

When no factor joins two eliminated variables, ``D`` is block diagonal (one (b, b) block per
eliminated variable) and its inverse costs one small inverse each: chapter 4's elimination of the
points, here for any graph whose eliminated variables all have one size ``b`` and whose kept
variables all have one size ``a``. ``B``'s nonzero blocks are the (kept, eliminated) pairs that
share a factor: they are the "observations" of ``course.solver.schur_reduction``, which sums
``B D^-1 B^T`` by pair.

:class:`SchurElimination` reads H as the assembler stores it (its upper triangle, CSC, variables in
the graph's order) through index arrays found once per pattern: each stored entry goes to A, to a
block of D, or to a coupling block, by a gather.
"""

import numpy as np
import scipy.linalg
import scipy.sparse as sp

from course.core.errors import SingularSystemError
from course.solver.schur_reduction import schur_reduction

#: the reduced system is factored densely (LAPACK's Cholesky) up to this size, sparsely above
DENSE_LIMIT = 2000
#: a pivot of a block's Cholesky factor keeping at most this share of its diagonal entry: singular
PIVOT_TOLERANCE = 1e-12


class SchurElimination:
    """``solve(H_upper, b, damping)``: the step of ``(H + diag(damping)) h = -b`` with ``eliminated``
    variables eliminated first.

    Args of ``__init__``: ``dims`` (N,) tangent sizes of the graph's variables; ``eliminated`` (E,)
    indices of the variables to eliminate (one size ``b``; no factor joins two of them); every other
    variable has one size ``a``; ``solver``: the sparse solver of the reduced system above
    ``DENSE_LIMIT`` (``solve(S_upper, rhs) -> -S^-1 rhs``); ``name`` and ``keys`` (the variables'
    names, N) for the errors.
    """

    def __init__(self, dims, eliminated, solver, name: str = "factor graph", keys=None):
        dims = np.asarray(dims, dtype=np.int64)
        eliminated = np.unique(np.asarray(eliminated, dtype=np.int64))  # sorted: numbered in the graph's order
        is_eliminated = np.zeros(len(dims), dtype=bool)
        is_eliminated[eliminated] = True
        kept = np.flatnonzero(~is_eliminated)
        sizes_e, sizes_k = set(dims[eliminated].tolist()), set(dims[kept].tolist())
        if len(sizes_e) != 1 or len(sizes_k) != 1:
            raise ValueError(f"{name}: eliminated variables of sizes {sorted(sizes_e)} and kept ones of sizes "
                             f"{sorted(sizes_k)}: each side needs one size")
        self.a, self.b = sizes_k.pop(), sizes_e.pop()
        self.name, self.solver = name, solver
        self._eliminated_keys = [keys[v] if keys is not None else f"number {v}" for v in eliminated]
        offsets = np.concatenate([[0], np.cumsum(dims)])
        n = int(offsets[-1])
        owner = np.repeat(np.arange(len(dims)), dims)  # the variable of every dof
        local = np.arange(n) - offsets[owner]  # its index inside the variable
        number = np.full(len(dims), -1, dtype=np.int64)  # a variable's number among the kept / the eliminated
        number[kept] = np.arange(len(kept))
        number[eliminated] = np.arange(len(eliminated))
        self._dof_is_e = is_eliminated[owner]
        self._dof_block = number[owner]
        self._dof_local = local
        self._C, self._P, self._n = len(kept), len(eliminated), n
        # the kept dofs in the reduced system's order (kept variable by kept variable), the eliminated ones
        # in D's: both are the graph's order, variables being numbered in it
        self._k_dofs = np.flatnonzero(~self._dof_is_e)
        self._e_dofs = np.flatnonzero(self._dof_is_e)
        self._pattern: tuple = ()

    # ------------------------------------------------------------ the index arrays, once per pattern

    def _analyse(self, H):
        a, b, C, P = self.a, self.b, self._C, self._P
        rows = H.indices.astype(np.int64)
        cols = np.repeat(np.arange(self._n), np.diff(H.indptr))
        e_r, e_q = self._dof_is_e[rows], self._dof_is_e[cols]
        blk_r, blk_q = self._dof_block[rows], self._dof_block[cols]
        loc_r, loc_q = self._dof_local[rows], self._dof_local[cols]

        both_e = e_r & e_q
        if np.any(blk_r[both_e] != blk_q[both_e]):
            s = np.flatnonzero(both_e & (blk_r != blk_q))[0]
            raise ValueError(f"{self.name}: H couples eliminated dofs {rows[s]} and {cols[s]} of two variables: "
                             "a factor joins two eliminated variables, D is not block diagonal")
        d_src = np.flatnonzero(both_e)
        d_pos = (blk_r[d_src] * b + loc_r[d_src]) * b + loc_q[d_src]
        d_pos_t = (blk_r[d_src] * b + loc_q[d_src]) * b + loc_r[d_src]

        mixed = e_r != e_q
        m_src = np.flatnonzero(mixed)
        k_dof_is_row = ~e_r[m_src]  # the kept dof is the row (kept before eliminated), or the column
        c = np.where(k_dof_is_row, blk_r[m_src], blk_q[m_src])
        p = np.where(k_dof_is_row, blk_q[m_src], blk_r[m_src])
        j = np.where(k_dof_is_row, loc_r[m_src], loc_q[m_src])
        i = np.where(k_dof_is_row, loc_q[m_src], loc_r[m_src])
        pairs, pair_of = np.unique(c * P + p, return_inverse=True)
        w_pos = (pair_of * a + j) * b + i

        both_k = ~e_r & ~e_q
        k_src = np.flatnonzero(both_k)
        kr, kq = blk_r[k_src] * a + loc_r[k_src], blk_q[k_src] * a + loc_q[k_src]
        nk = a * C
        self._pattern = (H.indptr.copy(), H.indices.copy())
        self._d = _gather_plan(np.concatenate([d_src, d_src]), np.concatenate([d_pos, d_pos_t]), P * b * b)
        self._w = _gather_plan(m_src, w_pos, len(pairs) * a * b)
        self._camera_index, self._point_index = (pairs // P).astype(np.int64), (pairs % P).astype(np.int64)
        self._k = (k_src, kr * nk + kq, kq * nk + kr)

    def _same_pattern(self, H) -> bool:
        indptr, indices = self._pattern
        return (H.indptr is indptr or np.array_equal(H.indptr, indptr)) and \
            (H.indices is indices or np.array_equal(H.indices, indices))

    # ------------------------------------------------------------ the step

    def solve(self, H_upper, b_vector, damping=None) -> np.ndarray:
        """``h`` (n,) of ``(H + diag(damping)) h = -b``; ``H_upper`` the upper triangle (n, n), CSC."""
        H = H_upper if sp.isspmatrix_csc(H_upper) else sp.csc_matrix(H_upper)
        if not H.has_canonical_format:  # duplicate entries are summed, as a factorisation would read them
            H = H.copy()
            H.sum_duplicates()
        if not self._pattern or not self._same_pattern(H):
            self._analyse(H)
        a, b, C, P, n = self.a, self.b, self._C, self._P, self._n
        data = H.data
        d = np.zeros(n) if damping is None else np.asarray(damping, dtype=float)
        g = np.asarray(b_vector, dtype=float)
        k_dofs, e_dofs = self._k_dofs, self._e_dofs
        D = _gathered(data, self._d).reshape(P, b, b)
        D[:, np.arange(b), np.arange(b)] += d[e_dofs].reshape(P, b)
        D_inv = self._inverse(D)
        W = _gathered(data, self._w).reshape(-1, a, b)
        ci, pi = self._camera_index, self._point_index
        reduction = schur_reduction(W, D_inv, ci, pi, C)  # B D^-1 B^T, (a C, a C)

        g_k, g_e = g[k_dofs], g[e_dofs].reshape(P, b)
        Dg = np.matmul(D_inv, g_e[:, :, None])  # (P, b, 1)
        rhs = -g_k + np.bincount((ci[:, None] * a + np.arange(a)).ravel(),
                                 weights=np.matmul(W, Dg[pi]).ravel(), minlength=a * C)

        h_k = self._reduced_step(data, d[k_dofs], reduction, rhs)
        Bt_h = np.matmul(W.transpose(0, 2, 1), h_k.reshape(C, a)[ci][:, :, None])[:, :, 0]  # (K, b)
        back = np.bincount((pi[:, None] * b + np.arange(b)).ravel(), weights=Bt_h.ravel(), minlength=b * P)
        h_e = -np.matmul(D_inv, (g_e + back.reshape(P, b))[:, :, None])[:, :, 0]
        h = np.empty(n)
        h[k_dofs] = h_k
        h[e_dofs] = h_e.ravel()
        return h

    def _inverse(self, D):
        """``D^-1`` (P, b, b) by the Cholesky factor of every block; a block that is not positive
        definite is a ``SingularSystemError`` naming its variable."""
        try:
            L = np.linalg.cholesky(D)
            # a pivot's share of its diagonal entry: down to rounding where the block is singular
            kept = np.min(np.einsum("pii->pi", L) ** 2 / np.einsum("pii->pi", D), axis=1)
            singular = not np.all(kept > PIVOT_TOLERANCE)
        except np.linalg.LinAlgError:
            singular = True
        if singular:
            lowest = np.linalg.eigvalsh(D)[:, 0] / np.maximum(np.abs(D).max(axis=(1, 2)), np.finfo(float).tiny)
            bad = int(np.argmin(lowest))
            raise SingularSystemError(
                f"{self.name}: the block of eliminated variable {self._eliminated_keys[bad]!r} (plus damping) is "
                f"not positive definite (lowest eigenvalue {lowest[bad]:.3g} of its largest entry): is it seen by "
                "too few factors, "
                "undamped?") from None
        L_inv = _lower_inverse(L)
        return np.matmul(L_inv.transpose(0, 2, 1), L_inv)

    def _reduced_step(self, data, damping_k, reduction, rhs):
        """``h_k`` of ``S h_k = rhs``, ``S = A + diag(damping_k) - reduction``."""
        k_src, flat, flat_t = self._k
        nk = len(rhs)
        if nk <= DENSE_LIMIT:
            S = -reduction.toarray()
            A = np.zeros(nk * nk)
            A[flat_t] = data[k_src]
            A[flat] = data[k_src]  # the diagonal once
            S += A.reshape(nk, nk)
            S[np.arange(nk), np.arange(nk)] += damping_k
            try:
                factor = scipy.linalg.cho_factor(S, lower=True, check_finite=False)
            except np.linalg.LinAlgError:
                raise SingularSystemError(f"{self.name}: the reduced system S is not positive definite: a "
                                          "direction is free (the gauge where nothing holds it, or too few "
                                          "observations), and an undamped step meets it (Levenberg-Marquardt and "
                                          "the dogleg damp it)") from None
            kept = np.diag(factor[0]) ** 2 / np.diag(S)
            if not np.all(np.isfinite(kept)) or kept.min() <= nk * np.finfo(float).eps:
                raise SingularSystemError(f"{self.name}: the reduced system S is numerically singular (a pivot "
                                          f"keeps {kept.min():.3g} of its diagonal entry)")
            return scipy.linalg.cho_solve(factor, rhs, check_finite=False)
        rows, cols = flat // nk, flat % nk
        A = sp.csc_matrix((data[k_src], (rows, cols)), shape=(nk, nk))
        S = sp.triu(A + sp.diags(damping_k) - reduction, format="csc")
        h = np.asarray(self.solver.solve(S, -rhs), dtype=float)  # the solver's S h = -(-rhs)
        if not np.all(np.isfinite(h)) or h @ rhs <= 0:
            raise SingularSystemError(f"{self.name}: the reduced system S is not positive definite")
        return h


def _lower_inverse(L) -> np.ndarray:
    """``L^-1`` (P, b, b) of lower triangular ``L`` (P, b, b) by forward substitution, all blocks at
    once (a loop over b's entries, not over P: ten times faster than a LAPACK call per block)."""
    b = L.shape[-1]
    out = np.zeros_like(L)
    for i in range(b):
        out[:, i, i] = 1.0 / L[:, i, i]
        for j in range(i):
            out[:, i, j] = -np.einsum("pk,pk->p", L[:, i, j:i], out[:, j:i, j]) * out[:, i, i]
    return out


def _gather_plan(source, position, size):
    """How to fill an array (size,) with ``out[position] = data[source]``: one gather ``data[order]``
    when every position has a source, else the scatter."""
    if len(position) == size and np.array_equal(np.sort(position), np.arange(size)):
        return source[np.argsort(position)], None, size
    return source, position, size


def _gathered(data, plan) -> np.ndarray:
    source, position, size = plan
    if position is None:
        return data[source]
    out = np.zeros(size)
    out[position] = data[source]
    return out
