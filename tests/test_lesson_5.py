"""Chapter 5's lesson (``notebooks/chapter5_vio.py``): theory derived, then hint, Jacobian-checker and check
cells for ``imu_preintegration`` and ``marginalisation``, the experiments, the written questions; and its
helpers (``course.notebook_helpers.chapter5``), with the reference, a wrong implementation and a TODO."""

import re

import nbformat
import numpy as np
import pytest
from executed_notebooks import cell_outputs, chapter_1_student_build, executed_small

from course import check_jacobian
from course.core.impl import REPO_ROOT
from course.notebook_helpers import chapter5
from course.problems.vio.sim import load_vio_sim
from notebooks import build

EXERCISES = {  # the lesson's hint and check cells, in order: (hint name, check name)
    "preintegrate": "imu_preintegration.preintegrate",
    "imu_factor_residual": "imu_preintegration",
    "marginalise": "marginalisation",
}
QUESTIONS = 4


@pytest.fixture(scope="module")
def nb():
    return build.read(build.NOTEBOOKS[build.CHAPTER5])


@pytest.fixture(scope="module")
def sim():
    return load_vio_sim("vio-sim:4:0")


@pytest.fixture(scope="module")
def interval(sim):
    return chapter5.keyframe_interval(sim, keyframe=1)


def _impl(tmp_path, name, body):
    """An implementation folder holding the reference's module ``name`` with ``body`` appended (a mistake)."""
    folder = tmp_path / "impl"
    folder.mkdir()
    (folder / "__init__.py").write_text("")
    (folder / f"{name}.py").write_text(f"import numpy as np\nfrom solutions.{name} import *  # noqa\n"
                                       f"from solutions import {name} as _reference\n\n{body}")
    return str(folder)


# ---------------------------------------------------------------- the lesson's cells


def test_the_lesson_is_theory_then_experiments_then_questions(nb):
    ids = [c.id for c in nb.cells]
    title = nb.cells[0].source
    for words in ("**Theory**", "**Experiments**", "**Written questions.**", 'hint("preintegrate", 1)',
                  "python -m autograder hint NAME LEVEL", "check_jacobian", "Conventions"):
        assert words in title, words
    assert ids.index("setup") < ids.index("imu-md") < ids.index("factor-md") < ids.index("window-md") \
        < ids.index("marginal-md") < ids.index("experiments-md") < ids.index("runs-md") < ids.index("questions-md")


def test_each_exercise_has_its_hint_then_its_check_and_a_checker_before_a_derived_jacobian(nb):
    code = [(c.id, c.source) for c in nb.cells if c.cell_type == "code"]
    place = {}
    for k, (_, source) in enumerate(code):
        for name in re.findall(r'^hint\("(\w+)", 1\)', source, re.M):
            place[("hint", name)] = k
        for name in re.findall(r'^check\("([\w.]+)"\)', source, re.M):
            place[("check", name)] = k
        if "check_jacobian(" in source:
            place.setdefault("checkers", []).append(k)
    previous = -1
    for hint_name, check_name in EXERCISES.items():
        assert previous < place[("hint", hint_name)] < place[("check", check_name)], (hint_name, check_name)
        previous = place[("check", check_name)]
    # the two Jacobians the student checks: the bias Jacobians (preintegrate), the residual against the window's
    first, second = place["checkers"]
    assert place[("hint", "preintegrate")] < first < place[("check", "imu_preintegration.preintegrate")]
    assert place[("hint", "imu_factor_residual")] < second < place[("check", "imu_preintegration")]
    # a cell that calls the student's code turns a TODO into one line
    for cell_id, source in code:
        if "IMPL)" in source and cell_id not in ("runs",):
            assert "todo_as_a_line" in source, cell_id


def test_the_theory_is_derived(nb):
    theory = "\n".join(c.source for c in nb.cells if c.id in ("imu-md", "factor-md", "window-md", "marginal-md"))
    for words in (r"\Delta v_{ij} := \sum", r"v_j = v_i + g\,\Delta t_{ij} + R_i\,\Delta v_{ij}", "telescoping",
                  r"R_j = R_i\,\Delta R_{ij}", "midpoint", r"O(h^3)",
                  r"\delta_{k+1} = A_k\,\delta_k + B_k\,\eta_k", r"\delta v_{k+1} = \delta v_k + \delta a_k\,dt_k",
                  r"\Sigma_{k+1} = A_k \Sigma_k A_k^\top + B_k Q_k B_k^\top", r"\sigma^2/dt",
                  r"J_{k+1} = A_k J_k + B_k",
                  "rows 0-2", "rows 3-5", "rows 6-8", "rows 9-14", "15 rows", "Schur complement",
                  r"\min_{\delta_m}", "Gaussian elimination", r"J^\top J = H^\ast", "Fill-in",
                  "first-estimate Jacobians", "4 directions"):
        assert words in theory, words


