"""The analytic IMU-factor Jacobian (course/problems/vio/imu_jacobians.py), at the rotation rows of the reference
``imu_factor_residual``, against central differences of that residual through the frame retraction."""

import ast
from pathlib import Path

import numpy as np
import pytest

from course.geometry.so3 import right_jacobian, right_jacobian_many, so3_exp, so3_log
from course.problems.vio import imu_jacobians as ij
from course.problems.vio.problem import frame_retract
from course.problems.vio.sim import load_vio_sim
from solutions.imu_preintegration import imu_factor_residual

#: the Jacobian against central differences, relative to its largest entry
JACOBIAN_REL_TOL = 1e-6
FD_STEP = 1e-6
#: keyframes every 5 camera frames (0.25 s, 50 IMU intervals) of a 2-second simulation
SIM_NAME, EVERY = "vio-sim:2:0", 5
#: the largest rotation angle (rad) of a state or of a rotation residual at a test point
MAX_ANGLE = 3.0


def _residual(s_i, s_j, pre, gravity):
    """The reference ``imu_factor_residual`` (9,) at frame states (15,)."""
    return imu_factor_residual((so3_exp(s_i[0:3]), s_i[6:9], s_i[3:6]), (so3_exp(s_j[0:3]), s_j[6:9], s_j[3:6]),
                               pre, (s_i[9:12], s_i[12:15]), gravity)


def _jacobian(s_i, s_j, pre, gravity):
    """The module's (9, 30) at the reference residual's rotation rows."""
    return ij.imu_jacobian(s_i, s_j, pre, gravity, _residual(s_i, s_j, pre, gravity)[0:3])


def _rotation_vector(rng, angle):
    u = rng.standard_normal(3)
    return angle * u / np.linalg.norm(u)


@pytest.fixture(scope="module")
def sim():
    return load_vio_sim(SIM_NAME)


def _keyframe(sim, k):
    """The true state (15,) of keyframe k (its biases the simulated ones) and its IMU index."""
    i = int(sim.frame_imu_index[EVERY * k])
    s = np.r_[so3_log(sim.rotations[i]), sim.positions[i], sim.velocities[i], sim.bias_gyro[i], sim.bias_accel[i]]
    return s, i


def _sim_preintegration(sim, k, scheme, bias_offset):
    """The preintegration from keyframe k to k + 1 at the true biases of k plus ``bias_offset`` (6,)."""
    from solutions.imu_preintegration import preintegrate

    s, a = _keyframe(sim, k)
    _, b = _keyframe(sim, k + 1)
    return preintegrate(sim.gyro[a:b + 1], sim.accel[a:b + 1], sim.dt, s[9:12] + bias_offset[:3],
                        s[12:15] + bias_offset[3:], sim.gyro_noise, sim.accel_noise, scheme=scheme)


def _synthetic_preintegration(rng):
    """Twelve random values shaped as a Preintegrated (no reference needed), with gyro-bias
    Jacobians large enough that ``Exp(dR/dbg delta b_g)`` turns by tenths of a radian."""
    m = lambda scale: scale * rng.standard_normal((3, 3))
    return (so3_exp(_rotation_vector(rng, 1.3)), rng.standard_normal(3), rng.standard_normal(3), 0.4, np.eye(9),
            m(3.0), m(1.0), m(0.5), m(0.3), m(0.1), 0.01 * rng.standard_normal(3), 0.1 * rng.standard_normal(3))


