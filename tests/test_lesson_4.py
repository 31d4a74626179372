"""Chapter 4's lesson (``notebooks/chapter4_bundle_adjustment.py``): theory derived, then hint and check
cells for ``bundle_adjustment``, ``robust_kernels``, ``gauge`` and ``parallel_assembly`` (a Jacobian-checker
cell before the Jacobians' check), the experiments, the written questions; its helpers
(``course.notebook_helpers.chapter4``) with the reference, a wrong implementation and a TODO; and the
notebook in a student tree where only chapter 1 is written."""

import re

import nbformat
import numpy as np
import pytest
from executed_notebooks import assert_no_level_3_hint_line, cell_outputs, chapter_1_student_build, executed_small

from course import check_jacobian
from course.core.impl import REPO_ROOT
from course.notebook_helpers import chapter4
from course.notebook_helpers.lesson import todo_as_one_line
from course.problems.bal import outliers
from course.problems.bal.dataset import load_bal
from notebooks import build

#: the lesson's hint and check cells, in order: (hint cell, hint name, check cell, check name)
EXERCISES = (
    ("hint-jacobians", "reprojection_residuals_and_jacobians", "check-jacobians",
     "bundle_adjustment.reprojection_residuals_and_jacobians"),
    (None, None, "check-normal-equations", "bundle_adjustment.normal_equations"),
    ("hint-schur", "schur_solve", "check-bundle-adjustment", "bundle_adjustment"),
    ("hint-robust", "robust_kernels", "check-robust", "robust_kernels"),
    ("hint-gauge", "gauge_directions", "check-gauge", "gauge"),
    ("hint-parallel", "parallel_assembly", "check-parallel", "parallel_assembly"),
)
THEORY = ("camera-md", "jacobian-md", "blocks-md", "schur-md", "robust-md", "gauge-md", "assembly-md")
QUESTIONS = 5
#: the code cells that show a figure, in order (the quick setting)
IMAGES = ["figure-camera", "figure-taylor", "sparsity", "kernels", "figure-irls", "gauge", "costs", "sweep", "dense"]


@pytest.fixture(scope="module")
def nb():
    return build.read(build.NOTEBOOKS[build.CHAPTER4])


@pytest.fixture(scope="module")
def scene():
    return load_bal("bal-synthetic:6:40")


def _impl(tmp_path, name, body):
    """An implementation folder holding the reference's module ``name`` with ``body`` appended (a mistake)."""
    folder = tmp_path / "impl"
    folder.mkdir(exist_ok=True)
    (folder / "__init__.py").write_text("")
    for module in ("bundle_adjustment", "parallel_assembly", "robust_kernels", "gauge"):
        if module != name:
            (folder / f"{module}.py").write_text(f"from solutions.{module} import *  # noqa\n")
    (folder / f"{name}.py").write_text(f"import numpy as np\nfrom solutions.{name} import *  # noqa\n"
                                       f"from solutions import {name} as _reference\n\n{body}")
    return str(folder)


# ---------------------------------------------------------------- the lesson's cells


def test_the_lesson_is_theory_then_experiments_then_questions(nb):
    ids = [c.id for c in nb.cells]
    title = nb.cells[0].source
    for words in ("**Theory**", "**Experiments**", "**Written questions.**",
                  'hint("reprojection_residuals_and_jacobians", 1)', "python -m autograder hint NAME LEVEL",
                  "check_jacobian", "Conventions", "plain addition"):
        assert words in title, words
    positions = [ids.index(cell) for cell in ("setup", *THEORY, "experiments-md", "costs-md", "rank-md",
                                              "behind-md", "dense-md", "outliers-md", "parallel-md",
                                              "questions-md")]
    assert positions == sorted(positions)


def test_each_exercise_has_its_hint_then_its_check_and_a_checker_before_the_jacobians_check(nb):
    code = {c.id: c.source for c in nb.cells if c.cell_type == "code"}
    ids = list(code)
    previous = ids.index("setup")
    for hint_cell, hint_name, check_cell, check_name in EXERCISES:
        if hint_cell is not None:
            assert code[hint_cell].startswith(f'hint("{hint_name}", 1)'), hint_cell
            assert previous < ids.index(hint_cell) < ids.index(check_cell), hint_cell
        assert code[check_cell].strip() == f'check("{check_name}")', check_cell
        assert previous < ids.index(check_cell)
        previous = ids.index(check_cell)
    assert ids.index("hint-jacobians") < ids.index("jacobian-check") < ids.index("check-jacobians")
    assert "check_jacobian(" in code["jacobian-check"]
    # a cell that calls your code turns a TODO into one line (the comparisons make it a row instead)
    for cell_id, source in code.items():
        if "IMPL" in source and cell_id not in ("setup", "costs", "behind", "parallel"):
            assert "todo_as_one_line()" in source, cell_id
    assert code["costs"].count('unimplemented="row"') == 1 and code["behind"].count('unimplemented="row"') == 1


