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
    raise NotImplementedError("TODO marginal_covariances.marginal_covariances: not implemented yet")


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
    raise NotImplementedError("TODO marginal_covariances.joint_marginal: not implemented yet")
