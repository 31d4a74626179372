"""IMU preintegration (solutions/imu_preintegration.py) against GTSAM and against finite differences.

- With the scheme GTSAM uses (``scheme="euler"``: the left sample of each interval),
  ``preintegrate`` agrees with ``gtsam.PreintegratedImuMeasurementsManifold`` (Forster's
  on-manifold preintegration) on the same samples: delta R, v, p, the bias Jacobians and the
  covariance, to 1e-9 relative (GTSAM's own deltas are not exposed as bias Jacobians by the
  wrapper: they are read from ``predict(NavState(), bias, H1, H2)`` at identity, where
  ``H2``'s rows are (rotation, position, velocity) in the body frame of the predicted state and
  its columns (accelerometer, gyroscope); its covariance is on the same ordering, body-frame p,
  v). ``gtsam.PreintegratedImuMeasurements`` is the tangent-space variant in this build; it
  differs by about 1e-7 relative (reported, not asserted to 1e-9).
- With the taught scheme (midpoint), the figures are far from GTSAM's (about 1e-2 relative in
  delta v over 0.3 s of the simulated loop) but much closer to the truth: the test measures both.
- The bias Jacobians are derivatives of the discrete scheme, checked by central differences;
  so is the residual's first-order bias correction.
"""

import numpy as np
import pytest

from course.problems.vio.sim import load_vio_sim
from solutions.imu_preintegration import Preintegrated, imu_factor_residual, preintegrate, so3_exp, so3_log

gtsam = pytest.importorskip("gtsam")

#: relative agreement with GTSAM with the same (Euler) scheme: max |ours - theirs| / max |theirs|
GTSAM_RTOL = 1e-9


@pytest.fixture(scope="module")
def window():
    """60 intervals (0.3 s) of the noisy simulated IMU, biases off the truth by a little."""
    s = load_vio_sim("vio-sim:2:1")
    i, j = 100, 160
    return {"sim": s, "i": i, "j": j, "gyro": s.gyro[i:j + 1], "accel": s.accel[i:j + 1], "dt": s.dt,
            "bg": s.bias_gyro[i] + 0.003, "ba": s.bias_accel[i] - 0.02}


def _gtsam(w, cls):
    s = w["sim"]
    params = gtsam.PreintegrationParams.MakeSharedU(9.81)
    params.setGyroscopeCovariance(s.gyro_noise**2 * np.eye(3))
    params.setAccelerometerCovariance(s.accel_noise**2 * np.eye(3))
    params.setIntegrationCovariance(np.zeros((3, 3)))
    pim = cls(params, gtsam.imuBias.ConstantBias(w["ba"], w["bg"]))
    for k in range(len(w["gyro"]) - 1):
        pim.integrateMeasurement(w["accel"][k], w["gyro"][k], w["dt"])
    H1, H2 = np.zeros((9, 9), order="F"), np.zeros((9, 6), order="F")
    pim.predict(gtsam.NavState(), gtsam.imuBias.ConstantBias(w["ba"], w["bg"]), H1, H2)
    R = pim.deltaRij().matrix()
    T = np.zeros((9, 9))  # ours (phi, v_world, p_world) -> GTSAM's (phi, p_body, v_body)
    T[0:3, 0:3], T[3:6, 6:9], T[6:9, 3:6] = np.eye(3), R.T, R.T
    return {"delta_R": R, "delta_v": pim.deltaVij(), "delta_p": pim.deltaPij(), "dR_dbg": H2[0:3, 3:6],
            "dp_dba": R @ H2[3:6, 0:3], "dp_dbg": R @ H2[3:6, 3:6], "dv_dba": R @ H2[6:9, 0:3],
            "dv_dbg": R @ H2[6:9, 3:6], "covariance": pim.preintMeasCov(), "T": T, "delta_t": pim.deltaTij()}


def _relative(ours, theirs):
    return float(np.max(np.abs(np.asarray(ours) - theirs)) / np.max(np.abs(theirs)))


def _differences(w, scheme, cls):
    s = w["sim"]
    pre = preintegrate(w["gyro"], w["accel"], w["dt"], w["bg"], w["ba"], s.gyro_noise, s.accel_noise, scheme=scheme)
    theirs = _gtsam(w, cls)
    out = {name: _relative(getattr(pre, name), theirs[name])
           for name in ("delta_R", "delta_v", "delta_p", "dR_dbg", "dv_dbg", "dv_dba", "dp_dbg", "dp_dba")}
    out["covariance"] = _relative(theirs["T"] @ pre.covariance @ theirs["T"].T, theirs["covariance"])
    assert pre.delta_t == pytest.approx(theirs["delta_t"], rel=1e-12)
    return out