def _points(rng, s_i, s_j, pre):
    """Pairs of states around (s_i, s_j): perturbed, with biases away from the preintegration's
    (which were set near s_i's), turned far (|phi| up to 3 rad), with a large rotation residual.

    Every angle stays below :data:`MAX_ANGLE`: the shared ``so3_log`` loses accuracy as its angle
    nears pi (about 1e-16 / (pi - t)^2), which central differences through the retraction (and
    the residual's own ``Log``) would magnify by 1 / FD_STEP."""
    out = []
    for kind in ("near", "near", "far turned", "far turned", "large residual"):
        for _ in range(1000):
            a, b = s_i.copy(), s_j.copy()
            a[0:3] = so3_log(so3_exp(a[0:3]) @ so3_exp(_rotation_vector(rng, 0.01)))
            b[0:3] = so3_log(so3_exp(b[0:3]) @ so3_exp(_rotation_vector(rng, 0.01)))
            a[3:9] += 0.1 * rng.standard_normal(6)
            b[3:9] += 0.1 * rng.standard_normal(6)
            a[9:15] += np.r_[0.02 * rng.standard_normal(3), 0.2 * rng.standard_normal(3)]  # delta b != 0
            b[9:15] += rng.standard_normal(6)  # unused by the factor
            if kind == "far turned":  # both turned by the same rotation, so that |phi_i| is in [2.5, 3]
                R_i = so3_exp(_rotation_vector(rng, rng.uniform(2.5, 3.0)))
                b[0:3] = so3_log(R_i @ so3_exp(a[0:3]).T @ so3_exp(b[0:3]))
                a[0:3] = so3_log(R_i)
            elif kind == "large residual":
                b[0:3] = so3_log(so3_exp(b[0:3]) @ so3_exp(_rotation_vector(rng, 2.0)))
            r = _residual(a, b, pre, np.zeros(3))
            if max(np.linalg.norm(a[0:3]), np.linalg.norm(b[0:3]), np.linalg.norm(r[0:3])) <= MAX_ANGLE:
                break
        else:
            raise AssertionError(f"no {kind} point with angles below {MAX_ANGLE}")
        out.append((a, b))
    return out


def _central_differences(s_i, s_j, pre, gravity):
    """(9, 30): central differences of the residual through ``frame_retract``."""
    J = np.zeros((9, 30))
    for col in range(30):
        d = np.zeros(15)
        d[col % 15] = FD_STEP
        if col < 15:
            plus = _residual(frame_retract(s_i, d), s_j, pre, gravity)
            minus = _residual(frame_retract(s_i, -d), s_j, pre, gravity)
        else:
            plus = _residual(s_i, frame_retract(s_j, d), pre, gravity)
            minus = _residual(s_i, frame_retract(s_j, -d), pre, gravity)
        J[:, col] = (plus - minus) / (2.0 * FD_STEP)
    return J


def _cases(sim, scheme, seed):
    """(s_i, s_j, preintegration) triples from the simulation's first three keyframe pairs."""
    rng = np.random.default_rng(seed)
    out = []
    for k in range(3):
        s_i, _ = _keyframe(sim, k)
        s_j, _ = _keyframe(sim, k + 1)
        offset = np.r_[0.01 * rng.standard_normal(3), 0.05 * rng.standard_normal(3)]
        pre = _sim_preintegration(sim, k, scheme, offset)
        out += [(a, b, pre) for a, b in _points(rng, s_i, s_j, pre)]
    return out


def _check_jacobian(s_i, s_j, pre, gravity):
    J = _jacobian(s_i, s_j, pre, gravity)
    assert J.shape == (9, 30)
    numeric = _central_differences(s_i, s_j, pre, gravity)
    err = np.max(np.abs(J - numeric))
    assert err <= JACOBIAN_REL_TOL * np.max(np.abs(J)), (err, np.max(np.abs(J)))
    assert np.all(J[:, 24:30] == 0.0)  # frame j's biases


def test_the_module_computes_no_residual():
    """The residual is the exercise's: the module offers the Jacobian alone, at the residual it is given."""
    assert not [name for name in vars(ij) if "residual" in name.lower()]


@pytest.mark.parametrize("scheme", ["midpoint", "euler"])
def test_the_jacobian_matches_central_differences_on_the_simulation(sim, scheme):
    for s_i, s_j, pre in _cases(sim, scheme, seed=2):
        _check_jacobian(s_i, s_j, pre, sim.gravity)