def test_the_theory_is_derived(nb):
    theory = "\n".join(c.source for c in nb.cells if c.id in THEORY)
    for words in (r"W^3 = -\theta^2 W", r"\frac{\sin\theta}{\theta}", r"p = -P_{xy} / P_z", r"P_z < 0",
                  r"d = 1 + k_1 \lVert p\rVert^2 + k_2 \lVert p\rVert^4", r"r_k = f\,d\,p - z_k",
                  "chain rule", r"\partial P / \partial t = I", r"\partial P / \partial X = R(w)",
                  r"R(w)\,\operatorname{Exp}\big(J_r(w)\,\delta w\big)", r"-[X]_\times \phi", "Taylor test",
                  "arrow", r"\operatorname{blockdiag}(V_p)", "Block elimination", "back-substitution",
                  "reduced camera system", r"(U - W V^{-1} W^\top)", "Schur complement", r"O((3P)^3)",
                  "covisibility", "iteratively reweighted least squares", r"w_k = \rho'(s_k(x))",
                  "Triggs' correction", r"\rho' + 2\rho'' s", "Huber", "Cauchy", "Tukey", "redescends",
                  "similarity", "7-dimensional", r"H n = 0", "fix the gauge", "damp",
                  "not associative", "chunk order", "never in the order the threads complete"):
        assert words in theory, words


def test_the_lesson_leaves_the_level_3_results_to_the_student(nb):
    """The stages' Jacobians, the derivative of R(w) X in w, the kernels' derivatives, the block sums of
    the reduced system and the gauge directions are what the hints hold at level 3: no cell states them."""
    text = "\n".join(c.source for c in nb.cells)
    for pattern in (r"-R\s*(\\,)?\s*\[X\]_\\times\s*(\\,)?\s*J_r",  # d(R(w) X)/dw
                    r"-1\s*/\s*P_z", r"P_x\s*/\s*P_z\^2", r"2\s*k_1\s*\+\s*4\s*k_2",  # dp/dP, d d/dp
                    r"a\s*/\s*\\sqrt\{s\}", r"1\s*/\s*t\b", r"u\^2", r"-2\s*u\s*/\s*a\^2",  # rho', rho''
                    r"2\s*\\rho''\s*v\s*v\^\\top", r"\\rho'\s*\\Omega\s*\+",  # the corrected information
                    r"J_r\(w\)\^\{-1\}\s*u_a", r"-R\(w\)\s*u_a", r"u_a\s*\\times\s*X",  # the gauge directions
                    r"\\sum_k\s*\\sum_l"):  # the block sums of S
        assert not re.search(pattern, text), pattern
    assert_no_level_3_hint_line(text, ("bundle_adjustment", "robust_kernels", "gauge", "parallel_assembly"),
                                strip=" :`-")


def test_questions_and_answer_cells(nb):
    cells = {c.id: c for c in nb.cells}
    questions = cells["questions-md"].source
    for k in range(1, QUESTIONS + 1):
        assert f"**Question {k}.**" in questions
        answer = cells[f"answer-{k}"]
        assert answer.cell_type == "markdown" and answer.metadata.get("tags") == [build.ANSWER_TAG]
        assert f"Your answer to question {k}" in answer.source
    assert f"answer-{QUESTIONS + 1}" not in cells and f"**Question {QUESTIONS + 1}.**" not in questions
    assert [c.id for c in nb.cells][-QUESTIONS - 1:] == ["questions-md"] + [f"answer-{k}" for k in
                                                                            range(1, QUESTIONS + 1)]
    # the two questions the chapter had are kept
    for words in ("Why can the BAL projection", "Count the residuals and unknowns"):
        assert words in questions, words
    reference = (REPO_ROOT / "solutions" / "answers" / "chapter4.md").read_text()
    assert reference.startswith("# RELEASE: omit")
    assert [int(n) for n in re.findall(r"^## Question (\d):", reference, re.M)] == list(range(1, QUESTIONS + 1))


# ---------------------------------------------------------------- the helpers


def test_a_todo_is_one_line(capsys, scene):
    with todo_as_one_line():
        chapter4.observation_setup(scene, 0, "exercises")
        raise AssertionError("the stub ran")
    with todo_as_one_line():
        chapter4.irls_location(chapter4.location_data(), [("huber", 2.45)], "exercises")
        raise AssertionError("the stub ran")
    assert capsys.readouterr().out.splitlines() == [
        "not implemented: TODO bundle_adjustment.reprojection_residuals_and_jacobians: write it, then run this "
        "cell again",
        "not implemented: TODO robust_kernels.huber: write it, then run this cell again"]
    with pytest.raises(ValueError), todo_as_one_line():
        raise ValueError("not a TODO: it goes through")


