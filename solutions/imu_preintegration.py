"""Chapter 5: IMU preintegration between two keyframes, and the residual of an IMU factor.

Forster, Carlone, Dellaert, Scaramuzza, "On-Manifold Preintegration for Real-Time
Visual-Inertial Odometry" (IEEE T-RO 2017), with right perturbations throughout. Between
keyframes i and j the IMU gives N + 1 samples ``omega_k``, ``a_k`` (k = 0..N) at times
``t_0 = t_i < t_1 < ... < t_N = t_j`` (``dt_k = t_{k+1} - t_k``). With the biases held at
``b_g``, ``b_a`` (the linearisation point, "b hat"), the preintegrated measurements are::

    Delta R_{k+1} = Delta R_k Exp(w_k dt_k)
    Delta v_{k+1} = Delta v_k + a_k dt_k
    Delta p_{k+1} = Delta p_k + Delta v_k dt_k + 1/2 a_k dt_k^2

starting from ``(I, 0, 0)``, independent of the states and of gravity. What ``w_k`` and
``a_k`` (the rate and the acceleration rotated into frame i) are is the integration scheme:

- ``"midpoint"`` (taught: the exercise): the average over the interval of both ends,
  ``w_k = (omega_k + omega_{k+1}) / 2 - b_g`` and
  ``a_k = (Delta R_k (a_k - b_a) + Delta R_{k+1} (a_{k+1} - b_a)) / 2``. It is second-order
  accurate (its error per interval is O(dt^3), not O(dt^2)) for the same samples, so at 200 Hz
  it follows a turning, accelerating body much better; it is what VINS-Mono integrates with.
- ``"euler"`` (GTSAM's, Forster's paper): the left end only, ``w_k = omega_k - b_g`` and
  ``a_k = Delta R_k (a_k - b_a)`` (the last sample ``omega_N``, ``a_N`` is not used).

How far apart, on 0.3 s (60 intervals) of the simulated loop (``course.problems.vio.sim``): with
``scheme="euler"`` this module agrees with GTSAM's ``PreintegratedImuMeasurementsManifold``
to about 1e-15 relative (deltas, bias Jacobians and covariance); the midpoint scheme differs
from it by about 1e-4 relative in Delta R and 2e-2 in Delta v and Delta p (3e-2 in the
gyro-bias Jacobians of v and p), and is about 100 times closer to the truth (noise-free
samples: 1e-7 rad, 5e-5 m/s, 2e-5 m against Euler's 1.4e-4 rad, 1e-2 m/s, 1e-3 m).

Linearisation. The error state is ``delta = (delta phi, delta v, delta p)`` (9,) with
``Delta R_true = Delta R Exp(delta phi)``, ``Delta v_true = Delta v + delta v``, likewise p.
One step maps it linearly, ``delta_{k+1} = A_k delta_k + B_k eta_k``, where ``eta_k =
(eta_g, eta_a)`` (6,) is the measurement noise of the interval, entering as the biases do
(``w_k - eta_g``, every ``a_. - b_a - eta_a``). Derive ``A_k`` (9, 9) and ``B_k`` (9, 6) for each
scheme by perturbing the three updates above and keeping the first-order terms
(``python -m autograder hint preintegrate 1``, then 2 and 3); the grader compares the covariance
and the bias Jacobians with the reference's values, so any correct form scores.

Covariance (9, 9), from ``Sigma_0 = 0``: ``Sigma_{k+1} = A_k Sigma_k A_k^T + B_k Q_k B_k^T`` with
``Q_k = diag(gyro_noise^2 I, accel_noise^2 I) / dt_k`` (the noise densities made discrete).
Bias Jacobians: a bias change ``delta b = (delta b_g, delta b_a)`` acts as a constant noise,
so ``J_{k+1} = A_k J_k + B_k`` from ``J_0 = 0``: ``J`` (9, 6) stacks ``dR/dbg`` (rows 0-2, cols
0-2; ``dR/dba = 0``), ``dv/dbg``, ``dv/dba`` (rows 3-5), ``dp/dbg``, ``dp/dba`` (rows 6-8), such
that to first order ``Delta R(b + delta b) = Delta R Exp(dR/dbg delta b_g)`` and
``Delta v(b + delta b) = Delta v + dv/dbg delta b_g + dv/dba delta b_a`` (p likewise).

Inputs at the edges of the contract (each is a check input):
- preintegrate: one interval (N = 1, two samples)
- preintegrate: the rate exactly 0 (gyro samples equal to the gyro bias: Exp and J_r at 0)
- preintegrate: dt a number, and dt one per interval
- preintegrate: scheme='euler'
- imu_factor_residual: the bias at the linearisation point (delta b = 0)
- imu_factor_residual: a rotation residual within 1e-3 of pi (pi - 1e-4)

Allowed imports: numpy, scipy, course.geometry.so3.
"""