@pytest.mark.parametrize("seed", range(4))
def test_the_jacobian_matches_central_differences_on_random_values(seed):
    """No reference needed: random states and a random preintegration with large bias Jacobians."""
    rng = np.random.default_rng(100 + seed)
    pre = _synthetic_preintegration(rng)
    s_i = np.r_[_rotation_vector(rng, 1.0), rng.standard_normal(12)]
    s_j = np.r_[so3_log(so3_exp(s_i[0:3]) @ so3_exp(_rotation_vector(rng, 1.0))), rng.standard_normal(12)]
    s_i[9:15] = np.r_[pre[10], pre[11]] + 0.1 * rng.standard_normal(6)
    for a, b in _points(rng, s_i, s_j, pre):
        _check_jacobian(a, b, pre, np.array([0.0, 0.0, -9.81]))


@pytest.mark.parametrize("angle", [0.0, 1e-6, 1e-4, 0.3, 2.0, np.pi - 1e-6, np.pi])
def test_the_inverse_right_jacobian_inverts_the_right_jacobian(angle):
    phi = _rotation_vector(np.random.default_rng(3), angle) if angle else np.zeros(3)
    np.testing.assert_allclose(ij.right_jacobian_inverse(phi) @ right_jacobian(phi), np.eye(3), atol=1e-12)
    both = np.stack([phi, 0.5 * phi])  # the stacked forms, row by row as the single ones
    np.testing.assert_allclose(right_jacobian_many(both), [right_jacobian(p) for p in both], rtol=0, atol=1e-15)
    np.testing.assert_allclose(ij.right_jacobian_inverse(both), [ij.right_jacobian_inverse(p) for p in both],
                               rtol=0, atol=1e-15)


def test_k_factors_at_once_are_the_factors_one_by_one():
    rng = np.random.default_rng(7)
    pres = [_synthetic_preintegration(rng) for _ in range(4)]
    s_i = np.column_stack([rng.uniform(-1, 1, (4, 3)), rng.standard_normal((4, 12))])
    s_j = np.column_stack([rng.uniform(-1, 1, (4, 3)), rng.standard_normal((4, 12))])
    gravity = np.array([0.0, 0.0, -9.81])
    r_R = np.array([_residual(s_i[k], s_j[k], pres[k], gravity)[0:3] for k in range(4)])
    J = ij.imu_jacobians(s_i, s_j, ij.stack_preintegrated(pres), gravity, r_R)
    assert J.shape == (4, 9, 30)
    for k in range(4):
        _check_jacobian(s_i[k], s_j[k], pres[k], gravity)
        np.testing.assert_array_equal(J[k], _jacobian(s_i[k], s_j[k], pres[k], gravity))
    with pytest.raises(ValueError, match=r"\(4, 15\)"):
        ij.imu_jacobians(s_i[:3], s_j, ij.stack_preintegrated(pres), gravity, r_R)
    with pytest.raises(ValueError, match="r_R"):
        ij.imu_jacobians(s_i, s_j, ij.stack_preintegrated(pres), gravity, r_R[:3])


def test_bad_arguments_are_named():
    pre = _synthetic_preintegration(np.random.default_rng(4))
    with pytest.raises(ValueError, match="s_i"):
        ij.imu_jacobian(np.zeros(9), np.zeros(15), pre, np.zeros(3), np.zeros(3))
    with pytest.raises(ValueError, match="12 values"):
        ij.imu_jacobian(np.zeros(15), np.zeros(15), pre[:11], np.zeros(3), np.zeros(3))
    with pytest.raises(ValueError, match="gravity"):
        ij.imu_jacobian(np.zeros(15), np.zeros(15), pre, np.zeros(2), np.zeros(3))
    with pytest.raises(ValueError, match="r_R"):
        ij.imu_jacobian(np.zeros(15), np.zeros(15), pre, np.zeros(3), np.zeros(9))


def test_the_module_does_not_import_the_solutions():
    """It must run in a student tree, where solutions/ is absent."""
    tree = ast.parse(Path(ij.__file__).read_text())
    names = [alias.name for node in ast.walk(tree) if isinstance(node, ast.Import) for alias in node.names]
    names += [node.module or "" for node in ast.walk(tree) if isinstance(node, ast.ImportFrom)]
    assert not [name for name in names if name.split(".")[0] in ("solutions", "exercises")]
