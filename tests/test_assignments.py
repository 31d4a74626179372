"""One assignment handed out (``python -m course release --assignment NAME``): what its student tree
and its Gradescope zip hold, and that they grade that assignment alone, with its points, its solved
files, its visibilities and its late policy."""

import json
import os
import re
import shutil
import subprocess
import zipfile
from datetime import timedelta
from pathlib import Path

import pytest
from conftest import gradescope_zip

from autograder.course_config import load, parse
from autograder.grade import grade
from autograder.release import assignment as handout
from autograder.release.carried_config import tomllib  # tomli on Python 3.10
from autograder.release.stubs import render
from course.core import chapters
from course.core.impl import REPO_ROOT

COURSE = load()
LATER_THAN_CH3 = ("ch3b", "ch4", "ch5", "ch6")


@pytest.fixture(scope="module")
def stubs():
    return render(REPO_ROOT / "solutions")


def test_each_assignment_hands_out_its_stubs_its_solved_files_and_nothing_later(stubs):
    for name, assignment in COURSE.assignments.items():
        files = handout.exercise_files(COURSE, assignment, stubs)
        later = {m for other in handout.later(COURSE, name) for m in COURSE.assignment(other).modules}
        assert not later & {rel[:-3] for rel in files}, name
        for module in assignment.modules:
            assert files[f"{module}.py"] == stubs[f"{module}.py"]
        for module in assignment.solved:
            text = files[f"{module}.py"]
            assert "NotImplementedError(\"TODO" not in text and "# BEGIN SOLUTION" not in text
            assert text == handout.released((REPO_ROOT / "solutions" / f"{module}.py").read_text())
        dropped = handout.dropped(COURSE, assignment)
        assert {f"autograder/expected/{m}.json" for m in assignment.exercises}.isdisjoint(dropped)
        kept = {p.name for p in (REPO_ROOT / "autograder" / "expected").glob("*.json")} - {
            Path(rel).name for rel in dropped}
        assert kept == {f"{m}.json" for m in assignment.exercises}, name
        carried = parse(tomllib.loads(handout.config_text(Path(COURSE.source), name)))
        assert list(carried.assignments) == [name]
        again = carried.assignment(name)
        assert dict(again.points) == dict(assignment.points)
        assert (again.exercises, again.solved, again.due, again.late, again.optional) == (
            assignment.exercises, assignment.solved, assignment.due, assignment.late, assignment.optional)
    ch3 = handout.dropped(COURSE, COURSE.assignment("ch3"))
    assert "notebooks/chapter4_bundle_adjustment.ipynb" in ch3 and "autograder/checks/gnc.py" in ch3
    assert "notebooks/chapter3_dogleg.py" not in ch3 and "autograder/checks/dogleg.py" not in ch3


def test_pipelines_take_the_pieces_not_graded_from_the_solved_code(tmp_path):
    """The reference dogleg with every other file a stub: every point of ch3 (the end-to-end runs solve
    the curve and a pose graph with the solved pieces); without an assignment, the pieces are the
    submission's own, as before."""
    folder = tmp_path / "submission"
    shutil.copytree(REPO_ROOT / "exercises", folder)
    shutil.copyfile(REPO_ROOT / "solutions" / "dogleg.py", folder / "dogleg.py")
    ch3 = COURSE.assignment("ch3")
    results = grade(str(folder), which="public", assignment=ch3)
    assert {r.exercise.split(".")[0] for r in results} == {"dogleg"}
    assert sum(r.score for r in results) == pytest.approx(ch3.maximum("public"))
    whole = grade(str(folder), only=["dogleg.end_to_end"], which="public")
    assert sum(r.score for r in whole) == 0


# ---------------------------------------------------------------- the student tree


def _run(python, tree, *args, timeout=300):
    env = {k: v for k, v in os.environ.items() if not k.startswith(("PYTHON", "COURSE_IMPL", "AUTOGRADER"))}
    env["PYTHONPATH"] = str(tree)
    return subprocess.run([python, *args], cwd=tree, env=env, capture_output=True, text=True, timeout=timeout)


