"""Extensions: private (a student tree's configuration names no student; the zip keeps them to grade),
from every source (the configuration's and Gradescope's own, a user's due date in
``submission_metadata.json``, whichever is later, and the feedback says which applied), and none
before its due date."""

import json
import os
import re
import subprocess
import sys
from datetime import datetime, timedelta, timezone
from pathlib import Path

import pytest

from autograder import course_config
from autograder.__main__ import main as grade_main
from autograder.course_config import ConfigError, load, parse
from autograder.late import CONFIGURED, GRANTED
from autograder.release import assignment as handout
from autograder.release.carried_config import config_text, has_personal, tomllib
from autograder.release.stubs import render
from course.core.impl import REPO_ROOT

#: the students the configuration below names: an e-mail, a sid, a Gradescope user id
EMAIL, SID, USER_ID = "s007@uni.edu", "8675309", "4417021"


def with_extensions(tmp_path) -> Path:
    """The shipped configuration with extensions in ch1 (by e-mail and sid) and ch3 (by user id)."""
    text = (REPO_ROOT / "autograder" / "course.toml").read_text()
    text = text.replace('due = 2027-02-05T23:59:00+01:00\n', 'due = 2027-02-05T23:59:00+01:00\n'
                        f'late = {{ per_day = 0.1, cutoff_days = 7, extensions = {{ "{EMAIL}" = '
                        f'2027-02-08T23:59:00+01:00, "{SID}" = 2027-02-07T12:00:00+01:00 }} }}\n', 1)
    text = text.replace('due = 2027-03-12T23:59:00+01:00\n', 'due = 2027-03-12T23:59:00+01:00\n'
                        f'[assignments.ch3.late]\nper_day = 0.1\ncutoff_days = 7\n'
                        f'extensions = {{ "{USER_ID}" = 2027-03-14T23:59:00+01:00 }}\n', 1)
    path = tmp_path / "course.toml"
    path.write_text(text)
    return path


@pytest.fixture(scope="module")
def stubs():
    return render(REPO_ROOT / "solutions")


def personal_data_in(tree: Path) -> list:
    """The files of ``tree`` that hold one of the configuration's students (every file, as bytes)."""
    found = []
    for path in sorted(tree.rglob("*")):
        if path.is_file() and not path.is_symlink():
            data = path.read_bytes()
            found += [f"{path.relative_to(tree)}: {key}" for key in (EMAIL, SID, USER_ID) if key.encode() in data]
    return found


@pytest.mark.parametrize("name", ["ch1", "ch3"])
def test_an_assignment_tree_with_extensions_names_no_student(tmp_path, stubs, name):
    source = with_extensions(tmp_path)
    course = load(source)
    assignment = course.assignment(name)
    assert assignment.late.extensions, "the configuration gives this assignment extensions"
    tree = tmp_path / "tree"
    handout.write_student_tree(tree, course, assignment, stubs)
    assert personal_data_in(tree) == []
    carried = parse(tomllib.loads((tree / "autograder" / "course.toml").read_text())).assignment(name)
    assert carried.due == assignment.due and carried.late.extensions == {}
    assert (carried.late.per_day, carried.late.cutoff) == (assignment.late.per_day, assignment.late.cutoff)


def test_the_zip_keeps_its_assignment_s_extensions_and_no_other(tmp_path, stubs):
    course = load(with_extensions(tmp_path))
    overlay = handout.bundle_overlay(course, course.assignment("ch1"), stubs)
    carried = parse(tomllib.loads(overlay["autograder/course.toml"])).assignment("ch1")
    assert set(carried.late.extensions) == {EMAIL, SID}
    assert USER_ID not in overlay["autograder/course.toml"]


def test_the_whole_course_s_configuration_drops_every_personal_key(tmp_path):
    source = with_extensions(tmp_path)
    with open(source, "rb") as handle:
        assert has_personal(tomllib.load(handle))
    text = config_text(source)
    assert EMAIL not in text and SID not in text and USER_ID not in text
    again = parse(tomllib.loads(text))
    assert list(again.assignments) == list(load(source).assignments)
    assert not has_personal(tomllib.loads(text))


def metadata(tmp_path, created: datetime, due: datetime, own_due: datetime | None, email="other@uni.edu") -> Path:
    user = {"email": email, "id": 99, "name": "A Student"}
    if own_due is not None:  # Gradescope's extension: the user's own assignment dates
        user["assignment"] = {"due_date": own_due.isoformat(), "late_due_date": None,
                              "release_date": "2027-01-20T00:00:00+01:00"}
    path = tmp_path / "submission_metadata.json"
    path.write_text(json.dumps({"id": 1, "created_at": created.isoformat(),
                                "assignment": {"due_date": due.isoformat(), "late_due_date": None, "title": "ch1"},
                                "users": [user]}))
    return path


def test_a_later_per_user_due_date_on_gradescope_is_on_time(tmp_path):
    ch1 = load().assignment("ch1")
    created = ch1.due + timedelta(days=2)
    granted = course_config.gradescope_metadata(metadata(tmp_path, created, ch1.due, ch1.due + timedelta(days=3)))
    assert granted.granted == ch1.due + timedelta(days=3)
    on_time = ch1.lateness(granted.created_at, granted.students, due=granted.due, granted=granted.granted)
    assert on_time.fraction == 1.0 and on_time.basis == GRANTED and on_time.due == ch1.due + timedelta(days=3)
    plain = course_config.gradescope_metadata(metadata(tmp_path, created, ch1.due, ch1.due))  # no extension
    assert plain.granted is None
    assert ch1.lateness(plain.created_at, plain.students, granted=plain.granted).fraction == pytest.approx(0.8)
    short = course_config.gradescope_metadata(metadata(tmp_path, created, ch1.due, ch1.due + timedelta(days=1)))
    late = ch1.lateness(short.created_at, short.students, granted=short.granted)
    assert late.fraction == pytest.approx(0.9) and late.basis == GRANTED  # one started day past it


