"""Chapter 5: the analytic Jacobian of an IMU factor's residual in the frames' tangents.

The VIO problem (``course.problems.vio.problem``) stores a keyframe as ``s = (phi, p, v, b_g, b_a)``
(15,) with ``R = Exp(phi)`` and the tangent ``(dphi, dp, dv, db_g, db_a)``: ``R <- R Exp(dphi)``
(a right perturbation), the rest added. :func:`imu_jacobian` gives the Jacobian (9, 30) of the
residual of the IMU factor between frames i and j in the 30 tangent coordinates
``(dphi_i, dp_i, dv_i, dbg_i, dba_i, dphi_j, dp_j, dv_j, dbg_j, dba_j)``. It computes no residual:
the residual is the exercise's (``imu_factor_residual``), and the problem passes the rotation rows
of the implementation's residual at the same states, from which ``E = Exp(r_R)`` below.

The residual is the one of chapter 5's exercise ``imu_factor_residual`` (Forster, Carlone, Dellaert,
Scaramuzza, T-RO 2017, eq. 45, first-order bias correction), ``r = (r_R, r_v, r_p)``: its docstring
defines it and its hints derive it. Below, ``theta = dR/dbg delta b_g`` is the bias correction's
rotation, ``E = Delta R'^T R_i^T R_j`` with ``Delta R' = Delta R Exp(theta)``, and ``u_v``, ``u_p`` the
velocity and position differences rotated into frame i, before the preintegrated values are subtracted.

The Jacobian, with ``[x]`` the skew matrix, ``J_r`` the right Jacobian of SO(3) and
``J_r^-1(e) = I + 1/2 [e] + (1/t^2 - cot(t/2) / (2 t)) [e]^2`` (``t = |e|``) its inverse,
from ``Log(E Exp(x)) = Log(E) + J_r^-1(Log E) x + O(x^2)``, ``Exp(-x) = I - [x] + O(x^2)``,
``Exp(theta + d) = Exp(theta) Exp(J_r(theta) d) + O(d^2)`` and ``Exp(x) R = R Exp(R^T x)``
(every block not listed is zero; in particular the bias columns of frame j)::

    d r_R / d dphi_i = -J_r^-1(r_R) R_j^T R_i         d r_R / d dphi_j = J_r^-1(r_R)
    d r_R / d dbg_i  = -J_r^-1(r_R) E^T J_r(theta) dR/dbg

    d r_v / d dphi_i = [u_v]       d r_v / d dv_i = -R_i^T      d r_v / d dv_j = R_i^T
    d r_v / d dbg_i  = -dv/dbg     d r_v / d dba_i = -dv/dba

    d r_p / d dphi_i = [u_p]       d r_p / d dp_i = -R_i^T      d r_p / d dp_j = R_i^T
    d r_p / d dv_i   = -dT R_i^T   d r_p / d dbg_i = -dp/dbg    d r_p / d dba_i = -dp/dba

How the rotation rows come about: perturbing R_i gives ``Delta R'^T Exp(-x) R_i^T R_j = E
Exp(-R_j^T R_i x)``; perturbing R_j gives ``E Exp(x)``; a gyro-bias change ``d`` gives
``Exp(-J_r(theta) dR/dbg d) E = E Exp(-E^T J_r(theta) dR/dbg d)``. The velocity and position
rows: ``Exp(-x) R_i^T u = R_i^T u + [R_i^T u] x`` to first order. They differ from Forster's
printed ones only because here the positions and velocities are perturbed additively in the
world (Forster: ``p <- p + R dp``) and the residual is ordered (R, v, p).

``J_r^-1(r_R)`` is finite for every ``|r_R| <= pi``, but the residual's ``Log`` jumps at
``|r_R| = pi`` (where ``E`` is a half turn, ``Log`` picks one of two opposite axes), so at a
half-turn rotation residual the derivative is as ill defined as the residual itself; a factor is
never linearised there in practice (its rotation residual is of the order of the gyro noise).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from course.geometry.so3 import exp_many, right_jacobian_many, skew

#: below this angle (rad) J_r^-1 uses its Taylor series
SMALL_ANGLE = 1e-4
#: the number of values of a preintegration (``Preintegrated``'s fields, in that order)
PREINTEGRATED_LENGTH = 12
FRAME_DOF = 15


def right_jacobian_inverse(phi) -> np.ndarray:
    """``J_r^-1(phi) = I + 1/2 [phi] + (1/t^2 - cot(t/2)/(2 t)) [phi]^2`` (3, 3), ``t = |phi|``
    (``cot(t/2) = cos(t/2) / sin(t/2)``, finite at ``t = pi``; singular at ``t = 2 pi``, never
    reached by a ``Log``). (K, 3, 3) for phi (K, 3)."""
    phi = np.asarray(phi, dtype=float)
    t2 = np.einsum("...i,...i->...", phi, phi)
    t = np.sqrt(t2)
    small = t < SMALL_ANGLE
    safe = np.where(small, 1.0, t)
    c = np.where(small, 1.0 / 12.0 + t2 / 720.0,
                 1.0 / (safe * safe) - np.cos(safe / 2.0) / (2.0 * safe * np.sin(safe / 2.0)))
    W = skew(phi)
    return np.eye(3) + 0.5 * W + c[..., None, None] * np.matmul(W, W)


class StackedPreintegration(NamedTuple):
    """K preintegrations as arrays: the fields of a ``Preintegrated`` with a leading K axis
    (``delta_R`` (K, 3, 3), ``delta_v`` (K, 3), ..., ``delta_t`` (K,)), the covariance left out."""

    delta_R: np.ndarray
    delta_v: np.ndarray
    delta_p: np.ndarray
    delta_t: np.ndarray
    dR_dbg: np.ndarray
    dv_dbg: np.ndarray
    dv_dba: np.ndarray
    dp_dbg: np.ndarray
    dp_dba: np.ndarray
    bias_gyro: np.ndarray
    bias_accel: np.ndarray


def stack_preintegrated(preintegrated) -> StackedPreintegration:
    """A :class:`StackedPreintegration` of a sequence of K preintegrations (each the 12 values of
    a ``Preintegrated``), built once per problem."""
    rows = []
    for k, values in enumerate(preintegrated):
        if len(values) != PREINTEGRATED_LENGTH:
            raise ValueError(f"preintegrated[{k}] must hold the {PREINTEGRATED_LENGTH} values of a Preintegrated, "
                             f"got {len(values)}")
        rows.append(values[:4] + values[5:])  # the covariance (index 4) is not used here
    shapes = ((3, 3), (3,), (3,), (), (3, 3), (3, 3), (3, 3), (3, 3), (3, 3), (3,), (3,))
    return StackedPreintegration(*(np.asarray([row[f] for row in rows], dtype=float).reshape((-1,) + shape)
                                   for f, shape in enumerate(shapes)))


def _frame(s, name) -> np.ndarray:
    s = np.asarray(s, dtype=float)
    if s.shape != (FRAME_DOF,):
        raise ValueError(f"{name} must be a frame state (phi, p, v, b_g, b_a) of shape (15,), got {s.shape}")
    return s


def imu_jacobian(s_i, s_j, preintegrated, gravity, r_R) -> np.ndarray:
    """``J = dr/d(tangents)`` (9, 30) of the IMU factor between frames i and j (the module docstring's
    formulas), at the rotation rows ``r_R`` (3,) of its residual there.

    Args: ``s_i``, ``s_j`` (15,) frame states ``(phi, p, v, b_g, b_a)`` (the biases of j are not
    used: their columns are zero); ``preintegrated``: the 12 values of a ``Preintegrated``
    (``delta_R, delta_v, delta_p, delta_t, covariance, dR_dbg, dv_dbg, dv_dba, dp_dbg, dp_dba,
    bias_gyro, bias_accel``; the covariance is not used); ``gravity`` (3,); ``r_R`` the first three
    entries of ``imu_factor_residual((R_i, v_i, p_i), (R_j, v_j, p_j), preintegrated, (b_g,i, b_a,i),
    gravity)`` at these states, as the implementation computes it (this module computes no residual).

    The rows of ``J`` are ``(r_R, r_v, r_p)``, not whitened; its columns
    ``(dphi_i, dp_i, dv_i, dbg_i, dba_i)`` then the same for j, as ``course.problems.vio.problem`` orders
    a frame's tangent. :func:`imu_jacobians` does K factors at once.
    """
    s_i, s_j = _frame(s_i, "s_i"), _frame(s_j, "s_j")
    if len(preintegrated) != PREINTEGRATED_LENGTH:
        raise ValueError(f"preintegrated must hold the {PREINTEGRATED_LENGTH} values of a Preintegrated, "
                         f"got {len(preintegrated)}")
    r_R = np.asarray(r_R, dtype=float)
    if r_R.shape != (3,):
        raise ValueError(f"r_R must be the rotation rows (3,) of the factor's residual, got shape {r_R.shape}")
    return imu_jacobians(s_i[None], s_j[None], stack_preintegrated([tuple(preintegrated)]), gravity, r_R[None])[0]


def imu_jacobians(s_i, s_j, pre: StackedPreintegration, gravity, r_R, R_i=None, R_j=None) -> np.ndarray:
    """:func:`imu_jacobian` of K factors at once: ``s_i``, ``s_j`` (K, 15), ``pre`` a
    :class:`StackedPreintegration` of K, ``r_R`` (K, 3) the rotation rows of their residuals; ``R_i``,
    ``R_j`` (K, 3, 3) ``Exp`` of the frames' rotation vectors where the caller has them; returns ``J``
    (K, 9, 30)."""
    s_i, s_j = np.asarray(s_i, dtype=float), np.asarray(s_j, dtype=float)
    K = len(pre.delta_t)
    if s_i.shape != (K, FRAME_DOF) or s_j.shape != (K, FRAME_DOF):
        raise ValueError(f"s_i and s_j must be ({K}, {FRAME_DOF}) frame states, got {s_i.shape} and {s_j.shape}")
    g = np.asarray(gravity, dtype=float)
    if g.shape != (3,):
        raise ValueError(f"gravity must have shape (3,), got {g.shape}")
    r_R = np.asarray(r_R, dtype=float)
    if r_R.shape != (K, 3):
        raise ValueError(f"r_R must be the rotation rows ({K}, 3) of the factors' residuals, got shape {r_R.shape}")
    T = pre.delta_t[:, None]
    R_i = exp_many(s_i[:, 0:3]) if R_i is None else R_i
    R_j = exp_many(s_j[:, 0:3]) if R_j is None else R_j
    p_i, v_i, p_j, v_j = s_i[:, 3:6], s_i[:, 6:9], s_j[:, 3:6], s_j[:, 6:9]

    def times(M, v):  # M_k v_k, (K, 3)
        return np.einsum("kab,kb->ka", M, v)

    theta = times(pre.dR_dbg, s_i[:, 9:12] - pre.bias_gyro)
    E = exp_many(r_R)  # r_R = Log(E), |r_R| <= pi
    Rt = R_i.transpose(0, 2, 1)
    u_v = times(Rt, v_j - v_i - g * T)
    u_p = times(Rt, p_j - p_i - v_i * T - 0.5 * g * T * T)

    # rows (r_R, r_v, r_p); columns i: 0 dphi, 3 dp, 6 dv, 9 dbg, 12 dba; j: + 15
    J = np.zeros((K, 9, 2 * FRAME_DOF))
    Jinv = right_jacobian_inverse(r_R)
    J[:, 0:3, 0:3] = -np.matmul(Jinv, np.matmul(R_j.transpose(0, 2, 1), R_i))
    J[:, 0:3, 9:12] = -np.matmul(Jinv, np.matmul(E.transpose(0, 2, 1), np.matmul(right_jacobian_many(theta),
                                                                                    pre.dR_dbg)))
    J[:, 0:3, 15:18] = Jinv
    J[:, 3:6, 0:3] = skew(u_v)
    J[:, 3:6, 6:9] = -Rt
    J[:, 3:6, 9:12] = -pre.dv_dbg
    J[:, 3:6, 12:15] = -pre.dv_dba
    J[:, 3:6, 21:24] = Rt
    J[:, 6:9, 0:3] = skew(u_p)
    J[:, 6:9, 3:6] = -Rt
    J[:, 6:9, 6:9] = -T[:, :, None] * Rt
    J[:, 6:9, 9:12] = -pre.dp_dbg
    J[:, 6:9, 12:15] = -pre.dp_dba
    J[:, 6:9, 18:21] = Rt
    return J
