"""Robust losses in a least-squares problem whose normal equations are built from ``r`` and ``J``.

A loss ``(kernel, a)`` (:class:`RobustLoss`; ``kernel`` one of :data:`KERNELS`, the functions of
the implementation's ``robust_kernels`` module, ``a`` its scale in the units of |r|) replaces each
residual block's ``s_k = |r_k|^2`` (unit information) by ``rho(s_k)``::

    chi2 = sum_k rho(s_k)
    b = sum_k rho'_k J_k^T r_k                      (half the gradient of chi2, as without a loss)
    H = sum_k J_k^T W_k J_k,   W_k = robust_kernels.robust_information(r_k, I, rho'_k, rho''_k)

so the gain ratio of Levenberg-Marquardt compares chi2 with a model of the same chi2.

To reuse code that builds ``H = J^T J`` and ``b = J^T r`` (the student's ``normal_equations``
and ``schur_solve``) unchanged, :func:`reweight` hands it transformed residuals and Jacobians:
with the Cholesky factor ``L_k L_k^T = W_k`` (n, n)::

    J~_k = L_k^T J_k,   r~_k = L_k^-1 (rho'_k r_k)
    =>  J~_k^T J~_k = J_k^T W_k J_k,   J~_k^T r~_k = rho'_k J_k^T r_k

A block with ``rho'_k = 0`` (Tukey beyond its threshold) has ``W_k = 0`` and no gradient: its
``r~_k`` and ``J~_k`` are zero. Elsewhere W_k must be positive definite (it is, by the rule of
``robust_information``: the first-order ``rho' I``, or the corrected form where its smallest
eigenvalue is at least 1e-6 rho'); a weight that is not raises ``SingularSystemError`` naming the
block. The same square-root idea as Triggs et al. (1999, section 4.3), in a general form.
"""

from dataclasses import dataclass

import numpy as np

from course.core.errors import SingularSystemError, check_array

#: the kernels of ``robust_kernels`` a loss can name
KERNELS = ("huber", "cauchy", "tukey")


@dataclass(frozen=True)
class RobustLoss:
    """A robust kernel and its scale ``a`` > 0 (threshold at ``|r| = a``, i.e. ``s = a^2``)."""

    kernel: str
    scale: float

    def __post_init__(self):
        if self.kernel not in KERNELS:
            raise ValueError(f"loss: unknown kernel {self.kernel!r}; choose one of {', '.join(KERNELS)}")
        if isinstance(self.scale, bool) or not isinstance(self.scale, (int, float)) or not 0 < self.scale < np.inf:
            raise ValueError(f"loss: the scale of {self.kernel} must be a finite number > 0, got {self.scale!r}")

    @classmethod
    def of(cls, loss) -> "RobustLoss | None":
        """None (plain least squares), a RobustLoss, or ``(kernel, scale)`` such as ``("huber", 2.0)``."""
        if loss is None or isinstance(loss, RobustLoss):
            return loss
        if isinstance(loss, (tuple, list)) and len(loss) == 2 and isinstance(loss[0], str):
            scale = float(loss[1]) if isinstance(loss[1], (int, float, np.floating)) else loss[1]
            return cls(loss[0], scale)
        raise ValueError(f"loss: expected None or (kernel, scale) such as ('huber', 2.0), got {loss!r}")

    def __str__(self) -> str:
        return f"{self.kernel}(a={self.scale:g})"


def evaluate(module, loss: RobustLoss, s):
    """``(rho, d_rho, dd_rho)`` (K,) of ``module.<kernel>(s, scale)`` at squared norms ``s`` (K,), checked."""
    where = f"robust_kernels.{loss.kernel}"
    out = getattr(module, loss.kernel)(s, loss.scale)
    if not isinstance(out, tuple) or len(out) != 3:
        raise ValueError(f"{where} returned {type(out).__name__}, expected a tuple (rho, d_rho, dd_rho)")
    return tuple(check_array(v, (len(s),), where, name) for v, name in zip(out, ("rho", "d_rho", "dd_rho")))


def robust_chi2(module, loss: RobustLoss, r) -> float:
    """``sum_k rho(|r_k|^2)`` for residual blocks r (K, n); inf when some residual is not finite."""
    r = np.asarray(r, dtype=float)
    if not np.all(np.isfinite(r)):
        return float("inf")
    rho, _, _ = evaluate(module, loss, np.sum(r * r, axis=1))
    return float(np.sum(rho))


