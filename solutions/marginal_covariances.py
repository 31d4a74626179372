"""Chapter 8: marginal covariances from the square-root information, without the dense inverse.

After elimination a smoother holds the square-root information ``R`` (n, n), upper triangular, of
``H = R^T R``; the covariance is ``Sigma = H^-1 = R^-1 R^-T`` (n, n). A variable's uncertainty is a
diagonal block of Sigma (its *marginal*), and data association needs the joint marginal of a few
variables. Sigma is dense even where R is sparse, so it is never formed: a chain of 20,000 scalar
variables would need 3.2 GB for it. The checks run such a chain under the grader's limits (2 GB of memory,
10 s by default): no dense (n, n) matrix, and work per stored entry of R, not per pair of variables.

Conventions: the variables are consecutive blocks of R's rows and columns, in R's order, of
tangent sizes ``sizes`` (``sum(sizes) = n``); variable v's rows are ``starts[v]:starts[v + 1]`` with
``starts = concatenate([[0], cumsum(sizes)])``. The last variable is the last one eliminated, the
root of the Bayes tree. R's *stored* entries (a scipy.sparse matrix, CSR or CSC; values 0 included,
``R.indices`` and ``R.data``, not ``R.nonzero()``) are its pattern, a Cholesky factor's:

- closed under elimination: if R[k, i] and R[k, j] are stored, k < i < j, then R[i, j] is stored
  (a stored entry may hold the value 0: it is still part of the pattern);
- each variable's diagonal block is stored whole (its upper triangle).

On such a pattern the entries of Sigma where R is stored (and their transposes) determine one
another, from the last row up, through R alone (derive how: ``python -m autograder hint
marginal_covariances 1``, then 2 and 3).

Inputs at the edges of the contract (each is a check input):
- one variable (the root is the whole of R)
- scalar variables only (every size 1)
- variables of sizes 1, 2, 3 and 6 mixed, with loop closures (fill-in in R)
- a filled-in entry of R stored with the value 0
- a variable with two or more children in the elimination tree (R's rows branch)
- R given as CSR
- R given as CSC
- a chain of 20,000 scalar variables (a dense Sigma needs 3.2 GB)
- joint_marginal: one key
- joint_marginal: keys not in increasing order

Allowed imports: numpy, scipy, course.core.errors.
"""

import numpy as np
import scipy.sparse as sp
from scipy.sparse.linalg import spsolve_triangular

from course.core.errors import SingularSystemError


