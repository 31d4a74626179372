"""The square-root information ``R`` (upper triangular, ``H[p, p] = R^T R``) in a given order.

The factorisation is not the marginals' exercise: it is CHOLMOD's supernodal ``L L^T`` (through
cvxopt, the factorisation the solvers use on large systems) in the permutation ``p`` given
(``nmethods = 1``, no postordering, so that each variable's scalars stay together), and
``R = L^T``. Where cvxopt is not installed, numpy's dense Cholesky factorises systems of at most
:data:`DENSE_LIMIT` scalars (its R stores the whole upper triangle).

The exercise's contract on R's stored pattern holds by construction: a symbolic Cholesky factor's
pattern is closed under elimination, and it contains the pattern of ``H[p, p]``, to which every
variable's diagonal block is added whole (stored zeros) before the analysis.
"""

import numpy as np
import scipy.sparse as sp

from course.core.errors import SingularSystemError
from course.core.peers import installed

#: the most scalars the dense fallback factorises (an (n, n) array of floats: 128 MB at 4000)
DENSE_LIMIT = 4000


def with_whole_blocks(H_upper, starts) -> sp.coo_matrix:
    """``H_upper`` (n, n) with every variable's diagonal block stored whole (its upper triangle; the
    entries H does not store are stored as 0), as COO upper triangle."""
    coo = sp.coo_matrix(sp.triu(H_upper))
    sizes = np.diff(starts)
    rows, cols = [], []
    for d in np.unique(sizes):
        a, b = np.triu_indices(int(d))
        first = np.asarray(starts[:-1])[sizes == d]
        rows.append((first[:, None] + a).ravel())
        cols.append((first[:, None] + b).ravel())
    row = np.concatenate([coo.row, *rows])
    col = np.concatenate([coo.col, *cols])
    data = np.concatenate([coo.data, np.zeros(len(row) - coo.nnz)])
    return sp.coo_matrix((data, (row, col)), shape=coo.shape)


def square_root_information(H_upper, starts, perm) -> sp.csr_matrix:
    """``R`` (n, n), CSR, upper triangular with ``H[perm][:, perm] = R^T R``, its pattern closed under
    elimination with each variable's diagonal block stored whole (the variables' ``starts`` (m + 1,) in
    H's order; ``perm`` (n,) keeps each variable's scalars together). ``SingularSystemError`` when H is
    not positive definite."""
    n = H_upper.shape[0]
    perm = np.asarray(perm, dtype=np.int64)
    upper = with_whole_blocks(H_upper, starts)
    if installed("cvxopt"):
        return _checked(_cholmod(upper, perm), upper)
    if n > DENSE_LIMIT:
        raise SingularSystemError(f"cvxopt (CHOLMOD) is not installed here and H has {n} rows, above the dense "
                                  f"factorisation's {DENSE_LIMIT}: pip install cvxopt")
    full = upper.toarray()
    full = full + np.triu(full, 1).T
    try:
        L = np.linalg.cholesky(full[np.ix_(perm, perm)])
    except np.linalg.LinAlgError:
        raise SingularSystemError("H is not positive definite (numpy's Cholesky failed)") from None
    rows, cols = np.triu_indices(n)
    return _checked(sp.csr_matrix((L.T[rows, cols], (rows, cols)), shape=(n, n)), upper)


#: a pivot ``R_ii^2`` below this times H's largest diagonal entry is a singular direction's rounding
PIVOT_FLOOR = 1e-13


def _checked(R, upper) -> sp.csr_matrix:
    """``R``, or ``SingularSystemError`` naming the smallest pivot when it is rounding's (a singular H
    that the factorisation got through with tiny positive pivots)."""
    pivots = R.diagonal() ** 2
    largest = float(np.max(upper.diagonal(), initial=0.0))
    k = int(np.argmin(pivots))
    if not np.all(np.isfinite(R.data)) or pivots[k] <= PIVOT_FLOOR * largest:
        raise SingularSystemError(f"H is singular to rounding: the pivot R_kk^2 = {pivots[k]:.3g} (row {k} of the "
                                  f"ordered H) against its largest diagonal entry {largest:.3g}")
    return R


def _cholmod(upper, perm) -> sp.csr_matrix:
    import cvxopt
    from cvxopt import cholmod

    n = upper.shape[0]
    matrix = cvxopt.spmatrix(upper.data, upper.row.astype(np.int64), upper.col.astype(np.int64), (n, n))
    saved = dict(cholmod.options)
    cholmod.options.clear()  # module-wide: the solvers' CholmodSolver factorises with the defaults
    cholmod.options.update({"supernodal": 2, "nmethods": 1, "postorder": False})
    try:
        symbolic = cholmod.symbolic(matrix, p=cvxopt.matrix(perm, tc="i"), uplo="U")
        cholmod.numeric(matrix, symbolic)
        L = cholmod.getfactor(symbolic)
    except ArithmeticError as exc:
        raise SingularSystemError(f"CHOLMOD could not factorise H: it is not positive definite ({exc})") from exc
    finally:
        cholmod.options.clear()
        cholmod.options.update(saved)
    colptr, rowind, values = L.CCS  # L (lower) by columns is R = L^T by rows
    return sp.csr_matrix((np.array(values, dtype=float).ravel(), np.array(rowind, dtype=np.int64).ravel(),
                          np.array(colptr, dtype=np.int64).ravel()), shape=(n, n))
