"""The reduction term of a Schur complement over block-sparse observations, by camera pair.

Eliminating the points of bundle adjustment leaves ``S = U - R`` on the cameras, with::

    R = sum over points p, over pairs (k, l) of observations of p:  W_k V_p^-1 W_l^T
        at block (c_k, c_l)                                         ((a C, a C), blocks (a, a))

``W`` (K, a, b) holds one coupling block per observation k of point ``p_k`` by camera
``c_k``, ``V_inv`` (P, b, b) the inverse of every point's (damped) block. That is the
sparse product ``Ys @ Ws^T`` of the hint of ``schur_solve`` (Ys, Ws the block rows Y_k =
W_k V_p^-1 and W_k). :func:`schur_reduction` computes it where numba is installed by two
compiled passes: the pattern (which camera pairs share a point, and the list of observation
pairs that fill each block), computed once per problem and kept, and the values, one a x b x a
block product per pair with ``c_l >= c_k`` only (R is symmetric: the lower blocks are the upper
ones transposed; a pair (k, k) adds its upper triangle only), ``Y_k = W_k V_p^-1`` formed as the
pairs reach k and nothing of size K written; with ``g_point`` the same pass sums the reduced right
side's term ``Y_k g_p``. ladybug-49: 214,329 block products in scipy's BSR product, 123,086 here
(31,843 of them half); 50 against 7.9 ms of CPU (a loaded 2-core SkylakeX). Without numba (no
wheel for every Python), for other block sizes than (9, 3), and in the autograder's children
(:mod:`course.core.jit`) it is that BSR product.
Same R to rounding.
"""

import numpy as np
import scipy.sparse as sp

from course.core import jit


def schur_reduction(W, V_inv, camera_index, point_index, num_cameras, g_point=None):
    """``R`` (a C, a C) as a ``scipy.sparse.bsr_matrix`` with (a, a) blocks, both triangles; with
    ``g_point`` (P, b) also the reduced right side's term ``sum_k W_k V_{p_k}^-1 g_point_{p_k}`` into
    block ``c_k``, (C, a), in the same pass: ``(R, that)``.

    Args: W (K, a, b); V_inv (P, b, b), symmetric; camera_index, point_index (K,) int;
    num_cameras C. Every camera row lists its blocks in column order. ``ValueError`` on shapes
    that do not fit or an index out of range (the compiled pass does not check its indices).
    """
    W = np.ascontiguousarray(W, dtype=float)
    V_inv = np.ascontiguousarray(V_inv, dtype=float)
    ci = np.ascontiguousarray(camera_index, dtype=np.int64)
    pi = np.ascontiguousarray(point_index, dtype=np.int64)
    K = len(ci)
    if W.ndim != 3 or len(W) != K or pi.shape != (K,) or ci.ndim != 1 or V_inv.shape[1:] != (W.shape[2],) * 2:
        raise ValueError(f"schur_reduction: W {W.shape}, V_inv {V_inv.shape}, camera_index {ci.shape} and "
                         f"point_index {pi.shape} do not fit: W (K, a, b), V_inv (P, b, b), both indices (K,)")
    g = np.zeros((0, W.shape[2])) if g_point is None else np.ascontiguousarray(g_point, dtype=float)
    if g_point is not None and g.shape != (len(V_inv), W.shape[2]):
        raise ValueError(f"schur_reduction: g_point {g.shape} does not fit V_inv {V_inv.shape}: (P, b)")
    for name, index, count in (("camera_index", ci, num_cameras), ("point_index", pi, len(V_inv))):
        if K and (index.min() < 0 or index.max() >= count):
            raise ValueError(f"schur_reduction: {name} holds {index.min()} to {index.max()}, not in [0, {count})")
    a = W.shape[1]
    compiled = jit.kernels(globals(), KERNELS) if W.shape[1:] == (CAMERA, POINT) else None
    if compiled is None:
        R, term = _bsr_product(W, V_inv, ci, pi, num_cameras, g)
    else:
        pattern, values = compiled[-2:]
        indptr, indices, pairs, source, transposed = _pattern_of(pattern, ci, pi, num_cameras, len(V_inv))
        data, term = values(W, V_inv, ci, pi, g, num_cameras, *pairs, indptr, indices, source, transposed)
        R = sp.bsr_matrix((data, indices, indptr), shape=(a * num_cameras, a * num_cameras))
    return R if g_point is None else (R, term)


def _bsr_product(W, V_inv, ci, pi, num_cameras, g):
    """``Ys @ Ws^T`` by scipy's block-sparse product (the path without numba), and ``Ys g`` (C, a)
    where ``g`` has rows."""
    a, b = W.shape[1:]
    order = np.argsort(ci, kind="stable")
    indptr = np.concatenate([[0], np.cumsum(np.bincount(ci, minlength=num_cameras))])
    W_sorted, p_sorted = W[order], pi[order]
    shape = (a * num_cameras, b * len(V_inv))
    Ys = sp.bsr_matrix((np.matmul(W_sorted, V_inv[p_sorted]), p_sorted, indptr), shape=shape)
    Ws = sp.bsr_matrix((W_sorted, p_sorted, indptr), shape=shape)
    product = sp.bsr_matrix(Ys @ Ws.T, blocksize=(a, a))
    product.sort_indices()
    term = (Ys @ g.ravel()).reshape(num_cameras, a) if len(g) else None
    return product, term