def test_the_lesson_leaves_the_level_3_results_to_the_student(nb):
    """The rotation row of A_k, B_k, the D blocks of the rotated acceleration, the three residuals solved
    from the relations and the block Schur complement are what the hints hold at level 3: no cell states them."""
    text = "\n".join(c.source for c in nb.cells if c.id not in ("fill-md",))
    for pattern in (r"R_i\^\\top\s*\\big\(\s*[vp]_j", r"R_i\^\\top\s*\(\s*[vp]_j", r"R_i\^\\top\s*R_j",  # the residuals
                    r"D_(\\phi|g|a)\s*=", r"\\delta\\phi_\{k\+1\}\s*=", r"E\^\\top\s*\\delta\\phi",
                    r"H_\{km\}\s*H_\{mm\}\^\{-1\}", r"H_\{kk\}\s*-\s*H_\{km\}", r"H_\{rr\}\s*-",
                    r"J_r\s*\\?,?\s*dt\s*\\?,?\s*\\eta_g"):
        assert not re.search(pattern, text), pattern


def test_questions_and_answer_cells(nb):
    cells = {c.id: c for c in nb.cells}
    questions = cells["questions-md"].source
    for k in range(1, QUESTIONS + 1):
        assert f"**Question {k}.**" in questions
        answer = cells[f"answer-{k}"]
        assert answer.cell_type == "markdown" and answer.metadata.get("tags") == ["answer"]
        assert f"Your answer to question {k}" in answer.source
    assert f"answer-{QUESTIONS + 1}" not in cells
    reference = (REPO_ROOT / "solutions" / "answers" / "chapter5.md").read_text()
    assert [int(n) for n in re.findall(r"^## Question (\d):", reference, re.M)] == list(range(1, QUESTIONS + 1))
    assert "four questions" in reference


# ---------------------------------------------------------------- the helpers


def test_preintegration_study_with_the_reference(sim):
    study = chapter5.preintegration_study(sim, "solutions")
    np.testing.assert_allclose(study.slopes(), [0.5, 0.5, 1.5], atol=0.05)
    assert study.accel_only < 1e-12  # Delta v, Delta p are linear in b_a
    middle = (study.sizes > 1e-4) & (study.sizes < 1e-2)
    for k in range(3):  # the gyroscope bias correction's error is of second order
        slope = np.polyfit(np.log(study.sizes[middle]), np.log(study.errors[middle, k]), 1)[0]
        assert abs(slope - 2.0) < 0.1, slope
    assert np.all((study.crossings() > 0.1) & (study.crossings() < 2.0))
    report = study.report()
    assert "slope of sigma(t)" in report and "Delta p (m)" in report and "sigma 0.02 rad/s" in report
    assert len(study.figure().axes) == 2


def test_bias_jacobian_check_passes_the_reference_and_names_a_wrong_block(interval, tmp_path):
    setup = chapter5.bias_jacobian_setup(interval, "solutions")
    assert check_jacobian(setup.f, setup.x, J=setup.J, plus=setup.plus, names=setup.names, rows=setup.rows,
                          out=None).ok
    wrong = _impl(tmp_path, "imu_preintegration", """
def preintegrate(*args, **kwargs):
    pre = _reference.preintegrate(*args, **kwargs)
    return pre._replace(dv_dba=-pre.dv_dba)
""")
    setup = chapter5.bias_jacobian_setup(interval, wrong)
    result = check_jacobian(*setup[:2], J=setup.J, plus=setup.plus, names=setup.names, rows=setup.rows, out=None)
    assert not result.ok and result.blocks and all(block.startswith("d delta v / d b_a") for block in result.blocks)


def test_residual_check_passes_the_reference_and_names_a_wrong_block(interval, tmp_path):
    setup = chapter5.residual_setup(interval, "solutions")
    assert len(setup.x) == 8 and [J.shape for J in setup.J] == [(9, 3)] * 8
    assert check_jacobian(setup.f, setup.x, J=setup.J, plus=setup.plus, names=setup.names, rows=setup.rows,
                          out=None).ok
    wrong = _impl(tmp_path, "imu_preintegration", """
def imu_factor_residual(state_i, state_j, preintegrated, bias_i, gravity):
    return _reference.imu_factor_residual(state_i, state_j, preintegrated, bias_i, -np.asarray(gravity))
""")
    setup = chapter5.residual_setup(interval, wrong)
    result = check_jacobian(setup.f, setup.x, J=setup.J, plus=setup.plus, names=setup.names, rows=setup.rows,
                            out=None)
    assert not result.ok and set(result.blocks) == {"d r_v / d R_i rotation", "d r_p / d R_i rotation"}