def test_euler_agrees_with_gtsam_manifold_preintegration(window):
    differences = _differences(window, "euler", gtsam.PreintegratedImuMeasurementsManifold)
    print("euler vs GTSAM (manifold):", {k: f"{v:.1e}" for k, v in differences.items()})
    assert max(differences.values()) <= GTSAM_RTOL, differences


def test_how_far_the_taught_midpoint_scheme_is_from_gtsam_and_from_the_truth(window):
    """Recorded for the notes: midpoint vs GTSAM's Euler, and both schemes vs the noise-free truth."""
    differences = _differences(window, "midpoint", gtsam.PreintegratedImuMeasurementsManifold)
    print("midpoint vs GTSAM (manifold):", {k: f"{v:.1e}" for k, v in differences.items()})
    assert 1e-6 < differences["delta_v"] < 1e-1  # a different scheme, the same quantity
    tangent = _differences(window, "euler", gtsam.PreintegratedImuMeasurements)
    print("euler vs GTSAM (default, tangent):", {k: f"{v:.1e}" for k, v in tangent.items()})
    assert max(tangent.values()) < 1e-3
    s, i, j = window["sim"], window["i"], window["j"]
    R_i, T = s.rotations[i], (j - i) * s.dt
    true_v = R_i.T @ (s.velocities[j] - s.velocities[i] - s.gravity * T)
    true_p = R_i.T @ (s.positions[j] - s.positions[i] - s.velocities[i] * T - 0.5 * s.gravity * T * T)
    errors = {}
    for scheme in ("euler", "midpoint"):
        pre = preintegrate(s.gyro_true[i:j + 1], s.accel_true[i:j + 1], s.dt, np.zeros(3), np.zeros(3), 0.0, 0.0,
                           scheme=scheme)
        errors[scheme] = (np.linalg.norm(so3_log(pre.delta_R.T @ R_i.T @ s.rotations[j])),
                          np.linalg.norm(pre.delta_v - true_v), np.linalg.norm(pre.delta_p - true_p))
    print("error vs the truth (rad, m/s, m):", errors)
    assert all(m < e / 10 for m, e in zip(errors["midpoint"], errors["euler"]))


def _perturbed(w, scheme, dbg, dba):
    s = w["sim"]
    return preintegrate(w["gyro"], w["accel"], w["dt"], w["bg"] + dbg, w["ba"] + dba, s.gyro_noise, s.accel_noise,
                        scheme=scheme)


@pytest.mark.parametrize("scheme", ["midpoint", "euler"])
def test_bias_jacobians_match_central_differences(window, scheme):
    """Central differences with h = 1e-6 (rad/s, m/s^2): truncation O(h^2), rounding ~1e-16/h."""
    pre, h = _perturbed(window, scheme, 0, 0), 1e-6
    for col in range(3):
        e = np.eye(3)[col] * h
        plus, minus = _perturbed(window, scheme, e, 0), _perturbed(window, scheme, -e, 0)
        dR = (so3_log(pre.delta_R.T @ plus.delta_R) - so3_log(pre.delta_R.T @ minus.delta_R)) / (2 * h)
        assert np.allclose(pre.dR_dbg[:, col], dR, rtol=1e-6, atol=1e-8)
        assert np.allclose(pre.dv_dbg[:, col], (plus.delta_v - minus.delta_v) / (2 * h), rtol=1e-6, atol=1e-8)
        assert np.allclose(pre.dp_dbg[:, col], (plus.delta_p - minus.delta_p) / (2 * h), rtol=1e-6, atol=1e-8)
        plus, minus = _perturbed(window, scheme, 0, e), _perturbed(window, scheme, 0, -e)
        assert np.allclose(so3_log(plus.delta_R.T @ minus.delta_R), 0.0, atol=1e-15)
        assert np.allclose(pre.dv_dba[:, col], (plus.delta_v - minus.delta_v) / (2 * h), rtol=1e-6, atol=1e-8)
        assert np.allclose(pre.dp_dba[:, col], (plus.delta_p - minus.delta_p) / (2 * h), rtol=1e-6, atol=1e-8)


def test_covariance_is_symmetric_positive_definite(window):
    pre = _perturbed(window, "midpoint", 0, 0)
    assert np.allclose(pre.covariance, pre.covariance.T, rtol=0, atol=1e-18)
    assert np.linalg.eigvalsh(pre.covariance).min() > 0


def _true_states(w):
    s, i, j = w["sim"], w["i"], w["j"]
    return ((s.rotations[i], s.velocities[i], s.positions[i]), (s.rotations[j], s.velocities[j], s.positions[j]))


