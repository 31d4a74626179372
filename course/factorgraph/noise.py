"""Gaussian noise models: the information matrix as the whitening a linearisation applies.

With ``Omega = L L^T`` (Cholesky), ``e^T Omega e = |L^T e|^2``: the whitened residual is ``L^T e`` and
the whitened Jacobian ``L^T J``, so that the assembly sums ``J^T J`` and ``J^T r`` alone.

The noise models a user gives a factor (``graph.add(..., noise=sigmas([0.1, 0.1, 0.05]))``): standard
deviations, an isotropic sigma, a full covariance or an information matrix, each optionally robust
(``sigmas(...).robust("huber", 1.0)``), as GTSAM's ``noiseModel`` makes them.
"""

from dataclasses import dataclass, replace

import numpy as np

from course.solver.robust import RobustLoss


def whitening(information, dim: int, count: int, where: str) -> np.ndarray | None:
    """``L^T`` (M, dim, dim) of ``information`` (M, dim, dim) or (dim, dim) (one for all), or None for
    unit information; a ``ValueError`` naming ``where`` and the first factor whose information is not
    symmetric positive definite."""
    if information is None:
        return None
    info = np.asarray(information, dtype=float)
    if info.shape == (dim, dim):
        info = np.broadcast_to(info, (count, dim, dim))
    if info.shape != (count, dim, dim):
        raise ValueError(f"{where}: information has shape {info.shape}, expected ({count}, {dim}, {dim})")
    asymmetric = np.abs(info - info.transpose(0, 2, 1)).max(axis=(1, 2)) > 1e-9 * np.abs(info).max(axis=(1, 2))
    if asymmetric.any():
        raise ValueError(f"{where}: the information of factor {int(np.argmax(asymmetric))} is not symmetric")
    try:
        L = np.linalg.cholesky(info)
    except np.linalg.LinAlgError:
        smallest = np.linalg.eigvalsh(info)[:, 0]
        k = int(np.argmin(smallest))
        raise ValueError(f"{where}: the information of factor {k} is not positive definite "
                         f"(smallest eigenvalue {smallest[k]:.3g})") from None
    return np.ascontiguousarray(L.transpose(0, 2, 1))


def diagonal(W) -> np.ndarray | None:
    """The diagonal (M, m) of ``W`` (M, m, m) where every ``W`` is diagonal (independent noise), else None."""
    if W is None:
        return None
    d = np.diagonal(W, axis1=1, axis2=2)
    return np.ascontiguousarray(d) if np.count_nonzero(W) == np.count_nonzero(d) else None


def whiten(W, r, J, out=None, diagonal=None):
    """``(W r, [W J_a])`` for ``W`` (M, m, m) or None (unit); written into ``out = (r_out, [J_a_out])``
    where given (each of the shape of its input). ``diagonal``: ``W``'s diagonal (M, m) where ``W`` is
    diagonal (:func:`diagonal`), by which ``W r`` is the product entry by entry (the same numbers: the
    other terms are 0), ten times faster than the sum over ``b`` of ``W_ab r_b``."""
    def whitened_r(r_out=None):
        if diagonal is not None:
            return np.multiply(diagonal, r, out=r_out)
        return np.einsum("mab,mb->ma", W, r, out=r_out)

    if out is None:
        if W is None:
            return r, J
        return whitened_r(), [np.matmul(W, block) for block in J]
    r_out, J_out = out
    if W is None:
        r_out[...] = r
        for block, block_out in zip(J, J_out):
            block_out[...] = block
    else:
        whitened_r(r_out)
        for block, block_out in zip(J, J_out):
            np.matmul(W, block, out=block_out)
    return r_out, J_out


# ---------------------------------------------------------------- noise models for FactorGraph.add(..., noise=)


@dataclass(frozen=True)
class Noise:
    """A factor's noise: its ``information`` (dim, dim) or (M, dim, dim) (one per factor of an
    ``add_many``) and its robust ``loss`` (None or ``course.solver.robust.RobustLoss``), as GTSAM's
    ``noiseModel`` holds them. Made by :func:`sigmas`, :func:`isotropic`, :func:`covariance` or
    :func:`information`; :meth:`robust` wraps one in a robust kernel (GTSAM's ``noiseModel.Robust``)."""

    information: np.ndarray
    loss: RobustLoss | None = None

    @property
    def dim(self) -> int:
        return int(self.information.shape[-1])

    def robust(self, kernel: str, scale: float) -> "Noise":
        """This noise with the robust loss ``(kernel, scale)`` (chapter 4's kernels, ``huber``, ``cauchy``,
        ``tukey``, on each factor's whitened ``|r|^2``; ``scale`` in whitened units, GTSAM's ``k``)."""
        return replace(self, loss=RobustLoss(kernel, float(scale)))


def sigmas(values) -> Noise:
    """Independent standard deviations (dim,) (or (M, dim)): information ``diag(1 / sigma^2)``
    (GTSAM's ``noiseModel.Diagonal.Sigmas``)."""
    s = np.asarray(values, dtype=float)
    if s.ndim not in (1, 2) or not np.all(np.isfinite(s)) or np.any(s <= 0):
        raise ValueError(f"sigmas: expected positive finite standard deviations (dim,) or (M, dim), got {s!r}")
    info = np.zeros(s.shape + (s.shape[-1],))
    info[..., np.arange(s.shape[-1]), np.arange(s.shape[-1])] = 1.0 / s**2
    return Noise(info)


def isotropic(dim: int, sigma: float) -> Noise:
    """One standard deviation for all ``dim`` components (GTSAM's ``noiseModel.Isotropic.Sigma``)."""
    return sigmas(np.full(int(dim), float(sigma)))


def covariance(matrix) -> Noise:
    """A full covariance (dim, dim) (or (M, dim, dim)), symmetric positive definite: information its
    inverse (GTSAM's ``noiseModel.Gaussian.Covariance``)."""
    C = np.asarray(matrix, dtype=float)
    if C.ndim not in (2, 3) or C.shape[-1] != C.shape[-2]:
        raise ValueError(f"covariance: expected a square matrix (dim, dim) or (M, dim, dim), got shape {C.shape}")
    batch = C if C.ndim == 3 else C[None]
    whitening(batch, C.shape[-1], len(batch), "covariance")  # symmetric positive definite, or a named error
    info = np.linalg.inv(batch)
    return Noise(0.5 * (info + info.transpose(0, 2, 1)) if C.ndim == 3 else 0.5 * (info[0] + info[0].T))


def information(matrix) -> Noise:
    """An information matrix (dim, dim) (or (M, dim, dim)) as it is (GTSAM's ``Gaussian.Information``)."""
    return Noise(np.asarray(matrix, dtype=float))
