"""The sparse solve a problem runs (``course.solver.choice``): ``auto`` keeps the implementation's
solver on a small system and takes CHOLMOD on a large one where cvxopt is installed, a missing cvxopt
falls back with one line, ``--solver ours`` runs the student's, an unknown name lists the choices;
every row of ``compare`` names the solve it ran, and the solves end at the same minimum."""

import shutil

import pytest

from course.app import compare
from course.app.cli import main
from course.core import peers
from course.core.impl import REPO_ROOT
from course.core.impl import load as load_impl
from course.problems.posegraph3d import dataset as datasets3d
from course.problems.posegraph3d.problem import PoseGraph3DProblem
from course.solver import SolverOptions, choice, minimize
from course.solver.cholmod import CholmodSolver
from course.solver.superlu import SuperLUSolver

SPARSE = load_impl("solutions").module("sparse_solve")
needs_cvxopt = pytest.mark.skipif(not peers.installed("cvxopt"), reason="cvxopt (CHOLMOD) is not installed here")
needs_qdldl = pytest.mark.skipif(not peers.installed("qdldl"), reason="qdldl is not installed here")


@needs_qdldl
def test_auto_keeps_the_implementations_solver_below_the_threshold():
    for name in (None, "auto"):
        solver, label = choice.choose(name, SPARSE, choice.AUTO_MIN_UNKNOWNS - 1)
        assert label == "ours" and isinstance(solver, SPARSE.SparseCholeskySolver)


@needs_cvxopt
def test_auto_takes_cholmod_on_a_large_system():
    solver, label = choice.choose("auto", SPARSE, choice.AUTO_MIN_UNKNOWNS)
    assert label == "cholmod" and isinstance(solver, CholmodSolver)


@needs_qdldl
def test_each_name_makes_its_solver_and_an_object_is_kept():
    assert isinstance(choice.choose("ours", SPARSE, 10**6)[0], SPARSE.SparseCholeskySolver)
    assert choice.choose("superlu", SPARSE, 10)[1] == "superlu"
    mine = SuperLUSolver()
    assert choice.choose(mine, SPARSE, 10) == (mine, "superlu")


@needs_qdldl
def test_a_missing_cvxopt_falls_back_to_the_implementations_solver_with_one_line(monkeypatch, capsys):
    real = peers.installed
    monkeypatch.setattr(peers, "installed", lambda library: library != "cvxopt" and real(library))
    monkeypatch.setattr(peers, "_announced", set())
    for name in ("auto", "cholmod", "auto"):
        solver, label = choice.choose(name, SPARSE, 10**6)
        assert label == "ours" and isinstance(solver, SPARSE.SparseCholeskySolver)
    lines = [line for line in capsys.readouterr().err.splitlines() if line.strip()]
    assert len(lines) == 1 and lines[0].startswith("cvxopt is not installed here")


def test_an_unknown_name_is_an_error_listing_the_choices(capsys):
    with pytest.raises(choice.UnknownSolveError, match="'qr'; choose one of auto, ours, cholmod, superlu"):
        choice.choose("qr", SPARSE, 10)
    with pytest.raises(SystemExit) as stop:
        main(["compare", "tinyGrid3D", "--solver", "qr"])
    assert stop.value.code == 2
    assert "choose from 'auto', 'ours', 'cholmod', 'superlu'" in capsys.readouterr().err
    with pytest.raises(ValueError, match="the curve solves its 3 x 3 system dense"):
        compare.find_runner("curve").run("curve", solver="cholmod")


def _solves():
    return [name for name in ("ours", "superlu", "cholmod")
            if name != "cholmod" or peers.installed("cvxopt")] if peers.installed("qdldl") else ["superlu"]


def test_the_solves_end_at_the_same_minimum_on_a_small_3d_graph():
    graph = datasets3d.load_dataset("tinyGrid3D")
    runs = {}
    for name in _solves():
        problem = PoseGraph3DProblem(graph, "solutions", solver=name)
        runs[name] = minimize(problem, "gauss-newton", options=SolverOptions(max_iterations=50))
        assert runs[name].linear_solve == name
    first = next(iter(runs.values()))
    for name, run in runs.items():
        assert run.final_chi2 == pytest.approx(first.final_chi2, rel=1e-9, abs=0.0), name
        assert run.iterations == first.iterations, name


