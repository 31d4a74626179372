"""``compare`` and ``demo`` outside the grader: the stop column, the line naming the exercise to look
at when a run of the student's ends above the peers or at the iteration limit, and the rows (never an
abort) for what is not written yet, with how to select what is."""

import re
import shutil

import numpy as np
import pytest

from course.app import compare
from course.app.cli import main
from course.core.impl import REPO_ROOT
from course.core.trace import RunResult


def _run(backend, method, chi2, stop="cost_tolerance", iterations=10):
    return RunResult(backend, method, np.zeros(3), 100.0, chi2, iterations, 0.01, stop_reason=stop)


def _impl(tmp_path, written, edit=None):
    """A folder laid out like exercises/: the stubs, with the reference's ``written`` modules copied in;
    ``edit`` = (module, old, new) a one-line change of one of them."""
    folder = tmp_path / "impl"
    shutil.copytree(REPO_ROOT / "exercises", folder, ignore=shutil.ignore_patterns("__pycache__"))
    for name in written:
        shutil.copyfile(REPO_ROOT / "solutions" / f"{name}.py", folder / f"{name}.py")
    if edit:
        module, old, new = edit
        path = folder / f"{module}.py"
        text = path.read_text()
        assert old in text
        path.write_text(text.replace(old, new, 1))
    return folder


CHAPTER1 = ("curve_model", "gauss_newton", "damping")


def test_short_stop_reasons():
    assert compare.short_stop_reason("cost_tolerance") == "cost_tolerance"
    assert compare.short_stop_reason("status 2: `ftol` termination condition is satisfied. (nfev 3, njev 2)") \
        == "cost_tolerance"
    assert compare.short_stop_reason("no_convergence: Maximum number of iterations reached. Number of "
                                     "iterations: 100.") == "max_iterations"
    assert compare.short_stop_reason("converged; gauge: priors") == "converged"
    assert compare.short_stop_reason("") == "-"
    table = compare.format_table([_run("ours", "lm-type1", 5.0, "max_iterations")])
    assert table.splitlines()[0].split()[-2:] == ["stop", "params"]
    assert "max_iterations" in table.splitlines()[-1]


def test_advice_names_the_exercise_of_a_run_above_the_peers_or_at_the_limit():
    runs = [_run("ours", "lm-type1", 34369.0), _run("ours", "lm-type3", 89.43),
            _run("ours", "dogleg", 89.43 * (1 + 1e-7), "max_iterations", 100),
            _run("ceres", "levenberg-marquardt", 89.43)]
    lines = compare.advice(runs, "curve", "exercises")
    assert lines[0].startswith("check: ours lm-type1 ended at chi2 34369") and lines[0].endswith(
        "look at damping.GavinType1")
    assert lines[1].startswith("check: ours dogleg stopped at the iteration limit (100 step attempts) without "
                               "converging: if more iterations (--max-iterations) do not end it at the peers' chi2")
    assert lines[1].endswith("look at dogleg (cauchy_point, dogleg_step, update_radius)")
    assert not any("lm-type3" in line for line in lines)
    assert compare.advice(runs, "curve", "solutions") == []  # the reference is not the student's
    assert compare.advice(runs[1:2] + runs[3:], "curve", "exercises") == []
    everyone = [_run("ours", "gauss-newton", 200.0), _run("ours", "lm-type1", 300.0), _run("g2o", "levenberg", 100.0)]
    lines = compare.advice(everyone, "posegraph", "/some/path")
    assert any("every method of ours is off: look first at pose_graph_edge and pose_graph_assembly" in line
               for line in lines)


def test_todo_hint_says_how_to_select_what_is_written():
    runs = [_run("ours", "lm-type1", 1.0),
            RunResult.skipped("ours", "dogleg", "not implemented: TODO dogleg.cauchy_point"),
            RunResult.skipped("ceres", "dogleg", "not implemented: TODO ceres_edge_cost.SE2EdgeCost.__init__"),
            _run("g2o", "levenberg", 1.0), RunResult.skipped("gtsam", "dogleg", "not run: gtsam is not installed here")]
    hint = compare.todo_hint(runs, "exercises")
    assert hint.startswith("2 run(s) stopped at a TODO of impl exercises (ceres_edge_cost.SE2EdgeCost.__init__, "
                           "dogleg.cauchy_point); write them")
    assert hint.endswith("select what is written: --methods lm-type1 or --backends ours,g2o")
    assert compare.todo_hint(runs[:1], "exercises") == ""