#: the compiled pass's block sizes: a camera's 9 parameters, a point's 3 (constants, so that the
#: compiler unrolls and vectorizes the block products)
CAMERA, POINT = 9, 3

#: a camera row of at most this many blocks is sorted by insertion, a longer one by a pass over the columns
SHORT_ROW = 64
#: the compiled functions (:func:`course.core.jit.kernels`), callees first
KERNELS = ("_groups", "_sort", "_position", "_pattern", "_values")
#: the last pattern computed: ``(camera_index, point_index, C, P)`` and what ``_pattern`` gave for it
_LAST: tuple = ()


def _pattern_of(pattern, ci, pi, C, P):
    """``pattern(ci, pi, C, P)``, kept for the next call with the same observations: a solver asks for
    the same pattern at every step (an index structure of the problem, as the assembler's)."""
    global _LAST
    if _LAST and _LAST[2:4] == (C, P) and np.array_equal(_LAST[0], ci) and np.array_equal(_LAST[1], pi):
        return _LAST[4]
    indptr, indices, pair_k, pair_l, pair_q, n_upper, source, transposed = pattern(ci, pi, C, P)
    found = (indptr, indices, (pair_k, pair_l, pair_q, n_upper), source, transposed)
    _LAST = (ci.copy(), pi.copy(), C, P, found)
    return found


def _groups(index, count):
    """``(pointer, members)``: the members of group g are ``members[pointer[g]:pointer[g + 1]]``,
    ascending (a counting sort)."""
    pointer = np.zeros(count + 1, dtype=np.int64)
    for g in index:
        pointer[g + 1] += 1
    for g in range(count):
        pointer[g + 1] += pointer[g]
    cursor = pointer[:count].copy()
    members = np.empty(len(index), dtype=np.int64)
    for k in range(len(index)):
        members[cursor[index[k]]] = k
        cursor[index[k]] += 1
    return pointer, members


def _sort(values, lo, hi):
    """Sort ``values[lo:hi]`` in place (insertion: a camera row is short, and np.sort is slow to compile)."""
    for x in range(lo + 1, hi):
        v = values[x]
        y = x - 1
        while y >= lo and values[y] > v:
            values[y + 1] = values[y]
            y -= 1
        values[y + 1] = v


def _position(sorted_values, lo, hi, value):
    """The index of ``value`` in ``sorted_values[lo:hi]`` (present), by bisection."""
    while hi - lo > 1:
        mid = (lo + hi) // 2
        if sorted_values[mid] <= value:
            lo = mid
        else:
            hi = mid
    return lo


def _pattern(ci, pi, C, P):
    """R's pattern and the pairs that fill it; compiled by numba (plain loops on purpose: that is
    what it compiles well, and fast).

    The upper blocks (c, d), d >= c, are numbered row by row in column order; ``pair_k, pair_l,
    pair_q`` list every pair (k, l) of observations of one point with ``c_k <= c_l`` (both orders
    when ``c_k = c_l``), point by point, and the upper block q it adds ``Y_k W_l^T`` to. R in BSR
    form: ``indptr, indices``, and for each of its blocks the upper block it is (``source``),
    transposed or not: row c holds the transposes of the blocks (d, c), d < c, then its own.
    """
    cam_ptr, cam_obs = _groups(ci, C)
    pt_ptr, pt_obs = _groups(pi, P)
    # the upper blocks of every camera row c: the cameras d >= c that share a point with c
    mark = np.empty(C, dtype=np.int64)
    upper_ptr = np.zeros(C + 1, dtype=np.int64)
    upper_cols = np.empty(0, dtype=np.int64)
    for stage in range(2):  # count, then list
        for c in range(C):
            mark[c] = -1
        for c in range(C):
            n = upper_ptr[c]
            for x in range(cam_ptr[c], cam_ptr[c + 1]):
                p = pi[cam_obs[x]]
                for y in range(pt_ptr[p], pt_ptr[p + 1]):
                    d = ci[pt_obs[y]]
                    if d >= c and mark[d] != c:
                        mark[d] = c
                        if stage == 1:
                            upper_cols[n] = d
                        n += 1
            if stage == 0:
                upper_ptr[c + 1] = n
            elif n - upper_ptr[c] <= SHORT_ROW:
                _sort(upper_cols, upper_ptr[c], n)
            else:  # a long row: the marked columns in order, one pass over them (no quadratic sort)
                n = upper_ptr[c]
                for d in range(c, C):
                    if mark[d] == c:
                        upper_cols[n] = d
                        n += 1
        if stage == 0:
            upper_cols = np.empty(upper_ptr[C], dtype=np.int64)
    # the pairs, point by point (a point's observations then stay in cache while its pairs are summed)
    count = 0
    for p in range(P):
        for x in range(pt_ptr[p], pt_ptr[p + 1]):
            for y in range(pt_ptr[p], pt_ptr[p + 1]):
                if ci[pt_obs[y]] >= ci[pt_obs[x]]:
                    count += 1
    pair_k = np.empty(count, dtype=np.int64)
    pair_l = np.empty(count, dtype=np.int64)
    pair_q = np.empty(count, dtype=np.int64)
    n = 0
    for p in range(P):
        for x in range(pt_ptr[p], pt_ptr[p + 1]):
            c = ci[pt_obs[x]]
            for y in range(pt_ptr[p], pt_ptr[p + 1]):
                d = ci[pt_obs[y]]
                if d >= c:
                    pair_k[n], pair_l[n] = pt_obs[x], pt_obs[y]
                    pair_q[n] = _position(upper_cols, upper_ptr[c], upper_ptr[c + 1], d)
                    n += 1
    # both triangles
    counts = np.empty(C, dtype=np.int64)
    for c in range(C):
        counts[c] = upper_ptr[c + 1] - upper_ptr[c]
    for c in range(C):
        for x in range(upper_ptr[c], upper_ptr[c + 1]):
            if upper_cols[x] > c:
                counts[upper_cols[x]] += 1
    indptr = np.zeros(C + 1, dtype=np.int64)
    for c in range(C):
        indptr[c + 1] = indptr[c] + counts[c]
    indices = np.empty(indptr[C], dtype=np.int64)
    source = np.empty(indptr[C], dtype=np.int64)
    transposed = np.zeros(indptr[C], dtype=np.bool_)
    cursor = indptr[:C].copy()
    for c in range(C):
        for x in range(upper_ptr[c], upper_ptr[c + 1]):
            d = upper_cols[x]
            indices[cursor[c]], source[cursor[c]] = d, x
            cursor[c] += 1
            if d > c:
                indices[cursor[d]], source[cursor[d]], transposed[cursor[d]] = c, x, True
                cursor[d] += 1
    return indptr, indices, pair_k, pair_l, pair_q, upper_ptr[C], source, transposed