from typing import NamedTuple

import numpy as np

from course.geometry.so3 import right_jacobian, skew, so3_exp, so3_log

SCHEMES = ("midpoint", "euler")


class Preintegrated(NamedTuple):
    """What :func:`preintegrate` returns (a tuple: unpack it or use the names).

    ``delta_R`` (3, 3), ``delta_v`` (3,), ``delta_p`` (3,), ``delta_t`` (float, t_j - t_i),
    ``covariance`` (9, 9) of (delta phi, delta v, delta p), the bias Jacobians ``dR_dbg``,
    ``dv_dbg``, ``dv_dba``, ``dp_dbg``, ``dp_dba`` (3, 3) each, and the biases the samples were
    corrected with, ``bias_gyro``, ``bias_accel`` (3,) ("b hat").
    """

    delta_R: np.ndarray
    delta_v: np.ndarray
    delta_p: np.ndarray
    delta_t: float
    covariance: np.ndarray
    dR_dbg: np.ndarray
    dv_dbg: np.ndarray
    dv_dba: np.ndarray
    dp_dbg: np.ndarray
    dp_dba: np.ndarray
    bias_gyro: np.ndarray
    bias_accel: np.ndarray


def _vector(value, name, n) -> np.ndarray:
    arr = np.asarray(value, dtype=float)
    if arr.shape != (n,):
        raise ValueError(f"{name} must have shape ({n},), got {arr.shape}")
    return arr


def _samples(gyro, accel, dt):
    """Validated ``(gyro (N + 1, 3), accel (N + 1, 3), dt (N,))``."""
    gyro, accel = np.asarray(gyro, dtype=float), np.asarray(accel, dtype=float)
    if gyro.ndim != 2 or gyro.shape[1] != 3 or len(gyro) < 2:
        raise ValueError(f"gyro must have shape (N + 1, 3) with N >= 1, got {gyro.shape}")
    if accel.shape != gyro.shape:
        raise ValueError(f"accel must have the shape of gyro {gyro.shape}, got {accel.shape}")
    dt = np.asarray(dt, dtype=float)
    dt = np.full(len(gyro) - 1, float(dt)) if dt.ndim == 0 else dt
    if dt.shape != (len(gyro) - 1,):
        raise ValueError(f"dt must be a number or have shape ({len(gyro) - 1},) (one per interval "
                         f"between the {len(gyro)} samples), got {dt.shape}")
    if not np.all(dt > 0):
        raise ValueError(f"dt must be positive, got min(dt) = {dt.min()}")
    return gyro, accel, dt


