"""The gauge of bundle adjustment: the reference directions annihilate J, H has exactly 7
zero eigenvalues without an anchor and none with the gauge fixed."""

import numpy as np
import pytest

from course.notebook_helpers.bal import jacobian_matrix
from course.problems.bal.dataset import synthetic
from course.problems.bal.gauge import dense_hessian, gauge_count, spectrum
from course.problems.bal.problem import BundleAdjustmentProblem
from solutions.gauge import gauge_directions


@pytest.fixture(scope="module")
def scene():
    return synthetic(5, 40, seed=3)


def test_the_seven_directions_are_the_null_space_of_h(scene):
    problem = BundleAdjustmentProblem(scene)
    lin = problem.linearize(problem.x0)
    H = dense_hessian(lin)
    J = jacobian_matrix(scene).toarray()
    np.testing.assert_allclose(H, J.T @ J, rtol=1e-12, atol=1e-9 * np.abs(H).max())
    N = gauge_directions(scene.cameras, scene.points)
    assert N.shape == (9 * 5 + 3 * 40, 7)
    s = np.linalg.svd(N, compute_uv=False)
    assert s[-1] > 1e-3 * s[0]  # independent
    assert np.abs(H @ N).max() <= 1e-9 * np.abs(H).max() * np.abs(N).max()


def test_seven_zero_eigenvalues_unanchored_none_with_the_gauge_fixed(scene):
    free = BundleAdjustmentProblem(scene)
    values = spectrum(free)
    assert gauge_count(free) == 7
    assert values[7] > 1e-9  # the eighth is far from zero
    assert gauge_count(BundleAdjustmentProblem(scene, fix_gauge=True)) == 0


def test_directions_near_zero_rotation_are_finite():
    scene = synthetic(3, 10, seed=1)
    cameras = scene.cameras.copy()
    cameras[0, :3] = 1e-9
    N = gauge_directions(cameras, scene.points)
    assert np.all(np.isfinite(N))
    np.testing.assert_allclose(N[:3, :3], -np.eye(3), atol=1e-8)  # dw = -J_r(w)^-1 u = -u at w = 0
