"""``pytest`` grading an implementation folder (``autograder.pytest_plugin``), run in pytester's folder
with the student tree's ``pytest.ini`` beside a copy of ``exercises/`` or ``solutions/``.

The runs are in-process: pytest's process is this one, so a side effect of importing the
implementation here would show with this process' pid. They grade the damping checks only (fast).
pytester drops the modules a run imported when it ends, and numpy's extension modules cannot load
twice in a process: one grading here first imports what the runs' gradings import.
"""

import os
import shutil
from pathlib import Path

import pytest

from autograder.checks import all_checks, select
from autograder.grade import grade
from autograder.report import total

pytest_plugins = ["pytester"]

REPO = Path(__file__).resolve().parents[1]
INI = REPO / "autograder" / "release" / "student_tree" / "pytest.ini"
PUBLIC_DAMPING = ("-k", "damping", "--autograder-set", "public")
DAMPING = select(all_checks(), ["damping"])


@pytest.fixture(scope="module", autouse=True)
def imported_once():
    """What a grading imports, imported before pytester's first snapshot (see the docstring)."""
    grade("solutions", checks=DAMPING[:1], which="all")


def folder_of(pytester, source: str) -> Path:
    """A copy of the repository's ``source`` folder as pytester's ``exercises/``, with the student
    tree's pytest.ini beside it."""
    shutil.copyfile(INI, pytester.path / "pytest.ini")
    folder = pytester.path / "exercises"
    shutil.copytree(REPO / source, folder, ignore=shutil.ignore_patterns("__pycache__"))
    return folder


def points_line(results, sets="public checks") -> str:
    """The line the plugin ends with for ``results`` (CheckResult), the total as the autograder's table prints it."""
    return f"autograder: {total(results)} points on the {len(results)} check{'s' * (len(results) != 1)} run ({sets})"


def edit(path: Path, old: str, new: str) -> None:
    text = path.read_text()
    assert old in text
    path.write_text(text.replace(old, new, 1))


def test_collection_lists_every_check_with_its_points(pytester):
    folder_of(pytester, "exercises")
    public = pytester.runpytest("--collect-only", "-q", "--autograder-set", "public")
    ids = [line for line in public.outlines if "::" in line]
    assert len(ids) == len(all_checks())
    assert "exercises/damping.py::GavinType1: update (accepted step) [1 pt]" in ids
    assert "exercises/damping.py::GavinType1: damping_diagonal [2 pts]" in ids
    assert "exercises::end_to_end::lm-type1 [2 pts]" in ids  # a check of several files: a group
    assert "exercises/pose_graph_edge.py::edge_error_and_jacobians: shapes [1 pt]" in ids
    # the instructor's tree (the reference is importable): the hidden-input items too
    both = [line for line in pytester.runpytest("--collect-only", "-q").outlines if "::" in line]
    assert len(both) == 2 * len(all_checks())
    assert "exercises/damping.py::GavinType1: update (accepted step) (hidden inputs) [1 pt]" in both


def test_a_folder_not_laid_out_like_exercises_is_pytests(pytester):
    shutil.copyfile(INI, pytester.path / "pytest.ini")
    pytester.makepyfile(**{"exercises/__init__.py": "", "exercises/damping.py": "",
                           "exercises/test_mine.py": "def test_it():\n    pass\n"})
    # importlib mode: the name `exercises` may already be taken in this process by the repository's package
    pytester.runpytest("--import-mode=importlib").assert_outcomes(passed=1)


def test_stubs_fail_with_the_not_implemented_feedback_and_k_runs_only_damping(pytester):
    folder_of(pytester, "exercises")
    result = pytester.runpytest(*PUBLIC_DAMPING)
    result.assert_outcomes(failed=len(DAMPING), deselected=len(all_checks()) - len(DAMPING))
    failures = result.reprec.getfailures()
    assert {rep.nodeid.split("::")[0] for rep in failures} == {"exercises/damping.py"}
    assert {rep.longreprtext for rep in failures} >= {"TODO damping.GavinType1.update: not implemented",
                                                     "TODO damping.GavinType3.gain_denominator: not implemented"}
    assert all(rep.longreprtext.startswith("TODO damping.") for rep in failures)
    assert "Traceback" not in result.stdout.str()
    points = sum(check.points for check in DAMPING)
    assert result.outlines[-3] == f"autograder: 0 / {points:g} points on the {len(DAMPING)} checks run (public checks)"
    assert result.outlines[-2].startswith("autograder: next: finish damping.GavinType1 (0 / ")


@pytest.mark.slow
def test_the_reference_passes_every_damping_check_public_and_hidden(pytester):
    folder_of(pytester, "solutions")
    result = pytester.runpytest("-k", "damping")
    result.assert_outcomes(passed=2 * len(DAMPING), deselected=2 * (len(all_checks()) - len(DAMPING)))
    points = 2 * sum(check.points for check in DAMPING)
    assert (f"autograder: {points:g} / {points:g} points on the {2 * len(DAMPING)} checks run "
            "(public and hidden checks)") in result.outlines


