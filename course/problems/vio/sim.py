"""Simulated visual-inertial data with ground truth (chapter 5: a sliding-window VIO back end).

In the spirit of the usual VIO teaching simulator: a body flies a smooth 3D loop (an ellipse
in x, y with a sinusoidal height), turning with it (yaw follows the ellipse, small roll and
pitch oscillations); an IMU samples it at ``imu_rate`` (200 Hz) and a camera at
``camera_rate`` (20 Hz) sees a fixed set of 3D landmarks on the walls of a box around the
loop. Everything is seeded: ``load_vio_sim("vio-sim:20:3")`` is 20 seconds from seed 3.

Conventions (those of the ``imu_preintegration`` exercise):

- world frame W with gravity ``g = (0, 0, -9.81)`` m/s^2; body frame B = the IMU's frame;
  ``R_wb`` (3, 3) rotates body coordinates into the world's, ``p``, ``v`` are the body's
  position and velocity in W;
- orientation from ZYX Euler angles ``R_wb = Rz(yaw) Ry(pitch) Rx(roll)``, whose body
  angular velocity is ``omega_b = (roll' - yaw' sin(pitch),
  pitch' cos(roll) + yaw' sin(roll) cos(pitch), -pitch' sin(roll) + yaw' cos(roll) cos(pitch))``;
- the gyroscope measures ``omega_b + b_g + n_g``, the accelerometer the specific force
  ``R_wb^T (a_w - g) + b_a + n_a``; white noises of density ``gyro_noise`` (rad/s/sqrt(Hz))
  and ``accel_noise`` (m/s^2/sqrt(Hz)) have per-sample standard deviation ``density / sqrt(dt)``;
  the biases are random walks ``b_{k+1} = b_k + sigma_walk sqrt(dt) n``;
- the camera is a pinhole (``K``) with ``R_bc``, ``t_bc`` (camera in body: ``X_b = R_bc X_c +
  t_bc``; its optical axis z looks along the body's x axis); a landmark ``X_w`` is seen at
  ``u = K (X_c / z_c)``, ``X_c = R_bc^T (R_wb^T (X_w - p) - t_bc)``, plus pixel noise, when
  ``z_c > MIN_DEPTH`` and it falls inside the image.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from course.core.errors import DatasetError

#: gravity in the world frame (m/s^2), along -z
GRAVITY = np.array([0.0, 0.0, -9.81])
PREFIX = "vio-sim"
DEFAULT_SECONDS, DEFAULT_SEED = 20.0, 0
#: the longest simulation a name may ask for (seconds)
MAX_SECONDS = 3600.0
IMU_RATE, CAMERA_RATE = 200, 20
#: noise densities and bias random walks (of the order of EuRoC's MEMS IMU)
GYRO_NOISE, ACCEL_NOISE = 1.7e-4, 2.0e-3  # rad/s/sqrt(Hz), m/s^2/sqrt(Hz)
GYRO_WALK, ACCEL_WALK = 2.0e-5, 3.0e-3  # rad/s^2/sqrt(Hz), m/s^3/sqrt(Hz)
PIXEL_NOISE = 1.0
IMAGE_SIZE = (640, 480)
MIN_DEPTH = 0.5
#: the loop: x = AX cos(K t), y = AY sin(K t), z = Z0 + AZ sin(KZ K t)
AX, AY, Z0, AZ, K_LOOP, KZ = 15.0, 20.0, 5.0, 1.0, np.pi / 10.0, 10.0
#: roll = ROLL cos(t), pitch = PITCH sin(t) (rad)
ROLL, PITCH = 0.1, 0.2


@dataclass(frozen=True)
class VioSim:
    """One simulated run: N + 1 IMU samples, F camera frames, L landmarks, M observations.

    IMU (at ``imu_times`` (N + 1,)): ``gyro``, ``accel`` (N + 1, 3) measured (bias and noise
    included); ``gyro_true``, ``accel_true`` (N + 1, 3) without bias or noise; ``bias_gyro``,
    ``bias_accel`` (N + 1, 3) the biases at each sample. Truth at the same times:
    ``rotations`` (N + 1, 3, 3) ``R_wb``, ``positions``, ``velocities`` (N + 1, 3).
    Camera: ``frame_imu_index`` (F,) the IMU sample of each frame (``frame_times`` (F,)),
    ``K`` (3, 3), ``R_bc`` (3, 3), ``t_bc`` (3,), ``landmarks`` (L, 3) in W, and the
    observations ``obs_frame``, ``obs_landmark`` (M,), ``obs_pixels`` (M, 2) (noisy) and
    ``obs_pixels_true`` (M, 2).
    """

    name: str
    seconds: float
    seed: int
    imu_rate: int
    camera_rate: int
    gravity: np.ndarray
    gyro_noise: float
    accel_noise: float
    gyro_walk: float
    accel_walk: float
    pixel_noise: float
    imu_times: np.ndarray
    gyro: np.ndarray
    accel: np.ndarray
    gyro_true: np.ndarray
    accel_true: np.ndarray
    bias_gyro: np.ndarray
    bias_accel: np.ndarray
    rotations: np.ndarray
    positions: np.ndarray
    velocities: np.ndarray
    frame_imu_index: np.ndarray
    frame_times: np.ndarray
    K: np.ndarray
    R_bc: np.ndarray
    t_bc: np.ndarray
    landmarks: np.ndarray
    obs_frame: np.ndarray
    obs_landmark: np.ndarray
    obs_pixels: np.ndarray
    obs_pixels_true: np.ndarray

    @property
    def dt(self) -> float:
        """The IMU sampling interval (s)."""
        return 1.0 / self.imu_rate


# ---------------------------------------------------------------- the trajectory


def _euler_rotation(roll, pitch, yaw) -> np.ndarray:
    """``Rz(yaw) Ry(pitch) Rx(roll)`` (T, 3, 3) for angles (T,)."""
    cr, sr, cp, sp, cy, sy = np.cos(roll), np.sin(roll), np.cos(pitch), np.sin(pitch), np.cos(yaw), np.sin(yaw)
    R = np.empty((len(roll), 3, 3))
    R[:, 0] = np.stack([cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr], axis=1)
    R[:, 1] = np.stack([sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr], axis=1)
    R[:, 2] = np.stack([-sp, cp * sr, cp * cr], axis=1)
    return R


def trajectory(t) -> dict:
    """The true motion at times ``t`` (T,): ``rotations`` (T, 3, 3), ``positions``,
    ``velocities``, ``accelerations`` (world, T, 3), ``omega_body`` (T, 3) (rad/s), all from
    the closed-form loop (derivatives exact, not differenced)."""
    t = np.asarray(t, dtype=float)
    k, kz = K_LOOP, KZ * K_LOOP
    positions = np.stack([AX * np.cos(k * t), AY * np.sin(k * t), Z0 + AZ * np.sin(kz * t)], axis=1)
    velocities = np.stack([-AX * k * np.sin(k * t), AY * k * np.cos(k * t), AZ * kz * np.cos(kz * t)], axis=1)
    accelerations = np.stack([-AX * k**2 * np.cos(k * t), -AY * k**2 * np.sin(k * t),
                              -AZ * kz**2 * np.sin(kz * t)], axis=1)
    roll, pitch, yaw = ROLL * np.cos(t), PITCH * np.sin(t), k * t
    droll, dpitch, dyaw = -ROLL * np.sin(t), PITCH * np.cos(t), np.full_like(t, k)
    omega_body = np.stack([droll - dyaw * np.sin(pitch),
                           dpitch * np.cos(roll) + dyaw * np.sin(roll) * np.cos(pitch),
                           -dpitch * np.sin(roll) + dyaw * np.cos(roll) * np.cos(pitch)], axis=1)
    return {"rotations": _euler_rotation(roll, pitch, yaw), "positions": positions, "velocities": velocities,
            "accelerations": accelerations, "omega_body": omega_body}


def _landmarks(rng) -> np.ndarray:
    """Points on the four walls of a box around the loop (x in +-(AX + 5), y in +-(AY + 5),
    z in [0, 10]), jittered off the walls by up to 0.5 m."""
    X, Y, per_wall = AX + 5.0, AY + 5.0, 120
    walls = []
    for axis, level, span in ((0, X, Y), (0, -X, Y), (1, Y, X), (1, -Y, X)):
        pts = np.empty((per_wall, 3))
        pts[:, axis] = level + rng.uniform(-0.5, 0.5, per_wall)
        pts[:, 1 - axis] = rng.uniform(-span, span, per_wall)
        pts[:, 2] = rng.uniform(0.0, 10.0, per_wall)
        walls.append(pts)
    return np.concatenate(walls)


# ---------------------------------------------------------------- the generator


def simulate(seconds: float = DEFAULT_SECONDS, seed: int = DEFAULT_SEED, *, imu_rate: int = IMU_RATE,
             camera_rate: int = CAMERA_RATE) -> VioSim:
    """Simulate ``seconds`` of flight with the noise of ``seed`` (see the module docstring).

    ``imu_rate`` must be a multiple of ``camera_rate`` (a frame every ``imu_rate //
    camera_rate`` IMU samples, the first at t = 0). Raises ValueError naming the argument.
    """
    seconds = float(seconds)
    if not np.isfinite(seconds) or seconds <= 0.0 or seconds > MAX_SECONDS:
        raise ValueError(f"seconds must be in (0, {MAX_SECONDS:g}], got {seconds!r}")
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ValueError(f"seed must be a non-negative integer, got {seed!r}")
    if int(imu_rate) != imu_rate or imu_rate <= 0:
        raise ValueError(f"imu_rate must be a positive integer (Hz), got {imu_rate!r}")
    if int(camera_rate) != camera_rate or camera_rate <= 0 or imu_rate % camera_rate:
        raise ValueError(f"camera_rate must be a positive integer dividing imu_rate={imu_rate}, got {camera_rate!r}")
    imu_rate, camera_rate = int(imu_rate), int(camera_rate)
    rng = np.random.default_rng([int(seed), 517])
    dt = 1.0 / imu_rate
    n = int(round(seconds * imu_rate))
    if n < 1:
        raise ValueError(f"seconds={seconds!r} is shorter than one IMU interval ({dt:g} s)")
    times = np.arange(n + 1) * dt
    truth = trajectory(times)
    R = truth["rotations"]
    gyro_true = truth["omega_body"]
    accel_true = np.einsum("kji,kj->ki", R, truth["accelerations"] - GRAVITY)  # R^T (a - g)

    bias_gyro0 = rng.normal(0.0, 0.01, 3)  # rad/s
    bias_accel0 = rng.normal(0.0, 0.05, 3)  # m/s^2
    walk = np.sqrt(dt) * rng.standard_normal((2, n, 3))
    bias_gyro = bias_gyro0 + np.concatenate([np.zeros((1, 3)), np.cumsum(GYRO_WALK * walk[0], axis=0)])
    bias_accel = bias_accel0 + np.concatenate([np.zeros((1, 3)), np.cumsum(ACCEL_WALK * walk[1], axis=0)])
    white = rng.standard_normal((2, n + 1, 3)) / np.sqrt(dt)
    gyro = gyro_true + bias_gyro + GYRO_NOISE * white[0]
    accel = accel_true + bias_accel + ACCEL_NOISE * white[1]

    K = np.array([[460.0, 0.0, 320.0], [0.0, 460.0, 240.0], [0.0, 0.0, 1.0]])
    R_bc = np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])  # camera z = body x
    t_bc = np.array([0.05, 0.04, 0.03])
    landmarks = _landmarks(rng)
    frames = np.arange(0, n + 1, imu_rate // camera_rate)
    X_b = np.einsum("fji,flj->fli", R[frames], landmarks[None] - truth["positions"][frames][:, None])
    X_c = np.einsum("ji,flj->fli", R_bc, X_b - t_bc)
    z = X_c[..., 2]
    with np.errstate(divide="ignore", invalid="ignore"):
        uv = np.einsum("ij,flj->fli", K[:2, :2], X_c[..., :2] / z[..., None]) + K[:2, 2]
    visible = ((z > MIN_DEPTH) & (uv[..., 0] >= 0) & (uv[..., 0] < IMAGE_SIZE[0]) & (uv[..., 1] >= 0)
               & (uv[..., 1] < IMAGE_SIZE[1]))
    obs_frame, obs_landmark = np.nonzero(visible)
    pixels_true = uv[obs_frame, obs_landmark]
    pixels = pixels_true + rng.normal(0.0, PIXEL_NOISE, pixels_true.shape)
    return VioSim(
        name=f"{PREFIX}:{seconds:g}:{int(seed)}", seconds=seconds, seed=int(seed), imu_rate=imu_rate,
        camera_rate=camera_rate, gravity=GRAVITY.copy(), gyro_noise=GYRO_NOISE, accel_noise=ACCEL_NOISE,
        gyro_walk=GYRO_WALK, accel_walk=ACCEL_WALK, pixel_noise=PIXEL_NOISE, imu_times=times, gyro=gyro,
        accel=accel, gyro_true=gyro_true, accel_true=accel_true, bias_gyro=bias_gyro, bias_accel=bias_accel,
        rotations=R, positions=truth["positions"], velocities=truth["velocities"], frame_imu_index=frames,
        frame_times=times[frames], K=K, R_bc=R_bc, t_bc=t_bc, landmarks=landmarks,
        obs_frame=obs_frame.astype(np.int64), obs_landmark=obs_landmark.astype(np.int64), obs_pixels=pixels,
        obs_pixels_true=pixels_true)


def parse_name(name: str) -> tuple[float, int]:
    """``(seconds, seed)`` of ``"vio-sim[:seconds[:seed]]"``; DatasetError naming the field."""
    if not isinstance(name, str):
        raise DatasetError(f"a vio-sim name is a string like 'vio-sim:20:3', got {type(name).__name__}")
    parts = name.strip().split(":")
    if parts[0] != PREFIX:
        raise DatasetError(f"{name!r} is not a vio-sim name: expected '{PREFIX}[:seconds[:seed]]', "
                           f"e.g. '{PREFIX}:20:3'")
    if len(parts) > 3:
        raise DatasetError(f"{name!r}: too many fields; expected '{PREFIX}[:seconds[:seed]]'")
    seconds, seed = DEFAULT_SECONDS, DEFAULT_SEED
    if len(parts) > 1:
        try:
            seconds = float(parts[1])
        except ValueError:
            raise DatasetError(f"{name!r}: seconds {parts[1]!r} is not a number") from None
        if not np.isfinite(seconds) or seconds <= 0.0 or seconds > MAX_SECONDS:
            raise DatasetError(f"{name!r}: seconds must be in (0, {MAX_SECONDS:g}], got {parts[1]!r}")
    if len(parts) > 2:
        try:
            seed = int(parts[2])
        except ValueError:
            raise DatasetError(f"{name!r}: seed {parts[2]!r} is not an integer") from None
        if seed < 0:
            raise DatasetError(f"{name!r}: seed must be non-negative, got {seed}")
    return seconds, seed


def load_vio_sim(name: str = PREFIX) -> VioSim:
    """The simulation a name asks for: ``"vio-sim"`` (20 s, seed 0), ``"vio-sim:60"``,
    ``"vio-sim:20:3"``."""
    seconds, seed = parse_name(name)
    if seconds * IMU_RATE < 0.5:
        raise DatasetError(f"{name!r}: seconds must cover at least one IMU interval ({1.0 / IMU_RATE:g} s)")
    return simulate(seconds, seed)
