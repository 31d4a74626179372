"""Chapter 4 peers: Ceres (through pycolmap), GTSAM and scipy on BAL problems, and ``compare`` on them."""

import json
import sys

import numpy as np
import pytest
from conftest import needs

from course.app import compare
from course.app.cli import main as course_main
from course.backends import registry
from course.backends.bal import common as bal_common
from course.backends.bal import scipy as scipy_bal
from course.core import peers
from course.problems.bal.dataset import (
    behind_camera,
    camera_frame_points,
    cost,
    in_front,
    load_bal,
    residuals,
    synthetic,
    write_bal,
)

#: scipy with its tolerances far below the recipe's ftol = 1e-4
TIGHT = {"ftol": 1e-15, "xtol": 1e-15, "gtol": 1e-15}
#: "reaches the minimum": a noise-free problem's final cost over its initial one
ZERO = 1e-10


def noiseless():
    """5 cameras, 40 points, exact observations (minimum cost 0), every point in front."""
    return synthetic(5, 40, seed=3, noise=0.0)


def ladybug():
    from course.core.data import data_dir

    folder = data_dir()
    if not (folder / "bal_ladybug").is_dir():
        pytest.skip(f"ladybug-49 not found in the data folder {folder} (set COURSE_DATA to use another)")
    return load_bal("ladybug-49")


def check_result(result, problem, backend):
    """What every BAL row promises: our chi2 over all observations at ``params``, a trace from 0."""
    cameras, points = bal_common.unpack(problem, result.params)
    assert result.backend == backend and not result.not_run
    assert result.initial_chi2 == pytest.approx(2.0 * cost(problem), rel=1e-12)
    assert result.final_chi2 == pytest.approx(2.0 * cost(problem, cameras, points), rel=1e-12)
    assert result.final_cost == pytest.approx(0.5 * result.final_chi2, rel=1e-12)
    assert result.trace and result.trace[0].iteration == 0
    assert len(result.peer_costs) == len(result.trace)
    json.dumps(result.to_json())  # JSON-ready: no NaN, no numpy scalars


# ---------------------------------------------------------------- scipy (core)


def test_scipy_jacobian_sparsity_covers_the_finite_difference_jacobian():
    from scipy.optimize._numdiff import approx_derivative

    problem = synthetic(3, 6, seed=1)
    x0 = bal_common.pack(problem.cameras, problem.points)
    recorder = scipy_bal._Recorder(problem, scipy_bal.jacobian_sparsity(problem))
    dense = approx_derivative(recorder.raw, x0, method="2-point")
    pattern = scipy_bal.jacobian_sparsity(problem).toarray()
    assert pattern.shape == dense.shape == (2 * problem.num_observations, 9 * 3 + 3 * 6)
    assert np.all(dense[pattern == 0] == 0.0)
    assert np.count_nonzero(pattern) == 24 * problem.num_observations
    sparse = recorder.jac(x0).toarray()  # the grouped differences: the same numbers
    np.testing.assert_allclose(sparse, dense, rtol=0, atol=1e-12 * np.abs(dense).max())


def test_scipy_reaches_zero_on_noiseless_data():
    problem = noiseless()
    result = scipy_bal.solve(problem, max_iterations=50, **TIGHT)
    check_result(result, problem, "scipy")
    assert result.final_cost < ZERO * result.initial_cost
    # scipy's cost is ours: the same function
    assert result.peer_initial_cost == pytest.approx(result.initial_cost, rel=1e-12)
    assert result.peer_final_cost == pytest.approx(result.final_cost, rel=1e-9, abs=1e-20)
    assert result.iterations == len(result.trace) - 1
    assert [r.iteration for r in result.trace] == list(range(len(result.trace)))
    assert result.trace[-1].accepted or any(r.accepted for r in result.trace[1:])


def test_scipy_max_iterations_and_bad_arguments():
    problem = synthetic(4, 20, seed=2)
    result = scipy_bal.solve(problem, max_iterations=2, **TIGHT)
    assert result.iterations == 2 and "nfev 3" in result.stop_reason
    with pytest.raises(ValueError, match="unknown method 'lm'"):
        scipy_bal.solve(problem, "lm")
    with pytest.raises(ValueError, match="max_iterations must be an integer >= 1"):
        scipy_bal.solve(problem, max_iterations=0)


