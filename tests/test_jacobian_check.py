"""``course.check_jacobian``: the students' Jacobian checker, on vector spaces, SE(2), SO(3) and SE(3)."""

import numpy as np
import pytest

import course
from course.core.impl import load
from course.geometry.jacobian_check import check_jacobian, numerical_jacobian
from course.geometry.so3 import exp_many, skew


def _edge_3d(seed=3):
    """One chapter 6 edge (the reference's error and Jacobians) and its error as a function of the two poses."""
    edge = load("solutions").module("pose_graph_3d").edge_errors_and_jacobians
    rng = np.random.default_rng(seed)
    t, R = rng.normal(size=(2, 3)), exp_many(rng.normal(size=(2, 3)))
    t_z, R_z = rng.normal(size=(1, 3)), exp_many(0.3 * rng.normal(size=(1, 3)))
    i, j = np.array([0]), np.array([1])
    _, A, B = edge(t, R, i, j, t_z, R_z)

    def error(T_i, T_j):
        return edge(np.concatenate([T_i[0], T_j[0]]), np.concatenate([T_i[1], T_j[1]]), i, j, t_z, R_z)[0]

    return error, [(t[:1], R[:1]), (t[1:], R[1:])], A, B


def test_the_reference_se3_edge_passes():
    error, poses, A, B = _edge_3d()
    lines = []
    result = check_jacobian(error, poses, J=[A, B], plus="se3", names=["T_i", "T_j"], rows="se3", out=lines.append)
    assert result.ok and not result.worst and result.max_error < 1e-7
    assert lines[0].startswith("Jacobian OK: 6 x 12")


@pytest.mark.parametrize("which, entry, block", [
    ("A", (4, 3), "d rotation / d T_i rotation"),
    ("A", (1, 5), "d translation / d T_i rotation"),
    ("B", (2, 0), "d translation / d T_j translation"),
])
def test_a_one_entry_slip_in_an_se3_edge_jacobian_is_found_and_its_block_named(which, entry, block):
    error, poses, A, B = _edge_3d()
    slipped = {"A": A.copy(), "B": B.copy()}
    slipped[which][(0, *entry)] += 0.25
    lines = []
    result = check_jacobian(error, poses, J=[slipped["A"], slipped["B"]], plus="se3", names=["T_i", "T_j"],
                            rows="se3", out=lines.append)
    assert not result.ok and result.wrong == 1
    (worst,) = result.worst
    column = entry[1] + (6 if which == "B" else 0)
    assert (worst.row, worst.column) == (entry[0], column)
    assert worst.block == block and list(result.blocks) == [block]
    assert worst.error == pytest.approx(0.25, abs=1e-6)
    assert block in lines[0] and f"J[{entry[0]}, {column}]" in lines[0]


def test_vectorized_blocks_name_the_edge_and_pose():
    """A (M, 6, 6) stack of per-edge blocks is checked as the block diagonal, per edge and pose."""
    edge = load("solutions").module("pose_graph_3d").edge_errors_and_jacobians
    rng = np.random.default_rng(0)
    M = 3
    t, R = rng.normal(size=(2 * M, 3)), exp_many(rng.normal(size=(2 * M, 3)))
    t_z, R_z = rng.normal(size=(M, 3)), exp_many(0.3 * rng.normal(size=(M, 3)))
    i, j = np.arange(M), M + np.arange(M)
    _, A, B = edge(t, R, i, j, t_z, R_z)
    A[2, 0, 4] -= 1.0

    def error(T_i, T_j):
        return edge(np.concatenate([T_i[0], T_j[0]]), np.concatenate([T_i[1], T_j[1]]), i, j, t_z, R_z)[0]

    result = check_jacobian(error, [(t[:M], R[:M]), (t[M:], R[M:])], J=[A, B], plus="se3",
                            names=["T_i", "T_j"], rows="se3", out=None)
    assert list(result.blocks) == ["d edge 2 translation / d T_i pose 2 rotation"]


def test_vector_so3_and_se2():
    x = np.array([0.3, -1.2, 2.0])
    assert check_jacobian(np.sin, x, J=np.diag(np.cos(x)), out=None).ok
    R = exp_many(np.array([[0.2, -0.4, 0.9]]))[0]
    v = np.array([1.0, 2.0, -0.5])
    assert check_jacobian(lambda R: R @ v, R, J=-R @ skew(v), plus="so3", out=None).ok  # d(R Exp(phi) v)/dphi
    assert not check_jacobian(lambda R: R @ v, R, J=R @ skew(v), plus="so3", out=None).ok
    edge = load("solutions").module("pose_graph_edge").edge_error_and_jacobians
    x_i, x_j, z = np.array([0.1, 0.2, 3.1]), np.array([1.0, -0.5, -3.0]), np.array([0.9, -0.6, 0.1])
    _, A, B = edge(x_i, x_j, z)
    result = check_jacobian(lambda a, b: edge(a, b, z)[0], [x_i, x_j], J=[A, B], plus="se2", rows="se2", out=None)
    assert result.ok
    A[0, 2] += 0.5
    result = check_jacobian(lambda a, b: edge(a, b, z)[0], [x_i, x_j], J=[A, B], plus="se2", rows="se2",
                            names=["x_i", "x_j"], out=None)
    assert list(result.blocks) == ["d translation / d x_i rotation"]


def test_without_j_it_returns_the_numerical_jacobian_and_course_exports_it():
    assert course.check_jacobian is check_jacobian
    result = check_jacobian(lambda x: x ** 2, np.array([1.0, 3.0]), out=None)
    assert result.ok and result.analytic is None
    np.testing.assert_allclose(result.numeric, np.diag([2.0, 6.0]), atol=1e-6)
    np.testing.assert_allclose(numerical_jacobian(lambda x: 2 * x, np.ones(2)), 2 * np.eye(2), atol=1e-8)
    with pytest.raises(ValueError, match="choose from"):
        check_jacobian(np.sin, np.ones(2), plus="se4")
    with pytest.raises(ValueError, match="expected"):
        check_jacobian(np.sin, np.ones(2), J=np.ones((3, 3)), out=None)
