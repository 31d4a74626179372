"""course.core.jit: when the framework's kernels are compiled, and that each compiled kernel gives
its numpy path's numbers (the Schur reduction's are in test_schur_reduction.py)."""

import numpy as np
import pytest

from course.core import jit, peers
from course.problems.bal import dataset


def _residuals(problem, monkeypatch, compiled: bool):
    if compiled:
        monkeypatch.delenv(jit.NO_JIT, raising=False)
    else:
        monkeypatch.setenv(jit.NO_JIT, "1")
    return dataset.residuals(problem.cameras, problem.points, problem.camera_index, problem.point_index,
                             problem.observations)


def test_no_kernels_when_switched_off(monkeypatch):
    monkeypatch.setenv(jit.NO_JIT, "1")
    assert jit.kernels(vars(dataset), dataset.KERNELS) is None


def test_no_kernels_without_numba_and_it_is_said_once(monkeypatch, capsys):
    monkeypatch.delenv(jit.NO_JIT, raising=False)
    monkeypatch.setattr(peers, "installed", lambda name: name != "numba")
    monkeypatch.setattr(peers, "_announced", set())
    assert jit.kernels(vars(dataset), dataset.KERNELS) is None
    assert jit.kernels(vars(dataset), dataset.KERNELS) is None
    assert capsys.readouterr().err.count("numba is not installed here") == 1


@pytest.mark.skipif(not peers.installed("numba"), reason=peers.missing_message("numba"))
def test_the_compiled_bal_residuals_are_numpys(monkeypatch):
    problem = dataset.load_bal("bal-synthetic:6:80:2")
    compiled = _residuals(problem, monkeypatch, True)
    numpy = _residuals(problem, monkeypatch, False)
    assert compiled.shape == numpy.shape == (problem.num_observations, 2)
    np.testing.assert_allclose(compiled, numpy, rtol=1e-13, atol=1e-12)


@pytest.mark.skipif(not peers.installed("numba"), reason=peers.missing_message("numba"))
def test_a_point_on_the_camera_plane_gives_the_same_non_finite_residual_on_both_paths(monkeypatch):
    cameras = np.array([[0.0, 0, 0, 0, 0, 0, 500, 0.1, 0.01], [0.1, -0.2, 0.05, 0.3, 0, -1, 480, 0, 0]])
    points = np.array([[1.0, 1.0, 0.0], [0.5, -0.2, -3.0]])  # camera 0 (R = I, t = 0) sees point 0 at P_z = 0
    problem = dataset.BALProblem(cameras, points, np.array([0, 1, 0, 1]), np.array([0, 0, 1, 1]),
                                 np.array([[1.0, 2.0], [3.0, 4.0], [5.0, 6.0], [7.0, 8.0]]))
    compiled = _residuals(problem, monkeypatch, True)
    numpy = _residuals(problem, monkeypatch, False)
    assert not np.any(np.isfinite(compiled[0])) and not np.any(np.isfinite(numpy[0]))
    np.testing.assert_allclose(compiled[1:], numpy[1:], rtol=1e-13, atol=1e-12)


def test_an_index_out_of_range_raises_as_numpy_does(monkeypatch):
    problem = dataset.load_bal("bal-synthetic:6:80:2")
    bad = problem.camera_index.copy()
    bad[5] = problem.num_cameras
    monkeypatch.delenv(jit.NO_JIT, raising=False)
    with pytest.raises(IndexError):
        dataset.residuals(problem.cameras, problem.points, bad, problem.point_index, problem.observations)


@pytest.mark.skipif(not peers.installed("numba"), reason=peers.missing_message("numba"))
@pytest.mark.parametrize("module", ["dataset", "schur_reduction"])
def test_a_well_formed_problem_takes_the_compiled_path(monkeypatch, module):
    from course.solver import schur_reduction

    monkeypatch.delenv(jit.NO_JIT, raising=False)
    target = {"dataset": dataset, "schur_reduction": schur_reduction}[module]
    problem = dataset.load_bal("bal-synthetic:6:80:2")
    compiled = jit.kernels(vars(target), target.KERNELS)
    called = []
    monkeypatch.setattr(jit, "kernels", lambda namespace, names: tuple(
        (lambda *args, kernel=kernel: called.append(1) or kernel(*args)) for kernel in compiled)
        if names == target.KERNELS else None)
    if module == "dataset":
        dataset.residuals(problem.cameras, problem.points, problem.camera_index, problem.point_index,
                          problem.observations)
    else:
        W = np.random.default_rng(0).normal(size=(problem.num_observations, 9, 3))
        V_inv = np.broadcast_to(np.eye(3), (problem.num_points, 3, 3))
        schur_reduction.schur_reduction(W, V_inv, problem.camera_index, problem.point_index, problem.num_cameras)
    assert called


@pytest.mark.skipif(not peers.installed("numba"), reason=peers.missing_message("numba"))
def test_where_no_cache_can_be_written_the_kernels_are_compiled_without_one(monkeypatch):
    import numba

    njit, asked = numba.njit, []

    def refusing(function, cache=False, **options):
        asked.append(cache)
        if cache:
            raise RuntimeError("cannot cache function: no locator available for file")
        return njit(function, cache=cache, **options)

    monkeypatch.delenv(jit.NO_JIT, raising=False)
    monkeypatch.setattr(numba, "njit", refusing)

    def twice(x):
        return 2.0 * x

    namespace = {"__name__": "tests.test_jit.read_only", "twice": twice}
    (compiled,) = jit.kernels(namespace, ("twice",))
    assert compiled(1.5) == 3.0 and namespace["twice"] is compiled
    assert asked == [True, False]
