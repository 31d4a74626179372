"""Chapter 3's lesson (``notebooks/chapter3_dogleg.py``): its helpers (``course.notebook_helpers.chapter3``),
what its executed cells show, and that a student tree with only chapter 1 written builds it.

The notebook runs in its quick setting (``COURSE_NOTEBOOK_SMALL=1``); those tests are slow."""

import re

import nbformat
import numpy as np
import pytest
from executed_notebooks import chapter_1_student_build, executed_small

from course.core.trace import IterationRecord, RunResult
from course.notebook_helpers import chapter3
from course.notebook_helpers.common import reached
from notebooks import build

# ---------------------------------------------------------------- the helpers


@pytest.fixture(scope="module")
def chapter_1_written(tmp_path_factory):
    """An implementation folder: the stubs, with chapter 1's three modules written (the reference's)."""
    import shutil

    from course.core.impl import REPO_ROOT

    folder = tmp_path_factory.mktemp("impl") / "mine"
    shutil.copytree(REPO_ROOT / "exercises", folder)
    for name in ("curve_model", "gauss_newton", "damping"):
        shutil.copy(REPO_ROOT / "solutions" / f"{name}.py", folder / f"{name}.py")
    return str(folder)


def test_rosenbrock_jacobian_matches_central_differences():
    from course.geometry.jacobian_check import check_jacobian

    _, J = chapter3.rosenbrock(chapter3.START)
    assert check_jacobian(lambda x: chapter3.rosenbrock(x)[0], chapter3.START.copy(), J=J, out=None).ok


def test_the_theorys_point_needs_a_trust_region():
    """At START the Gauss-Newton step raises F: the figure's point is one where the model fails."""
    F, g, H = chapter3.model()
    h_gn = np.linalg.solve(H, -g)
    assert 0.5 * np.sum(chapter3.rosenbrock(chapter3.START + h_gn)[0] ** 2) > F
    assert min(chapter3.RADII) < np.linalg.norm(g @ g / (g @ H @ g) * g) < max(chapter3.RADII) < np.linalg.norm(h_gn)


@pytest.mark.parametrize("radius", [0.2, 0.9, 1.7, 5.0])
def test_trust_region_step_solves_the_subproblem(radius):
    """|h| = radius with h = -(H + lambda I)^{-1} g, lambda >= 0 (or h_gn inside), and no point of
    the circle does better."""
    F, g, H = chapter3.model()
    h = chapter3.trust_region_step(g, H, radius)
    h_gn = np.linalg.solve(H, -g)
    L = lambda s: g @ s + 0.5 * s @ H @ s  # noqa: E731
    if np.linalg.norm(h_gn) <= radius:
        np.testing.assert_allclose(h, h_gn)
        return
    assert np.linalg.norm(h) == pytest.approx(radius, rel=1e-9)
    angles = np.linspace(0.0, 2.0 * np.pi, 3601)
    circle = radius * np.column_stack([np.cos(angles), np.sin(angles)])
    assert L(h) <= min(L(p) for p in circle) + 1e-9


def test_dogleg_path_draws_the_reference_steps(capsys):
    fig = chapter3.dogleg_path("solutions")
    out = capsys.readouterr().out
    assert len(fig.axes) == 2
    assert "|h_gn| = 2.305, |a| = 0.8084" in out and "F(x + h_gn) = 2.531" in out
    for radius, case in zip(chapter3.RADII, ("steepest-descent", "dogleg", "dogleg")):
        assert f"radius {radius:g}: your dogleg step is {case}, |h| = {radius:g}," in out
    # the dogleg step is within 0.25 of the exact trust-region step on each circle, closest near h_gn
    distances = [float(d) for d in re.findall(r"\|h\| = [\d.]+, ([\d.]+) from the exact", out)]
    assert len(distances) == 3 and max(distances) < 0.25 and distances[-1] == min(distances)


def test_dogleg_path_names_the_todo_and_still_draws(capsys):
    fig = chapter3.dogleg_path("exercises")
    out = capsys.readouterr().out
    assert out.startswith("not written yet: TODO dogleg.cauchy_point (your dogleg.py):")
    assert "|h_gn| = 2.305" in out and "|a|" not in out and len(fig.axes) == 2


