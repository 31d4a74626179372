"""``python -m course ...``: demo, compare, release; exit codes and outputs."""

import json
import re
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


def test_unimplemented_exercises_are_rows_naming_the_todo(capsys):
    assert main(["compare", "curve", "--impl", "exercises", "--backends", "ours"]) == 0
    out = capsys.readouterr().out
    assert re.search(r"^ours +lm-type1 +not implemented: TODO curve_model\.residuals_and_jacobian$", out, flags=re.M)
    assert "5 run(s) stopped at a TODO of impl exercises (curve_model.residuals_and_jacobian)" in out


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


# ---------------------------------------------------------------- every strategy, where the user picks one

KINDS = {"curve": "curve", "posegraph": "manhattan:30", "bal": "bal-synthetic:4:30:1", "posegraph3d": None}


def test_every_strategy_of_the_minimizer_is_known_described_and_offered_for_every_family():
    from course.app import compare
    from course.backends import registry
    from course.core.method_names import DEFAULT_METHODS, OUR_METHODS
    from course.solver import ALL_METHODS, METHODS
    from course.solver.strategies import make_strategy

    assert ALL_METHODS == tuple(OUR_METHODS) and METHODS == DEFAULT_METHODS
    for method in ALL_METHODS:  # what the minimizer knows: make_strategy builds each
        assert make_strategy(method).factorizations == 0
    with pytest.raises(ValueError, match="lm-scaled-nielsen"):
        make_strategy("newton")
    assert set(registry.KINDS) == set(KINDS) == set(registry.PEERS)
    for kind in registry.KINDS:
        offered = registry.pairs(kind, every=True)
        assert [m for b, m in offered if b == "ours"] == list(ALL_METHODS)
        for method in ALL_METHODS:
            assert compare.plan_for(kind, methods=[method], backends=["ours"]) == [("ours", method)]
        for backend, method in offered:
            assert registry.describe(kind, backend, method)
        default = compare.plan_for(kind)  # no --methods: the chapters' methods, the scaled one on request
        assert [m for b, m in default if b == "ours"] == list(DEFAULT_METHODS)
        assert default == registry.pairs(kind)


@pytest.mark.parametrize("command", ["compare", "demo"])
def test_help_lists_every_method_with_what_it_is(command, capsys):
    from course.backends import registry
    from course.core.method_names import OUR_METHODS

    with pytest.raises(SystemExit) as exc:
        main([command, "--help"])
    assert exc.value.code == 0
    lines = capsys.readouterr().out.splitlines()
    for method, what in OUR_METHODS.items():
        assert any(line.split() == [method, *what.split()] for line in lines), method
    for kind in registry.KINDS:
        for backend, method in registry.pairs(kind):
            if backend != "ours":
                what = registry.describe(kind, backend, method)
                assert any(line.split() == [backend, method, *what.split()] for line in lines), (kind, backend, method)
    assert "lm-scaled-nielsen, lm-source, run only when named" in " ".join(lines)


@pytest.mark.parametrize("dataset, valid, invalid", [
    ("curve", ["gauss-newton", "lm-scaled-nielsen", "dogleg", "levenberg-marquardt", "lm", "trf"], ["levenberg"]),
    ("bal-synthetic:4:30:1", ["lm-type3", "lm-scaled-nielsen", "levenberg-marquardt", "trf"], ["lm", "levenberg"]),
    ("manhattan:30", ["lm-scaled-nielsen", "levenberg"], ["trf"]),
])
def test_an_unknown_method_is_refused_with_the_valid_ones_for_its_family(dataset, valid, invalid, capsys):
    assert main(["compare", dataset, "--methods", "lm-type3,newton"]) == 2
    err = capsys.readouterr().err
    assert "unknown method(s) newton for" in err and "--help" in err
    offered = err.split("choose from ", 1)[1].split(" (")[0].split(", ")
    assert set(valid) <= set(offered) and not set(invalid) & set(offered), offered


