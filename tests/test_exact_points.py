"""Exact points (``autograder.point_grid``): a full score is its check's maximum, and the full scores of
an assignment sum to its ``total`` exactly, on every path a grade takes.

The property: random totals and point splits of random assignments of the real checks (a seeded
loop), the reference's full fractions put through what the judge, ``results.json``, the gradebook,
the LMS files and the class report compute, give exactly the total. Then the paths themselves, with
``total = 100`` over two exercises whose checks are worth thirds of a point (2.7778, 8.3333): the
Gradescope command (``--json``, and its late penalty), ``batch`` with the report and the CSVs
(one grading run, shared by the tests below). The pytest plugin's is in ``tests/test_pytest_plugin.py``.
"""

import csv
import json
import random
from datetime import timedelta
from fractions import Fraction
from pathlib import Path
from types import SimpleNamespace

import pytest

from autograder import point_grid, report
from autograder.checks import ORDER, modules
from autograder.classroom import export, gradebook
from autograder.classroom import report as class_report
from autograder.course_config import ConfigError, parse
from autograder.grade import HIDDEN_SUFFIX, CheckResult, mark
from autograder.late import Lateness
from course.core.impl import REPO_ROOT

CONFIG = """[assignments.thirds]
title = "Curve model and Gauss-Newton, out of 100"
exercises = ["curve_model", "gauss_newton"]
total = 100
due = 2027-02-05T23:59:00+01:00
late = { per_day = 0.1, cutoff_days = 7 }
"""
FILES = ("curve_model", "gauss_newton")


def test_the_grid_rounds_as_written_and_sums_in_whole_steps():
    assert point_grid.steps(0.3) == 3000 and point_grid.steps("1.23455") == 12346 and point_grid.steps(2) == 20000
    assert point_grid.total([0.1] * 10) == 1.0 and sum([0.1] * 10) != 1.0
    assert point_grid.scaled(1.2821, 1.0) == 1.2821 and point_grid.scaled(100, 0.7000000000000001) == 70.0
    assert point_grid.scaled(3, 1.5) == 3.0 and point_grid.scaled(3, -1) == 0.0
    shares = {"a": Fraction(100, 3), "b": Fraction(100, 3), "c": Fraction(100, 3)}
    assert point_grid.apportion(shares) == {"a": 33.3334, "b": 33.3333, "c": 33.3333}
    assert point_grid.apportion({"x": 4, "y": Fraction(1, 3)}) == {"x": 4.0, "y": 0.3333}  # on the grid: kept
    with pytest.raises(ValueError):
        point_grid.exact(float("nan"))


def random_assignment(rng: random.Random) -> tuple:
    """A random assignment of the real checks: exercises, optional ones, points per module or
    exercise, hidden checks counted or not, and a total on the grid; with its TOML data."""
    registry = dict(modules())
    exercises = rng.sample(ORDER, rng.randint(1, 4))
    optional = [e for e in exercises[1:] if rng.random() < 0.3]
    points = {}
    for exercise in exercises:
        if rng.random() < 0.4:
            points[exercise] = rng.choice([rng.randint(1, 60), round(rng.uniform(0.5, 40), 2)])
        elif rng.random() < 0.3:
            unit = rng.choice(sorted({c.exercise for c in registry[exercise].CHECKS}))
            points[unit] = rng.randint(1, 30)
    counts = rng.random() < 0.8
    total = rng.choice([100, 10, 7, 1, rng.randint(1, 1000), round(rng.uniform(1, 300), 2), 99.9998])
    graded = {m for e in exercises for m in registry[e].MODULES}
    solved = sorted({m for e in exercises for m in getattr(registry[e], "USES", ()) if m not in graded})
    raw = {"exercises": exercises, "optional": optional, "solved": solved, "points": points, "hidden_counts": counts,
           "total": total}
    return parse({"assignments": {"a": raw}}).assignment("a"), total, counts