def test_the_radius_figure_and_table_of_the_curve():
    run = chapter3.dogleg_on_curve("solutions")
    fig = chapter3.radius_per_attempt(run)
    assert len(fig.axes) == 2
    table = chapter3.attempts_table(run).splitlines()
    assert len(table) == run.iterations + 1
    # the first attempts take the same Gauss-Newton step, rejected, on one factorization
    first = [line.split() for line in table[1:9]]
    assert {row[2] for row in first} == {"74.25"} and {row[3] for row in first} == {"inside"}
    assert {row[5] for row in first} == {"False"} and {row[6] for row in first} == {"1"}
    assert table[9].split()[3] == "boundary"
    assert run.factorizations == 6 and run.iterations == 18


def test_dogleg_on_curve_names_the_todo(chapter_1_written, capsys):
    assert chapter3.dogleg_on_curve(chapter_1_written) is None
    assert capsys.readouterr().out.startswith("not written yet: TODO dogleg.cauchy_point")


def _run(method, chi2, rejected=(), backend="ours"):
    trace = [IterationRecord(0, 10.0)] + [IterationRecord(k, chi2, accepted=k not in rejected, factorizations=k)
                                          for k in range(1, 4)]
    return RunResult(backend, method, np.zeros(3), 10.0, chi2, 3, 0.01, trace=trace, factorizations=3)


def test_factorization_table_marks_what_did_not_run():
    runs = [_run("gauss-newton", 5.0), _run("dogleg", 5.0, rejected=(2,)),
            RunResult.skipped("ours", "lm-type1", "not implemented: TODO damping.GavinType1.update")]
    table = chapter3.factorization_table({"toy": runs})
    row = table.splitlines()[-1]
    assert row == "| toy | 3 / 3 (0 rejected) | - | - | - | 3 / 3 (1 rejected) |"


def test_reached_without_our_gauss_newton_is_a_question_mark():
    peer = _run("dogleg", 5.0, backend="gtsam")
    assert reached(peer, [peer]) == "?"
    assert reached(peer, [peer, _run("gauss-newton", 5.0)]) == "yes"


def test_rejection_demo_names_the_todo(chapter_1_written, capsys):
    chapter3.rejection_demo(chapter_1_written, lambda name: None)
    assert capsys.readouterr().out.strip() == "curve: ours dogleg: not implemented: TODO dogleg.cauchy_point"


def test_the_lesson_leaves_the_results_to_the_student():
    """The derivations stop where the exercise starts: no Cauchy step length, no stable root, no
    decrease of a case (the hints' level 3)."""
    source = build.NOTEBOOKS[build.CHAPTER3].read_text()
    for result in (r"\alpha^\star = ", r"\alpha = \frac", "|g|^2 / g^T H g", r"\frac{g^\top g}", r"(d - c)",
                   "d + c", r"\beta = \frac", "2 |a| - radius", "(1 - beta)^2"):
        assert result not in source, result


# ---------------------------------------------------------------- the executed notebook


def _execute(path):
    nb = executed_small(path)
    outputs = [o for c in nb.cells if c.cell_type == "code" for o in c.outputs]
    errors = [o for o in outputs if o.output_type == "error"]
    assert not errors, errors
    by_cell = {c.get("id"): "".join(o.get("text", "") for o in c.outputs if o.output_type == "stream")
               for c in nb.cells if c.cell_type == "code"}
    results = "\n".join(o["data"].get("text/plain", "") for o in outputs if o.output_type == "execute_result")
    images = [o for o in outputs if "image/png" in o.get("data", {})]
    return nb, by_cell, results, images


def _questions(nb, count):
    markdown = {c.get("id"): c for c in nb.cells if c.cell_type == "markdown"}
    for k in range(1, count + 1):
        assert f"**Question {k}.**" in markdown["questions-md"].source
        answer = markdown[f"answer-{k}"]
        assert build.ANSWER_TAG in answer.metadata.get("tags", [])
        assert answer.source.strip() == f"**Your answer to question {k}:** *(double-click to edit)*"
    assert f"**Question {count + 1}.**" not in markdown["questions-md"].source


