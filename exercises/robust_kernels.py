"""Chapter 4 exercise: robust kernels and the robust weighting of a residual's information.

A robust kernel ``rho`` replaces a residual's squared Mahalanobis norm ``s = e^T Omega e`` in
the cost: ``chi2 = sum_k rho(s_k)`` instead of ``sum_k s_k`` (the course's chi2 has no 1/2).
Every kernel here follows Ceres' scaled form (``ceres/loss_function.h``): with the scale
``a > 0`` in the units of the residual's norm ``|e| = sqrt(s)``, the kernel is
``a^2 rho_1(s / a^2)`` for its unit form ``rho_1``, so that ``rho(s) = s + O(s^2)`` near 0
(``rho(0) = 0``, ``rho'(0) = 1``) and the threshold between the quadratic and the robust part
sits at ``s = a^2``, i.e. ``|e| = a``::

    Huber   rho(s) = s                          for s <= a^2
                   = 2 a sqrt(s) - a^2          for s >  a^2
    Cauchy  rho(s) = a^2 log(1 + s / a^2)
    Tukey   rho(s) = a^2 / 3 (1 - (1 - s / a^2)^3)   for s <= a^2
                   = a^2 / 3                         for s >  a^2

Huber and Cauchy are exactly Ceres' ``HuberLoss(a)`` and ``CauchyLoss(a)``. Tukey is twice
Ceres' ``TukeyLoss(a)``, which is ``a^2 / 6 (1 - (1 - s / a^2)^3)`` with ``rho'(0) = 1/2``:
here every kernel has ``rho'(0) = 1``, so that an inlier costs what it costs without a kernel.

Each kernel function returns ``(rho, d_rho, dd_rho)``: the value ``rho(s)`` and the
derivatives ``rho'(s)``, ``rho''(s)`` *in s* (not in |e|), every one an array (K,), one entry
per residual: derive them from the definitions above (``python -m autograder hint huber 1``, and
``cauchy``, ``tukey``). Gauss-Newton with a kernel (Triggs, McLauchlan, Hartley, Fitzgibbon,
"Bundle Adjustment - A Modern Synthesis", 1999, section 4.3) differentiates ``rho(e(x)^T Omega
e(x))`` twice by the chain rule, keeping only first derivatives of ``e``:
:func:`robust_information` gives the weighted information that takes Omega's place in
``H = J^T Omega J``. No Python loop over residuals.
K >= 1 residuals everywhere.

Inputs at the edges of the contract (each is a check input):
- huber: s = 0
- huber: one residual (K = 1)
- huber: s exactly at the threshold a^2 (a binary fraction: a^2 exact)
- huber: s just above the threshold (a^2 (1 + 2^-20); hidden 1e-7 to 1e-3 above)
- cauchy: s = 0
- cauchy: one residual (K = 1)
- tukey: s = 0
- tukey: one residual (K = 1)
- tukey: s exactly at the threshold a^2 (a binary fraction: a^2 exact)
- tukey: s just above the threshold (a^2 (1 + 2^-20); hidden 1e-7 to 1e-3 above)
- robust_information: one residual (K = 1)
- robust_information: one Omega (n, n) shared by all residuals
- robust_information: exactly on rho' + 2 rho'' s = 0 (Huber's robust branch: first-order)
- robust_information: just above the margin, rho' + 2 rho'' s = 1.1e-6 rho' (corrected)
- robust_information: just below the margin, rho' + 2 rho'' s = 0.5e-6 rho' (first-order)

Allowed imports: numpy, scipy.
"""

import numpy as np

#: the corrected weighting is used where its eigenvalue along the residual, relative to rho',
#: is at least this (a margin above rounding: see :func:`robust_information`)
DEFINITE_MARGIN = 1e-6


def _check_s(s, scale, function):
    """``s`` as a float array (K,) of finite values >= 0 and ``scale`` as a float > 0, or ValueError."""
    s = np.asarray(s, dtype=float)
    if s.ndim != 1:
        raise ValueError(f"{function}: s must be an array (K,) of squared norms, got shape {s.shape}")
    bad = np.flatnonzero(~np.isfinite(s) | (s < 0))
    if len(bad):
        k = int(bad[0])
        what = "is negative" if np.isfinite(s[k]) else "is not a finite number"
        raise ValueError(f"{function}: s[{k}] = {s[k]} {what}: s = e^T Omega e is a squared norm, >= 0")
    try:
        a = float(scale)
    except (TypeError, ValueError):
        raise ValueError(f"{function}: scale must be a number > 0, got {scale!r}") from None
    if not 0 < a < np.inf:
        raise ValueError(f"{function}: scale must be a finite number > 0, got {a}")
    return s, a


def huber(s, scale):
    """Huber's kernel: ``(rho, d_rho, dd_rho)`` (K,) each at squared norms ``s`` (K,), scale ``a``.

    With ``a = scale`` (the branch ``s <= a^2`` includes the threshold itself)::

        s <= a^2:  rho = s
        s >  a^2:  rho = 2 a sqrt(s) - a^2

    Derive ``rho'`` and ``rho''`` in s on each branch (``python -m autograder hint huber``); ``rho``
    and ``rho'`` are continuous at ``s = a^2``, ``rho''`` is not. The robust branch is the linear ``2 a |e| - a^2`` in
    ``|e| = sqrt(s)``. Hint: ``np.where`` on both branches, with ``sqrt(s)`` replaced by 1 where
    it is not used, so that s = 0 never divides by zero.
    """
    s, a = _check_s(s, scale, "robust_kernels.huber")
    raise NotImplementedError("TODO robust_kernels.huber: not implemented yet")


