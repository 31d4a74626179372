"""The lazy folder (``tests/student_variants/lazy.py``: every exercise delegating to code the tree
ships) scores what the stubs score, 0, with each file refused for its imports: in this tree (the
grader's API and ``pytest``), in the whole course's student tree and in an assignment's, graded as a
student does (``make check``: ``python -m autograder`` in the tree)."""

import os
import re
import subprocess
import sys

import pytest

from autograder.allowed_imports import load_contracts, refusals, shown
from autograder.checks import all_checks
from autograder.course_config import load
from autograder.grade import grade
from autograder.release import assignment as handout
from autograder.release.stubs import render, write_student_tree
from course.core.impl import REPO_ROOT
from student_variants.lazy import LAZY, NAMED, build_lazy, lazy_text

CONTRACTS = load_contracts()
EXERCISES = REPO_ROOT / "exercises"


def test_the_list_covers_every_exercise():
    assert sorted(LAZY) == sorted(CONTRACTS)


@pytest.mark.parametrize("name", sorted(NAMED))
def test_each_delegation_of_the_issue_is_refused_with_its_file_line_and_allowed_list(tmp_path, name):
    module, imported = NAMED[name]
    text = lazy_text((EXERCISES / f"{module}.py").read_text(), module)
    line = next(number for number, row in enumerate(text.splitlines(), start=1)
                if row.startswith(("from ", "import ")) and imported in row)
    folder = tmp_path / "lazy"
    folder.mkdir()
    (folder / "__init__.py").write_text("")
    (folder / f"{module}.py").write_text(text)
    why = refusals(folder)[module]
    assert why.startswith(f"lazy/{module}.py:") and "refused before running" in why
    assert f"lazy/{module}.py:{line}: refused before running: imports {imported}" in why \
        or f"line {line} {imported}" in why, why
    assert f"Allowed: {shown(CONTRACTS[module])}." in why


@pytest.fixture(scope="module")
def lazy(tmp_path_factory):
    return build_lazy(EXERCISES, tmp_path_factory.mktemp("lazy") / "lazy")


def test_the_lazy_folder_scores_nothing_every_check_refused(lazy):
    results = grade(str(lazy), which="public")
    assert len(results) == len(all_checks())
    assert sum(r.score for r in results) == 0
    # an exercise file's checks are not run; a run of several files (end_to_end) meets them unwritten
    refused = {r.name for r in results if r.status == "refused" and "refused before running" in r.message}
    runs = {r.name for r in results if r.name not in refused}
    assert {r.name.split(":")[0].split(".")[0] for r in results if r.name in runs} <= {"end_to_end", "pose_graph"}
    assert all("refused before running" in r.message for r in results if r.name in runs), \
        [r.message for r in results if r.name in runs and "refused before" not in r.message][:2]
    edge = next(r for r in results if r.exercise == "pose_graph_edge.edge_error_and_jacobians")
    assert edge.message.startswith("lazy/pose_graph_edge.py:") and "Allowed: numpy, scipy;" in edge.message
    from autograder.classroom.gradebook import status_of

    assert status_of(results) == "refused imports"  # what the class's grades.csv says of it
    assert status_of([r for r in results if r.status != "refused"]) == "ok"


def test_pytest_reports_the_refusal(lazy):
    out = subprocess.run([sys.executable, "-m", "pytest", str(lazy), "-p", "autograder.pytest_plugin", "-q",
                          "-p", "no:cacheprovider", "--autograder-set", "public", "--autograder-only", "curve_model"],
                         cwd=REPO_ROOT, capture_output=True, text=True, timeout=300)
    assert "lazy/curve_model.py:" in out.stdout and "refused before running" in out.stdout, out.stdout[-3000:]
    assert re.search(r"autograder: 0 / \d+ points", out.stdout), out.stdout[-2000:]


def _run(python, tree, *args, timeout=600):
    env = {k: v for k, v in os.environ.items() if not k.startswith(("PYTHON", "COURSE_IMPL", "AUTOGRADER"))}
    env["PYTHONPATH"] = str(tree)
    return subprocess.run([python, *args], cwd=tree, env=env, capture_output=True, text=True, timeout=timeout)


def _lazy_tree(tree, tmp_path):
    """``tree`` with its ``exercises/`` made lazy (as a student who edits them in place)."""
    folder = build_lazy(tree / "exercises", tmp_path / "lazy-exercises")
    for path in folder.glob("*.py"):
        if path.name != "__init__.py":
            (tree / "exercises" / path.name).write_text(path.read_text())
    return tree


def _total(text):
    found = re.search(r"^Total: (\d+(?:\.\d+)?) / (\d+(?:\.\d+)?)", text, flags=re.M)
    assert found, text
    return float(found.group(1)), float(found.group(2))


@pytest.mark.slow
def test_the_whole_course_student_tree_scores_nothing(tmp_path, python):
    tree = tmp_path / "tree"
    write_student_tree(tree, render(REPO_ROOT / "solutions"), REPO_ROOT)
    assert not (tree / "solutions").exists() and (tree / "autograder" / "imports.json").is_file()
    out = _run(python, _lazy_tree(tree, tmp_path), "-m", "autograder")
    assert out.returncode == 0, out.stdout[-2000:] + out.stderr[-2000:]
    score, maximum = _total(out.stdout)
    assert score == 0 and maximum > 0
    assert "exercises/pose_graph_edge.py:" in out.stdout and "refused before running" in out.stdout


@pytest.mark.slow
@pytest.mark.parametrize("name", ["ch2", "ch7"])
def test_an_assignment_tree_scores_nothing(tmp_path, python, name):
    course = load()
    tree = tmp_path / name
    handout.write_student_tree(tree, course, course.assignment(name), render(REPO_ROOT / "solutions"))
    out = _run(python, _lazy_tree(tree, tmp_path), "-m", "autograder")
    assert out.returncode == 0, out.stdout[-2000:] + out.stderr[-2000:]
    assert _total(out.stdout) == (0, course.assignment(name).maximum("public")), out.stdout[-3000:]
    for module in course.assignment(name).modules:
        if module not in course.assignment(name).solved:
            assert f"exercises/{module}.py:" in out.stdout, module


def test_a_refused_package_init_is_said_once_and_the_package_graded_without_it(tmp_path):
    folder = tmp_path / "mine"
    folder.mkdir()
    (folder / "__init__.py").write_text("import sys\n")
    (folder / "curve_model.py").write_text((REPO_ROOT / "solutions" / "curve_model.py").read_text())
    notices: list = []
    results = grade(str(folder), only=["curve_model"], which="public", notices=notices)
    assert all(r.full for r in results), [r.message for r in results if not r.full]
    assert notices == ["mine/__init__.py:1: refused before running: imports sys, which the package's __init__.py "
                       "does not allow. Allowed: numpy, scipy; from the standard library abc, bisect, cmath, "
                       "collections, contextlib, copy, dataclasses, enum, functools, heapq, itertools, math, numbers, "
                       "operator, typing, warnings. It is not run: the package is graded without it"]
