"""Gaussian noise models: the information matrix as the whitening a linearisation applies.

With ``Omega = L L^T`` (Cholesky), ``e^T Omega e = |L^T e|^2``: the whitened residual is ``L^T e`` and
the whitened Jacobian ``L^T J``, so that the assembly sums ``J^T J`` and ``J^T r`` alone.
"""

import numpy as np


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


def whiten(W, r, J):
    """``(W r, [W J_a])`` for ``W`` (M, m, m) or None (unit)."""
    if W is None:
        return r, J
    return np.einsum("mab,mb->ma", W, r), [np.matmul(W, block) for block in J]
