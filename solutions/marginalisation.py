"""Chapter 5: marginalisation, the prior a sliding-window back end keeps of what it drops.

A sliding window (a visual-inertial estimator's last few poses and the landmarks they see)
stays small by removing its oldest variables, but their measurements must not be lost:
they are folded into a *prior* on the variables that remain. With the course's convention
(``b = J^T W r``, the Gauss-Newton step solves ``H dx = -b``) the window's linearised cost is::

    c(dx) = 1/2 dx^T H dx + b^T dx + const

Split ``dx`` into the variables to remove (m) and those kept (r, in their original order)::

    H = [[H_rr, H_rm],      b = [b_r,
         [H_mr, H_mm]]           b_m]

Minimise ``c`` over ``dx_m`` (for a given ``dx_r``) and put the minimiser back: what is left is a
cost of ``dx_r`` alone, ``1/2 dx_r^T H_prior dx_r + b_prior^T dx_r + const``. Derive ``H_prior`` and
``b_prior`` from the blocks (``python -m autograder hint marginalise 1``, then 2 and 3).

This is also the information form of the Gaussian marginal: when H is definite,
``H_prior = ((H^-1)_rr)^-1``. Removing x2 from a chain x1 - x2 - x3 leaves a direct factor
between x1 and x3 (fill-in): the prior couples every kept variable that shared a
factor with a removed one.

``H_mm`` can be singular: a landmark seen once (by one bearing) is unconstrained along the
ray, a window without a prior has a gauge freedom. Its inverse is therefore taken as a
pseudo-inverse from the eigen-decomposition of the symmetrised block, dropping the
eigenvalues at or below ``eps`` times the largest one (a *relative* threshold: the scale of
H is the units' choice, an absolute one would depend on it).

Inputs at the edges of the contract (each is a check input):
- marginalise: one variable removed (m = 1)
- marginalise: removed indices neither contiguous nor sorted
- marginalise: H_mm singular (a landmark seen once, by one bearing)
- marginalise: an eigenvalue of H_mm 1e-12 times its largest (below eps max(s), dropped)
- prior_residual: H_prior of full rank
- prior_residual: H_prior of rank 4 of 6 (exact zero eigenvalues)
- prior_residual: an eigenvalue above an absolute 1e-8 but below eps max(s) (dropped)
- prior_update: J square
- prior_update: J with fewer rows than columns (a prior of lower rank)

Allowed imports: numpy, scipy.
"""

import numpy as np


def _matrix(H, name):
    H = np.asarray(H, dtype=float)
    if H.ndim != 2 or H.shape[0] != H.shape[1]:
        raise ValueError(f"{name} must be a square matrix, got shape {H.shape}")
    if not np.all(np.isfinite(H)):
        raise ValueError(f"{name} has entries that are not finite")
    return H


def _vector(b, n, name):
    b = np.asarray(b, dtype=float)
    if b.shape != (n,):
        raise ValueError(f"{name} must have shape ({n},), got {b.shape}")
    if not np.all(np.isfinite(b)):
        raise ValueError(f"{name} has entries that are not finite")
    return b


def _eps(eps):
    if not (np.isfinite(eps) and 0.0 <= eps < 1.0):
        raise ValueError(f"eps must be in [0, 1) (relative to the largest eigenvalue), got {eps}")
    return float(eps)


def removal_indices(remove, n):
    """``remove`` as an int array after checking it: integers in ``[0, n)``, no duplicates,
    not every index (something must be kept). Raises ``ValueError`` naming ``remove``."""
    raw = np.asarray(remove)
    if raw.ndim != 1:
        raise ValueError(f"remove must be a 1-D array of indices, got shape {raw.shape}")
    if raw.size and not np.issubdtype(raw.dtype, np.integer):
        raise ValueError(f"remove must hold integer indices, got dtype {raw.dtype}")
    remove = raw.astype(np.int64)
    if np.any((remove < 0) | (remove >= n)):
        raise ValueError(f"remove has indices outside [0, {n}): {remove[(remove < 0) | (remove >= n)].tolist()}")
    if len(np.unique(remove)) != len(remove):
        raise ValueError(f"remove has duplicate indices: {sorted(remove.tolist())}")
    if len(remove) == n:
        raise ValueError("remove names every variable: nothing would be kept")
    return remove