# ---------------------------------------------------------------- Ceres through pycolmap


@needs("pycolmap")
def test_colmap_conversion_projects_as_bal():
    from course.backends.bal import colmap as colmap_bal

    problem = synthetic(4, 25, seed=5)
    reconstruction, point_ids = colmap_bal.to_reconstruction(problem)
    predicted = residuals(problem.cameras, problem.points, problem.camera_index, problem.point_index,
                          np.zeros_like(problem.observations))
    for k in range(0, problem.num_observations, 7):
        image = reconstruction.images[int(problem.camera_index[k]) + 1]
        uv = image.project_point(problem.points[problem.point_index[k]])
        np.testing.assert_allclose(uv, predicted[k] * [1.0, -1.0], rtol=1e-12, atol=1e-9)
    cameras, points, kept = colmap_bal.from_reconstruction(problem, reconstruction, point_ids)
    assert kept.all()
    np.testing.assert_allclose(cameras, problem.cameras, rtol=0, atol=1e-12)
    np.testing.assert_array_equal(points, problem.points)


@needs("pycolmap")
@pytest.mark.parametrize("method", ["levenberg-marquardt", "dogleg"])
def test_colmap_reaches_zero_on_noiseless_data(method):
    from course.backends.bal import colmap as colmap_bal

    problem = noiseless()
    result = colmap_bal.solve(problem, method, max_iterations=100)
    check_result(result, problem, "ceres")
    assert result.final_cost < ZERO * result.initial_cost
    assert result.removed_points == result.removed_observations == 0
    # every point in front: Ceres scores all observations, so its start cost is ours (7 digits in its table)
    assert result.peer_initial_cost == pytest.approx(result.initial_cost, rel=1e-6)
    assert result.iterations == result.trace[-1].iteration >= 1
    assert result.stop_reason.startswith("convergence")


@needs("pycolmap")
def test_colmap_table_parser():
    from course.backends.bal import colmap as colmap_bal

    text = ("iter      cost      cost_change  |gradient|   |step|    tr_ratio  tr_radius  ls_iter  iter_time  "
            "total_time\n"
            "   0  8.508021e+05    0.00e+00    8.57e+06   0.00e+00   0.00e+00  1.00e+04        0    2.88e-02  "
            "  1.12e-01\n"
            "   1  5.357261e+04    7.97e+05    4.14e+06   0.00e+00   9.53e-01  3.00e+04        1    9.14e-02  "
            "  2.04e-01\n"
            "some other line 1 2 3\n")
    rows = colmap_bal.parse_iterations(text)
    assert [r["iteration"] for r in rows] == [0, 1]
    assert rows[1]["cost"] == 5.357261e04 and rows[1]["tr_ratio"] == 0.953 and rows[1]["total_time"] == 0.204
    report = colmap_bal.parse_report("   Iterations : 6\n         Time : 0.491273 [s]\n"
                                     "  Termination : NO_CONVERGENCE\n")
    assert report == {"termination": "NO_CONVERGENCE", "iterations": 6, "time": 0.491273}


@needs("pycolmap")
def test_colmap_on_ladybug_removes_the_points_behind_the_cameras():
    from course.backends.bal import colmap as colmap_bal

    problem = ladybug()
    result = colmap_bal.solve(problem, max_iterations=2)
    check_result(result, problem, "ceres")
    assert (result.removed_points, result.removed_observations) == (10, 31)
    assert result.behind_camera_start == behind_camera(problem) == 31
    assert result.initial_cost == pytest.approx(850912.4606808, abs=1e-6)
    assert result.peer_initial_cost == pytest.approx(850802.09, rel=1e-6)  # without the 31 observations
    assert result.iterations == 2 and result.stop_reason.startswith("max_iterations")
    assert result.final_cost < 0.1 * result.initial_cost