def test_every_row_of_compare_names_its_solve():
    graph = datasets3d.load_dataset("tinyGrid3D")
    runs = compare.run_posegraph3d(graph, methods=["gauss-newton"], backends=["ours", "ours-autodiff"],
                                   solver="superlu")
    assert [(r.backend, r.linear_solve) for r in runs] == [("ours", "superlu"), ("ours-autodiff", "superlu")]
    assert all(r.to_json()["linear_solve"] == "superlu" for r in runs)
    header, _, *rows = compare.format_table(runs).splitlines()
    assert header.split()[header.split().index("ms/iter") + 1] == "solve"
    assert all(row.split()[7] == "superlu" for row in rows)


def _students(tmp_path):
    """Chapter 6's pieces written, the chapter-2 sparse solve not: a folder laid out like exercises/."""
    folder = tmp_path / "impl"
    shutil.copytree(REPO_ROOT / "exercises", folder, ignore=shutil.ignore_patterns("__pycache__"))
    for name in ("pose_graph_3d", "pose_graph_3d_assembly"):
        shutil.copyfile(REPO_ROOT / "solutions" / f"{name}.py", folder / f"{name}.py")
    return folder


@needs_qdldl
def test_solver_ours_runs_the_students_and_auto_on_a_large_graph_says_what_ran(tmp_path, capsys, monkeypatch):
    folder = str(_students(tmp_path))
    assert main(["compare", "tinyGrid3D", "--impl", folder, "--backends", "ours", "--methods", "gauss-newton",
                 "--solver", "ours"]) == 0
    out = capsys.readouterr().out
    assert "not implemented: TODO sparse_solve.SparseCholeskySolver.solve" in out
    monkeypatch.setattr(choice, "AUTO_MIN_UNKNOWNS", 10)  # tinyGrid3D's 54 unknowns count as large
    graph = datasets3d.load_dataset("tinyGrid3D")
    runs = compare.run_posegraph3d(graph, impl=folder, methods=["gauss-newton"], backends=["ours"],
                                   unimplemented="row")
    expected = "cholmod" if peers.installed("cvxopt") else ""
    if expected:
        assert not runs[0].not_run and runs[0].linear_solve == "cholmod"
    else:  # without cvxopt, auto falls back to the student's unwritten solver: the row names its TODO
        assert "TODO sparse_solve.SparseCholeskySolver.solve" in runs[0].not_run


@needs_cvxopt
def test_cholmod_analyses_the_pattern_when_the_problem_is_made_and_a_todo_waits_for_the_run(tmp_path):
    """The ordering and the symbolic factor are found when a problem is made (its H's pattern is fixed
    then, as GTSAM's optimizer finds its ordering when it is made), on the chapter's problem and on the
    factor graph; the solves keep them. An assembly still a TODO leaves the analysis to the first solve,
    and the run's row names the TODO."""
    from course.factorgraph import FactorGraphProblem
    from course.problems.posegraph3d.factor_graph import as_factor_graph

    graph = datasets3d.load_dataset("tinyGrid3D")
    for problem in (PoseGraph3DProblem(graph, "solutions", solver="cholmod"),
                    FactorGraphProblem(as_factor_graph(graph), "solutions", solver="cholmod")):
        symbolic = problem._solver._symbolic
        assert symbolic is not None, type(problem).__name__
        run = minimize(problem, "gauss-newton", options=SolverOptions(max_iterations=5))
        assert problem._solver._symbolic is symbolic and run.iterations >= 1, type(problem).__name__
    folder = tmp_path / "impl"
    shutil.copytree(REPO_ROOT / "exercises", folder, ignore=shutil.ignore_patterns("__pycache__"))
    shutil.copyfile(REPO_ROOT / "solutions" / "pose_graph_3d.py", folder / "pose_graph_3d.py")
    text = (REPO_ROOT / "solutions" / "pose_graph_3d_assembly.py").read_text()
    start, end = text.index("    def assemble"), text.index("#: the derived results")
    stub = '    def assemble(self, e, A, B, information):\n        raise NotImplementedError("TODO assemble")\n\n\n'
    (folder / "pose_graph_3d_assembly.py").write_text(text[:start] + stub + text[end:])
    problem = PoseGraph3DProblem(graph, str(folder), solver="cholmod")
    assert problem._solver._symbolic is None
    runs = compare.run_posegraph3d(graph, impl=str(folder), methods=["gauss-newton"], backends=["ours"],
                                   solver="cholmod", unimplemented="row")
    assert "TODO assemble" in runs[0].not_run