def preintegrate(gyro, accel, dt, bias_gyro, bias_accel, gyro_noise, accel_noise, scheme="midpoint"):
    """Preintegrate the N + 1 samples between two keyframes (the module docstring's math).

    Args: ``gyro``, ``accel`` (N + 1, 3) the samples at ``t_0 .. t_N`` (rad/s, m/s^2, body
    frame); ``dt`` (N,) or a number, the intervals ``t_{k+1} - t_k`` (s); ``bias_gyro``,
    ``bias_accel`` (3,) the biases to subtract ("b hat"); ``gyro_noise``, ``accel_noise`` the
    white-noise densities (rad/s/sqrt(Hz), m/s^2/sqrt(Hz)); ``scheme``: ``"midpoint"`` (the
    exercise) or ``"euler"`` (GTSAM's; optional for you).

    Returns a :class:`Preintegrated` (``delta_R``, ``delta_v``, ``delta_p``, ``delta_t``,
    ``covariance``, ``dR_dbg``, ``dv_dbg``, ``dv_dba``, ``dp_dbg``, ``dp_dba``, ``bias_gyro``,
    ``bias_accel``). A loop over the N intervals is inherent; inside it, update the covariance
    and the bias Jacobians with the *old* ``Delta R_k`` (and ``Delta v_k``) before overwriting them.
    """
    gyro, accel, dt = _samples(gyro, accel, dt)
    bias_gyro, bias_accel = _vector(bias_gyro, "bias_gyro", 3), _vector(bias_accel, "bias_accel", 3)
    if scheme not in SCHEMES:
        raise ValueError(f"scheme must be one of {SCHEMES}, got {scheme!r}")
    # BEGIN SOLUTION
    q_g, q_a = float(gyro_noise) ** 2, float(accel_noise) ** 2
    acc = accel - bias_accel  # a~_k, (N + 1, 3)
    if scheme == "midpoint":
        rates = (gyro[:-1] + gyro[1:]) / 2.0 - bias_gyro
    else:
        rates = gyro[:-1] - bias_gyro
    dR, dv, dp = np.eye(3), np.zeros(3), np.zeros(3)
    cov, J = np.zeros((9, 9)), np.zeros((9, 6))
    eye = np.eye(3)
    for k in range(len(dt)):
        h = dt[k]
        phi = rates[k] * h
        E = so3_exp(phi)
        Jr = right_jacobian(phi)
        R_next = dR @ E
        if scheme == "midpoint":
            a = (dR @ acc[k] + R_next @ acc[k + 1]) / 2.0
            D_phi = -(dR @ skew(acc[k]) + R_next @ skew(acc[k + 1]) @ E.T) / 2.0
            D_g = R_next @ skew(acc[k + 1]) @ Jr * (h / 2.0)
            D_a = -(dR + R_next) / 2.0
        else:
            a = dR @ acc[k]
            D_phi, D_g, D_a = -dR @ skew(acc[k]), np.zeros((3, 3)), -dR
        A = np.eye(9)
        A[0:3, 0:3] = E.T
        A[3:6, 0:3] = D_phi * h
        A[6:9, 0:3] = D_phi * (h * h / 2.0)
        A[6:9, 3:6] = eye * h
        B = np.zeros((9, 6))
        B[0:3, 0:3] = -Jr * h
        B[3:6, 0:3], B[3:6, 3:6] = D_g * h, D_a * h
        B[6:9, 0:3], B[6:9, 3:6] = D_g * (h * h / 2.0), D_a * (h * h / 2.0)
        Q = np.diag(np.r_[np.full(3, q_g), np.full(3, q_a)]) / h
        cov = A @ cov @ A.T + B @ Q @ B.T
        J = A @ J + B
        dp = dp + dv * h + a * (h * h / 2.0)
        dv = dv + a * h
        dR = R_next
    return Preintegrated(dR, dv, dp, float(dt.sum()), cov, J[0:3, 0:3], J[3:6, 0:3], J[3:6, 3:6], J[6:9, 0:3],
                         J[6:9, 3:6], bias_gyro, bias_accel)
    # END SOLUTION