@pytest.mark.slow
def test_compare_curve_with_chapter_1_written_prints_every_row(tmp_path, capsys):
    impl = _impl(tmp_path, CHAPTER1)
    assert main(["compare", "curve", "--impl", str(impl)]) == 0
    out = capsys.readouterr().out
    assert re.search(r"^ours +dogleg +not implemented: TODO dogleg\.cauchy_point$", out, flags=re.M)
    for method in ("gauss-newton", "lm-type1", "lm-type2", "lm-type3"):
        assert re.search(rf"^ours +{method} +\d+ .* cost_tolerance ", out, flags=re.M), method
    assert "select what is written: --methods gauss-newton,lm-type1,lm-type2,lm-type3" in out
    assert "check:" not in out


@pytest.mark.slow
def test_a_broken_lm_type1_is_flagged_by_compare(tmp_path, capsys):
    """lambda multiplied after an accepted step instead of divided: the run converges nowhere near the peers."""
    impl = _impl(tmp_path, CHAPTER1, ("damping", "lam=max(state.lam / self.l_down, LAMBDA_MIN)",
                                      "lam=min(state.lam * self.l_up, LAMBDA_MAX)"))
    assert main(["compare", "curve", "--impl", str(impl), "--methods", "lm-type1,lm-type3,lm,trf"]) == 0
    out = capsys.readouterr().out
    (line,) = [line for line in out.splitlines() if line.startswith("check: ours")]
    assert line.startswith("check: ours lm-type1 ended at chi2") and "above the peers' best" in line
    assert ("stopped at the iteration limit (100 step attempts) without converging: if more iterations "
            "(--max-iterations) do not end it at the peers' chi2, look at damping (GavinType1.__init__, "
            "GavinType1.initial_state, GavinType1.damping_diagonal, GavinType1.gain_denominator, "
            "GavinType1.update), curve_model (residuals_and_jacobian), gauss_newton (") in line
    assert "GavinType3" not in line  # what the run called, not every strategy
    assert re.search(r"^ours +lm-type1 +100 .* max_iterations ", out, flags=re.M)
    # given more iterations it still ends far above: then the line names the exercise alone
    assert main(["compare", "curve", "--impl", str(impl), "--methods", "lm-type1,lm", "--max-iterations", "300"]) == 0
    (line,) = [line for line in capsys.readouterr().out.splitlines() if line.startswith("check: ours")]
    assert "above the peers' best levenberg-marquardt" in line


def test_the_demo_says_how_to_get_the_data_folder_once(capsys, monkeypatch):
    from course.app import cli
    from course.core.data import missing_data_help
    from course.core.errors import MissingDataError

    monkeypatch.setattr(cli, "_DATA_HELP_SAID", [])
    for name in ("intel", "smallGrid3D"):
        cli._skipped(name, MissingDataError(f"dataset {name!r}: data folder /x not found", missing_data_help()))
    out = capsys.readouterr().out
    assert out.count("your instructor ships it") == 1 and "smallGrid3D skipped: dataset 'smallGrid3D': data" in out


@pytest.mark.slow
def test_the_benchmark_goes_on_past_an_unwritten_todo(tmp_path):
    """Chapter 1 written: every section that needs another chapter's piece is one line naming its TODO."""
    from course.app import benchmark

    impl = _impl(tmp_path, CHAPTER1)
    lines = []
    benchmark.main(repeats=1, graphs=("manhattan:30",), impl=str(impl), out=lines.append,
                   bal=("bal-synthetic:4:30",), solvers=False, parallel=False, graphs3d=("pose3example",), vio=(),
                   solution_graphs=("manhattan:30",))
    text = "\n".join(lines)
    assert "manhattan:30 skipped: TODO pose_graph" in text
    assert "pose3example    skipped: TODO pose_graph_3d" in text
    assert "bal-synthetic:4:30 bundle adjustment skipped: TODO bundle_adjustment." in text
    assert "skipped: TODO bundle_adjustment." in lines[-1]


@pytest.mark.slow
def test_a_pose_graph_does_not_stop_at_the_ceres_cost(tmp_path, capsys):
    """Chapter 2 written but its Ceres cost: the Ceres rows name the TODO, everything else runs."""
    impl = _impl(tmp_path, CHAPTER1 + ("pose_graph_edge", "pose_graph_assembly", "sparse_solve"))
    assert main(["compare", "manhattan:30", "--impl", str(impl)]) == 0
    out = capsys.readouterr().out
    assert re.search(r"^ceres +levenberg-marquardt +not implemented: TODO ceres_edge_cost\.", out, flags=re.M)
    assert re.search(r"^ours +lm-type3 +\d+ ", out, flags=re.M)
    assert "or select what is written: --methods gauss-newton,lm-type1,lm-type2,lm-type3 or --backends ours," in out
    assert "check:" not in out