def marginalise(H, b, remove, eps=1e-8):
    """The prior ``(H_prior, b_prior)`` on the kept variables after removing ``remove``.

    Args:
        H: (n, n) the window's symmetric positive semidefinite ``J^T W J``;
        b: (n,) its ``J^T W r`` (the step solves ``H dx = -b``);
        remove: (m,) distinct indices in ``[0, n)`` of the variables to marginalise, in any order;
        eps: eigenvalues of ``H_mm`` at or below ``eps`` times its largest are treated as zero.

    Eliminate the removed variables ``dx_m`` from ``H dx = -b`` (block rows r and m): what is left
    is a system ``H_prior dx_r = -b_prior`` in the kept ones; derive it (``python -m autograder hint
    marginalise``), with the pseudo-inverse ``H_mm^+`` in place of ``H_mm^-1``.

    Returns:
        ``H_prior`` (n - m, n - m) and ``b_prior`` (n - m,), over the kept indices in increasing
        (original) order, where ``H_mm^+ = V diag(1 / s) V^T`` over the eigenpairs ``(s, V[:, k])`` of
        ``(H_mm + H_mm^T) / 2`` with ``s > eps max(s)`` (``np.linalg.eigh``: eigenvectors are
        the columns of V).
    """
    H = _matrix(H, "H")
    n = len(H)
    b = _vector(b, n, "b")
    remove = removal_indices(remove, n)
    eps = _eps(eps)
    # BEGIN SOLUTION
    keep = np.array([i for i in range(n) if i not in set(remove.tolist())], dtype=np.int64)
    H_mm = H[np.ix_(remove, remove)]
    s, V = np.linalg.eigh(0.5 * (H_mm + H_mm.T))
    big = s > eps * s.max() if len(s) and s.max() > 0 else np.zeros(len(s), dtype=bool)
    H_mm_inv = (V[:, big] / s[big]) @ V[:, big].T
    H_rm = H[np.ix_(keep, remove)]
    H_mr = H[np.ix_(remove, keep)]
    H_prior = H[np.ix_(keep, keep)] - H_rm @ H_mm_inv @ H_mr
    b_prior = b[keep] - H_rm @ H_mm_inv @ b[remove]
    return 0.5 * (H_prior + H_prior.T), b_prior
    # END SOLUTION


def prior_residual(H_prior, b_prior, eps=1e-8):
    """The prior as a residual ``e(dx) = e + J dx`` whose cost ``1/2 |e + J dx|^2`` has
    Hessian ``J^T J = H_prior`` and gradient ``J^T e = b_prior`` (so a solver can treat the
    prior as one more factor).

    With the eigen-decomposition ``H_prior = V diag(s) V^T`` (``np.linalg.eigh`` of the
    symmetrised matrix) and only the eigenpairs with ``s > eps max(s)`` kept (relative
    threshold, as in :func:`marginalise`)::

        J = diag(sqrt(s)) V^T            (r, n)
        e = diag(1 / sqrt(s)) V^T b_prior  (r,)

    where r is the number of eigenvalues kept. Then ``J^T J = V diag(s) V^T`` and
    ``J^T e = V V^T b_prior``, which is ``b_prior`` whenever ``b_prior`` lies in the range of
    ``H_prior`` (always so for a prior from :func:`marginalise` of a window ``J^T J``,
    ``J^T r``). J and e are unique only up to a common orthogonal transform of their rows.

    Args: H_prior (n, n) symmetric positive semidefinite, b_prior (n,), eps in [0, 1).
    Returns: ``(J (r, n), e (r,))``.
    """
    H_prior = _matrix(H_prior, "H_prior")
    b_prior = _vector(b_prior, len(H_prior), "b_prior")
    eps = _eps(eps)
    # BEGIN SOLUTION
    s, V = np.linalg.eigh(0.5 * (H_prior + H_prior.T))
    big = s > eps * s.max() if len(s) and s.max() > 0 else np.zeros(len(s), dtype=bool)
    root = np.sqrt(s[big])
    J = root[:, None] * V[:, big].T
    e = (V[:, big].T @ b_prior) / root
    return J, e
    # END SOLUTION


def prior_update(J, e0, x_lin, x):
    """The prior's residual at the kept state ``x`` to first order, its Jacobian fixed at
    the linearisation point ``x_lin`` where it was made (as sliding-window estimators do:
    relinearising a prior would need the measurements it replaced)::

        e(x) = e0 + J (x - x_lin)

    Args: J (r, n), e0 (r,) from :func:`prior_residual`; x_lin (n,) the kept variables when
    the prior was made; x (n,) their current values (vector states updated by addition).
    Returns: e (r,).
    """
    J = np.asarray(J, dtype=float)
    if J.ndim != 2:
        raise ValueError(f"J must be a 2-D array, got shape {J.shape}")
    e0 = _vector(e0, J.shape[0], "e0")
    x_lin = _vector(x_lin, J.shape[1], "x_lin")
    x = _vector(x, J.shape[1], "x")
    # BEGIN SOLUTION
    return e0 + J @ (x - x_lin)
    # END SOLUTION


#: the derived results, in three levels (``python -m autograder hint NAME LEVEL``; the release
#: prints levels 1..N into the docstrings with ``--hints N``, course.core.hints)
HINTS = {
    "marginalise": (
        """Reorder the unknowns as (kept r, removed m): ``[[H_rr, H_rm], [H_mr, H_mm]] [dx_r; dx_m] = -[b_r; b_m]``.
        Solve the second block row for ``dx_m`` and put it into the first.""",
        """``dx_m = -H_mm^+ (b_m + H_mr dx_r)``, so ``(H_rr - H_rm H_mm^+ H_mr) dx_r = -(b_r - H_rm H_mm^+ b_m)``:
        the Schur complement of ``H_mm``.""",
        """``H_prior = H_rr - H_rm H_mm^+ H_mr`` and ``b_prior = b_r - H_rm H_mm^+ b_m``.""",
    ),
}