def check_inputs(R, sizes):
    """``(R as CSR with sorted indices, starts (m + 1,))``, or a ``ValueError`` / ``TypeError`` naming the
    argument and the entry; ``SingularSystemError`` for a zero on the diagonal (names the row)."""
    if not sp.issparse(R):
        raise TypeError(f"R must be a scipy.sparse matrix (CSR or CSC), got {type(R).__name__}")
    if R.ndim != 2 or R.shape[0] != R.shape[1]:
        raise ValueError(f"R must be square (n, n), got shape {R.shape}")
    n = R.shape[0]
    R = sp.csr_matrix(R, dtype=float, copy=True)
    R.sum_duplicates()
    R.sort_indices()
    if not np.all(np.isfinite(R.data)):
        raise ValueError("R has entries that are not finite")
    rows = np.repeat(np.arange(n), np.diff(R.indptr))
    below = (R.indices < rows) & (R.data != 0.0)
    if below.any():
        k = int(np.flatnonzero(below)[0])
        raise ValueError(f"R must be upper triangular: R[{rows[k]}, {R.indices[k]}] = {R.data[k]:g} is below the "
                         "diagonal")
    if (R.indices < rows).any():  # stored zeros below the diagonal: not part of an upper-triangular pattern
        R = sp.csr_matrix(sp.triu(R, format="csr"))
        R.sort_indices()
        rows = np.repeat(np.arange(n), np.diff(R.indptr))
    zero = np.flatnonzero(R.diagonal() == 0.0)
    if zero.size:
        raise SingularSystemError(f"R is singular: its diagonal entry R[{zero[0]}, {zero[0]}] (row {zero[0]}) is 0")
    sizes = np.asarray(sizes)
    if sizes.ndim != 1 or sizes.size == 0 or not np.issubdtype(sizes.dtype, np.integer):
        raise ValueError(f"sizes must be a non-empty list of integers (one tangent size per variable), got {sizes!r}")
    if (sizes < 1).any():
        v = int(np.flatnonzero(sizes < 1)[0])
        raise ValueError(f"sizes[{v}] = {sizes[v]}: every variable's size must be >= 1")
    if int(sizes.sum()) != n:
        raise ValueError(f"sizes must sum to n = {n} (R's size), got sum(sizes) = {int(sizes.sum())}")
    starts = np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64)
    owner = np.repeat(np.arange(len(sizes)), sizes)
    inside = owner[rows] == owner[R.indices]
    count = np.bincount(owner[rows[inside]], minlength=len(sizes))
    short = np.flatnonzero(count != sizes * (sizes + 1) // 2)
    if short.size:
        v = int(short[0])
        raise ValueError(f"R must store variable {v}'s diagonal block whole (rows and columns "
                         f"{starts[v]}:{starts[v + 1]}, its upper triangle): {count[v]} of "
                         f"{sizes[v] * (sizes[v] + 1) // 2} entries stored")
    return R, starts


def check_keys(keys, count):
    """``keys`` as an int array, or a ``ValueError`` naming the entry (out of range, repeated, none)."""
    keys = np.asarray(keys)
    if keys.ndim != 1 or keys.size == 0 or not np.issubdtype(keys.dtype, np.integer):
        raise ValueError(f"keys must be a non-empty list of variable indices, got {keys!r}")
    bad = np.flatnonzero((keys < 0) | (keys >= count))
    if bad.size:
        raise ValueError(f"keys[{bad[0]}] = {keys[bad[0]]} is not a variable index in [0, {count})")
    seen: dict = {}
    for k, key in enumerate(keys.tolist()):
        if key in seen:
            raise ValueError(f"keys[{k}] = {key} repeats keys[{seen[key]}]: each variable once")
        seen[key] = k
    return keys.astype(np.int64)


def marginal_covariances(R, sizes):
    """The marginal covariance of every variable: ``[Sigma_vv (d_v, d_v) for v in range(len(sizes))]``,
    the diagonal blocks of ``Sigma = (R^T R)^-1``.

    Args: ``R`` scipy.sparse (n, n), upper triangular with a nonzero diagonal, its stored pattern a
    Cholesky factor's (the module docstring); ``sizes`` the variables' tangent sizes, in R's order.
    Compute Sigma only where R is stored (and its transpose): no dense (n, n) matrix, no inverse of R
    or H. Raises ``ValueError`` naming the argument and the entry for bad input (not square, not upper
    triangular, sizes not summing to n), ``SingularSystemError`` for a zero on the diagonal.
    """
    R, starts = check_inputs(R, sizes)
    # BEGIN SOLUTION
    # The scalar recursion, a variable's rows at a time (its diagonal block is stored whole). For variable
    # v, rows F, let K be the columns after F that its last row stores: by the closure every row of F
    # stores only columns of F and K, every pair of K is on the pattern, and K lies in the columns
    # F_p + K_p of the variable p that owns K[0] (v's parent in the elimination tree). Rows F of
    # ``R Sigma = R^-T``, with X = R_FF^-1:
    #     Sigma_FK = -X R_FK Sigma_KK,    Sigma_FF = X (X^T - R_FK Sigma_FK^T)
    # Each variable keeps Sigma on (F + K) x (F + K) (its *front*) until its children have read theirs.
    # A variable whose rows nest into the next one's (the next is its parent, it is the parent's only child,
    # and its K is the parent's F + K) runs with it as one block of rows: fewer, larger steps.
    indptr, indices, data = R.indptr, R.indices, R.data
    n = R.shape[0]
    rows_after = indptr[starts[1:]] - indptr[starts[1:] - 1] - 1  # |K| of each variable's last row
    first_after = indices[np.minimum(indptr[starts[1:] - 1] + 1, len(indices) - 1)]
    nested = (rows_after[:-1] > 0) & (first_after[:-1] == starts[1:-1])
    only_child = np.bincount(np.searchsorted(starts, first_after[rows_after > 0], side="right") - 1,
                             minlength=len(rows_after)) == 1
    nested &= only_child[1:] & (rows_after[:-1] == np.diff(starts)[1:] + rows_after[1:])
    bounds = starts[np.flatnonzero(np.concatenate([[True], ~nested, [True]]))]
    count = len(bounds) - 1
    sizes = np.diff(bounds)
    owner = np.repeat(np.arange(count), sizes)
    # K of each variable: the columns after its rows in its last row; F + K its columns, in one array
    last = bounds[1:] - 1
    in_last = np.concatenate([np.arange(indptr[i], indptr[i + 1]) for i in last.tolist()])
    K_owner = np.repeat(np.arange(count), np.diff(indptr)[last])
    keep = indices[in_last] > last[K_owner]
    K_cols, K_owner = indices[in_last][keep], K_owner[keep]
    K_count = np.bincount(K_owner, minlength=count)
    K_ptr = np.concatenate([[0], np.cumsum(K_count)])
    width = sizes + K_count  # |F| + |K|
    col_ptr = np.concatenate([[0], np.cumsum(width)])
    cols = np.empty(col_ptr[-1], dtype=np.int64)
    K_at = col_ptr[K_owner] + sizes[K_owner] + np.arange(len(K_cols)) - K_ptr[K_owner]
    cols[K_at] = K_cols
    F_at = np.setdiff1d(np.arange(col_ptr[-1]), K_at, assume_unique=True)
    cols[F_at] = np.arange(n)
    key = np.repeat(np.arange(count), width) * n + cols  # ascending: variable, then column

    def position(v, c, what):
        """Where columns ``c`` of variable ``v`` (arrays) sit in ``cols``; ValueError off the pattern."""
        at = np.searchsorted(key, v * n + c)
        bad = (at >= len(key)) | (key[np.minimum(at, len(key) - 1)] != v * n + c)
        if bad.any():
            raise ValueError(f"R's pattern is not closed under elimination: {what(int(np.flatnonzero(bad)[0]))} (a "
                             "stored 0 is part of the pattern)")
        return at - col_ptr[v]

    # every stored entry's place in its (|F|, |F| + |K|) block of rows
    rows = np.repeat(np.arange(n), np.diff(indptr))
    local = position(owner[rows], indices, lambda k: f"row {rows[k]} stores column {indices[k]}, which the last "
                                                     f"row of its rows' block, {last[owner[rows[k]]]}, does not")
    row_ptr = np.concatenate([[0], np.cumsum(sizes * width)])
    blocks = np.zeros(row_ptr[-1])
    blocks[row_ptr[owner[rows]] + (rows - bounds[owner[rows]]) * width[owner[rows]] + local] = data
    parent = np.full(count, -1)
    parent[K_count > 0] = owner[cols[(col_ptr[:-1] + sizes)[K_count > 0]]]
    # K's places in the parent's columns
    where = position(parent[K_owner], K_cols, lambda k: f"row {last[K_owner[k]]} stores column {K_cols[k]}, which "
                                                        f"the rows from {bounds[parent[K_owner[k]]]} on do not")
    # X = R_FF^-1 of every block of rows, a size at a time
    X_all: list = [None] * count
    for d in np.unique(sizes).tolist():
        group = np.flatnonzero(sizes == d)
        R_FF = np.stack([blocks[row_ptr[v]:row_ptr[v + 1]].reshape(d, -1)[:, :d] for v in group.tolist()])
        for v, X in zip(group.tolist(), np.linalg.inv(np.triu(R_FF))):
            X_all[v] = X
    waiting = np.bincount(parent[parent >= 0], minlength=count)  # children yet to read a front
    fronts: list = [None] * count
    out: list = [None] * count
    for v in range(count - 1, -1, -1):
        d, w, X = sizes[v], width[v], X_all[v]
        front = np.empty((w, w))
        if w > d:
            p = parent[v]
            at = where[K_ptr[v]:K_ptr[v + 1]]
            S = fronts[p][at[:, None], at]
            R_FK = blocks[row_ptr[v]:row_ptr[v + 1]].reshape(d, w)[:, d:]
            S_FK = -X @ (R_FK @ S)
            front[:d, :d] = X @ (X.T - R_FK @ S_FK.T)
            front[:d, d:] = S_FK
            front[d:, :d] = S_FK.T
            front[d:, d:] = S
            waiting[p] -= 1
            if not waiting[p]:
                fronts[p] = None
        else:
            front[:, :] = X @ X.T
        out[v] = front[:d, :d]
        if waiting[v]:
            fronts[v] = front
    # each variable's block of its block of rows' front
    block = np.searchsorted(bounds, starts[:-1], side="right") - 1
    marginals = []
    for v, b in enumerate(block.tolist()):
        a, e = starts[v] - bounds[b], starts[v + 1] - bounds[b]
        marginals.append(0.5 * (out[b][a:e, a:e] + out[b][a:e, a:e].T))
    return marginals
    # END SOLUTION


def joint_marginal(R, sizes, keys):
    """The joint covariance of the variables ``keys`` (in the order given): ``Sigma[cols][:, cols]``
    (sum d, sum d), ``cols`` the rows of ``keys[0]``, then of ``keys[1]``, ...; cross-covariances included.

    Args: ``R`` and ``sizes`` as :func:`marginal_covariances`; ``keys`` a list of variable indices, no
    repeats. By triangular solves for the columns ``cols`` only (``E`` (n, sum d) the columns of the
    identity at ``cols``): ``Sigma E = R^-1 (R^-T E)``; no dense (n, n) matrix. Raises ``ValueError``
    for a key out of range or repeated, and as :func:`marginal_covariances` for R and sizes.
    """
    R, starts = check_inputs(R, sizes)
    keys = check_keys(keys, len(starts) - 1)
    # BEGIN SOLUTION
    n = R.shape[0]
    cols = np.concatenate([np.arange(starts[v], starts[v + 1]) for v in keys])
    E = np.zeros((n, len(cols)))
    E[cols, np.arange(len(cols))] = 1.0
    X = spsolve_triangular(R, spsolve_triangular(sp.csr_matrix(R.T), E, lower=True), lower=False)
    X = np.asarray(X).reshape(n, len(cols))
    return X[cols]
    # END SOLUTION


#: the derived results, in three levels (``python -m autograder hint NAME LEVEL``; the release
#: prints levels 1..N into the docstrings with ``--hints N``, course.core.hints)
HINTS = {
    "marginal_covariances": (
        """Multiply ``Sigma = R^-1 R^-T`` by R on the left: ``R Sigma = R^-T``, and R^-T is lower triangular
        with diagonal ``1 / R_ii``. Read the entries of this identity on and above the diagonal, one row of R
        at a time: each gives one entry of Sigma from entries of later rows. Go from the last row up, and keep
        Sigma in a dict or per-row arrays on R's pattern only.""",
        """Row i, column j >= i of ``R Sigma = R^-T``: ``R_ii Sigma_ij + sum_{k > i, R_ik stored} R_ik Sigma_kj
        = (R^-T)_ij``, which is ``1 / R_ii`` for j = i and 0 for j > i. Every k in the sum is a stored column of
        row i, and so is j when R_ij is stored: by the closure of the pattern, Sigma_kj (k, j > i) lies on the
        pattern of a later row (R_kj or R_jk stored), already computed. Sigma is symmetric: Sigma_kj = Sigma_jk.""",
        """From the last row up (i = n - 1, ..., 0), over the stored columns k > i of row i::

            Sigma_ij = -(1 / R_ii) sum_{k > i, R_ik stored} R_ik Sigma_kj     (j > i, R_ij stored) first,
            Sigma_ii =  (1 / R_ii) (1 / R_ii - sum_{k > i, R_ik stored} R_ik Sigma_ki)   then,

        with Sigma_kj = Sigma_jk. The last row gives Sigma_nn = 1 / R_nn^2. Variable v's marginal is the block
        ``Sigma[starts[v]:starts[v + 1], starts[v]:starts[v + 1]]``, on the pattern since R's diagonal blocks are
        stored whole.""",
    ),
    "joint_marginal": (
        """The columns of Sigma at ``cols`` are ``Sigma E``; ``Sigma = R^-1 R^-T`` applies as two triangular
        solves, never as an inverse. Then keep the rows ``cols`` of the result, in the order of ``keys``.""",
        """``Y = R^-T E`` solves the lower-triangular ``R^T Y = E``; ``X = R^-1 Y`` solves the upper-triangular
        ``R X = Y`` (scipy.sparse.linalg.spsolve_triangular, ``lower=True`` then ``lower=False``). The answer is
        ``X[cols]`` (equivalently ``Y^T Y``).""",
        """::

            cols = concatenate([arange(starts[v], starts[v + 1]) for v in keys])   # in the order of keys
            E = zeros((n, len(cols))); E[cols, arange(len(cols))] = 1
            Y = spsolve_triangular(R^T (CSR), E, lower=True)
            X = spsolve_triangular(R, Y, lower=False)
            return X[cols]                                                          # (sum d, sum d)""",
    ),
}