FREE_FIRST_POSE = ("pose_graph_fast", "        data[self._fixed_diagonal] = 1.0\n", "")


def test_a_pose_left_free_is_a_failed_row_naming_the_assembly_and_the_singular_h(tmp_path, capsys):
    """The assembler forgets the fixed pose: a damped solver would wander to the iteration limit on a
    singular H; instead every run of ours is a row ``failed: ...`` and one line says why, where, and
    that H is singular; the peers' rows still run and compare exits 0."""
    written = CHAPTER1 + ("pose_graph_edge", "pose_graph_assembly", "sparse_solve", "pose_graph_fast", "dogleg")
    impl = _impl(tmp_path, written, FREE_FIRST_POSE)
    text = (impl / "pose_graph_fast.py").read_text()
    (impl / "pose_graph_fast.py").write_text(text.replace("        data[self._dead] = 0.0\n", "", 1))
    assert main(["compare", "manhattan:200", "--impl", str(impl), "--backends", "ours,g2o"]) == 0
    out = capsys.readouterr().out
    assert len(re.findall(r"^ours +\S+ +failed: pose_graph_fast\.SparseAssembler\.assemble \(see below\)$", out,
                          flags=re.M)) == 5
    assert re.search(r"^g2o +gauss-newton +\d+ ", out, flags=re.M)
    (line,) = [line for line in out.splitlines() if line.startswith("check: ours")]
    assert line.startswith("check: ours gauss-newton, lm-type1, lm-type2, lm-type3, dogleg failed: "
                           "pose_graph_fast.SparseAssembler.assemble: pose 0 is fixed but not held still")
    assert "H is singular (3 gauge freedoms" in line
    assert "\n  look at pose_graph_fast\n" in out


def test_the_per_edge_loop_forgetting_the_fixed_pose_is_named_too(tmp_path):
    from course.core.errors import ContractError
    from course.problems.posegraph import dataset as datasets
    from course.problems.posegraph.problem import PoseGraphProblem

    impl = _impl(tmp_path, CHAPTER1 + ("pose_graph_edge", "pose_graph_assembly", "sparse_solve"),
                 ("pose_graph_assembly", "for k in fixed:", "for k in ():"))
    problem = PoseGraphProblem(datasets.load_dataset("w100"), impl, vectorized=False)
    with pytest.raises(ContractError, match=r"pose_graph_assembly\.assemble_normal_equations: pose 0 is fixed"):
        problem.linearize(problem.x0)
    reference = PoseGraphProblem(datasets.load_dataset("w100"), "solutions", vectorized=False)
    assert reference.linearize(reference.x0).chi2 > 0


def test_an_error_of_the_students_code_is_a_row_with_its_file_and_line(tmp_path, capsys):
    impl = _impl(tmp_path, CHAPTER1, ("curve_model", "import numpy as np", "import numpy as np\nnp = None"))
    assert main(["compare", "curve", "--impl", str(impl), "--methods", "gauss-newton,lm"]) == 0
    out = capsys.readouterr().out
    assert re.search(r"^ours +gauss-newton +failed: AttributeError \(see below\)$", out, flags=re.M)
    assert re.search(r"failed: AttributeError: .*\(at .*curve_model\.py:\d+\)\n  look at curve_model", out)
    assert re.search(r"^scipy +lm +failed: AttributeError", out, flags=re.M)  # the peer runs the student's model


#: chapter 2 written, chapter 1 left as stubs (as a student of chapter 2 may have it)
CHAPTER2 = ("pose_graph_edge", "pose_graph_assembly", "sparse_solve", "ceres_edge_cost", "pose_graph_fast")
#: a sign slip in the vectorized A (d e_t / d theta_i's first row)
FAST_SIGN_SLIP = ("pose_graph_fast", "A[:, 0, 2] = cz * du + sz * dv", "A[:, 0, 2] = -(cz * du + sz * dv)")
#: a slip in the Ceres cost's rotation (R(phi)^T d's first row)
CERES_SLIP = ("ceres_edge_cost", "qx = cp * dx + sp * dy", "qx = cp * dx - sp * dy")


def _check_lines(out):
    return [line for line in out.splitlines() if line.startswith("check: ")]


