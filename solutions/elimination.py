"""Chapter 8: eliminating one variable from a linear(ised) Gaussian factor graph.

The factors adjacent to a variable x, linearised, whitened and stacked, have the error::

    ||A_x x + A_s s - b||^2        A_x (m, n_x), A_s (m, n_s), b (m,)

where x is the variable (n_x unknowns) and s its separator: the other variables those factors
touch, stacked (n_s unknowns). A column block of A_s is zero in the rows of a factor that does
not touch that variable. Eliminating x splits this error into a Gaussian conditional on x given
s and a new factor on s alone (Dellaert and Kaess, "Factor Graphs for Robot Perception", ch. 3;
GTSAM's convention)::

    ||A_x x + A_s s - b||^2 = ||R x + S s - d||^2 + ||A_new s - b_new||^2 + c     for all x, s

with c >= 0 a constant and

- the conditional ``p(x | s) ~ exp(-1/2 ||R x + S s - d||^2)``: R (n_x, n_x) upper triangular
  and invertible, S (n_x, n_s), d (n_x,);
- the new factor ``||A_new s - b_new||^2``: A_new (k, n_s) for any k >= 0, b_new (k,).

The split is not unique: the rows of R (with the same rows of S and d) may change sign, and
A_new, b_new may be any rows with the same ``A_new^T A_new`` and ``A_new^T b_new``. The grader
compares what is unique: R upper triangular, ``R^T R``, ``R^T S``, ``R^T d``, ``A_new^T A_new`` and
``A_new^T b_new``. Derive the split (``python -m autograder hint eliminate_variable 1``, then 2
and 3); either way is right: an orthogonal factorisation of the stacked rows, or the Cholesky
factor of the information ``Lambda = [A_x A_s]^T [A_x A_s]`` (with ``eta = [A_x A_s]^T b``) and
its Schur complement. The new factor's information can be singular (it is zero when m = n_x):
writing it back as rows must not fail there.

A variable its factors do not determine (A_x of rank < n_x) has no conditional:
``SingularSystemError`` naming the rank (the given code checks this).

Inputs at the edges of the contract (each is a check input):
- one factor of n_x rows (m = n_x): the new factor is empty
- no separator (n_s = 0)
- a scalar variable (n_x = 1)
- a planar pose (n_x = 3) with factors of different sizes: a prior, odometry and a landmark
- ill-scaled whitened blocks (entries from 1e-3 to 1e3)
- fewer rows than n_x + n_s: the new factor's information is singular but not zero
- as many rows as n_x + n_s or more, with a separator direction no row measures (a singular new factor)

Allowed imports: numpy, scipy, course.core.errors.
"""

import numpy as np
import scipy.linalg
import scipy.linalg.lapack

from course.core.errors import ShapeError, SingularSystemError


def _clearly_full_rank(A_x) -> bool:
    """True when A_x (m, n_x) has rank n_x by a margin no rounding reaches, from the Cholesky factor R of its
    Gram matrix (cheaper than the SVD of ``matrix_rank``): ``sigma_min(A_x)^2 >= 1 / ||R^-1||_F^2`` up to the
    Gram matrix's rounding (about ``eps ||A_x||_F^2``). False (then the SVD decides) when not clear."""
    G = A_x.T @ A_x
    L, info = scipy.linalg.lapack.dpotrf(G, lower=1)  # LAPACK directly: a failure is info > 0, not an exception
    if info:
        return False
    L_inv, info = scipy.linalg.lapack.dtrtri(L, lower=1)
    margin = 1e3 * A_x.shape[1] * np.finfo(float).eps * np.trace(G)
    return not info and bool(margin * float(np.vdot(L_inv, L_inv)) < 1.0)