def reweight(module, loss: RobustLoss, r, jacobians, values=None):
    """``(r~ (K, n), (J~ ...), chi2)``: residual blocks r (K, n) and Jacobian blocks (K, n, m_j)
    transformed so that ``J~^T J~ = J^T W J`` and ``J~^T r~ = rho' J^T r`` (module docstring);
    ``chi2 = sum_k rho(|r_k|^2)``. ``values``: :func:`evaluate`'s ``(rho, d_rho, dd_rho)`` at these
    r where the caller has them already."""
    r = np.asarray(r, dtype=float)
    K, n = r.shape
    s = np.sum(r * r, axis=1)
    rho, d_rho, dd_rho = evaluate(module, loss, s) if values is None else values
    where = f"robust_kernels.{loss.kernel}"
    if np.any(d_rho < 0):
        k = int(np.flatnonzero(d_rho < 0)[0])
        raise ValueError(f"{where} returned d_rho[{k}] = {d_rho[k]} < 0 at s = {s[k]}: a robust kernel never decreases")
    weight = check_array(module.robust_information(r, np.eye(n), d_rho, dd_rho), (K, n, n),
                         "robust_kernels.robust_information", "weighted")
    if n == 2:  # pixel residuals (bundle adjustment, VIO): the 2x2 Cholesky factor written out
        out = _reweight_2(r, jacobians, weight, d_rho)
        if out is not None:
            return out[0], out[1], float(np.sum(rho))
    active = np.flatnonzero(d_rho > 0)
    L = np.zeros((K, n, n))
    try:
        L[active] = np.linalg.cholesky(weight[active])
    except np.linalg.LinAlgError:
        lowest = np.linalg.eigvalsh(weight[active])[:, 0]
        k = int(active[np.argmin(lowest / d_rho[active])])
        raise SingularSystemError(
            f"robust_kernels.robust_information returned a weight that is not positive definite for residual {k} "
            f"(s = {s[k]:.6g}, rho' = {d_rho[k]:.6g}, rho'' = {dd_rho[k]:.6g}, eigenvalues "
            f"{np.linalg.eigvalsh(weight[k])}): use the corrected form only where rho' + 2 rho'' s > 1e-6 rho'"
        ) from None
    r_tilde = np.zeros((K, n))
    scaled = d_rho[active, None] * r[active]
    r_tilde[active] = np.linalg.solve(L[active], scaled[:, :, None])[:, :, 0]
    L_t = L.transpose(0, 2, 1)
    return r_tilde, tuple(np.matmul(L_t, np.asarray(J, dtype=float)) for J in jacobians), float(np.sum(rho))


def _reweight_2(r, jacobians, weight, d_rho):
    """:func:`reweight`'s ``(r~, J~s)`` for blocks of 2 rows, with ``L = [[l00, 0], [l10, l11]]``,
    ``l00 = sqrt(w00)``, ``l10 = w10 / l00``, ``l11 = sqrt(w11 - l10^2)`` (what LAPACK computes), or
    None when some active weight is not positive definite (the general path says which)."""
    active = d_rho > 0
    w00, w10, w11 = weight[:, 0, 0], weight[:, 1, 0], weight[:, 1, 1]
    if active.all():  # every block weighted (Huber, Cauchy; Tukey within its threshold): no masks, same values
        return _reweight_2_all(r, jacobians, w00, w10, w11, d_rho)
    with np.errstate(invalid="ignore", divide="ignore"):
        l00 = np.sqrt(np.where(active, w00, 1.0))
        l10 = np.where(active, w10, 0.0) / l00
        pivot = np.where(active, w11, 1.0) - l10 * l10
        if not np.all(w00[active] > 0) or not np.all(pivot > 0):
            return None
    l11 = np.sqrt(pivot)
    scaled = np.where(active, d_rho, 0.0)[:, None] * r
    y0 = scaled[:, 0] / l00
    r_tilde = np.stack([y0, (scaled[:, 1] - l10 * y0) / l11], axis=1)
    on = active.astype(float)
    return r_tilde, _lower_times(jacobians, l00 * on, l10 * on, l11 * on)


def _reweight_2_all(r, jacobians, w00, w10, w11, d_rho):
    """:func:`_reweight_2` where every ``rho'`` is positive (no block left out)."""
    with np.errstate(invalid="ignore", divide="ignore"):
        l00 = np.sqrt(w00)
        l10 = w10 / l00
        pivot = w11 - l10 * l10
        if not np.all(w00 > 0) or not np.all(pivot > 0):
            return None
    l11 = np.sqrt(pivot)
    scaled = d_rho[:, None] * r
    r_tilde = np.empty_like(scaled)
    r_tilde[:, 0] = y0 = scaled[:, 0] / l00
    r_tilde[:, 1] = (scaled[:, 1] - l10 * y0) / l11
    return r_tilde, _lower_times(jacobians, l00, l10, l11)


def _lower_times(jacobians, l00, l10, l11) -> tuple:
    """Each ``J`` (K, 2, c) times ``L^T`` on the left, ``L = [[l00, 0], [l10, l11]]`` (each (K,)): its rows
    ``l00 J_0 + l10 J_1`` and ``l11 J_1``."""
    l00, l10, l11 = l00[:, None], l10[:, None], l11[:, None]
    weighted = []
    for J in jacobians:
        J = np.asarray(J, dtype=float)
        J_tilde = np.empty_like(J)
        J_tilde[:, 0] = l00 * J[:, 0] + l10 * J[:, 1]
        J_tilde[:, 1] = l11 * J[:, 1]
        weighted.append(J_tilde)
    return tuple(weighted)