def _graph3d(tmp_path):
    """A 3D chain of three poses and a loop closure, the start moved off the measurements."""
    info = " ".join(["1 0 0 0 0 0", "1 0 0 0 0", "1 0 0 0", "4 0 0", "4 0", "4"])
    lines = ["VERTEX_SE3:QUAT 0 0 0 0 0 0 0 1", "VERTEX_SE3:QUAT 1 1.1 0.1 0 0 0 0.05 1",
             "VERTEX_SE3:QUAT 2 2.2 -0.1 0.1 0 0.05 0 1",
             f"EDGE_SE3:QUAT 0 1 1 0 0 0 0 0 1 {info}", f"EDGE_SE3:QUAT 1 2 1 0 0 0 0 0 1 {info}",
             f"EDGE_SE3:QUAT 0 2 2 0 0 0 0 0 1 {info}"]
    path = tmp_path / "chain3d.g2o"
    path.write_text("\n".join(lines) + "\n")
    return str(path)


@pytest.mark.parametrize("kind", list(KINDS))
def test_compare_runs_lm_scaled_nielsen_on_every_family(kind, tmp_path, capsys):
    dataset = KINDS[kind] or _graph3d(tmp_path)
    out = tmp_path / "runs.json"
    assert main(["compare", dataset, "--methods", "lm-scaled-nielsen", "--backends", "ours", "--json", str(out)]) == 0
    assert re.search(r"^ours +lm-scaled-nielsen +\d+ ", capsys.readouterr().out, flags=re.M)
    (run,) = json.loads(out.read_text())["runs"]
    assert run["method"] == "lm-scaled-nielsen" and run["final_chi2"] < run["initial_chi2"]


def test_compare_on_a_small_bal_problem_with_lm_scaled_nielsen_beside_the_peers(capsys):
    """The BAL comparison with the scaled damping and every peer method (the peers missing here are rows)."""
    assert main(["compare", "bal-synthetic:4:30:1", "--methods", "lm-scaled-nielsen,lm-type3,trf",
                 "--max-iterations", "30"]) == 0
    table = capsys.readouterr().out
    assert re.search(r"^ours +lm-scaled-nielsen +\d+ ", table, flags=re.M)
    assert re.search(r"^ours +lm-type3 +\d+ ", table, flags=re.M) and re.search(r"^scipy +trf ", table, flags=re.M)


def test_demo_offers_lm_scaled_nielsen_too(tmp_path, capsys):
    assert main(["demo", "--curve-only", "--methods", "lm-scaled-nielsen", "--backends", "ours", "--repeat", "1",
                 "--out", str(tmp_path / "out")]) == 0
    assert re.search(r"^ours +lm-scaled-nielsen +\d+ ", capsys.readouterr().out, flags=re.M)
    (run,) = json.loads((tmp_path / "out" / "curve.json").read_text())["runs"]
    assert run["method"] == "lm-scaled-nielsen" and run["final_chi2"] < run["initial_chi2"]


def test_chapter_7s_back_ends_run_only_when_named():
    """``--methods`` alone keeps to the default back ends (gtsam-custom's LM on ladybug-49 takes minutes);
    ``--backends`` naming one runs it, every method it offers unless ``--methods`` says which."""
    from course.app import compare

    plan = compare.plan_for("bal", methods=["lm-type1", "levenberg-marquardt", "trf"])
    assert {b for b, _ in plan} == {"ours", "ceres", "gtsam", "scipy"}
    assert compare.plan_for("posegraph", methods=["dogleg"], backends=["ours", "ours-autodiff"]) == [
        ("ours", "dogleg"), ("ours-autodiff", "dogleg")]
    named = compare.plan_for("bal", backends=["ours", "gtsam-custom"])
    assert ("gtsam-custom", "levenberg-marquardt") in named and ("ours", "lm-type3") in named
