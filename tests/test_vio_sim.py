"""The simulated visual-inertial data (course.problems.vio.sim): names parse with clear errors, runs are
seeded, the IMU is consistent with the trajectory (noise-free samples integrated from the
true initial state reproduce it), and every observation is the projection of its landmark."""

import numpy as np
import pytest

from course.core.errors import DatasetError
from course.problems.vio.sim import GRAVITY, load_vio_sim, parse_name, simulate, trajectory
from solutions.imu_preintegration import so3_exp, so3_log


@pytest.fixture(scope="module")
def sim():
    return load_vio_sim("vio-sim:20:3")


def test_names_parse_with_defaults():
    assert parse_name("vio-sim") == (20.0, 0)
    assert parse_name("vio-sim:5") == (5.0, 0)
    assert parse_name("vio-sim:2.5:7") == (2.5, 7)


@pytest.mark.parametrize("name, says", [
    ("vio_sim:20", "not a vio-sim name"), ("vio-sim:abc", "seconds 'abc' is not a number"),
    ("vio-sim:-1", "seconds must be in"), ("vio-sim:20:x", "seed 'x' is not an integer"),
    ("vio-sim:20:-2", "seed must be non-negative"), ("vio-sim:1:2:3", "too many fields"),
    ("vio-sim:0.001", "at least one IMU interval"),
])
def test_bad_names_say_which_field(name, says):
    with pytest.raises(DatasetError, match=says):
        load_vio_sim(name)


def test_bad_arguments_name_the_argument():
    with pytest.raises(ValueError, match="seed"):
        simulate(1.0, -1)
    with pytest.raises(ValueError, match="camera_rate"):
        simulate(1.0, 0, camera_rate=30)


def test_seeded_and_shaped(sim):
    again, other = load_vio_sim("vio-sim:20:3"), load_vio_sim("vio-sim:20:4")
    assert np.array_equal(sim.gyro, again.gyro) and np.array_equal(sim.obs_pixels, again.obs_pixels)
    assert not np.allclose(sim.gyro, other.gyro)
    n = 20 * 200
    assert sim.gyro.shape == sim.accel.shape == sim.bias_gyro.shape == (n + 1, 3)
    assert sim.rotations.shape == (n + 1, 3, 3) and sim.positions.shape == sim.velocities.shape == (n + 1, 3)
    assert len(sim.frame_imu_index) == 20 * 20 + 1 and np.all(np.diff(sim.frame_times) == pytest.approx(0.05))
    assert np.allclose(sim.gravity, [0.0, 0.0, -9.81])
    assert np.bincount(sim.obs_frame, minlength=len(sim.frame_times)).min() >= 5  # every frame sees landmarks
    orthogonal = np.einsum("kji,kjl->kil", sim.rotations, sim.rotations) - np.eye(3)
    assert np.abs(orthogonal).max() < 1e-12 and np.all(np.linalg.det(sim.rotations) > 0)


def test_the_imu_measures_the_derivatives_of_the_trajectory():
    """omega_b = (R^T R')^vee and a_b = R^T (p'' - g), by central differences (h = 1e-5 s)."""
    t, h = np.array([0.3, 4.1, 13.7]), 1e-5
    before, now, after = trajectory(t - h), trajectory(t), trajectory(t + h)
    for k in range(len(t)):
        R = now["rotations"][k]
        omega = so3_log(before["rotations"][k].T @ after["rotations"][k]) / (2 * h)
        assert np.allclose(omega, now["omega_body"][k], rtol=0, atol=1e-8)
        acc = (after["positions"][k] - 2 * now["positions"][k] + before["positions"][k]) / h**2
        assert np.allclose(acc, now["accelerations"][k], rtol=0, atol=1e-3)
        vel = (after["positions"][k] - before["positions"][k]) / (2 * h)
        assert np.allclose(vel, now["velocities"][k], rtol=0, atol=1e-8)
        assert R.shape == (3, 3)


def test_noise_free_imu_integrated_from_the_truth_reproduces_the_trajectory(sim):
    """Midpoint integration of the noise-free samples in the world frame over 20 s (4000 steps):
    drift below 1 cm in position, 1 mm/s in velocity, 1e-5 rad in attitude."""
    R, v, p = sim.rotations[0], sim.velocities[0], sim.positions[0]
    dt, g, a = sim.dt, GRAVITY, sim.accel_true
    worst = np.zeros(3)
    for k in range(len(sim.imu_times) - 1):
        R_next = R @ so3_exp((sim.gyro_true[k] + sim.gyro_true[k + 1]) / 2.0 * dt)
        acc = (R @ a[k] + R_next @ a[k + 1]) / 2.0 + g
        p = p + v * dt + 0.5 * acc * dt * dt
        v = v + acc * dt
        R = R_next
        worst = np.maximum(worst, [np.linalg.norm(so3_log(sim.rotations[k + 1].T @ R)),
                                   np.linalg.norm(v - sim.velocities[k + 1]),
                                   np.linalg.norm(p - sim.positions[k + 1])])
    assert worst[0] < 1e-5 and worst[1] < 1e-3 and worst[2] < 1e-2, worst


def test_the_measurements_carry_the_biases_and_the_noise(sim):
    residual = sim.gyro - sim.gyro_true - sim.bias_gyro
    assert np.std(residual) == pytest.approx(sim.gyro_noise * np.sqrt(sim.imu_rate), rel=0.05)
    residual = sim.accel - sim.accel_true - sim.bias_accel
    assert np.std(residual) == pytest.approx(sim.accel_noise * np.sqrt(sim.imu_rate), rel=0.05)
    steps = np.diff(sim.bias_accel, axis=0)
    assert np.std(steps) == pytest.approx(sim.accel_walk * np.sqrt(sim.dt), rel=0.05)


def test_observations_are_projections_of_their_landmarks(sim):
    k = sim.frame_imu_index[sim.obs_frame]
    X_b = np.einsum("nji,nj->ni", sim.rotations[k], sim.landmarks[sim.obs_landmark] - sim.positions[k])
    X_c = (X_b - sim.t_bc) @ sim.R_bc
    assert np.all(X_c[:, 2] > 0.5)
    uv = X_c[:, :2] / X_c[:, 2:] @ sim.K[:2, :2].T + sim.K[:2, 2]
    assert np.allclose(uv, sim.obs_pixels_true, rtol=0, atol=1e-9)
    assert np.std(sim.obs_pixels - sim.obs_pixels_true) == pytest.approx(sim.pixel_noise, rel=0.05)
