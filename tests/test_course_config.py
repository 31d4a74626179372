"""autograder.course_config: the shipped semester, each mistake's error, the points; exact ``--only``."""

import subprocess
import sys
from datetime import datetime, timedelta, timezone

import pytest

from autograder import course_config
from autograder.checks import ORDER, SelectionError, all_checks, module_of, select
from autograder.course_config import ConfigError, load, parse
from course.core.impl import REPO_ROOT

SEMESTER = ("ch1", "ch2", "ch3", "ch3b", "ch4", "ch5", "ch6", "ch7", "ch8")


def minimal(**assignment) -> dict:
    return {"assignments": {"ch1": {"exercises": ["curve_model", "gauss_newton"], **assignment}}}


def error_of(data) -> ConfigError:
    with pytest.raises(ConfigError) as info:
        parse(data, "course.toml")
    return info.value


def test_the_shipped_semester_assigns_every_check_exactly_once():
    course = load()
    assert tuple(course.assignments) == SEMESTER
    seen: dict = {}
    for assignment in course.assignments.values():
        for check in assignment.checks():
            assert check.name not in seen, (check.name, seen.get(check.name), assignment.name)
            seen[check.name] = assignment.name
    assert sorted(seen) == sorted(check.name for check in all_checks())
    owners = [name for a in course.assignments.values() for name in a.exercises]
    assert sorted(owners) == sorted(ORDER)
    for assignment in course.assignments.values():
        assert assignment.due is not None and assignment.due.utcoffset() is not None
        assert assignment.late.per_day == pytest.approx(0.1)
    assert course.assignment("ch3").exercises == ("dogleg",)
    assert course.assignment("ch2").optional == ("pose_graph_fast",)
    assert course.assignment("ch4").optional == ("gauge",)


def test_default_points_are_the_checks_own():
    course = load()
    ch1 = course.assignment("ch1")
    by_name = {check.name: check.points for check in all_checks()}
    assert all(check.points == by_name[check.name] for check in ch1.checks())
    public = sum(c.points for c in ch1.checks())
    assert ch1.maximum("public") == public and ch1.maximum() == 2 * public
    ch2 = course.assignment("ch2")  # pose_graph_fast is extra credit: out of the maximum
    fast = sum(c.points for c in ch2.checks() if module_of()[c.name] == "pose_graph_fast")
    assert fast > 0 and ch2.maximum("public") == sum(c.points for c in ch2.checks()) - fast


def test_points_per_module_exercise_check_and_total():
    check = "end_to_end: lm-type3"
    data = {"assignments": {"ch1": {"exercises": ["curve_model", "damping", "end_to_end", "gauss_newton"],
                                    "points": {"damping": 30, "damping.GavinType1": 12, check: 5}}}}
    a = parse(data).assignment("ch1")
    damping = [c for c in a.checks() if module_of()[c.name] == "damping"]
    # the most specific wins: GavinType1 is 12, types 2 and 3 keep their share of 30 (13 of 21 points)
    assert sum(c.points for c in damping if c.exercise == "damping.GavinType1") == pytest.approx(12)
    assert sum(c.points for c in damping) == pytest.approx(12 + 30 * 13 / 21)
    module_only = parse({"assignments": {"ch1": {"exercises": ["damping"], "points": {"damping": 30}}}})
    assert sum(c.points for c in module_only.assignment("ch1").checks()) == pytest.approx(30)
    assert a.points[check] == 5
    assert a.exercises == ("curve_model", "gauss_newton", "damping", "end_to_end")  # report order
    scaled = parse({"assignments": {"ch1": {"exercises": ["curve_model"], "total": 100}}}).assignment("ch1")
    assert scaled.maximum() == pytest.approx(100) and scaled.maximum("public") == pytest.approx(50)
    uncounted = parse(minimal(total=40, hidden_counts=False)).assignment("ch1")
    assert uncounted.maximum() == pytest.approx(40) and uncounted.maximum("hidden") == 0


