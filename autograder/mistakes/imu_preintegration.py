# RELEASE: omit
"""Known mistakes in ``imu_preintegration`` (see ``autograder.mistakes``): the midpoint
preintegration and the IMU residual written out one step at a time, with one slip or none."""

import numpy as np

from autograder.checks.imu_preintegration import FIELDS, PRE, RES
from course.geometry.so3 import skew


def _exp(phi):
    theta = float(np.linalg.norm(phi))
    W = skew(phi)
    if theta < 1e-8:
        return np.eye(3) + W + W @ W / 2.0
    return np.eye(3) + np.sin(theta) / theta * W + (1 - np.cos(theta)) / theta**2 * (W @ W)


def _log(R):
    cos_t = np.clip((np.trace(R) - 1.0) / 2.0, -1.0, 1.0)
    theta = float(np.arccos(cos_t))
    w = np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]]) / 2.0
    return w if theta < 1e-8 else w * theta / np.sin(theta)


def _jr(phi):
    theta = float(np.linalg.norm(phi))
    W = skew(phi)
    if theta < 1e-8:
        return np.eye(3) - W / 2.0 + W @ W / 6.0
    return np.eye(3) - (1 - np.cos(theta)) / theta**2 * W + (theta - np.sin(theta)) / theta**3 * (W @ W)


def _intervals(call, scheme, gyro_bias, accel_bias) -> list:
    """Per interval ``(dt, E, J_r, a0, a1, [a0]x, [a1]x)``: what the slips that integrate the same
    samples the same way share."""
    gyro, accel, dt, bg, ba, _, _ = call.args
    gyro, accel = np.asarray(gyro, dtype=float), np.asarray(accel, dtype=float)
    n = len(gyro) - 1
    dt = np.broadcast_to(np.asarray(dt, dtype=float), (n,))
    bg = np.asarray(bg, dtype=float) if gyro_bias else np.zeros(3)
    ba_used = np.asarray(ba, dtype=float) if accel_bias else np.zeros(3)
    out = []
    for k in range(n):
        h = dt[k]
        w = ((gyro[k] + gyro[k + 1]) / 2.0 if scheme == "midpoint" else gyro[k]) - bg
        a0, a1 = accel[k] - ba_used, accel[k + 1] - ba_used
        out.append((h, _exp(w * h), _jr(w * h), a0, a1, skew(a0), skew(a1)))
    return out


def preintegrate(call, *, scheme="midpoint", gyro_bias=True, accel_bias=True, both_new=False, half=0.5,
                 new_velocity=False, left=False, rot_block="E^T", per_dt=True, propagate=True, swap_q=False,
                 jac_sign=1.0, d_g_sign=1.0, shared=None):
    """The 12 outputs of ``preintegrate`` with one slip or none. ``shared``, a dict: the intervals
    (:func:`_intervals`) kept across the slips of one call."""
    _, _, dt, _, _, gn, an = call.args
    key = (scheme, gyro_bias, accel_bias)
    shared = {} if shared is None else shared
    if key not in shared:
        shared[key] = _intervals(call, scheme, gyro_bias, accel_bias)
    q = np.r_[np.full(3, an**2), np.full(3, gn**2)] if swap_q else np.r_[np.full(3, gn**2), np.full(3, an**2)]
    R, v, p, cov, J = np.eye(3), np.zeros(3), np.zeros(3), np.zeros((9, 9)), np.zeros((9, 6))
    for h, E, Jr, a0, a1, S0, S1 in shared[key]:
        Rn = R @ E
        if scheme == "midpoint":
            acc = Rn @ (a0 + a1) / 2.0 if both_new else (R @ a0 + Rn @ a1) / 2.0
            D_phi = -(R @ S0 + Rn @ S1 @ E.T) / 2.0
            D_g, D_a = d_g_sign * Rn @ S1 @ Jr * h / 2.0, -(R + Rn) / 2.0
        else:
            acc, D_phi, D_g, D_a = R @ a0, -R @ S0, np.zeros((3, 3)), -R
        A = np.eye(9)
        A[:3, :3] = E.T if rot_block == "E^T" else E
        A[3:6, :3], A[6:9, :3], A[6:9, 3:6] = D_phi * h, D_phi * h * h / 2.0, np.eye(3) * h
        B = np.zeros((9, 6))
        B[:3, :3] = -(Jr.T if left else Jr) * h
        B[3:6, :3], B[3:6, 3:] = D_g * h, D_a * h
        B[6:9, :3], B[6:9, 3:] = D_g * h * h / 2.0, D_a * h * h / 2.0
        Q = np.diag(q / h if per_dt else q)
        cov = (A @ cov @ A.T if propagate else cov) + B @ Q @ B.T
        J = A @ J + jac_sign * B
        if new_velocity:
            v = v + acc * h
            p = p + v * h + half * acc * h * h
        else:
            p = p + v * h + half * acc * h * h
            v = v + acc * h
        R = Rn
    dt = np.broadcast_to(np.asarray(dt, dtype=float), (len(shared[key]),))
    return {"delta_R": R, "delta_v": v, "delta_p": p, "delta_t": float(np.sum(dt)), "covariance": cov,
            "dR_dbg": J[:3, :3], "dv_dbg": J[3:6, :3], "dv_dba": J[3:6, 3:], "dp_dbg": J[6:9, :3],
            "dp_dba": J[6:9, 3:]}