@pytest.fixture(scope="module")
def ch3_tree(tmp_path_factory, stubs):
    target = tmp_path_factory.mktemp("ch3") / "tree"
    handout.write_student_tree(target, COURSE, COURSE.assignment("ch3"), stubs)
    return target


def test_the_ch3_tree_holds_nothing_of_later_chapters(ch3_tree):
    files = {p.relative_to(ch3_tree).as_posix() for p in ch3_tree.rglob("*") if p.is_file()}
    for name in LATER_THAN_CH3:
        later = COURSE.assignment(name)
        for module in later.modules:
            assert f"exercises/{module}.py" not in files
        for module in later.exercises:
            assert f"autograder/expected/{module}.json" not in files
            assert f"autograder/checks/{module}.py" not in files
        later_paths = chapters.files(chapters.chapter(name))  # its notebook, problems, peers, helpers
        assert not [f for f in files for rel in later_paths if f == rel or f.startswith(rel + "/")], name
    assert not [f for f in files if f.startswith(("course/factorgraph/", "course/problems/bal/"))]
    assert [f for f in files if f.startswith("autograder/expected/")] == ["autograder/expected/dogleg.json"]
    assert not [f for f in files if f.startswith(("solutions/", "tests/"))]
    assert (ch3_tree / "autograder" / "ASSIGNMENT").read_text().strip() == "ch3"
    assert "## This assignment: ch3" in (ch3_tree / "README.md").read_text()
    assert "raise NotImplementedError" not in (ch3_tree / "exercises" / "curve_model.py").read_text()
    assert "raise NotImplementedError" in (ch3_tree / "exercises" / "dogleg.py").read_text()


def _total(text):
    found = re.search(r"^Total: (\d+(?:\.\d+)?) / (\d+(?:\.\d+)?)", text, flags=re.M)
    assert found, text
    return float(found.group(1)), float(found.group(2))


@pytest.mark.slow
def test_the_ch3_tree_grades_ch3_alone_stubs_zero_reference_every_point(ch3_tree, python, tmp_path):
    maximum = COURSE.assignment("ch3").maximum("public")
    out = _run(python, ch3_tree, "-m", "autograder")
    assert out.returncode == 0, out.stdout + out.stderr
    assert _total(out.stdout) == (0, maximum) and "assignment ch3" in out.stdout
    checked = re.findall(r"^(\w[\w.]*)\s+\d+(?:\.\d+)?\s+\d", out.stdout, flags=re.M)
    assert checked and all(name.startswith("dogleg.") for name in checked), checked
    solved = tmp_path / "solved"
    shutil.copytree(ch3_tree, solved, ignore=shutil.ignore_patterns("__pycache__"))
    for name in ("dogleg.py", "initialisation.py"):
        shutil.copyfile(REPO_ROOT / "solutions" / name, solved / "exercises" / name)
    full = _run(python, solved, "-m", "autograder")
    assert _total(full.stdout) == (maximum, maximum), full.stdout + full.stderr
    tests = _run(python, solved, "-m", "pytest", "-q", "-p", "no:cacheprovider")
    assert tests.returncode == 0, tests.stdout[-3000:] + tests.stderr[-2000:]
    assert f"autograder: {maximum:g} / {maximum:g} points on the 10 checks run (public checks)" in tests.stdout


# ---------------------------------------------------------------- the Gradescope zip


@pytest.fixture(scope="module")
def ch1_zip(tmp_path_factory):
    """``release --assignment ch1 --gradescope`` from a copy of this tree, and what runs it."""
    base = tmp_path_factory.mktemp("gradescope-ch1")
    for built in gradescope_zip(base, base / "ch1.zip", "--assignment", "ch1"):
        assert "Gradescope autograder of assignment ch1" in built["stdout"]
        yield built


def test_the_ch1_zip_holds_ch1s_stubs_and_its_configuration(ch1_zip):
    with zipfile.ZipFile(ch1_zip["zip"]) as archive:
        names = set(archive.namelist())
        assert archive.read("autograder/ASSIGNMENT").decode().strip() == "ch1"
        assert "[assignments.ch1]" in archive.read("autograder/course.toml").decode()
    exercises = {n for n in names if n.startswith("exercises/")}
    assert exercises == {f"exercises/{m}.py" for m in ("__init__", "curve_model", "gauss_newton", "damping")}
    assert "solutions/dogleg.py" in names and "autograder/oracle.py" in names  # the hidden checks need them