def test_the_taylor_test_tells_the_true_derivative_from_a_right_perturbations():
    study = chapter4.rotation_taylor_study()
    slopes = list(study.slopes.values())
    np.testing.assert_allclose(slopes, [1.0, 1.0, 2.0], atol=0.05)
    right = study.errors["D = -R [X]_x (a right perturbation, not w + dw)"]
    assert np.all(right[study.steps < 1e-3] > 1e3 * study.errors["D = central differences of w -> R(w) X"][
        study.steps < 1e-3])
    # at w = 0 the right perturbation is the derivative: its error is second order too
    assert chapter4.rotation_taylor_study(angle=0.0).slopes["D = -R [X]_x (a right perturbation, not w + dw)"] \
        == pytest.approx(2.0, abs=0.05)
    assert len(chapter4.rotation_taylor_figure(study).axes) == 1
    assert len(chapter4.camera_model_figure().axes) == 2


def test_the_observation_setup_passes_the_reference_and_names_a_wrong_block(scene, tmp_path):
    k = chapter4.generic_observation(scene)
    assert abs(np.linalg.norm(scene.cameras[scene.camera_index[k], :3]) - 2.0) < 0.2
    assert chapter4.observation_line(scene, k).startswith(f"bal-synthetic:6:40:0, observation {k}: camera ")
    setup = chapter4.observation_setup(scene, k, "solutions")
    assert [J.shape for J in setup.J] == [(2, 9), (2, 3)]
    assert check_jacobian(setup.f, setup.x, J=setup.J, plus=setup.plus, names=setup.names, rows=setup.rows,
                          out=None).ok
    # the classic slip: the rotation's columns of a right perturbation, -A R [X]_x, without J_r
    wrong = _impl(tmp_path, "bundle_adjustment", """
from course.geometry.so3 import exp_many, skew


def reprojection_residuals_and_jacobians(cameras, points, camera_index, point_index, observations):
    r, J_cam, J_point = _reference.reprojection_residuals_and_jacobians(cameras, points, camera_index,
                                                                        point_index, observations)
    R = exp_many(np.asarray(cameras)[camera_index, :3])
    A = np.matmul(J_point, np.transpose(R, (0, 2, 1)))  # d predicted / d P
    J_cam = J_cam.copy()
    J_cam[:, :, :3] = -np.matmul(np.matmul(A, R), skew(np.asarray(points)[point_index]))
    return r, J_cam, J_point
""")
    setup = chapter4.observation_setup(scene, k, wrong)
    result = check_jacobian(setup.f, setup.x, J=setup.J, plus=setup.plus, names=setup.names, rows=setup.rows,
                            out=None)
    assert not result.ok and set(result.blocks) == {"d x / d camera w", "d y / d camera w"}


def test_irls_with_the_reference_kernels():
    data = chapter4.location_data()
    runs = {run.name: run for run in chapter4.irls_location(data, outliers.DEFAULT_LOSSES[:4], "solutions")}
    assert list(runs) == ["least squares", "huber(a=2.45)", "cauchy(a=2.45)", "tukey(a=4.5)"]
    inliers = float(np.mean(data.samples[data.inlier]))
    mean = float(np.mean(data.samples))
    assert f"{mean:.1f}" == "2.7"  # what the lesson's prose quotes
    assert np.all(runs["least squares"].estimates == mean)
    final = {name: run.estimates[-1] for name, run in runs.items()}
    assert abs(final["tukey(a=4.5)"] - inliers) < 0.02  # every outlier beyond a: a weighted mean of the inliers
    assert abs(final["cauchy(a=2.45)"] - inliers) < 0.2 < abs(final["huber(a=2.45)"] - inliers) < mean - inliers
    assert np.all(runs["tukey(a=4.5)"].weights[~data.inlier] == 0)
    assert np.all(runs["huber(a=2.45)"].weights[~data.inlier] > 0.1)  # bounded influence, never zero
    assert len(chapter4.irls_figure(data, list(runs.values())).axes) == 2


def test_the_sum_order_table_with_the_reference_and_with_chunks_that_follow_the_workers(tmp_path):
    problem = load_bal("bal-synthetic:8:300:3")
    table = chapter4.sum_order_table(problem, "solutions", chunks=(1, 3), workers=(1, 2), repeats=2)
    rows = table.splitlines()[2:]
    assert rows[0].split() == ["1", "0.0e+00", "0.0e+00", "yes"]
    assert rows[1].endswith("yes") and all(0 < float(v) < 1e-13 for v in rows[1].split()[1:3])
    # a parallel assembly whose chunks follow the workers, not the chunks asked for: the bits change
    wrong = _impl(tmp_path, "parallel_assembly", """
def normal_equations_parallel(r, J_cam, J_point, camera_index, point_index, num_cameras, num_points,
                              workers=2, chunks=None, kernel=None):
    return _reference.normal_equations_parallel(r, J_cam, J_point, camera_index, point_index, num_cameras,
                                                num_points, workers=workers, chunks=4 * workers, kernel=kernel)
""")
    table = chapter4.sum_order_table(problem, wrong, chunks=(3,), workers=(1, 2), repeats=1)
    assert table.splitlines()[-1].endswith("NO")


