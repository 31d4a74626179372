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


def _by_angle(t, series, closed) -> np.ndarray:
    """A coefficient (K,) of the angles ``t`` (K,): ``closed(t)`` where ``t >= SMALL_ANGLE``, ``series(t)``
    below, each evaluated only where it applies (no division by a zero angle, no trigonometry twice)."""
    small = t < SMALL_ANGLE
    if not small.any():
        return closed(t)
    out = np.empty_like(t)
    out[small] = series(t[small])
    out[~small] = closed(t[~small])
    return out


def _quadratic(phi, a, c) -> np.ndarray:
    """``I + a [phi]_x + c [phi]_x^2`` (K, 3, 3) for phi (K, 3) and coefficients a, c (K,) or scalars, entry by
    entry with ``[phi]_x^2 = phi phi^T - |phi|^2 I`` (the diagonal ``-(y^2 + z^2)``, ...): several times
    faster than the batched products of (K, 3, 3) matrices."""
    x, y, z = phi[:, 0], phi[:, 1], phi[:, 2]
    xx, yy, zz = x * x, y * y, z * z
    cxy, cxz, cyz = c * x * y, c * x * z, c * y * z
    ax, ay, az = a * x, a * y, a * z
    out = np.empty((len(phi), 3, 3))
    out[:, 0, 0], out[:, 0, 1], out[:, 0, 2] = 1.0 - c * (yy + zz), cxy - az, cxz + ay
    out[:, 1, 0], out[:, 1, 1], out[:, 1, 2] = cxy + az, 1.0 - c * (xx + zz), cyz - ax
    out[:, 2, 0], out[:, 2, 1], out[:, 2, 2] = cxz - ay, cyz + ax, 1.0 - c * (xx + yy)
    return out


def _angles(phi) -> np.ndarray:
    return np.sqrt(np.einsum("ki,ki->k", phi, phi))


def exp_many(phi) -> np.ndarray:
    """``Exp(phi_k)`` (K, 3, 3) for rotation vectors phi (K, 3); the formula of :func:`so3_exp`."""
    phi = np.asarray(phi, dtype=float).reshape(-1, 3)
    t = _angles(phi)
    a = _by_angle(t, lambda s: 1.0 - s * s / 6.0, lambda s: np.sin(s) / s)
    b = _by_angle(t, lambda s: 0.5 - s * s / 24.0, lambda s: (1.0 - np.cos(s)) / (s * s))
    return _quadratic(phi, a, b)


def log_many(R) -> np.ndarray:
    """``Log(R_k)`` (K, 3) for rotations R (K, 3, 3), angles in [0, pi]; the method of
    :func:`so3_log` (stable at 0 and near pi); up to :data:`FEW` rotations, by it (faster there)."""
    R = np.asarray(R, dtype=float).reshape(-1, 3, 3)
    if len(R) <= FEW:
        return np.array([so3_log(m) for m in R]).reshape(-1, 3)
    cos_t = np.clip((R[:, 0, 0] + R[:, 1, 1] + R[:, 2, 2] - 1.0) / 2.0, -1.0, 1.0)
    w = np.empty((len(R), 3))
    w[:, 0], w[:, 1], w[:, 2] = R[:, 2, 1] - R[:, 1, 2], R[:, 0, 2] - R[:, 2, 0], R[:, 1, 0] - R[:, 0, 1]
    w /= 2.0
    sin_t = _angles(w)
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
    t = _angles(phi)
    b = _by_angle(t, lambda s: 0.5 - s * s / 24.0, lambda s: (1.0 - np.cos(s)) / (s * s))
    c = _by_angle(t, lambda s: 1.0 / 6.0 - s * s / 120.0, lambda s: (s - np.sin(s)) / (s * s * s))
    return _quadratic(phi, -b, c)


def right_jacobian_inverse_many(phi) -> np.ndarray:
    """``J_r(phi_k)^-1 = I + [phi]/2 + (1/t^2 - (1 + cos t) / (2 t sin t)) [phi]^2`` (K, 3, 3).

    ``Log(Exp(phi) Exp(d)) = phi + J_r(phi)^-1 d + O(|d|^2)``. Right at every angle up to pi: the
    coefficient is finite there (``1 / pi^2``), and written with ``(1 + cos t) / sin t = 1 / tan(t / 2)``
    so that it stays so (the quotient is 0 / 0 at pi; ``tan(pi / 2)`` is about 1.6e16 in floating point).
    """
    phi = np.asarray(phi, dtype=float).reshape(-1, 3)
    t = _angles(phi)
    c = _by_angle(t, lambda s: 1.0 / 12.0 + s * s / 720.0,
                  lambda s: 1.0 / (s * s) - 1.0 / (2.0 * s * np.tan(0.5 * s)))
    return _quadratic(phi, 0.5, c)
