"""SO(3): the skew matrix, ``Exp``, ``Log`` and the right Jacobian, for the framework (the VIO
problem, its analytic IMU Jacobians, the window, the GTSAM peer) and for the exercises that need
them (chapter 5's preintegration, chapter 4's bundle adjustment and gauge): given, not graded.
"""

import math

import numpy as np

#: below this angle (rad) Exp, Log and J_r use their Taylor series
SMALL_ANGLE = 1e-5
#: up to this many rotations, log_many loops over so3_log (3 us a rotation against 23 us a call)
FEW = 8


def skew(v) -> np.ndarray:
    """``[v]_x`` with ``[v]_x u = v x u``: (3, 3) for v (3,), (K, 3, 3) for v (K, 3)."""
    v = np.asarray(v, dtype=float)
    if v.ndim == 1:  # the common case, built directly (several times faster than the general one)
        return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])
    S = np.zeros(v.shape[:-1] + (3, 3))
    S[..., 0, 1], S[..., 0, 2], S[..., 1, 2] = -v[..., 2], v[..., 1], -v[..., 0]
    S[..., 1, 0], S[..., 2, 0], S[..., 2, 1] = v[..., 2], -v[..., 1], v[..., 0]
    return S


def so3_exp(phi) -> np.ndarray:
    """``Exp(phi) = I + sin(t)/t [phi] + (1 - cos t)/t^2 [phi]^2`` (3, 3), ``t = |phi|``.

    Written out entry by entry with ``[phi]^2 = phi phi^T - t^2 I`` on Python floats: the VIO
    window calls it about 40,000 times a run, where numpy's per-call overhead was most of its cost."""
    x, y, z = (float(v) for v in np.asarray(phi, dtype=float).reshape(3))
    t2 = x * x + y * y + z * z
    t = math.sqrt(t2)
    if t < SMALL_ANGLE:
        a, b = 1.0 - t2 / 6.0, 0.5 - t2 / 24.0
    else:
        a, b = math.sin(t) / t, (1.0 - math.cos(t)) / t2
    bxy, bxz, byz = b * x * y, b * x * z, b * y * z
    return np.array([[1.0 - b * (y * y + z * z), bxy - a * z, bxz + a * y],
                     [bxy + a * z, 1.0 - b * (x * x + z * z), byz - a * x],
                     [bxz - a * y, byz + a * x, 1.0 - b * (x * x + y * y)]])


def so3_log(R) -> np.ndarray:
    """``Log(R)`` (3,), the angle in [0, pi] (stable near pi: from the symmetric part).

    Away from pi, on Python floats as :func:`so3_exp` (numpy's per-call overhead was most of its cost)."""
    R = np.asarray(R, dtype=float)
    if R.shape != (3, 3):
        raise ValueError(f"so3_log takes a (3, 3) rotation, got shape {R.shape}")
    (r00, r01, r02), (r10, r11, r12), (r20, r21, r22) = R.tolist()
    cos_t = min(1.0, max(-1.0, (r00 + r11 + r22 - 1.0) / 2.0))
    wx, wy, wz = (r21 - r12) / 2.0, (r02 - r20) / 2.0, (r10 - r01) / 2.0  # sin(t) u
    t = math.atan2(math.sqrt(wx * wx + wy * wy + wz * wz), cos_t)  # accurate at every angle, unlike arccos
    if t < np.pi - 1e-3:
        scale = 1.0 + t * t / 6.0 if t < SMALL_ANGLE else t / math.sin(t)
        return np.array([wx * scale, wy * scale, wz * scale])
    w = np.array([wx, wy, wz])
    S = (R + R.T) / 2.0 - cos_t * np.eye(3)  # (1 - cos t) u u^T
    k = int(np.argmax(np.diag(S)))
    u = S[:, k] / np.sqrt((1.0 - cos_t) * S[k, k])  # S[:, k] = (1 - cos t) u_k u
    if u @ w < 0:
        u = -u
    return t * u


