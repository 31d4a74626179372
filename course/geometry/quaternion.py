"""Unit quaternions ``(qx, qy, qz, qw)`` (the order of g2o files) and rotation matrices,
vectorized over K: what the 3D readers, writers and peers convert with."""

import numpy as np


def to_matrix(q) -> np.ndarray:
    """Rotation matrices (K, 3, 3) of quaternions q (K, 4) ``(x, y, z, w)``, normalised first
    (files do not always give them to the last digit; q and -q give the same R)."""
    q = np.asarray(q, dtype=float).reshape(-1, 4)
    norm = np.linalg.norm(q, axis=1)
    if np.any(~np.isfinite(norm)) or np.any(norm < 1e-12):
        k = int(np.flatnonzero(~np.isfinite(norm) | (norm < 1e-12))[0])
        raise ValueError(f"quaternion {k} has norm {norm[k]:g}: not a rotation")
    x, y, z, w = (q / norm[:, None]).T
    return np.stack([
        np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)], -1),
        np.stack([2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)], -1),
        np.stack([2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)], -1),
    ], -2)


def from_matrix(R) -> np.ndarray:
    """Unit quaternions (K, 4) ``(x, y, z, w)`` with ``w >= 0`` of rotations R (K, 3, 3)
    (Shepperd's method: from the largest of w, x, y, z, so accurate at every angle)."""
    R = np.asarray(R, dtype=float).reshape(-1, 3, 3)
    trace = np.einsum("kii->k", R)
    diag = np.einsum("kii->ki", R)
    # 4 w^2, 4 x^2, 4 y^2, 4 z^2, each from the trace and the diagonal
    squares = np.stack([1 + trace, 1 + 2 * diag[:, 0] - trace, 1 + 2 * diag[:, 1] - trace,
                        1 + 2 * diag[:, 2] - trace], axis=1)
    pick = np.argmax(squares, axis=1)
    big = np.sqrt(np.maximum(squares[np.arange(len(R)), pick], 0.0))  # 2 |component|
    s = R[:, 2, 1] - R[:, 1, 2], R[:, 0, 2] - R[:, 2, 0], R[:, 1, 0] - R[:, 0, 1]  # 4 w (x, y, z)
    p = R[:, 0, 1] + R[:, 1, 0], R[:, 0, 2] + R[:, 2, 0], R[:, 1, 2] + R[:, 2, 1]  # 4 (xy, xz, yz)
    wxyz = np.empty((len(R), 4))
    rows = {
        0: lambda b, i: (b / 2, s[0][i] / (2 * b), s[1][i] / (2 * b), s[2][i] / (2 * b)),
        1: lambda b, i: (s[0][i] / (2 * b), b / 2, p[0][i] / (2 * b), p[1][i] / (2 * b)),
        2: lambda b, i: (s[1][i] / (2 * b), p[0][i] / (2 * b), b / 2, p[2][i] / (2 * b)),
        3: lambda b, i: (s[2][i] / (2 * b), p[1][i] / (2 * b), p[2][i] / (2 * b), b / 2),
    }
    for case, row in rows.items():
        idx = np.flatnonzero(pick == case)
        if len(idx):
            wxyz[idx] = np.stack(row(big[idx], idx), axis=1)
    wxyz *= np.where(wxyz[:, :1] < 0, -1.0, 1.0)
    return np.concatenate([wxyz[:, 1:], wxyz[:, :1]], axis=1)