@pytest.mark.slow
def test_chapter3_lesson_executes(tmp_path):
    nb, cells, results, images = _execute(build.CHAPTER3)
    # the theory: hint and check cells, in the lesson's order, before the experiments
    ids = [c.get("id") for c in nb.cells]
    assert ids.index("hint-cauchy") < ids.index("check-cauchy") < ids.index("hint-dogleg-step") \
        < ids.index("figure-path") < ids.index("check-dogleg") < ids.index("experiments-md") < ids.index("questions-md")
    assert "dogleg.cauchy_point, hint 1 of 3" in cells["hint-cauchy"]
    assert "dogleg.dogleg_step, hint 1 of 3" in cells["hint-dogleg-step"]
    for cell, exercise in (("check-cauchy", "dogleg.cauchy_point"), ("check-dogleg", "dogleg")):
        assert "Autograder: implementation solutions, public checks" in cells[cell] and "Total: " in cells[cell]
        assert f"{exercise} (solutions): " in results
    assert "dogleg.update_radius" in cells["check-dogleg"] and "dogleg.end_to_end" in cells["check-dogleg"]
    assert results.count("full marks on the public checks") == 2, results
    # the theory's figures print what the prose quotes
    for words in ("F = 1.156", "|h_gn| = 2.305", "F(x + h_gn) = 2.531",
                  "radius 0.5: your dogleg step is steepest-descent"):
        assert words in cells["figure-path"], words
    assert re.search(r"^\s+8\s+78\.12\s+74\.25\s+inside", cells["figure-radius"], re.M)
    assert re.search(r"^\s+13\s+2\.441\s+2\.441\s+boundary\s+3\.85\s+True\s+1$", cells["figure-radius"], re.M)
    # the experiments as before
    text = "\n".join(cells.values())
    for words in ("curve (start chi2", "manhattan:200 (start chi2", "at GN minimum"):
        assert words in text
    assert re.search(r"dogleg: [1-9]\d* retries after a rejection, new factorizations before each: \[0\]", text)
    # the dogleg path and the radius (theory), per iteration and per second on two datasets
    assert len(images) == 6
    _questions(nb, 4)
    nbformat.write(nb, tmp_path / "executed.ipynb")


@pytest.mark.slow
def test_a_student_tree_with_chapter_1_written_builds_chapter_3(python, tmp_path):
    """The lesson in a student tree where only chapter 1 is written: every cell of chapter 3 runs,
    each unwritten piece is one line naming its TODO; chapter 3b's cells that need chapter 2 say so
    in one short output."""
    built = chapter_1_student_build(python)  # the tree and every notebook built once per test run
    out = built["out"]
    log = built["output"]
    assert built["returncode"] == 0, log[-3000:]
    assert re.search(r"chapter3_dogleg\.ipynb: all \d+ code cells ran", log), log[-3000:]
    assert re.search(r"chapter3b_initialisation\.ipynb: (all \d+|\d+ of \d+) code cells ran", log), log[-3000:]
    nb = nbformat.read(out / "chapter3_dogleg.ipynb", as_version=4)
    cells = {c.get("id"): "".join(o.get("text", "") for o in c.outputs if o.output_type == "stream")
             for c in nb.cells if c.cell_type == "code"}
    assert cells["figure-path"].startswith("not written yet: TODO dogleg.cauchy_point")
    assert cells["figure-radius"].startswith("not written yet: TODO dogleg.cauchy_point")
    assert "not run here: ours dogleg (not implemented: TODO dogleg.cauchy_point)" in cells["runs"]
    # the rejection experiment runs on mit where the data folder is here (its pose graphs: chapter 2's
    # TODO), else on the curve (the dogleg's)
    assert re.search(r"TODO (dogleg\.cauchy_point|pose_graph_assembly)", cells["rejection"]), cells["rejection"]
    assert "Traceback" not in (out / "chapter3_dogleg.ipynb").read_text()
    nb3b = nbformat.read(out / "chapter3b_initialisation.ipynb", as_version=4)
    errors = [o for c in nb3b.cells for o in c.get("outputs", []) if o.output_type == "error"]
    assert all(len(o["traceback"]) == 1 and o["traceback"][0].startswith(build.TODO_MARK) for o in errors), errors