def test_a_todo_is_one_line(interval, capsys):
    for call in (lambda: chapter5.bias_jacobian_setup(interval, "exercises"),
                 lambda: chapter5.residual_setup(interval, "exercises"),
                 lambda: chapter5.marginal_report("exercises")):
        with chapter5.todo_as_a_line():
            call()
            raise AssertionError("the stub ran")
    lines = capsys.readouterr().out.splitlines()
    assert lines == [
        "not run: not implemented: TODO imu_preintegration.preintegrate (write it, then run this cell again)",
        "not run: not implemented: TODO imu_preintegration.preintegrate (write it, then run this cell again)",
        "not run: not implemented: TODO marginalisation.marginalise (write it, then run this cell again)"]


def test_marginal_report_tells_the_schur_complement_from_conditioning(tmp_path):
    report = chapter5.marginal_report("solutions")
    assert report.count("(OK)") == 2 and "WRONG" not in report
    conditioning = _impl(tmp_path, "marginalisation", """
def marginalise(H, b, remove, eps=1e-8):
    keep = [i for i in range(len(b)) if i not in set(int(r) for r in remove)]
    return np.asarray(H)[np.ix_(keep, keep)], np.asarray(b)[keep]
""")
    assert chapter5.marginal_report(conditioning).count("(WRONG)") == 2


def test_marginal_densities_are_the_gaussians_they_name():
    problem = chapter5.TwoVariables()
    d = chapter5.marginal_densities(problem)
    mean, cov = d["joint"]
    H, _ = problem.system()
    assert d["marginal"][1] == pytest.approx(np.sqrt(cov[1, 1]), rel=1e-12)  # the marginal of the joint
    assert d["conditional"][1] == pytest.approx(1.0 / np.sqrt(H[1, 1]), rel=1e-12)
    assert d["conditional"][1] < d["marginal"][1] < d["dropped"][1]
    assert d["marginal"][0] == pytest.approx(mean[1])
    assert len(chapter5.marginal_figure().axes) == 2 and len(chapter5.window_graph_figure().axes) == 3


# ---------------------------------------------------------------- the lesson, run


_outputs = cell_outputs


@pytest.mark.slow
def test_the_lesson_runs_with_the_reference_at_full_marks(tmp_path):
    nb = executed_small(build.CHAPTER5)
    outputs, text, results = _outputs(nb)
    errors = [(k, o.get("evalue")) for k, v in outputs.items() for o in v if o.output_type == "error"]
    assert not errors, errors
    for cell, name in (("check-preintegrate", "imu_preintegration.preintegrate"), ("check-imu", "imu_preintegration"),
                       ("check-marginalisation", "marginalisation")):
        assert "Autograder: implementation solutions, public checks" in text[cell], cell
        assert results[cell].startswith(f"{name} (solutions): ") and results[cell].endswith(
            "full marks on the public checks"), results[cell]
    for cell, name in (("hint-preintegrate", "preintegrate"), ("hint-residual", "imu_factor_residual"),
                       ("hint-marginalise", "marginalise")):
        assert "hint 1 of 3" in text[cell] and f"python -m autograder hint {name} 2" in text[cell], cell
    assert text["jacobian-preintegrate"].startswith("Jacobian OK: 9 x 6")
    assert text["jacobian-residual"].startswith("Jacobian OK: 9 x 24")
    assert text["identity-marginalise"].count("(OK)") == 2
    assert "slope of sigma(t)" in text["figure-preintegration"]
    images = {k: sum("image/png" in o.get("data", {}) for o in v) for k, v in outputs.items()}
    assert {k: n for k, n in images.items() if n} == {"figure-preintegration": 1, "figure-window": 1,
                                                      "figure-marginal": 1, "fill": 1, "cost": 1, "ape": 1}
    nbformat.write(nb, tmp_path / "executed.ipynb")


@pytest.mark.slow
def test_in_a_student_tree_with_chapter_1_written_the_lesson_names_its_todos(python, tmp_path):
    """A student who wrote chapter 1 only: the lesson runs to the end; each cell that needs chapter 5's
    code is one line naming the TODO (its check cells: a table of TODOs), and no cell fails."""
    built = chapter_1_student_build(python)  # the tree and every notebook built once per test run
    out = built["out"]
    assert built["returncode"] == 0, built["output"][-3000:]
    assert re.search(r"chapter5_vio\.ipynb: all \d+ code cells ran", built["output"]), built["output"][-2000:]
    outputs, text, results = _outputs(nbformat.read(out / "chapter5_vio.ipynb", as_version=4))
    todo = "not run: not implemented: TODO {} (write it, then run this cell again)\n"
    assert text["figure-preintegration"] == todo.format("imu_preintegration.preintegrate")
    assert text["jacobian-preintegrate"] == todo.format("imu_preintegration.preintegrate")
    assert text["jacobian-residual"] == todo.format("imu_preintegration.preintegrate")
    assert text["identity-marginalise"] == todo.format("marginalisation.marginalise")
    for cell in ("check-preintegrate", "check-imu", "check-marginalisation"):
        assert "implementation exercises" in text[cell] and "reach a TODO" in results[cell], cell
    assert "hint 1 of 3" in text["hint-residual"]
    assert "Traceback" not in "".join(text.values())