# ---------------------------------------------------------------- the lesson, run


_outputs = cell_outputs


@pytest.mark.slow
def test_the_lesson_runs_with_the_reference_at_full_marks(tmp_path):
    nb = executed_small(build.CHAPTER4)
    outputs, text, results = _outputs(nb)
    errors = [(k, o.get("evalue")) for k, v in outputs.items() for o in v if o.output_type == "error"]
    assert not errors, errors
    for hint_cell, hint_name, check_cell, check_name in EXERCISES:
        assert "Autograder: implementation solutions, public checks" in text[check_cell], check_cell
        assert results[check_cell].startswith(f"{check_name} (solutions): ") and results[check_cell].endswith(
            "full marks on the public checks"), results[check_cell]
        if hint_cell is not None:
            assert "hint 1 of 3" in text[hint_cell] and "Hint 2" not in text[hint_cell], hint_cell
            assert f"(more: python -m autograder hint {hint_name} 2)" in text[hint_cell], hint_cell
    checker = text["jacobian-check"]
    assert checker.startswith("bal-synthetic:6:40:0, observation 0: camera 0 (rotated by |w| = ")
    assert "\nJacobian OK: 2 x 12" in checker and "Jacobian WRONG: 1 of 24 entries" in checker
    assert "d y / d camera w" in checker
    assert all(line.endswith("yes") for line in text["sum-order"].splitlines()[2:]) and "NO" not in text["sum-order"]
    assert "gauge free : 7 of" in text["gauge"] and "gauge fixed: 0 of" in text["gauge"]
    # the numbers the prose and the questions quote are the ones printed
    assert "(rotated by |w| = 2.08 rad)" in checker and "1.47x" in text["parallel"]
    if "ladybug-49: 49 cameras" in text["sparsity"]:  # the data folder is here
        assert re.search(r"J +63686 +23769 ", text["sparsity"]) and " 4519.7" in text["sparsity"]
    images = [k for k, v in outputs.items() for o in v if "image/png" in o.get("data", {})]
    assert images == IMAGES
    assert "Traceback" not in "".join(text.values()) and "not implemented" not in "".join(text.values())
    nbformat.write(nb, tmp_path / "executed.ipynb")


@pytest.mark.slow
def test_in_a_student_tree_with_chapter_1_written_the_lesson_names_its_todos(python, tmp_path):
    """A student who wrote chapter 1 only: the lesson runs to the end; each cell that needs chapter 4's
    code is one line naming the TODO (its check cells: a table of TODOs), the peers run, no cell fails."""
    from course.core import peers
    built = chapter_1_student_build(python)  # the tree and every notebook built once per test run
    out = built["out"]
    assert built["returncode"] == 0, built["output"][-3000:]
    log = built["output"]
    assert re.search(r"chapter4_bundle_adjustment\.ipynb: all \d+ code cells ran", log), log[-2000:]
    nb = nbformat.read(out / "chapter4_bundle_adjustment.ipynb", as_version=4)
    outputs, text, results = _outputs(nb)
    todo = "not implemented: TODO {}: write it, then run this cell again\n"
    jacobians = "bundle_adjustment.reprojection_residuals_and_jacobians"
    for cell in ("sparsity", "gauge", "sum-order", "per-iteration", "sweep", "dense", "outliers"):
        assert todo.format(jacobians) in text[cell], (cell, text[cell])
    assert text["jacobian-check"].endswith(todo.format(jacobians))
    assert text["kernels"] == todo.format("robust_kernels.huber") == text["figure-irls"]
    for _, _, check_cell, _ in EXERCISES:
        assert "implementation exercises" in text[check_cell] and "reach a TODO" in results[check_cell], check_cell
    assert "hint 1 of 3" in text["hint-schur"]
    # our rows name their TODO, the peers' rows ran
    assert "not implemented: TODO" in text["costs"]
    if peers.installed("pycolmap"):
        assert re.search(r"ceres +levenberg-marquardt +\d+", text["costs"]), text["costs"]
    images = [k for k, v in outputs.items() for o in v if "image/png" in o.get("data", {})]
    assert {"figure-camera", "figure-taylor", "costs"} <= set(images)
    assert "Traceback" not in nbformat.writes(nb)
