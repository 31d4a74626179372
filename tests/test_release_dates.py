"""Release dates: ``release_after`` per assignment (given, or when the previous assignment closes),
and a student tree that hands out solved code refused before it without ``--force``, naming the
reference files it hands out."""

from datetime import datetime, timedelta, timezone

import pytest

from autograder.course_config import ConfigError, load, parse
from autograder.release.release_date import early_release, handed_out
from course.app.cli import main as cli
from course.core.impl import REPO_ROOT

COURSE = load()
CET = timezone(timedelta(hours=1))


def test_the_default_is_when_the_previous_assignment_closes_extensions_included():
    data = {"defaults": {"late": {"per_day": 0.1, "cutoff_days": 2}},
            "assignments": {
                "ch1": {"exercises": ["curve_model", "gauss_newton"], "due": "2027-02-05T23:59:00+01:00",
                        "late": {"per_day": 0.1, "cutoff_days": 2,
                                 "extensions": {"a@b.c": "2027-02-09T23:59:00+01:00"}}},
                "ch2": {"exercises": ["damping"], "due": "2027-02-20T23:59:00+01:00"},
                "ch3": {"exercises": ["dogleg"], "solved": ["curve_model", "gauss_newton", "pose_graph_edge",
                                                            "pose_graph_assembly", "sparse_solve", "pose_graph_fast"],
                        "release_after": "2027-02-15T08:00:00+01:00"}}}
    course = parse(data)
    ch1, ch2, ch3 = (course.assignment(n) for n in ("ch1", "ch2", "ch3"))
    assert ch1.release_after is None and ch1.closes == datetime(2027, 2, 11, 23, 59, tzinfo=CET)
    assert ch2.release_after == ch1.closes and ch2.release_basis == "when ch1 closes"
    assert ch3.release_after == datetime(2027, 2, 15, 8, 0, tzinfo=CET) and ch3.release_basis == "set"
    data["assignments"]["ch3"]["release_after"] = "soon"
    with pytest.raises(ConfigError, match="assignments.ch3.release_after: expected an ISO 8601"):
        parse(data)


def test_a_tree_with_solved_code_is_too_early_before_release_after_and_says_what_it_hands_out():
    ch3 = COURSE.assignment("ch3")
    before, after = ch3.release_after - timedelta(minutes=1), ch3.release_after
    why = early_release(COURSE, ch3, before)
    assert why.startswith(f"assignment ch3 is released after {ch3.release_after.isoformat()} (when ch2 closes)")
    assert "exercises/curve_model.py (reference code of ch1)" in why
    assert "exercises/sparse_solve.py (reference code of ch2)" in why
    assert len(handed_out(COURSE, ch3)) == len(ch3.solved)
    assert early_release(COURSE, ch3, after) == ""
    ch2 = COURSE.assignment("ch2")  # hands out nothing solved: no date holds it back
    assert not ch2.solved and early_release(COURSE, ch2, ch2.release_after - timedelta(days=1)) == ""


def far_release(tmp_path):
    """The shipped configuration with ch3 released after 2099."""
    text = (REPO_ROOT / "autograder" / "course.toml").read_text()
    text = text.replace("due = 2027-03-12T23:59:00+01:00\n",
                        "due = 2027-03-12T23:59:00+01:00\nrelease_after = 2099-01-01T00:00:00+00:00\n", 1)
    path = tmp_path / "course.toml"
    path.write_text(text)
    return str(path)


def test_release_refuses_before_release_after_without_force(tmp_path, capsys):
    target = tmp_path / "ch3-tree"
    assert cli(["release", "--assignment", "ch3", "--student", str(target), "--config", far_release(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert "error: assignment ch3 is released after 2099-01-01T00:00:00+00:00" in err and "give --force" in err
    assert "exercises/dogleg.py" not in err and "exercises/pose_graph_edge.py (reference code of ch2)" in err
    assert not target.exists()


def test_release_with_force_writes_the_tree_and_says_what_it_hands_out(tmp_path, capsys, monkeypatch):
    from autograder import oracle
    from autograder.release import stubs

    monkeypatch.setattr(oracle, "release_expected", lambda check=False: [])  # this tree's data is not at stake
    monkeypatch.setattr(stubs, "release", lambda **kwargs: [])
    target = tmp_path / "ch3-tree"
    assert cli(["release", "--assignment", "ch3", "--student", str(target), "--force",
                "--config", far_release(tmp_path)]) == 0
    captured = capsys.readouterr()
    assert "warning: assignment ch3 is released after" in captured.err and "(--force)" in captured.err
    assert "wrote the student tree of assignment ch3" in captured.out
    assert "raise NotImplementedError" not in (target / "exercises" / "curve_model.py").read_text()
