"""``python -m course ...``: demo, compare, release; exit codes and outputs."""

import json
import subprocess
import sys

import pytest
from conftest import needs

from course.app.cli import main
from course.core.backend_names import BACKENDS
from course.core.impl import REPO_ROOT


def test_import_is_cheap():
    heavy = "('numpy', 'scipy', 'pyceres', 'matplotlib')"
    code = f"import sys, course.app.cli; print(sorted(m for m in {heavy} if sys.modules.get(m) is not None))"
    out = subprocess.run([sys.executable, "-c", code], cwd=REPO_ROOT, capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"


@needs("pyceres")
def test_compare_curve_json_schema(tmp_path, capsys):
    path = tmp_path / "runs" / "curve.json"
    assert main(["compare", "curve", "--json", str(path)]) == 0
    table = capsys.readouterr().out
    for word in ("backend", "method", "iters", "final chi2", "ms/iter", "lm-type2", "levenberg-marquardt", "trf"):
        assert word in table
    doc = json.loads(path.read_text())
    assert doc["dataset"] == "curve"
    pairs = {(r["backend"], r["method"]) for r in doc["runs"]}
    assert {("ours", "gauss-newton"), ("ours", "lm-type1"), ("ours", "lm-type2"), ("ours", "lm-type3"),
            ("ceres", "levenberg-marquardt"), ("ceres", "dogleg"), ("scipy", "lm"), ("scipy", "trf")} <= pairs
    for run in doc["runs"]:
        assert run["backend"] in BACKENDS
        assert isinstance(run["iterations"], int) and run["iterations"] == len(run["trace"]) - 1
        assert run["final_chi2"] < run["initial_chi2"]
        assert run["seconds"] > 0
        assert run["trace"][0]["iteration"] == 0
        assert run["trace"][0]["chi2"] == pytest.approx(run["initial_chi2"], rel=1e-9)
        assert len(run["params"]) == 3
        for record in run["trace"]:
            assert {"iteration", "chi2", "damping", "rho", "step_norm", "accepted", "seconds"} <= set(record)
            assert record["damping"] is None or isinstance(record["damping"], float)  # NaN -> null


def test_compare_filters_and_plot(tmp_path, capsys):
    plot = tmp_path / "chi2.png"
    assert main(["compare", "curve", "--backends", "ours,scipy", "--methods", "lm-type3,lm", "--plot", str(plot)]) == 0
    out = capsys.readouterr().out
    assert "lm-type3" in out and "scipy" in out and "ceres" not in out
    assert plot.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_unknown_dataset_is_a_clear_usage_error(capsys):
    assert main(["compare", "no-such-dataset"]) == 2
    err = capsys.readouterr().err
    assert "unknown dataset 'no-such-dataset'" in err and "curve" in err


def test_unknown_backend_and_method(capsys):
    assert main(["compare", "curve", "--backends", "nope"]) == 2
    assert "unknown backend" in capsys.readouterr().err
    assert main(["compare", "curve", "--methods", "newton"]) == 2
    assert "unknown method" in capsys.readouterr().err


def test_unimplemented_exercises_fail_with_the_todo(capsys):
    assert main(["compare", "curve", "--impl", "exercises", "--backends", "ours"]) == 1
    assert "TODO curve_model.residuals_and_jacobian" in capsys.readouterr().err


@pytest.mark.slow
def test_demo_writes_plots(tmp_path, capsys):
    out = tmp_path / "out"
    assert main(["demo", "--out", str(out), "--repeat", "1"]) == 0
    table = capsys.readouterr().out
    assert "lm-type1" in table and "ceres" in table and "scipy" in table
    for name in ("curve_chi2.png", "curve_lambda.png", "curve_fit.png"):
        data = (out / name).read_bytes()
        assert data[:8] == b"\x89PNG\r\n\x1a\n" and len(data) > 10_000, name
    doc = json.loads((out / "curve.json").read_text())
    assert doc["dataset"] == "curve" and len(doc["runs"]) >= 8


def test_python_dash_m_course_runs(tmp_path):
    out = subprocess.run([sys.executable, "-m", "course", "compare", "curve", "--backends", "ours",
                          "--methods", "lm-type1"], cwd=REPO_ROOT, capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    assert "lm-type1" in out.stdout


def test_no_command_is_a_usage_error():
    with pytest.raises(SystemExit) as exc:
        main([])
    assert exc.value.code == 2


@pytest.mark.slow
def test_vio_prints_the_table_and_writes_json(tmp_path, capsys):
    assert main(["vio", "vio-sim:3:0", "--no-peers", "--json", str(tmp_path / "vio.json")]) == 0
    out = capsys.readouterr().out
    assert "APE rmse (m)" in out and "window 10 (with prior)" in out and "GTSAM" not in out
    results = json.loads((tmp_path / "vio.json").read_text())
    assert set(results) == {"window 10 (with prior)", "window 10 (without prior)", "batch"}
    assert set(results["batch"]) == {"rmse", "max", "scale", "mean_solve_seconds", "solves", "mean_iterations"}
    assert 0.0 < results["window 10 (with prior)"]["rmse"] < 0.1


def test_vio_with_unwritten_exercises_says_which_todo(capsys):
    assert main(["vio", "vio-sim:2:0", "--no-peers", "--impl", "exercises"]) == 1
    assert "TODO imu_preintegration.preintegrate" in capsys.readouterr().err
