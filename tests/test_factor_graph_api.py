"""What a user of the engine reads and ports: a solution by key, typed, and the tangent conventions
beside GTSAM's (an information matrix of a GTSAM ``BetweenFactorPose3`` ported by the converter)."""

import numpy as np
import pytest
from conftest import needs

from course.factorgraph import (
    BETWEEN_SE2,
    BETWEEN_SE3,
    SE2,
    SE3,
    FactorGraph,
    FactorGraphProblem,
    Pose3,
    Vector,
    conventions,
    se3_value,
)
from course.geometry.so3 import so3_exp
from course.solver import minimize


def test_a_solution_is_read_by_key_and_typed():
    graph = FactorGraph("mixed")
    graph.add_variable("x0", SE2, [0.0, 0.0, 0.0])
    graph.add_variable("x1", SE2, [0.9, 0.1, 0.05])
    graph.add_variable("p0", SE3, se3_value([1.0, 2.0, 3.0], so3_exp([0.1, 0.2, 0.3])))
    graph.add_variable("l0", Vector(2), [4.0, 5.0])
    graph.fix("x0")
    graph.add(BETWEEN_SE2, ["x0", "x1"], [1.0, 0.0, 0.0])
    problem = FactorGraphProblem(graph)
    values = problem.values_of(minimize(problem, "lm-type3").params)
    assert list(values) == ["x0", "x1", "p0", "l0"] and len(values) == 4
    np.testing.assert_allclose(values["x1"], [1.0, 0.0, 0.0], atol=1e-10)
    pose = values["p0"]
    assert isinstance(pose, Pose3)
    np.testing.assert_allclose(pose.t, [1.0, 2.0, 3.0])
    np.testing.assert_allclose(pose.R, so3_exp([0.1, 0.2, 0.3]))
    np.testing.assert_allclose(pose.matrix()[:3, 3], [1.0, 2.0, 3.0])
    assert values.array("p0").shape == (12,)
    np.testing.assert_allclose(values["l0"], [4.0, 5.0])
    with pytest.raises(KeyError, match="mixed: no variable 'x9'"):
        values["x9"]


def test_the_pose3_converter_swaps_the_halves_and_is_its_own_inverse():
    rng = np.random.default_rng(3)
    A = rng.normal(size=(6, 6))
    info = A @ A.T
    ours = conventions.from_gtsam_pose3(info)
    np.testing.assert_array_equal(ours[:3, :3], info[3:, 3:])
    np.testing.assert_array_equal(ours[:3, 3:], info[3:, :3])
    np.testing.assert_array_equal(conventions.to_gtsam_pose3(ours), info)
    with pytest.raises(ValueError, match=r"\(\.\.\., 6, 6\), got shape \(3, 3\)"):
        conventions.from_gtsam_pose3(np.eye(3))


def test_a_ceres_quaternion_covariance_is_rotated_into_our_right_tangent():
    R = so3_exp([0.4, -0.2, 1.1])
    C_left = np.diag([1e-4, 4e-4, 9e-4])
    C = conventions.from_ceres_quaternion_covariance(C_left, R)
    np.testing.assert_allclose(C, R.T @ C_left @ R, atol=1e-18)
    np.testing.assert_allclose(conventions.from_ceres_quaternion_covariance(C_left, R, before_2_2=True), 4 * C,
                               atol=1e-18)


@needs("gtsam")
def test_a_gtsam_information_matrix_ported_by_the_converter_gives_gtsams_chi2():
    """Sigmas 0.01 rad on the rotation, 0.5 m on the translation, correlated: copied as it is, the matrix
    weighs the translation error as a rotation's (a chi2 off by orders of magnitude); converted, the
    two agree up to the second-order difference of GTSAM's twist and our split error."""
    import gtsam

    rng = np.random.default_rng(7)
    sigmas = np.array([0.01, 0.01, 0.01, 0.5, 0.5, 0.5])  # GTSAM: rotation first
    L = np.diag(sigmas) @ (np.eye(6) + 0.1 * rng.normal(size=(6, 6)))
    info_gtsam = np.linalg.inv(L @ L.T)
    t_z, R_z = np.array([1.0, 0.2, -0.1]), so3_exp([0.0, 0.1, 0.3])
    t_j = t_z + np.array([0.3, -0.2, 0.4])
    R_j = R_z @ so3_exp([0.004, -0.003, 0.005])
    factor = gtsam.BetweenFactorPose3(0, 1, gtsam.Pose3(gtsam.Rot3(R_z), t_z), gtsam.noiseModel.Gaussian.Information(
        info_gtsam))
    values = gtsam.Values()
    values.insert(0, gtsam.Pose3())
    values.insert(1, gtsam.Pose3(gtsam.Rot3(R_j), t_j))
    theirs = 2.0 * factor.error(values)

    def ours(information):
        graph = FactorGraph("ported")
        graph.add_variable("x0", SE3, se3_value(np.zeros(3), np.eye(3)))
        graph.add_variable("x1", SE3, se3_value(t_j, R_j))
        graph.add(BETWEEN_SE3, ["x0", "x1"], se3_value(t_z, R_z), information)
        problem = FactorGraphProblem(graph)
        return problem.chi2(problem.x0)

    assert ours(conventions.from_gtsam_pose3(info_gtsam)) == pytest.approx(theirs, rel=0.02)
    assert ours(info_gtsam) > 100 * theirs