def cauchy(s, scale):
    """Cauchy's (Lorentzian) kernel: ``(rho, d_rho, dd_rho)`` (K,) each at ``s`` (K,), scale ``a``.

    With ``t = 1 + s / a^2``: ``rho = a^2 log(t)``; derive ``rho'`` and ``rho''`` in s
    (``python -m autograder hint cauchy``).

    Hint: ``np.log1p(s / a^2)`` keeps full precision for small s.
    """
    s, a = _check_s(s, scale, "robust_kernels.cauchy")
    raise NotImplementedError("TODO robust_kernels.cauchy: not implemented yet")


def tukey(s, scale):
    """Tukey's biweight: ``(rho, d_rho, dd_rho)`` (K,) each at ``s`` (K,), scale ``a``.

    With ``u = 1 - s / a^2``::

        s <= a^2:  rho = a^2 / 3 (1 - u^3)
        s >  a^2:  rho = a^2 / 3

    Derive ``rho'`` and ``rho''`` in s (``python -m autograder hint tukey``); all three are
    continuous at ``s = a^2`` (u = 0): a residual beyond the threshold has no
    influence at all. Note ``1 - u^3 = (s / a^2)(1 + u + u^2)``, exact for small s.
    (Ceres' ``TukeyLoss`` is half of this, with ``rho'(0) = 1/2``: here ``rho'(0) = 1``.)
    """
    s, a = _check_s(s, scale, "robust_kernels.tukey")
    raise NotImplementedError("TODO robust_kernels.tukey: not implemented yet")


def robust_information(e, Omega, d_rho, dd_rho):
    """The robust weighting of each residual's information: ``weighted`` (K, n, n).

    Args: residuals ``e`` (K, n); information ``Omega`` (K, n, n), or (n, n) shared by all;
    ``d_rho``, ``dd_rho`` (K,): a kernel's ``rho'(s_k)``, ``rho''(s_k)`` at ``s_k = e_k^T Omega_k e_k``.

    The *corrected* form is the Hessian of ``rho(e^T Omega e)`` in e, halved like chi2's
    ``H = J^T Omega J``: derive it (``python -m autograder hint robust_information``); it is
    ``rho' Omega`` plus a rank-one term along ``v = Omega e`` (n,). The *first-order* form is
    ``rho' Omega`` alone (the halved gradient is ``rho' Omega e`` either way). The rank-one term changes the curvature
    along one direction only: for Omega positive definite the corrected form is positive
    semi-definite exactly when ``rho' + 2 rho'' s >= 0`` (its eigenvalue along that direction,
    in the metric of Omega, is ``rho' + 2 rho'' s``; the others are ``rho'``). Use, per residual::

        corrected    where  rho' + 2 rho'' s > DEFINITE_MARGIN rho'      (DEFINITE_MARGIN = 1e-6)
        first-order  elsewhere

    Why: an indefinite weight would make H indefinite and the step could go uphill, so there
    the first-order form (always positive semi-definite for rho' >= 0, what iteratively
    reweighted least squares uses) is taken. The test is strict, with a margin, rather than
    ``>= 0``: at equality the weight is singular along ``Omega e`` while the gradient points
    along it (the quadratic model is then linear in that direction), and Huber's whole robust
    branch sits exactly on the equality (``rho' + 2 rho'' s = a/sqrt(s) - a/sqrt(s) = 0``), where
    rounding would decide. So: Huber's robust branch gets the first-order form, Cauchy the
    corrected one for ``s < a^2``, Tukey for ``s < a^2 / 5``. (Triggs et al. 1999, section 4.3,
    apply the correction as a square root, scaling e and J, which needs
    ``1 + 2 s rho'' / rho' > 0``; Ceres' corrector applies it only where ``rho'' > 0`` and the
    first-order scaling by ``sqrt(rho')`` elsewhere.)

    Hint: ``np.einsum`` or ``np.matmul`` on stacks; ``np.where`` on a (K, 1, 1) mask.
    """
    e = np.asarray(e, dtype=float)
    Omega = np.asarray(Omega, dtype=float)
    d_rho, dd_rho = np.asarray(d_rho, dtype=float), np.asarray(dd_rho, dtype=float)
    where = "robust_kernels.robust_information"
    if e.ndim != 2:
        raise ValueError(f"{where}: e must be an array (K, n) of residuals, got shape {e.shape}")
    K, n = e.shape
    if Omega.shape not in ((n, n), (K, n, n)):
        raise ValueError(f"{where}: Omega must have shape ({n}, {n}) or ({K}, {n}, {n}) for e of shape {e.shape}, "
                         f"got {Omega.shape}")
    for name, value in (("d_rho", d_rho), ("dd_rho", dd_rho)):
        if value.shape != (K,):
            raise ValueError(f"{where}: {name} must have shape ({K},) for e of shape {e.shape}, got {value.shape}")
    raise NotImplementedError("TODO robust_kernels.robust_information: not implemented yet")