@pytest.mark.parametrize("data, key, says", [
    ({"assignments": {"ch1": {"exercises": ["curve_model"], "colour": "red"}}}, "assignments.ch1.colour",
     "unknown key"),
    ({"semester": {}, "assignments": {"ch1": {"exercises": ["curve_model"]}}}, "semester", "unknown key"),
    (minimal(late={"per_week": 0.1}), "assignments.ch1.late.per_week", "unknown key"),
    ({"assignments": {"ch1": {"exercises": ["curve_modle"]}}}, "assignments.ch1.exercises[0]",
     "did you mean curve_model"),
    (minimal(optional=["damping"]), "assignments.ch1.optional", "not one of this assignment's exercises"),
    (minimal(points={"curve_model": -1}), "assignments.ch1.points.curve_model", "points >= 0"),
    (minimal(points={"pose_graph_edge": 3}), "assignments.ch1.points.pose_graph_edge", "unknown name"),
    (minimal(due="next friday"), "assignments.ch1.due", "ISO 8601"),
    (minimal(due="2027-02-05T23:59:00"), "assignments.ch1.due", "without one"),
    (minimal(due=datetime(2027, 2, 5).date()), "assignments.ch1.due", "a date without a time"),
    (minimal(late={"per_day": 1.5}), "assignments.ch1.late.per_day", "fraction in [0, 1]"),
    (minimal(late={"cutoff_days": -2}), "assignments.ch1.late.cutoff_days", ">= 0"),
    (minimal(late={"extensions": {"a@b.c": "soon"}}), "assignments.ch1.late.extensions.a@b.c", "ISO 8601"),
    (minimal(hidden_visibility="later"), "assignments.ch1.hidden_visibility", "after_published"),
    ({"assignments": {"ch1": {"exercises": ["curve_model"]}, "ch2": {"exercises": ["pose_graph_edge", "curve_model"]}}},
     "assignments.ch2.exercises", "already in assignments.ch1"),
    ({"assignments": {"ch3": {"exercises": ["dogleg"]}}}, "assignments.ch3.solved", "curve_model"),
    ({"assignments": {"ch1": {"exercises": ["curve_model"], "solved": ["dogleg"]}, "ch3": {"exercises": ["dogleg"],
      "solved": ["curve_model", "gauss_newton", "pose_graph_edge", "pose_graph_assembly", "sparse_solve",
                 "pose_graph_fast"]}}}, "assignments.ch1.solved", "comes later"),
    ({"assignments": {}}, "assignments", "at least one"),
])
def test_each_mistake_names_the_file_the_key_and_what_was_expected(data, key, says):
    error = error_of(data)
    assert error.path == "course.toml" and error.key == key, str(error)
    assert str(error).startswith(f"course.toml: {key}: ") and says in str(error), str(error)


def test_a_file_that_is_not_toml_and_an_unknown_assignment(tmp_path):
    bad = tmp_path / "course.toml"
    bad.write_text("[assignments.ch1\n")
    with pytest.raises(ConfigError, match=f"{bad}: not valid TOML"):
        load(bad)
    with pytest.raises(ConfigError, match="assignments.ch9: no such assignment.*ch1, ch2"):
        load().assignment("ch9")


def test_the_late_policy_and_gradescope_metadata(tmp_path):
    a = load().assignment("ch1")
    two_days = a.due + timedelta(days=2)
    assert a.lateness(two_days).fraction == pytest.approx(0.8)
    assert a.lateness(a.due - timedelta(seconds=1)).fraction == 1.0
    assert a.lateness(a.due + timedelta(days=8)).fraction == 0.0  # past the cutoff of 7 days
    extended = parse(minimal(due="2027-02-05T23:59:00+01:00", late={"per_day": 0.1, "extensions": {
        "s@x.edu": "2027-02-08T23:59:00+01:00"}})).assignment("ch1")
    assert extended.lateness(extended.due + timedelta(days=2), ("123", "s@x.edu")).fraction == 1.0
    meta = tmp_path / "submission_metadata.json"
    meta.write_text('{"created_at": "2027-02-07T23:59:00.500000+01:00", "assignment": {"due_date": '
                    '"2027-02-05T23:59:00.000000+01:00"}, "users": [{"email": "s@x.edu", "id": 7, "name": "S"}]}')
    submitted = course_config.gradescope_metadata(meta)
    assert submitted.created_at == datetime(2027, 2, 7, 22, 59, 0, 500000, tzinfo=timezone.utc)
    assert "s@x.edu" in submitted.students and "7" in submitted.students
    assert submitted.due == datetime(2027, 2, 5, 22, 59, tzinfo=timezone.utc)


