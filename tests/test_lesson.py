"""The lessons' cells: ``check(NAME)`` grades one exercise through the autograder (public checks,
sandboxed children) and prints its table; ``hint(NAME, LEVEL)`` prints one level."""

import pytest

from autograder.lesson import check, hint


def test_check_grades_the_reference_with_full_marks(capsys):
    summary = check("curve_model", impl="solutions")
    out = capsys.readouterr().out
    assert "Autograder: implementation solutions, public checks" in out and "J vs finite differences" in out
    assert summary.full and summary.score == summary.max_score > 0
    assert repr(summary).endswith("full marks on the public checks")


def test_check_names_the_todo_of_a_stub(capsys):
    summary = check("gauss_newton", impl="exercises")
    out = capsys.readouterr().out
    assert "TODO gauss_newton.normal_equations" in out
    assert summary.score == 0 and summary.not_implemented > 0 and "reach a TODO" in repr(summary)


def test_check_follows_course_impl(monkeypatch, capsys):
    monkeypatch.setenv("COURSE_IMPL", "solutions")
    assert check("damping.GavinType1").full
    assert "implementation solutions" in capsys.readouterr().out


def test_check_of_an_unknown_name_says_so():
    with pytest.raises(ValueError, match="no check or exercise"):
        check("no_such_exercise", impl="solutions")


def test_hint_prints_one_level(capsys):
    hint("dogleg_step", 2)
    out = capsys.readouterr().out
    assert "hint 2 of 3" in out and "Hint 1" not in out and "(more: python -m autograder hint dogleg_step 3)" in out