def _start(bundle, name, files, metadata=None):
    root = bundle["roots"] / name
    (root / "submission").mkdir(parents=True)
    with zipfile.ZipFile(bundle["zip"]) as archive:
        archive.extractall(root / "source")
    for rel, text in files.items():
        (root / "submission" / rel).write_text(text)
    if metadata is not None:
        (root / "submission_metadata.json").write_text(json.dumps(metadata))
    env = {k: v for k, v in os.environ.items() if not k.startswith(("PYTHON", "AUTOGRADER"))}
    env["AUTOGRADER_ROOT"] = str(root)
    env["PATH"] = f"{bundle['bin']}{os.pathsep}{env.get('PATH', '/usr/bin:/bin')}"
    return root, subprocess.Popen(["bash", str(root / "source" / "run_autograder")], cwd=str(root), env=env,
                                  stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def _results(started):
    root, process = started
    out, err = process.communicate(timeout=300)
    assert process.returncode == 0, out[-2000:] + err[-2000:]
    return json.loads((root / "results" / "results.json").read_text())


def _metadata(late: timedelta, extended: timedelta | None = None) -> dict:
    """Gradescope's metadata of a submission ``late`` after ch1's due date; ``extended``: the user's own
    due date that far after it (an extension granted on Gradescope)."""
    due = COURSE.assignment("ch1").due
    user: dict = {"email": "student@example.edu", "id": 1234, "name": "A Student"}
    if extended is not None:
        user["assignment"] = {"due_date": (due + extended).isoformat(), "late_due_date": None}
    return {"created_at": (due + late).isoformat(), "assignment": {"due_date": due.isoformat(), "title": "ch1"},
            "users": [user]}


@pytest.mark.slow
def test_the_ch1_zip_grades_ch1_with_its_points_visibilities_and_late_policy(ch1_zip):
    ch1 = COURSE.assignment("ch1")
    reference = {f"{m}.py": (REPO_ROOT / "solutions" / f"{m}.py").read_text() for m in ch1.modules}
    stubs = {f"{m}.py": (REPO_ROOT / "exercises" / f"{m}.py").read_text() for m in ch1.modules}
    runs = {"on time": _start(ch1_zip, "on-time", reference, _metadata(-timedelta(hours=1))),
            "stubs": _start(ch1_zip, "stubs", stubs, _metadata(-timedelta(hours=1)))}
    runs["late"] = _start(ch1_zip, "late", reference, _metadata(timedelta(days=2)))
    runs["extended"] = _start(ch1_zip, "extended", reference, _metadata(timedelta(days=2), timedelta(days=3)))
    results = {name: _results(started) for name, started in runs.items()}
    maximum = ch1.maximum()
    for name, data in results.items():
        assert sum(t["max_score"] for t in data["tests"]) == pytest.approx(maximum), name
        assert all(t["name"].split(":")[0].split(".")[0] in ch1.exercises for t in data["tests"]), name
        hidden = [t for t in data["tests"] if t["name"].endswith("(hidden inputs)")]
        assert hidden and {t["visibility"] for t in hidden} == {ch1.hidden_visibility}
        assert {t["visibility"] for t in data["tests"] if t not in hidden} == {"visible"}
    assert results["on time"]["score"] == pytest.approx(maximum), results["on time"]["output"]
    assert results["stubs"]["score"] == 0
    late = results["late"]
    assert late["score"] == pytest.approx(0.8 * maximum), late["output"]
    assert re.search(r"^Late: 2\.00 days late: 2 started days at 10%, 80% of the score kept \(due "
                     rf"{re.escape(ch1.due.isoformat())}, the assignment's due date\)", late["output"], re.M)
    extended = results["extended"]  # Gradescope's extension: on time, and the feedback says so
    assert extended["score"] == pytest.approx(maximum), extended["output"]
    assert f"Submitted: on time (due {(ch1.due + timedelta(days=3)).isoformat()}, an extension on Gradescope)" in \
        extended["output"]