def imu_factor_residual(state_i, state_j, preintegrated, bias_i, gravity):
    """The residual (9,) of an IMU factor between keyframes i and j (Forster et al., eq. 45).

    Args: ``state_i``, ``state_j`` = ``(R (3, 3), v (3,), p (3,))`` (``R = R_wb``, v and p in
    the world frame); ``preintegrated``: a :class:`Preintegrated` (or the same 12 values as a
    tuple) computed at the biases ``b hat = (bias_gyro, bias_accel)`` it holds; ``bias_i`` =
    ``(b_g (3,), b_a (3,))``, the current estimate of the biases at i; ``gravity`` (3,), e.g.
    ``(0, 0, -9.81)``.

    Exact, noise-free preintegrated measurements at the true biases satisfy (gravity ``g``, ``dT =
    delta_t``, the biases constant between i and j)::

        R_j = R_i Delta R
        v_j = v_i + g dT + R_i Delta v
        p_j = p_i + v_i dT + 1/2 g dT^2 + R_i Delta p

    First correct the measurements to the bias ``b_i`` to first order, with ``delta b = b_i - b hat``
    and the bias Jacobians (module docstring; no re-integration): ``Delta R'``, ``Delta v'``,
    ``Delta p'``. The residual compares what the states say each preintegrated quantity is (solve
    the relations above for it) with the corrected measurement: ``r_R = Log(Delta R'^T (...))``,
    ``r_v = (...) - Delta v'``, ``r_p = (...) - Delta p'``, all in frame i; derive them
    (``python -m autograder hint imu_factor_residual 1``, then 2 and 3).

    Returns ``concatenate([r_R, r_v, r_p])`` (9,), zero for the true states and biases of
    noise-free data integrated exactly.
    """
    if len(preintegrated) != len(Preintegrated._fields):
        raise ValueError(f"preintegrated must hold the {len(Preintegrated._fields)} values of Preintegrated "
                         f"{Preintegrated._fields}, got {len(preintegrated)}")
    pre = Preintegrated(*preintegrated)
    if len(state_i) != 3 or len(state_j) != 3:
        raise ValueError("state_i and state_j must be (R (3, 3), v (3,), p (3,))")
    if len(bias_i) != 2:
        raise ValueError("bias_i must be (bias_gyro (3,), bias_accel (3,))")
    R_i, R_j = np.asarray(state_i[0], dtype=float), np.asarray(state_j[0], dtype=float)
    if R_i.shape != (3, 3) or R_j.shape != (3, 3):
        raise ValueError(f"state_i[0] and state_j[0] (R) must have shape (3, 3), got {R_i.shape}, {R_j.shape}")
    v_i, p_i = _vector(state_i[1], "state_i[1] (v)", 3), _vector(state_i[2], "state_i[2] (p)", 3)
    v_j, p_j = _vector(state_j[1], "state_j[1] (v)", 3), _vector(state_j[2], "state_j[2] (p)", 3)
    b_g, b_a = _vector(bias_i[0], "bias_i[0] (bias_gyro)", 3), _vector(bias_i[1], "bias_i[1] (bias_accel)", 3)
    g = _vector(gravity, "gravity", 3)
    # BEGIN SOLUTION
    dbg = b_g - np.asarray(pre.bias_gyro, dtype=float)
    dba = b_a - np.asarray(pre.bias_accel, dtype=float)
    dR = np.asarray(pre.delta_R) @ so3_exp(np.asarray(pre.dR_dbg) @ dbg)
    dv = np.asarray(pre.delta_v) + np.asarray(pre.dv_dbg) @ dbg + np.asarray(pre.dv_dba) @ dba
    dp = np.asarray(pre.delta_p) + np.asarray(pre.dp_dbg) @ dbg + np.asarray(pre.dp_dba) @ dba
    T = float(pre.delta_t)
    r_R = so3_log(dR.T @ R_i.T @ R_j)
    r_v = R_i.T @ (v_j - v_i - g * T) - dv
    r_p = R_i.T @ (p_j - p_i - v_i * T - 0.5 * g * T * T) - dp
    return np.concatenate([r_R, r_v, r_p])
    # END SOLUTION