def test_the_residual_vanishes_at_the_truth_and_its_bias_correction_is_first_order(window):
    s, i, j = window["sim"], window["i"], window["j"]
    state_i, state_j = _true_states(window)
    exact = preintegrate(s.gyro_true[i:j + 1], s.accel_true[i:j + 1], s.dt, np.zeros(3), np.zeros(3), 0.0, 0.0)
    r = imu_factor_residual(state_i, state_j, exact, (np.zeros(3), np.zeros(3)), s.gravity)
    assert np.abs(r).max() < 1e-4  # the midpoint scheme's own error over 0.3 s
    # a bias change of size d: first-order correction vs re-integration, the gap is O(d^2)
    pre = _perturbed(window, "midpoint", 0, 0)
    gaps = []
    for d in (1e-3, 1e-4):
        dbg, dba = d * np.array([1.0, -2.0, 0.5]), 10 * d * np.array([-1.0, 0.3, 2.0])
        again = _perturbed(window, "midpoint", dbg, dba)
        bias = (window["bg"] + dbg, window["ba"] + dba)
        corrected = imu_factor_residual(state_i, state_j, pre, bias, s.gravity)
        reintegrated = imu_factor_residual(state_i, state_j, again, bias, s.gravity)
        gaps.append(np.abs(corrected - reintegrated).max())
    assert gaps[1] < gaps[0] / 50, gaps  # quadratic: 100x smaller for 10x smaller d


def test_residual_matches_its_definition_through_a_perturbed_state(window):
    """Move state_j by a known amount: r_v and r_p move by R_i^T of it, r_R by its log."""
    s = window["sim"]
    state_i, (R_j, v_j, p_j) = _true_states(window)
    pre = _perturbed(window, "midpoint", 0, 0)
    bias = (window["bg"], window["ba"])
    base = imu_factor_residual(state_i, (R_j, v_j, p_j), pre, bias, s.gravity)
    dv, dp, dphi = np.array([0.1, -0.2, 0.05]), np.array([-0.3, 0.1, 0.2]), np.array([1e-3, -2e-3, 5e-4])
    moved = imu_factor_residual(state_i, (R_j @ so3_exp(dphi), v_j + dv, p_j + dp), pre, bias, s.gravity)
    R_i = state_i[0]
    assert np.allclose(moved[3:6] - base[3:6], R_i.T @ dv, rtol=0, atol=1e-12)
    assert np.allclose(moved[6:9] - base[6:9], R_i.T @ dp, rtol=0, atol=1e-12)
    assert np.allclose(moved[0:3] - base[0:3], dphi, rtol=0, atol=1e-5)  # J_r^-1(r) dphi, r small


def test_preintegrate_accepts_a_dt_per_interval_and_a_plain_tuple_in_the_residual(window):
    s = window["sim"]
    n = len(window["gyro"]) - 1
    a = preintegrate(window["gyro"], window["accel"], np.full(n, s.dt), window["bg"], window["ba"], 0.1, 0.1)
    b = preintegrate(window["gyro"], window["accel"], s.dt, window["bg"], window["ba"], 0.1, 0.1)
    assert np.array_equal(a.delta_p, b.delta_p) and isinstance(a, Preintegrated)
    state_i, state_j = _true_states(window)
    r1 = imu_factor_residual(state_i, state_j, a, (window["bg"], window["ba"]), s.gravity)
    r2 = imu_factor_residual(state_i, state_j, tuple(a), (window["bg"], window["ba"]), s.gravity)
    assert np.array_equal(r1, r2)


@pytest.mark.parametrize("kwargs, says", [
    ({"gyro": np.zeros((1, 3))}, "gyro must have shape"), ({"accel": np.zeros((5, 2))}, "accel must have"),
    ({"dt": np.ones(3)}, "dt must be a number or have shape"), ({"dt": -0.1}, "dt must be positive"),
    ({"bias_gyro": np.zeros(2)}, "bias_gyro must have shape"), ({"scheme": "rk4"}, "scheme must be one of"),
])
def test_clear_errors(kwargs, says):
    args = {"gyro": np.zeros((5, 3)), "accel": np.zeros((5, 3)), "dt": 0.005, "bias_gyro": np.zeros(3),
            "bias_accel": np.zeros(3), "gyro_noise": 0.1, "accel_noise": 0.1} | kwargs
    with pytest.raises(ValueError, match=says):
        preintegrate(**args)


@pytest.mark.parametrize("angle", [1e-9, 1e-4, 0.5, 2.0, 3.0, np.pi - 2e-3, np.pi - 1e-4, np.pi - 1e-8, np.pi])
def test_so3_log_inverts_exp_at_every_angle_up_to_pi(angle):
    rng = np.random.default_rng(7)
    for _ in range(20):
        u = rng.standard_normal(3)
        u /= np.linalg.norm(u)
        phi = so3_log(so3_exp(angle * u))
        assert np.linalg.norm(so3_exp(phi) - so3_exp(angle * u)) <= 1e-12  # the same rotation
        if angle < np.pi - 1e-6:  # below pi the vector itself is unique
            assert np.allclose(phi, angle * u, rtol=0, atol=1e-9)
