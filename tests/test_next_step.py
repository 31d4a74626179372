"""The grader's last line (``autograder.report.next_step``): after full marks, the next exercise or the
chapter's lesson; before, the first exercise graded that is not at full marks."""

import subprocess
import sys

from autograder import report
from autograder.checks import CHAPTER, LESSONS, ORDER, all_checks
from autograder.grade import CheckResult
from course.core.impl import REPO_ROOT


def _results(units, score=1.0):
    """One result per check of ``units``, each at ``score`` times its points."""
    return [CheckResult(c.name, c.exercise, score * c.points, float(c.points), "ok")
            for c in all_checks() if c.exercise in units]


def test_every_check_module_has_a_chapter_with_a_lesson():
    assert set(CHAPTER) == set(ORDER)
    assert set(CHAPTER.values()) == set(LESSONS)
    for lesson in LESSONS.values():
        assert (REPO_ROOT / lesson).is_file(), lesson


def test_full_marks_name_the_next_exercise():
    line = report.next_step(_results({"damping.GavinType1"}))
    assert line == "next: damping.GavinType2 (chapter 1; `python -m autograder --only damping.GavinType2`)"


def test_the_end_of_a_chapter_names_its_lesson_then_the_next_chapter():
    line = report.next_step(_results({"end_to_end"}))
    assert line.startswith("next: chapter 1's lesson, notebooks/chapter1_curve_fitting.ipynb (`make notebooks`), "
                           "then pose_graph_edge.edge_error_and_jacobians (chapter 2;")
    line = report.next_step(_results({"dogleg.cauchy_point", "dogleg.dogleg_step", "dogleg.update_radius",
                                      "dogleg.end_to_end"}))
    assert "chapter 3's lesson, notebooks/chapter3_dogleg.ipynb" in line and "initialisation." in line
    line = report.next_step(_results({"gnc.gnc"}))
    assert line.startswith("next: chapter 6's lesson, notebooks/chapter6_pose_graphs_3d.ipynb (`make notebooks`), "
                           "then jets.Jet (chapter 7;")
    line = report.next_step(_results({"factor_linearisation.BlockSparseAssembler"}))
    assert line.startswith("next: chapter 7's lesson, notebooks/chapter7_factor_graphs.ipynb (`make notebooks`), "
                           "then elimination.eliminate_variable (chapter 8;")
    last = report.next_step(_results({"incremental_update.wildfire_update"}))
    assert last == "next: every exercise is at full marks; the last lesson is notebooks/chapter8_elimination.ipynb"


def test_an_exercise_below_full_marks_comes_first():
    results = _results({"curve_model.residuals_and_jacobian"}) + _results({"damping.GavinType2"}, score=0.5)
    line = report.next_step(results)
    assert line.startswith("next: finish damping.GavinType2 (") and "--only damping.GavinType2" in line
    assert report.next_step([]) == ""
    table = report.table(results, "exercises", 1.0, 2)
    assert table.splitlines()[-1] == line
    assert line in report.gradescope(results, 1.0)["output"]


def test_the_grader_prints_next_after_full_marks():
    out = subprocess.run([sys.executable, "-m", "autograder", "--impl", "solutions", "--only", "gauss_newton",
                          "--set", "public"], cwd=REPO_ROOT, capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr
    assert out.stdout.splitlines()[-1].startswith("next: damping.GavinType1 (chapter 1;")