def _values(W, V_inv, ci, pi, g, C, pair_k, pair_l, pair_q, n_upper, indptr, indices, source, transposed):
    """R's blocks (in the order of ``_pattern``'s ``indices``) for W (K, CAMERA, POINT), and where ``g``
    (P, POINT) has rows the term ``sum_k Y_k g_{p_k}`` (C, CAMERA) of the right side; compiled.

    ``Y_k = W_k V_p^-1`` is formed when the pairs reach a new first observation k (they list each k's pairs one
    after another) and ``W_l^T`` is read from W where it lies: no (K, 9, 3) arrays written and read back. A pair
    (k, k) adds the symmetric ``W_k V_p^-1 W_k^T``: its upper triangle only, and every diagonal block is the
    mirror of its upper triangle (the pairs (k, l), l != k, of one camera come in both orders: their sum is
    symmetric too)."""
    upper = np.zeros((n_upper, CAMERA, CAMERA))
    term = np.zeros((C, CAMERA))
    Y = np.empty((CAMERA, POINT))
    last = -1
    for t in range(len(pair_k)):
        k, m, q = pair_k[t], pair_l[t], pair_q[t]
        if k != last:
            p = pi[k]
            for i in range(CAMERA):
                w0, w1, w2 = W[k, i, 0], W[k, i, 1], W[k, i, 2]
                for j in range(POINT):
                    Y[i, j] = w0 * V_inv[p, 0, j] + w1 * V_inv[p, 1, j] + w2 * V_inv[p, 2, j]
            if len(g):  # every k has one run of pairs (its pair (k, k) among them): Y_k g_p added once
                for i in range(CAMERA):
                    term[ci[k], i] += Y[i, 0] * g[p, 0] + Y[i, 1] * g[p, 1] + Y[i, 2] * g[p, 2]
            last = k
        if k == m:  # two loops, not one from a variable start: the full one is unrolled by the compiler
            for i in range(CAMERA):
                y0, y1, y2 = Y[i, 0], Y[i, 1], Y[i, 2]
                for j in range(i, CAMERA):
                    upper[q, i, j] += y0 * W[m, j, 0] + y1 * W[m, j, 1] + y2 * W[m, j, 2]
        else:
            for i in range(CAMERA):
                y0, y1, y2 = Y[i, 0], Y[i, 1], Y[i, 2]
                for j in range(CAMERA):
                    upper[q, i, j] += y0 * W[m, j, 0] + y1 * W[m, j, 1] + y2 * W[m, j, 2]
    data = np.empty((len(source), CAMERA, CAMERA))
    for c in range(len(indptr) - 1):
        for f in range(indptr[c], indptr[c + 1]):
            x = source[f]
            for i in range(CAMERA):
                for j in range(CAMERA):
                    if indices[f] == c:  # a diagonal block: its upper triangle, mirrored
                        data[f, i, j] = upper[x, i, j] if j >= i else upper[x, j, i]
                    else:
                        data[f, i, j] = upper[x, j, i] if transposed[f] else upper[x, i, j]
    return data, term