def _inputs(A_x, A_s, b):
    A_x, A_s, b = (np.asarray(a, dtype=float) for a in (A_x, A_s, b))
    for name, a, ndim in (("A_x", A_x, 2), ("A_s", A_s, 2), ("b", b, 1)):
        if a.ndim != ndim:
            raise ShapeError(f"{name} must be a {ndim}-D array, got shape {a.shape}")
        if not np.isfinite(a).all():
            raise ValueError(f"{name} has entries that are not finite")
    m = len(b)
    for name, a in (("A_x", A_x), ("A_s", A_s)):
        if len(a) != m:
            raise ShapeError(f"{name} has {len(a)} rows but b has {m}: every row is one whitened measurement")
    if A_x.shape[1] == 0:
        raise ShapeError("A_x has no columns: the eliminated variable has at least one unknown")
    if m >= A_x.shape[1] and _clearly_full_rank(A_x):
        return A_x, A_s, b
    rank = int(np.linalg.matrix_rank(A_x)) if m else 0
    if rank < A_x.shape[1]:
        raise SingularSystemError(
            f"A_x has rank {rank} < n_x = {A_x.shape[1]}: the factors adjacent to the variable do not "
            "determine it, so it has no Gaussian conditional (add a prior or more measurements)")
    return A_x, A_s, b


def eliminate_variable(A_x, A_s, b):
    """Eliminate the variable x from ``||A_x x + A_s s - b||^2``.

    Args: A_x (m, n_x) of rank n_x, A_s (m, n_s) (n_s may be 0), b (m,).
    Returns: ``(R, S, d, A_new, b_new)``: R (n_x, n_x) upper triangular, S (n_x, n_s), d (n_x,), A_new (k, n_s)
    and b_new (k,) for some k >= 0, such that for all x, s
    ``||A_x x + A_s s - b||^2 = ||R x + S s - d||^2 + ||A_new s - b_new||^2 + c`` (c >= 0 a constant).
    Raises ShapeError for rows that disagree or b not 1-D, SingularSystemError when A_x has rank < n_x.
    """
    A_x, A_s, b = _inputs(A_x, A_s, b)
    # BEGIN SOLUTION
    n_x, n_s = A_x.shape[1], A_s.shape[1]
    A = np.hstack([A_x, A_s])
    Lam = A.T @ A
    eta = A.T @ b
    L = np.linalg.cholesky(Lam[:n_x, :n_x])
    R = L.T
    S = scipy.linalg.lapack.dtrtrs(L, Lam[:n_x, n_x:], lower=1)[0]  # R^-T Lambda_xs (LAPACK's triangular solve)
    d = scipy.linalg.lapack.dtrtrs(L, eta[:n_x], lower=1)[0]  # R^-T eta_x
    Lam_new = Lam[n_x:, n_x:] - S.T @ S
    eta_new = eta[n_x:] - S.T @ d
    # the new factor: an upper Cholesky factor of [Lam_new | eta_new] that skips the pivots rounding
    # leaves of a direction no row measures (Lam_new is singular when m - n_x < n_s)
    # (a pivot at or below 1e-10 of its diagonal in Lambda_ss is zero up to rounding: no row measures it)
    floor = 1e-10 * np.diagonal(Lam)[n_x:]
    factor = None
    if n_s and len(b) >= n_x + n_s:  # most often definite: one factorisation, when no pivot is at the floor
        try:
            L_new = np.linalg.cholesky(Lam_new)
            if np.all(np.diagonal(L_new) ** 2 > floor):
                eta_rows = scipy.linalg.lapack.dtrtrs(L_new, eta_new, lower=1)[0]
                factor = np.column_stack([L_new.T, eta_rows])
        except np.linalg.LinAlgError:
            pass
    if factor is None and 0 < len(b) - n_x < n_s:  # fewer rows than unknowns: the rows of a QR, rank-deficient
        T = np.linalg.qr(np.column_stack([A_x, A_s, b]), mode="r")
        factor = T[n_x:, n_x:]
    if factor is None:  # pivot by pivot, skipping those at the floor; the pivots above it a run at a time
        W = np.column_stack([Lam_new, eta_new])
        rows = []
        j = 0
        while j < n_s:
            if W[j, j] <= floor[j]:  # skipped: nothing after it changes
                j += 1
                continue
            # the pivots from j on that LAPACK's Cholesky takes before the first at the floor: one run, its rows
            # at once (the same as one by one), the rows after it updated by one product
            U, info = scipy.linalg.lapack.dpotrf(W[j:n_s, j:n_s])
            q = info - 1 if info else n_s - j
            # (the first pivot, W[j, j], is above the floor by the test above: the run holds it at least)
            low = np.flatnonzero(np.diagonal(U)[1:q] ** 2 <= floor[j + 1:j + q])
            q = int(low[0]) + 1 if len(low) else q
            U = scipy.linalg.lapack.dpotrf(W[j:j + q, j:j + q])[0]  # the run's own factor (a failed call's is not)
            run = np.zeros((q, n_s + 1))
            run[:, j:j + q] = U
            run[:, j + q:] = scipy.linalg.lapack.dtrtrs(U, W[j:j + q, j + q:], trans=1)[0]
            W[j + q:, j + q:] -= run[:, j + q:n_s].T @ run[:, j + q:]
            rows += list(run)
            j += q
        factor = np.array(rows).reshape(len(rows), n_s + 1)
    return R, S, d, factor[:, :n_s], factor[:, n_s]
    # END SOLUTION