def test_the_later_of_the_configuration_s_and_gradescope_s_extension_applies(tmp_path):
    ch1 = load(with_extensions(tmp_path)).assignment("ch1")  # EMAIL: until 3 days after the due date
    created = ch1.due + timedelta(days=2, hours=12)
    for own, basis, fraction in ((ch1.due + timedelta(days=1), CONFIGURED, 1.0),
                                 (ch1.due + timedelta(days=4), GRANTED, 1.0)):
        meta = course_config.gradescope_metadata(metadata(tmp_path, created, ch1.due, own, email=EMAIL))
        kept = ch1.lateness(meta.created_at, meta.students, granted=meta.granted)
        assert (kept.basis, kept.fraction) == (basis, fraction)
    meta = course_config.gradescope_metadata(metadata(tmp_path, ch1.due + timedelta(days=4), ch1.due, None,
                                                      email=EMAIL))
    late = ch1.lateness(meta.created_at, meta.students, granted=meta.granted)
    assert late.basis == CONFIGURED and late.fraction == pytest.approx(0.9)


@pytest.mark.slow
def test_the_feedback_says_which_due_date_applied(tmp_path, capsys):
    ch1 = load().assignment("ch1")
    meta = metadata(tmp_path, ch1.due + timedelta(days=2), ch1.due, ch1.due + timedelta(days=3))
    out = tmp_path / "results.json"
    assert grade_main(["--impl", "solutions", "--assignment", "ch1", "--set", "public", "--only", "curve_model",
                       "--metadata", str(meta), "--json", str(out)]) == 0
    data = json.loads(out.read_text())
    due = (ch1.due + timedelta(days=3)).isoformat()
    assert f"Submitted: on time (due {due}, {GRANTED})" in data["output"]
    assert data["score"] == pytest.approx(sum(t["max_score"] for t in data["tests"]))
    assert f"(due {due}, {GRANTED})" in capsys.readouterr().out


def test_an_extension_before_its_due_date_is_refused():
    data = {"assignments": {"ch1": {"exercises": ["curve_model"], "due": "2027-02-05T23:59:00+01:00",
                                    "late": {"per_day": 0.1, "extensions": {EMAIL: "2027-02-05T12:00:00+01:00"}}}}}
    with pytest.raises(ConfigError) as info:
        parse(data, "course.toml")
    assert info.value.key == f"assignments.ch1.late.extensions.{EMAIL}"
    assert "before the due date of assignments.ch1" in str(info.value)
    data["assignments"]["ch1"]["late"]["extensions"][EMAIL] = "2027-02-05T23:59:00+01:00"  # the same: allowed
    assert parse(data).assignment("ch1").late.extensions[EMAIL] == datetime(2027, 2, 5, 22, 59, tzinfo=timezone.utc)


def test_the_checker_prints_dates_late_policy_and_extensions(tmp_path):
    source = with_extensions(tmp_path)
    env = {**os.environ, "PYTHONPATH": str(REPO_ROOT)}
    out = subprocess.run([sys.executable, "-m", "autograder.course_config", str(source)], cwd=tmp_path, env=env,
                         capture_output=True, text=True, check=True).stdout
    blocks = dict(re.findall(r"^  (\w+): .*\n((?:      .*\n)+)", out, flags=re.M))
    assert list(blocks) == list(load(source).assignments)
    assert "release after - ; due 2027-02-05T23:59:00+01:00".replace(" ;", ";") in blocks["ch1"]
    assert "closes 2027-02-15T23:59:00+01:00" in blocks["ch1"]  # the longest extension plus the cutoff of 7 days
    assert "late: 10% per started day, cutoff 7 days; 2 extensions" in blocks["ch1"]
    assert f"extension: {SID} until 2027-02-07T12:00:00+01:00" in blocks["ch1"]
    assert f"extension: {EMAIL} until 2027-02-08T23:59:00+01:00" in blocks["ch1"]
    assert "release after 2027-02-15T23:59:00+01:00 (when ch1 closes)" in blocks["ch2"]
    assert "cutoff 3 days; 0 extensions" in blocks["ch6"]


def test_the_whole_course_s_student_tree_names_no_student(tmp_path):
    """``release --student DIR`` without an assignment copies the repository: its configuration is
    rewritten without extensions (here from a small repository holding the configuration alone)."""
    from autograder.release.stubs import write_student_tree

    root = tmp_path / "repo"
    (root / "autograder").mkdir(parents=True)
    (root / "autograder" / "course.toml").write_text(with_extensions(tmp_path).read_text())
    tree = tmp_path / "tree"
    write_student_tree(tree, {"__init__.py": ""}, root)
    assert personal_data_in(tree) == []
    again = parse(tomllib.loads((tree / "autograder" / "course.toml").read_text()))
    assert list(again.assignments) == list(load(root / "autograder" / "course.toml").assignments)


def test_a_commented_out_extension_does_not_reach_a_student_tree(tmp_path):
    from autograder.release.stubs import write_student_tree

    root = tmp_path / "repo"
    (root / "autograder").mkdir(parents=True)
    text = (REPO_ROOT / "autograder" / "course.toml").read_text()
    (root / "autograder" / "course.toml").write_text(f'# late = {{ extensions = {{ "{EMAIL}" = 2027-02-08 }} }}\n'
                                                     + text)
    write_student_tree(tmp_path / "tree", {"__init__.py": ""}, root)
    assert personal_data_in(tmp_path / "tree") == []