def test_only_selects_exact_names_and_says_which_are_close():
    checks = all_checks()
    assert [c.name for c in select(checks, ["pose_graph"])] == ["pose_graph.end_to_end: gauss-newton"]
    assert {c.exercise for c in select(checks, ["damping"])} == {f"damping.GavinType{k}" for k in (1, 2, 3)}
    assert {c.exercise for c in select(checks, ["end_to_end"])} == {"end_to_end"}
    assert len(select(checks, ["dogleg.end_to_end"])) == 2
    one = checks[0].name
    assert [c.name for c in select(checks, [one])] == [one]
    with pytest.raises(SelectionError, match="'pose_grap' matches no .*close: pose_graph"):
        select(checks, ["pose_grap"])
    with pytest.raises(SelectionError, match="'damping.GavinType' matches no"):
        select(checks, ["damping.GavinType"])


def test_list_only_pose_graph_lists_its_end_to_end_only():
    out = subprocess.run([sys.executable, "-m", "autograder", "--list", "--only", "pose_graph"], cwd=REPO_ROOT,
                         capture_output=True, text=True, check=True).stdout
    assert [line.split(None, 1)[1] for line in out.strip().splitlines()] == [
        "pose_graph.end_to_end: gauss-newton", "total"]
    bad = subprocess.run([sys.executable, "-m", "autograder", "--list", "--only", "pose_graph_3", "--assignment",
                          "ch6"], cwd=REPO_ROOT, capture_output=True, text=True)
    assert bad.returncode == 2 and "close: pose_graph_3d" in bad.stderr
    ch3 = subprocess.run([sys.executable, "-m", "autograder", "--list", "--assignment", "ch3"], cwd=REPO_ROOT,
                         capture_output=True, text=True, check=True).stdout
    assert all(line.split(None, 1)[1].startswith("dogleg.") for line in ch3.strip().splitlines()[:-1])


def test_results_carry_extra_credit_uncounted_hidden_checks_and_lateness():
    from autograder import report
    from autograder.grade import CheckResult, mark
    from autograder.late import Lateness

    data = {"assignments": {"ch2": {"exercises": ["pose_graph_edge", "pose_graph_assembly", "pose_graph_fast"],
                                    "optional": ["pose_graph_fast"],
                                    "hidden_visibility": "after_due_date", "hidden_counts": False}}}
    ch2 = parse(data).assignment("ch2")
    results = []
    for check in ch2.checks():
        for hidden in (False, True):
            result = CheckResult(check.name + (" (hidden inputs)" if hidden else ""), check.exercise, check.points,
                                 check.points, "ok", hidden=hidden)
            results.append(mark(result, check, ch2))
    edge = sum(c.points for c in ch2.checks() if not c.exercise.startswith("pose_graph_fast"))
    fast = sum(c.points for c in ch2.checks() if c.exercise.startswith("pose_graph_fast"))
    assert report.earned(results) == edge + fast and report.maximum(results) == edge == ch2.maximum()
    assert report.total(results).startswith(f"{edge + fast:g} / {edge:g} (extra credit included")
    data = report.gradescope(results, 1.0, Lateness(timedelta(days=1, hours=2), 0.8, "1.08 days late: ..."))
    assert data["score"] == pytest.approx(0.8 * (edge + fast))
    assert "Late: 1.08 days late" in data["output"]
    by_name = {t["name"]: t for t in data["tests"]}
    hidden = [t for t in data["tests"] if "(hidden inputs)" in t["name"]]
    assert {t["visibility"] for t in hidden} == {"after_due_date"}
    assert all(t["score"] == 0 == t["max_score"] and t["output"].startswith("Not counted") for t in hidden)
    extra = [t for name, t in by_name.items() if "extra credit" in name]
    assert extra and all(t["max_score"] == 0 and t["score"] > 0 for t in extra)


def test_pytest_autograder_only_keeps_the_exact_names():
    run = subprocess.run([sys.executable, "-m", "pytest", "exercises", "--collect-only", "-q", "-p", "no:cacheprovider",
                          "--autograder-only", "pose_graph"], cwd=REPO_ROOT, capture_output=True, text=True)
    items = [line for line in run.stdout.splitlines() if line.startswith("exercises")]
    assert items and all("::pose_graph::end_to_end" in line for line in items), run.stdout
    bad = subprocess.run([sys.executable, "-m", "pytest", "exercises", "--collect-only", "-q", "-p", "no:cacheprovider",
                          "--autograder-only", "pose_grap"], cwd=REPO_ROOT, capture_output=True, text=True)
    assert bad.returncode != 0 and "close: pose_graph" in bad.stdout + bad.stderr