def full_results(assignment) -> list:
    """The results of a submission with every check right (fraction 1, as the judge scores it), public and hidden."""
    results = []
    for check in assignment.checks():
        for hidden in (False, True):
            score = point_grid.scaled(check.points, 1.0)
            result = CheckResult(check.name + (HIDDEN_SUFFIX if hidden else ""), check.exercise, score,
                                 point_grid.on_grid(check.points), "ok", hidden=hidden)
            results.append(mark(result, check, assignment))
    return results


def test_full_fractions_score_exactly_the_total_for_random_totals_and_splits(tmp_path):
    rng = random.Random(20261128)
    for trial in range(150):
        assignment, total, counts = random_assignment(rng)
        label = f"trial {trial}: {assignment.exercises}, total {total}, hidden counts {counts}"
        assert assignment.maximum() == total, label
        assert assignment.maximum("public") == (total / 2 if counts else total), label
        required = [c for c in assignment.checks() if not assignment.is_extra(c)]
        exact = sum(Fraction(repr(c.points)) for c in required) * (2 if counts else 1)
        assert exact == Fraction(repr(float(total))), label  # on the grid, exactly
        results = full_results(assignment)
        assert all(r.full and r.score == r.max_score for r in results), label
        extra = point_grid.total(r.score for r in results if r.extra and r.counted)
        assert report.maximum(results) == total and report.earned(results) == point_grid.total([total, extra]), label
        data = report.gradescope(results, 1.0, Lateness(timedelta(0), 1.0, "on time"))
        counted = [t for t in data["tests"] if t["max_score"] > 0]
        assert all(t["score"] == t["max_score"] for t in counted), label
        assert data["score"] == report.earned(results), label
        if not extra:  # the gradebook's, the report's and the LMS files' sums, from the record read back
            folder = tmp_path / f"t{trial}"
            sub = SimpleNamespace(id="s1", name="S", sid="1", email="s@x.edu")
            record = gradebook.adjust(gradebook.record(sub, results, 1.0, "graded", {"assignment": "a"}))
            gradebook.save(folder / "results", json.loads(json.dumps(record)))
            row = next(csv.DictReader(gradebook.table(gradebook.load_all(folder / "results")).splitlines()))
            assert row["total"] == row["max"] == row["before_penalty"] == gradebook.number(total), label
            assert export.load_assignment(folder, {}).maximum == total, label
            (student,), _ = class_report.load_students(folder)
            assert student.score == student.max_score == total, label
            late = gradebook.adjust(record, lateness=Lateness(timedelta(days=2), 0.8, "2 days late"))
            assert late["score"] == point_grid.scaled(total, Fraction(4, 5)), label
            assert point_grid.total([late["score"], late["extra_data"]["late"]["penalty"]]) == total, label


def test_a_total_off_the_grid_is_refused():
    with pytest.raises(ConfigError, match="assignments.a.total: expected a multiple of 0.0002"):
        parse({"assignments": {"a": {"exercises": ["curve_model"], "total": 100.0001}}})
    assert parse({"assignments": {"a": {"exercises": ["curve_model"], "total": 100.0001,
                                        "hidden_counts": False}}}).assignment("a").maximum() == 100.0001


# ---------------------------------------------------------------- the paths, with total = 100


@pytest.fixture(scope="module")
def course(tmp_path_factory) -> Path:
    folder = tmp_path_factory.mktemp("course")
    (folder / "course.toml").write_text(CONFIG)
    return folder / "course.toml"