_PRE_SLIPS = [
    ({"scheme": "euler"}, "you integrated with the left sample of each interval only (Euler, as GTSAM does): the "
                          "exercise averages both ends (midpoint), w_k = (omega_k + omega_{k+1}) / 2 - b_g"),
    ({"gyro_bias": False}, "the gyroscope bias is not subtracted: w_k = (omega_k + omega_{k+1}) / 2 - b_g"),
    ({"accel_bias": False}, "the accelerometer bias is not subtracted: use a_k - b_a and a_{k+1} - b_a"),
    ({"both_new": True}, "both samples are rotated by Delta R_{k+1}: the first end of the interval needs Delta R_k "
                         "(rotate a_k before updating Delta R)"),
    ({"half": 1.0}, "Delta p needs 1/2 a_k dt^2, not a_k dt^2"),
    ({"new_velocity": True}, "Delta p was updated with the new Delta v_{k+1}: update Delta p with the old Delta v_k "
                             "before Delta v"),
    ({"left": True}, "that is the left Jacobian J_l = J_r^T: a gyro noise or bias change enters on the right, "
                     "Delta R Exp(w dt - eta dt) = Delta R Exp(w dt) Exp(-J_r(w dt) eta dt)"),
    ({"rot_block": "E"}, "the rotation block of A is E^T = Exp(w_k dt)^T: Delta R Exp(delta phi) E = Delta R E "
                         "Exp(E^T delta phi)"),
    ({"per_dt": False}, "the noise densities become discrete covariances divided by dt: Q_k = diag(sigma_g^2, "
                        "sigma_a^2) / dt_k"),
    ({"propagate": False}, "the covariance was not propagated through A_k: Sigma_{k+1} = A_k Sigma_k A_k^T + "
                           "B_k Q_k B_k^T"),
    ({"swap_q": True}, "gyro and accelerometer noises swapped: the first three columns of B_k are the gyro's"),
    ({"d_g_sign": -1.0}, "D_g has the opposite sign: the gyro noise turns Delta R_{k+1} into Delta R_{k+1} "
                         "Exp(-J_r eta_g dt), and [x]_x y = -[y]_x x turns -Delta R_{k+1} [J_r eta_g dt]_x a_{k+1} "
                         "into +Delta R_{k+1} [a_{k+1}]_x J_r eta_g dt"),
    ({"jac_sign": -1.0}, "the bias Jacobians have the opposite sign: a bias is subtracted from the measurement, "
                         "as the noise is, so J_{k+1} = A_k J_k + B_k with B_k's -J_r dt"),
]