#: the derived results, in three levels (``python -m autograder hint NAME LEVEL``; the release
#: prints levels 1..N into the docstrings with ``--hints N``, course.core.hints)
HINTS = {
    "preintegrate": (
        """Write each true quantity as the estimate plus its error (``Delta R_k Exp(delta phi_k)``,
        ``Delta v_k + delta v_k``, ...) and each sample's noise as the bias does, put them into the three
        updates, and keep the terms of first order in ``delta`` and ``eta``. Do the rotation first (its
        error feeds the others), then the scheme's rotated acceleration ``a_k``: its derivatives by
        ``delta phi``, ``eta_g`` and ``eta_a`` (call them ``D_phi``, ``D_g``, ``D_a``) give the rows of v and p.""",
        """With ``E = Exp(w_k dt)``, ``J_r = J_r(w_k dt)`` (the right Jacobian of SO(3)), ``R = Delta R_k``,
        ``R' = Delta R_{k+1}``, ``[x]`` the skew matrix: ``Exp(x + dx) = Exp(x) Exp(J_r(x) dx)``;
        ``Exp(phi) E = E Exp(E^T phi)`` (moving an error through a rotation); and
        ``R Exp(phi) a = R a - R [a] phi`` to first order. So ``delta phi_{k+1} = E^T delta phi_k -
        J_r dt eta_g``, and the rotated acceleration's error is ``D_phi delta phi_k + D_g eta_g + D_a eta_a``.""",
        """With ``E = Exp(w_k dt)``, ``J_r = J_r(w_k dt)``, ``R = Delta R_k``, ``R' = Delta R_{k+1}``, ``[x]``
        the skew matrix, and for the scheme's acceleration

        - Euler:    ``D_phi = -R [a~_k]``,  ``D_g = 0``,  ``D_a = -R``  (``a~ = a - b_a``),
        - midpoint: ``D_phi = -(R [a~_k] + R' [a~_{k+1}] E^T) / 2``,  ``D_g = R' [a~_{k+1}] J_r dt / 2``,
          ``D_a = -(R + R') / 2``,

        (the derivatives of the rotated acceleration by delta phi, eta_g and eta_a)::

            A_k = [[E^T,             0,      0],      B_k = [[-J_r dt,          0         ],
                   [D_phi dt,        I,      0],             [D_g dt,           D_a dt     ],
                   [D_phi dt^2 / 2,  I dt,   I]]             [D_g dt^2 / 2,     D_a dt^2 / 2]]""",
    ),
    "imu_factor_residual": (
        """Two steps. Correct the preintegrated measurements to the current bias with the first-order
        expansions the bias Jacobians define (the rotation multiplicatively, v and p additively). Then
        solve each of the three relations for its preintegrated quantity (``Delta R``, ``Delta v``,
        ``Delta p``) in terms of the states and gravity, and compare with the corrected measurement:
        on SO(3) by the Log of the relative rotation, in R^3 by a difference.""",
        """``R_i^T R_i = I``: multiplying the relations by ``R_i^T`` isolates the preintegrated quantity,
        e.g. ``Delta v = R_i^T (v_j - v_i - g dT)``, and ``Delta R = R_i^T R_j``. The corrections are
        ``Delta R' = Delta R Exp(dR/dbg delta b_g)`` and ``Delta v' = Delta v + dv/dbg delta b_g + dv/dba
        delta b_a`` (``Delta p'`` likewise).""",
        """With ``delta b = b_i - b hat`` and ``dT = delta_t``::

            Delta R' = Delta R Exp(dR/dbg delta b_g)
            Delta v' = Delta v + dv/dbg delta b_g + dv/dba delta b_a
            Delta p' = Delta p + dp/dbg delta b_g + dp/dba delta b_a

            r_R = Log(Delta R'^T R_i^T R_j)
            r_v = R_i^T (v_j - v_i - g dT) - Delta v'
            r_p = R_i^T (p_j - p_i - v_i dT - 1/2 g dT^2) - Delta p'""",
    ),
}