#: the derived results, in three levels (``python -m autograder hint NAME LEVEL``; the release
#: prints levels 1..N into the docstrings with ``--hints N``, course.core.hints)
HINTS = {
    "eliminate_variable": (
        """Either factorise the stacked rows ``[A_x | A_s | b]`` by an orthogonal transform (a partial QR:
        Householder reflections on x's columns), and read the conditional from the first n_x rows and the new
        factor from the rest; or form the information ``Lambda = A^T A``, ``eta = A^T b`` of ``A = [A_x A_s]``
        and complete the square in x: the new factor's information is the Schur complement of ``Lambda_xx``.""",
        """An orthogonal Q keeps the norm: ``||A_x x + A_s s - b|| = ||Q^T (A_x x + A_s s - b)||``, and with
        ``Q^T [A_x | A_s | b] = [[R, S, d], [0, A_new, b_new]]`` the squared norm splits in two. Or: the error is
        ``[x; s]^T Lambda [x; s] - 2 eta^T [x; s] + b^T b``; with ``Lambda_xx = R^T R`` write its x part as
        ``||R x + S s - d||^2`` and match the terms in ``x x``, ``x s`` and ``x``: ``R^T S = Lambda_xs`` and
        ``R^T d = eta_x``; what is left in s is ``s^T (Lambda_ss - S^T S) s - 2 (eta_s - S^T d)^T s``.""",
        """Cholesky route: ``R = chol(Lambda_xx)`` upper (``np.linalg.cholesky`` gives the lower ``L``;
        ``R = L^T``), ``S = R^-T Lambda_xs``, ``d = R^-T eta_x`` with ``eta = A^T b``; the new factor has
        information ``Lambda_ss - S^T S`` and information vector ``eta_s - S^T d``, written back as rows
        ``A_new``, ``b_new`` with ``A_new^T A_new = Lambda_ss - S^T S`` and ``A_new^T b_new = eta_s - S^T d``
        (a Cholesky that skips zero pivots, or ``diag(sqrt(e)) V^T`` over the positive eigenvalues e of
        ``eigh``, with ``b_new = diag(1 / sqrt(e)) V^T (eta_s - S^T d)``; it may be singular, even zero).
        QR route: ``np.linalg.qr(np.column_stack([A_x, A_s, b]), mode="r")`` gives ``T``; ``R = T[:n_x, :n_x]``,
        ``S = T[:n_x, n_x:-1]``, ``d = T[:n_x, -1]``, ``A_new = T[n_x:, n_x:-1]``, ``b_new = T[n_x:, -1]``
        (the signs of R's rows are free).""",
    ),
}