_EULER_SLIP = ({"scheme": "midpoint"}, "you averaged both ends of each interval (midpoint) where scheme='euler' "
                                      "takes the left sample only: w_k = omega_k - b_g, a_k rotated by Delta R_k")


def _known_pre(call, ref):
    out = {name: [] for name in FIELDS}
    scheme = call.kwargs.get("scheme", "midpoint")
    slips = _PRE_SLIPS if scheme == "midpoint" else [_EULER_SLIP, *_PRE_SLIPS[1:]]
    shared: dict = {}
    for slip, why in slips:
        for name, value in preintegrate(call, **{"scheme": scheme, **slip}, shared=shared).items():
            out[name].append((value, why))
    return out


def residual(call, *, rotate="R_i^T", g_sign=-1.0, g_half=0.5, correct=True, left=False, order="dR^T Ri^T Rj",
             with_vi=True, ba_sign=1.0):
    """The residual (9,) with one slip or none."""
    (R_i, v_i, p_i), (R_j, v_j, p_j), pre, (b_g, b_a), g = call.args
    R_i, R_j, g = np.asarray(R_i, dtype=float), np.asarray(R_j, dtype=float), np.asarray(g, dtype=float)
    dR0, dv0, dp0, T, _, JR, Jvg, Jva, Jpg, Jpa, bg_hat, ba_hat = pre
    dbg = np.asarray(b_g) - bg_hat if correct else np.zeros(3)
    dba = ba_sign * (np.asarray(b_a) - ba_hat) if correct else np.zeros(3)
    dR = _exp(JR @ dbg) @ dR0 if left else dR0 @ _exp(JR @ dbg)
    dv, dp = dv0 + Jvg @ dbg + Jva @ dba, dp0 + Jpg @ dbg + Jpa @ dba
    M = R_i.T if rotate == "R_i^T" else R_i
    r_R = _log(dR.T @ R_i.T @ R_j) if order == "dR^T Ri^T Rj" else _log(R_i.T @ R_j @ dR.T)
    r_v = M @ (v_j - v_i + g_sign * g * T) - dv
    r_p = M @ (p_j - p_i - (v_i * T if with_vi else 0.0) + g_sign * g_half * g * T * T) - dp
    return np.concatenate([r_R, r_v, r_p])


_RES_SLIPS = [
    ({"rotate": "R_i"}, "R_i rotates body into world: bring the world-frame differences into frame i with R_i^T"),
    ({"g_sign": 1.0}, "gravity has the wrong sign: v_j - v_i - g dT (the accelerometer does not feel g, "
                      "so Delta v holds the rest of the motion)"),
    ({"g_sign": 0.0}, "gravity was left out: v_j - v_i - g dT and p_j - p_i - v_i dT - 1/2 g dT^2"),
    ({"g_half": 1.0}, "the gravity term of the position is 1/2 g dT^2, not g dT^2"),
    ({"correct": False}, "the first-order bias correction is missing: delta b = b_i - b hat moves Delta R, v, p "
                         "through the bias Jacobians"),
    ({"left": True}, "the rotation's bias correction goes on the right: Delta R Exp(dR/dbg delta b_g)"),
    ({"order": "Ri^T Rj dR^T"}, "r_R = Log(Delta R'^T R_i^T R_j), not Log(R_i^T R_j Delta R'^T)"),
    ({"with_vi": False}, "the position residual needs - v_i dT: p_j - p_i - v_i dT - 1/2 g dT^2"),
    ({"ba_sign": -1.0}, "delta b_a = b_i - b hat, not b hat - b_i"),
]


def _known_res(call, ref):
    return {"value": [(residual(call, **slip), why) for slip, why in _RES_SLIPS]}


MISTAKES = {f"{PRE}: {title}": _known_pre for title in (
    "delta R", "delta v, delta p and delta t", "covariance", "rotation bias Jacobian dR/dbg",
    "velocity and position bias Jacobians")}
MISTAKES |= {f"{RES}: {title}": _known_res for title in (
    "rotation residual r_R", "velocity residual r_v", "position residual r_p")}