@pytest.mark.slow
def test_points_and_feedback_are_the_autograders_and_lf_and_x_rerun_the_failures(pytester):
    folder = folder_of(pytester, "solutions")
    edit(folder / "damping.py", "return lam * np.asarray(diag_H)", "return np.asarray(diag_H)")  # lambda forgotten
    result = pytester.runpytest(*PUBLIC_DAMPING)
    graded = grade(str(folder), only=["damping"], which="public")
    wrong = [r for r in graded if not r.full]
    assert wrong and len(wrong) < len(graded)
    result.assert_outcomes(passed=len(graded) - len(wrong), failed=len(wrong),
                           deselected=len(all_checks()) - len(DAMPING))
    assert sorted(rep.longreprtext for rep in result.reprec.getfailures()) == sorted(r.message for r in wrong)
    assert points_line(graded) in result.outlines

    again = pytester.runpytest(*PUBLIC_DAMPING, "--lf")
    outcomes = again.parseoutcomes()  # --lf skips the other files' collection: fewer deselected
    assert outcomes["failed"] == len(wrong) and "passed" not in outcomes
    assert f"run-last-failure: rerun previous {len(wrong)} failure" in again.stdout.str()
    assert points_line(wrong) in again.outlines

    first = pytester.runpytest(*PUBLIC_DAMPING, "-x")
    first.assert_outcomes(failed=1, passed=[r.full for r in graded].index(False),
                          deselected=len(all_checks()) - len(DAMPING))


def test_pytest_never_imports_the_implementation(pytester, tmp_path):
    folder = folder_of(pytester, "solutions")
    marks = tmp_path / "imported"
    marks.mkdir(mode=0o777)
    marks.chmod(0o777)
    # no import statement (the grader refuses os in an exercise package): the pid from /proc; a child running
    # as another user may not write there, and need not: only the pytest process's pid counts
    side_effect = ('try:\n'
                   f'    open({str(marks)!r} + "/{{name}}-" + open("/proc/self/stat").read().split()[0], "w").close()\n'
                   'except OSError:\n    pass\n')
    (folder / "__init__.py").write_text(side_effect.format(name="init"))
    (folder / "damping.py").write_text(side_effect.format(name="damping") + 'raise RuntimeError("imported!")\n'
                                       + (folder / "damping.py").read_text())
    result = pytester.runpytest(*PUBLIC_DAMPING, "-k", "GavinType1 and initial_state")
    result.assert_outcomes(failed=1, deselected=len(all_checks()) - 1)
    assert not [name for name in os.listdir(marks) if name.endswith(f"-{os.getpid()}")]
    (failure,) = result.reprec.getfailures()
    assert "RuntimeError" in failure.longreprtext and "imported!" in failure.longreprtext  # said by the child


def test_an_assignment_out_of_100_passes_every_item_with_exactly_100_points(pytester, monkeypatch):
    """``total = 100`` over checks worth thirds of a point (2.7778, 8.3333): the reference passes every
    item, public and hidden, and the points line says 100 / 100 (``tests/test_exact_points.py``)."""
    from autograder import course_config, pytest_plugin

    thirds = course_config.parse({"assignments": {"thirds": {"exercises": ["curve_model", "gauss_newton"],
                                                             "total": 100}}}).assignment("thirds")
    monkeypatch.setattr(pytest_plugin, "assignment", lambda: thirds)  # as a tree of that assignment reads it
    folder_of(pytester, "solutions")
    result = pytester.runpytest()
    count = 2 * len(thirds.checks())
    result.assert_outcomes(passed=count)
    assert (f"autograder: 100 / 100 points on the {count} checks run (public and hidden checks)"
            in result.outlines)
    assert any("[8.3333 pts]" in line for line in pytester.runpytest("--collect-only", "-q").outlines)


def test_m_selects_one_exercise_exactly_where_k_takes_every_name_that_contains_it(pytester):
    """The student README's ``pytest -m damping``: each item carries its check module's name as a
    marker, matched whole; ``-k pose_graph`` also takes pose_graph_3d's checks, ``-m pose_graph`` not."""
    folder_of(pytester, "exercises")
    pose_graph = select(all_checks(), ["pose_graph"])
    exact = [line for line in pytester.runpytest("--collect-only", "-q", "--autograder-set", "public", "-m",
                                                 "pose_graph").outlines if "::" in line]
    assert len(exact) == len(pose_graph) and all(line.startswith("exercises::pose_graph::") for line in exact)
    loose = [line for line in pytester.runpytest("--collect-only", "-q", "--autograder-set", "public", "-k",
                                                 "pose_graph").outlines if "::" in line]
    assert any("pose_graph_3d" in line for line in loose) and len(loose) > len(exact)
    result = pytester.runpytest("-m", "damping", "--autograder-set", "public")
    result.assert_outcomes(failed=len(DAMPING), deselected=len(all_checks()) - len(DAMPING))
    readme = (REPO / "autograder" / "release" / "student_tree" / "README.md").read_text()
    assert ".venv/bin/pytest -m damping " in readme