@pytest.mark.slow
def test_a_slip_in_pose_graph_fast_names_the_functions_that_ran_never_an_unwritten_one(tmp_path, capsys):
    """Gauss-Newton on a pose graph runs pose_graph_fast and sparse_solve, never gauss_newton.solve_step:
    with a slip in pose_graph_fast its line names what ran, and the Ceres rows (the student's correct
    cost) are not flagged."""
    impl = _impl(tmp_path, CHAPTER2, FAST_SIGN_SLIP)
    assert main(["compare", "manhattan:200", "--impl", str(impl), "--backends", "ours,ceres,g2o"]) == 0
    out = capsys.readouterr().out
    (line,) = _check_lines(out)
    assert line.startswith("check: ours gauss-newton ended at chi2") and "above the peers' best gauss-newton" in line
    assert "pose_graph_fast (" in line and "edge_errors_and_jacobians" in line and "SparseAssembler.assemble" in line
    assert "gauss_newton" not in line and "damping" not in line and "ceres_edge_cost" not in line
    assert re.search(r"^ceres +levenberg-marquardt +\d+ ", out, flags=re.M)


@pytest.mark.slow
def test_a_slip_in_ceres_edge_cost_flags_the_ceres_rows_and_names_the_cost(tmp_path, capsys):
    """The Ceres rows run the student's cost: they are judged against the other peers' best, as ours
    are, and the line names the cost's methods; ours (the correct pose_graph_fast) is not flagged."""
    impl = _impl(tmp_path, CHAPTER2, CERES_SLIP)
    assert main(["compare", "manhattan:200", "--impl", str(impl), "--backends", "ours,ceres,g2o"]) == 0
    lines = _check_lines(capsys.readouterr().out)
    assert [line.split(" ended at")[0] for line in lines[:2]] == ["check: ceres levenberg-marquardt",
                                                                  "check: ceres dogleg"]
    assert all("above the peers' best" in line for line in lines[:2])
    assert lines[2].startswith("check: the 2 runs above are off: look first at ceres_edge_cost (SE2EdgeCost.__init__, "
                               "SE2EdgeCost.Evaluate")
    assert not any(line.startswith("check: ours") for line in lines)


def test_advice_judges_a_peer_row_that_ran_the_students_code_against_the_other_peers():
    runs = [_run("ours", "gauss-newton", 65.4), _run("g2o", "gauss-newton", 65.4),
            _run("ceres", "levenberg-marquardt", 514.0), _run("g2o", "levenberg", 65.4)]
    runs[0].called = ("pose_graph_fast.edge_errors_and_jacobians", "sparse_solve.SparseCholeskySolver.solve")
    runs[1].called = runs[3].called = ()
    runs[2].called = ("ceres_edge_cost.SE2EdgeCost.__init__", "ceres_edge_cost.SE2EdgeCost.Evaluate")
    lines = compare.advice(runs, "posegraph", "/some/path")
    assert lines[0] == ("check: ceres levenberg-marquardt ended at chi2 514, above the peers' best "
                        "levenberg-marquardt 65.4 (relative 6.9): look at ceres_edge_cost (SE2EdgeCost.__init__, "
                        "SE2EdgeCost.Evaluate)")
    assert len(lines) == 2  # and the line on grading one exercise
    # the same row with nothing recorded is a peer's, and a peer's row is never flagged
    runs[2].called = None
    assert compare.advice(runs, "posegraph", "/some/path") == []


def test_the_recording_names_what_ran_and_puts_every_function_back(tmp_path):
    from course.core import impl as impl_loader

    folder = _impl(tmp_path, ("pose_graph_edge", "pose_graph_assembly"))
    loaded = impl_loader.load(str(folder))
    assembly = loaded.module("pose_graph_assembly")
    original = assembly.assemble_normal_equations
    edge = assembly.pose_graph_edge.edge_error_and_jacobians
    with loaded.recording() as recording:
        assert assembly.assemble_normal_equations is not original
        poses = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.1]])
        assembly.assemble_normal_equations(poses, np.array([0]), np.array([1]), np.array([[1.0, 0.0, 0.1]]),
                                           np.eye(3)[None], np.array([0]))
        assert assembly.assemble_normal_equations is original  # put back at its first call
    assert recording.names == ("pose_graph_assembly.assemble_normal_equations",
                               "pose_graph_edge.edge_error_and_jacobians")
    assert assembly.pose_graph_edge.edge_error_and_jacobians is edge
    with loaded.recording() as recording:
        pass
    assert recording.names == ()  # a stub never called is never named