def right_jacobian(phi) -> np.ndarray:
    """``J_r(phi) = I - (1 - cos t)/t^2 [phi] + (t - sin t)/t^3 [phi]^2`` (3, 3)."""
    phi = np.asarray(phi, dtype=float)
    t2 = float(phi @ phi)
    t = np.sqrt(t2)
    if t < SMALL_ANGLE:
        b, c = 0.5 - t2 / 24.0, 1.0 / 6.0 - t2 / 120.0
    else:
        b, c = (1.0 - np.cos(t)) / t2, (t - np.sin(t)) / (t2 * t)
    W = skew(phi)
    return np.eye(3) - b * W + c * (W @ W)


# ---------------------------------------------------------------- vectorized over K rotations


def exp_many(phi) -> np.ndarray:
    """``Exp(phi_k)`` (K, 3, 3) for rotation vectors phi (K, 3); the formula of :func:`so3_exp`."""
    phi = np.asarray(phi, dtype=float).reshape(-1, 3)
    t2 = np.einsum("ki,ki->k", phi, phi)
    t = np.sqrt(t2)
    small = t < SMALL_ANGLE
    safe = np.where(small, 1.0, t)
    a = np.where(small, 1.0 - t2 / 6.0, np.sin(safe) / safe)
    b = np.where(small, 0.5 - t2 / 24.0, (1.0 - np.cos(safe)) / (safe * safe))
    W = skew(phi)
    return np.eye(3) + a[:, None, None] * W + b[:, None, None] * np.matmul(W, W)


def log_many(R) -> np.ndarray:
    """``Log(R_k)`` (K, 3) for rotations R (K, 3, 3), angles in [0, pi]; the method of
    :func:`so3_log` (stable at 0 and near pi); up to :data:`FEW` rotations, by it (faster there)."""
    R = np.asarray(R, dtype=float).reshape(-1, 3, 3)
    if len(R) <= FEW:
        return np.array([so3_log(m) for m in R]).reshape(-1, 3)
    cos_t = np.clip((np.einsum("kii->k", R) - 1.0) / 2.0, -1.0, 1.0)
    w = np.stack([R[:, 2, 1] - R[:, 1, 2], R[:, 0, 2] - R[:, 2, 0], R[:, 1, 0] - R[:, 0, 1]], axis=1) / 2.0
    sin_t = np.linalg.norm(w, axis=1)
    t = np.arctan2(sin_t, cos_t)
    small = t < SMALL_ANGLE
    scale = np.where(small, 1.0 + t * t / 6.0, t / np.where(small, 1.0, sin_t))
    out = w * scale[:, None]
    for k in np.flatnonzero(t >= np.pi - 1e-3):  # rare: sin t carries no accuracy there
        out[k] = so3_log(R[k])
    return out


def right_jacobian_many(phi) -> np.ndarray:
    """``J_r(phi_k)`` (K, 3, 3) for phi (K, 3); the formula of :func:`right_jacobian`."""
    phi = np.asarray(phi, dtype=float).reshape(-1, 3)
    t2 = np.einsum("ki,ki->k", phi, phi)
    t = np.sqrt(t2)
    small = t < SMALL_ANGLE
    safe = np.where(small, 1.0, t)
    b = np.where(small, 0.5 - t2 / 24.0, (1.0 - np.cos(safe)) / (safe * safe))
    c = np.where(small, 1.0 / 6.0 - t2 / 120.0, (safe - np.sin(safe)) / (safe * safe * safe))
    W = skew(phi)
    return np.eye(3) - b[:, None, None] * W + c[:, None, None] * np.matmul(W, W)


def right_jacobian_inverse_many(phi) -> np.ndarray:
    """``J_r(phi_k)^-1 = I + [phi]/2 + (1/t^2 - (1 + cos t) / (2 t sin t)) [phi]^2`` (K, 3, 3).

    ``Log(Exp(phi) Exp(d)) = phi + J_r(phi)^-1 d + O(|d|^2)``; defined for t < pi.
    """
    phi = np.asarray(phi, dtype=float).reshape(-1, 3)
    t2 = np.einsum("ki,ki->k", phi, phi)
    t = np.sqrt(t2)
    small = t < SMALL_ANGLE
    safe = np.where(small, 1.0, t)
    c = np.where(small, 1.0 / 12.0 + t2 / 720.0,
                 1.0 / (safe * safe) - (1.0 + np.cos(safe)) / (2.0 * safe * np.sin(safe)))
    W = skew(phi)
    return np.eye(3) + 0.5 * W + c[:, None, None] * np.matmul(W, W)