def test_the_gradescope_command_scores_exactly_100_and_90_when_a_day_late(course, tmp_path, capsys):
    """What ``run_autograder`` runs in the zip: ``python -m autograder --json`` (with Gradescope's metadata)."""
    from autograder.__main__ import main

    metadata = tmp_path / "submission_metadata.json"
    metadata.write_text('{"created_at": "2027-02-06T10:00:00+01:00", "assignment": {"due_date": '
                        '"2027-02-05T23:59:00+01:00"}, "users": [{"email": "s@x.edu", "id": 7}]}')
    for extra, score in (((), 100.0), (("--metadata", str(metadata)), 90.0)):
        out = tmp_path / "results.json"
        assert main(["--impl", "solutions", "--config", str(course), "--assignment", "thirds", "--json", str(out),
                     *extra]) == 0
        data = json.loads(out.read_text())
        assert data["score"] == score
        assert len(data["tests"]) == 16 and all(t["score"] == t["max_score"] > 0 for t in data["tests"])
        assert {t["max_score"] for t in data["tests"]} == {2.7778, 8.3333, 5.5556}
        assert "Total: 100 / 100" in capsys.readouterr().out


@pytest.fixture(scope="module")
def graded(course, tmp_path_factory) -> Path:
    """A class of two graded by ``batch`` on ``total = 100``: ada on time, bob a day late (90%)."""
    from autograder.classroom import batch

    root = tmp_path_factory.mktemp("class")
    for student in ("ada", "bob"):
        (root / "uploads" / student).mkdir(parents=True)
        for name in FILES:
            (root / "uploads" / student / f"{name}.py").write_text((REPO_ROOT / "solutions" / f"{name}.py").read_text())
    (root / "roster.csv").write_text("id,sid,email,name,submitted\nada,9001,ada@x.edu,Ada,2027-02-05T10:00:00+01:00\n"
                                     "bob,9002,bob@x.edu,Bob,2027-02-06T10:00:00+01:00\n")
    out = root / "out"
    assert batch.main([str(root / "uploads"), "--out", str(out), "--config", str(course), "--assignment", "thirds",
                       "--roster", str(root / "roster.csv"), "--timeout", "10", "--jobs", "2"]) == 0
    return out


def test_batch_records_score_exactly_100(graded):
    ada = gradebook.load(graded / "results" / "ada.json")
    assert ada["score"] == 100.0 and all(t["score"] == t["max_score"] for t in ada["tests"])
    assert point_grid.total(t["max_score"] for t in ada["tests"]) == 100.0
    bob = gradebook.load(graded / "results" / "bob.json")
    assert bob["score"] == 90.0 and bob["extra_data"]["late"]["penalty"] == 10.0


def test_the_csvs_carry_exactly_100(graded, tmp_path):
    with open(graded / "grades.csv", newline="") as file:
        rows = {row["id"]: row for row in csv.DictReader(file)}
    assert (rows["ada"]["total"], rows["ada"]["max"]) == ("100", "100")
    assert (rows["bob"]["total"], rows["bob"]["before_penalty"], rows["bob"]["penalty"]) == ("90", "100", "10")
    assert rows["ada"]["curve_model.residuals_and_jacobian"] == "55.5554"  # 2 x (2.7778 + 3 x 8.3333)
    assert export.main([str(graded), "--canvas", str(tmp_path / "canvas.csv"), "--moodle",
                        str(tmp_path / "moodle.csv")]) == 0
    canvas = list(csv.reader((tmp_path / "canvas.csv").open(newline="")))
    assert canvas[1][-1] == "100" and sorted(row[-1] for row in canvas[2:]) == ["100", "90"]
    moodle = list(csv.reader((tmp_path / "moodle.csv").open(newline="")))
    assert sorted(row[-1] for row in moodle[1:]) == ["100", "90"]


def test_the_report_shows_everyone_at_full_marks(graded):
    students, notes = class_report.load_students(graded)
    assert not notes and {s.sid: (s.score, s.max_score) for s in students} == {"ada": (100.0, 100.0),
                                                                               "bob": (90.0, 100.0)}
    rates = class_report.pass_rates(students)
    assert len(rates) == 16 and all(full == size == 2 for _, _, _, full, size in rates)
    page = (graded / "report.html").read_text()
    assert "out of 100 points" in page and "2 / 2" in page and "0 / 2" not in page