def test_the_front_variant_is_the_problem_without_the_points_behind_a_camera():
    problem = ladybug()
    front = load_bal("ladybug-49:front")
    assert (problem.num_points - front.num_points, problem.num_observations - front.num_observations) == (10, 31)
    assert behind_camera(front) == 0 and front.num_cameras == problem.num_cameras
    assert front.name == "ladybug-49:front" and "without the 10 points (and their 31 observations)" in front.source
    assert cost(front) == pytest.approx(850802.09, rel=1e-6)  # Ceres' start on ladybug-49, as pycolmap reports it
    # the points kept, renumbered in order, with their observations
    kept = np.setdiff1d(np.arange(problem.num_points), np.unique(problem.point_index[
        camera_frame_points(problem.cameras, problem.points, problem.camera_index, problem.point_index)[:, 2] >= 0]))
    np.testing.assert_array_equal(front.points, problem.points[kept])
    np.testing.assert_array_equal(front.points[front.point_index], problem.points[problem.point_index][
        np.isin(problem.point_index, kept)])
    assert load_bal("dubrovnik-3-7:front").num_points == load_bal("dubrovnik-3-7").num_points  # nothing behind


@needs("pycolmap")
def test_colmap_on_the_front_variant_deletes_nothing():
    from course.backends.bal import colmap as colmap_bal

    front = in_front(ladybug())
    result = colmap_bal.solve(front, max_iterations=2)
    assert (result.removed_points, result.removed_observations) == (0, 0)
    assert result.peer_initial_cost == pytest.approx(result.initial_cost, rel=1e-6)  # as its report prints it


# ---------------------------------------------------------------- GTSAM


@needs("gtsam")
def test_gtsam_start_is_the_bal_start_and_scores_like_ours():
    from course.backends.bal import gtsam as gtsam_bal

    problem = noiseless()
    for gauge in gtsam_bal.GAUGES:
        graph, values = gtsam_bal.to_gtsam(problem, gauge)
        assert graph.error(values) == pytest.approx(cost(problem), rel=1e-12)  # the priors are 0 at the start
        cameras, points = gtsam_bal.from_gtsam(problem, values)
        np.testing.assert_allclose(cameras, problem.cameras, rtol=0, atol=1e-12)
        np.testing.assert_array_equal(points, problem.points)
    with pytest.raises(ValueError, match="unknown gauge"):
        gtsam_bal.to_gtsam(problem, "fixed")


@needs("gtsam")
def test_gtsam_reaches_zero_on_noiseless_data_without_priors():
    from course.backends.bal import gtsam as gtsam_bal

    problem = noiseless()
    result = gtsam_bal.solve(problem, max_iterations=100, gauge="none")
    check_result(result, problem, "gtsam")
    assert result.final_cost < ZERO * result.initial_cost
    assert result.peer_initial_cost == pytest.approx(result.initial_cost, rel=1e-12)
    assert result.peer_final_cost == pytest.approx(result.final_cost, rel=1e-6, abs=1e-18)
    # the priors of GTSAM's example hold camera 0 (f included) and point 0 at their perturbed start
    with_priors = gtsam_bal.solve(problem, max_iterations=100)
    assert with_priors.final_cost < 1e-4 * with_priors.initial_cost and "gauge: priors" in with_priors.stop_reason


@needs("gtsam")
def test_gtsam_on_ladybug_scores_the_observations_behind_the_cameras_zero():
    import gtsam

    from course.backends.bal import gtsam as gtsam_bal
    from course.core.data import data_dir

    problem = ladybug()
    graph, values = gtsam_bal.to_gtsam(problem)
    assert graph.error(values) == pytest.approx(850802.09, abs=1e-2)
    assert cost(problem) == pytest.approx(850912.46, abs=1e-2)
    # the same start as GTSAM's own reader
    sfm = gtsam.SfmData.FromBalFile(str(data_dir() / "bal_ladybug" / "problem-49-7776-pre.txt"))
    for c in (0, 17, 48):
        ours = values.atPinholeCameraCal3Bundler(gtsam.symbol_shorthand.C(c))
        assert ours.equals(sfm.camera(c), 1e-12)


# ---------------------------------------------------------------- compare


def test_registry_bal_kind():
    assert registry.library("bal", "ceres") == "pycolmap"
    assert registry.library("posegraph", "ceres") == "pyceres"
    assert registry.library("bal", "gtsam") == "gtsam"
    pairs = registry.pairs("bal")
    assert ("ceres", "levenberg-marquardt") in pairs and ("gtsam", "levenberg-marquardt") in pairs
    assert ("scipy", "trf") in pairs and ("ours", "lm-type1") in pairs


def test_bal_names_go_to_the_bal_runner(tmp_path):
    for name in ("ladybug-49", "dubrovnik-3-7", "bal-synthetic:10:200"):
        assert compare.find_runner(name).kind == "bal"
    path = tmp_path / "problem.txt"
    write_bal(synthetic(3, 8), path)
    assert compare.find_runner(str(path)).kind == "bal"
    assert compare.find_runner("intel").kind == "posegraph"


def test_run_bal_every_pair_is_a_row():
    problem = synthetic(4, 30, seed=1)
    runs = compare.run_bal(problem, max_iterations=30)
    assert [(r.backend, r.method) for r in runs] == compare.bal_plan()
    by_pair = {(r.backend, r.method): r for r in runs}
    assert not by_pair[("ours", "gauss-newton")].not_run  # the gauge is fixed by default
    (free,) = compare.run_bal(problem, methods=["gauss-newton"], backends=["ours"], fix_gauge=False)
    assert free.not_run.startswith("failed: ")  # the free gauge: S is singular
    for (backend, _), run in by_pair.items():
        if not run.not_run:
            check_result(run, problem, backend)
            assert run.final_chi2 < 0.05 * run.initial_chi2
        else:
            assert backend == "ours" or run.not_run.startswith("not run: ")
    table = compare.format_table(runs) + "\n" + compare.format_bal(runs)
    assert "lm-type1" in table and "peer final cost" in table


def test_missing_pycolmap_is_a_row_and_one_line(monkeypatch, capsys):
    monkeypatch.setitem(sys.modules, "pycolmap", None)
    monkeypatch.setattr(peers, "_announced", set())
    runs = compare.run_bal(synthetic(3, 10), backends=["ceres", "scipy"], max_iterations=5)
    ceres = [r for r in runs if r.backend == "ceres"]
    assert ceres and all(r.not_run == "not run: pycolmap is not installed here" for r in ceres)
    assert all(not r.not_run for r in runs if r.backend == "scipy")
    assert capsys.readouterr().err.count(peers.missing_message("pycolmap")) == 1


def test_cli_compare_bal_options(tmp_path, capsys):
    path = tmp_path / "bal.json"
    argv = ["compare", "bal-synthetic:4:30", "--backends", "ours,scipy", "--methods", "lm-type3,trf",
            "--max-iterations", "20", "--json", str(path)]
    assert course_main(argv) == 0
    out = capsys.readouterr().out
    assert "lm-type3" in out and "trf" in out and "dogleg" not in out and "peer final cost" in out
    doc = json.loads(path.read_text())
    assert doc["dataset"] == "bal-synthetic:4:30"
    assert [(r["backend"], r["method"]) for r in doc["runs"]] == [("ours", "lm-type3"), ("scipy", "trf")]
    for run in doc["runs"]:
        assert run["iterations"] == len(run["trace"]) - 1 <= 20
        assert run["bal"]["final_cost"] == pytest.approx(0.5 * run["final_chi2"], rel=1e-12)
        assert len(run["params"]) == 9 * 4 + 3 * 30
    assert course_main(["compare", "bal-synthetic:4:30", "--backends", "g2o"]) == 2
    assert "unknown backend" in capsys.readouterr().err


@needs("pycolmap", "gtsam")
@pytest.mark.slow
def test_compare_ladybug_few_iterations(capsys):
    ladybug()
    argv = ["compare", "ladybug-49", "--methods", "lm-type1,levenberg-marquardt,trf", "--max-iterations", "2"]
    assert course_main(argv) == 0
    out = capsys.readouterr().out
    assert "10 points, 31 observations" in out
    for backend in ("ours", "ceres", "gtsam", "scipy"):
        assert f"\n{backend} " in out
