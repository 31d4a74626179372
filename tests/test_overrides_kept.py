"""The instructor's overrides kept with the class (``autograder.classroom.overrides``): the graded folder
keeps them in ``overrides.csv``, a plain ``batch`` applies them, ``--overrides FILE`` adds or replaces
lines there, a check name that names nothing stops the run with the close names, a ``total`` line
overrides the whole assignment, and a check's line covers its hidden twin unless it says ``no``.

One grading run (the curve model's checks, public and hidden, of two students: the reference and a
residual with the wrong sign); every later run only applies overrides to the records kept.
"""

import csv
from datetime import timedelta
from pathlib import Path

import pytest

from autograder.classroom import batch, gradebook, overrides
from autograder.classroom.overrides import Override
from autograder.grade import HIDDEN_SUFFIX
from autograder.late import Lateness
from course.core.impl import REPO_ROOT

R = "curve_model.residuals_and_jacobian: r values"
HEADER = "id,check,points,reason,twin\n"


def test_merge_replaces_the_same_student_and_check_and_appends_the_rest():
    kept = [Override("ada", R, 1.0, "first"), Override("bob", R, 2.0, "bob's")]
    new = [Override("ADA", R, 3.0, "again"), Override("ada", "total", 9, "x")]
    merged, added, replaced = overrides.merge(kept, new)
    assert (added, replaced) == (1, 1)
    assert [(o.student, o.points, o.reason) for o in merged] == [("ADA", 3.0, "again"), ("bob", 2.0, "bob's"),
                                                                 ("ada", 9, "x")]


def test_a_check_s_override_covers_its_hidden_twin_unless_it_says_no():
    twin = R + HIDDEN_SUFFIX
    chosen = {o.check: o.points for o in overrides.for_student([Override("ada", R, 1.0, "r")], "ada")}
    assert chosen == {R: 1.0, twin: 1.0}
    alone = overrides.for_student([Override("ada", R, 1.0, "r", twin=False)], "ada")
    assert [o.check for o in alone] == [R]
    named = overrides.for_student([Override("ada", twin, 2.5, "own"), Override("ada", R, 1.0, "r")], "ada")
    assert {o.check: o.points for o in named} == {R: 1.0, twin: 2.5}  # a line naming the twin wins
    whole = overrides.for_student([Override("ada", "total", 7.0, "excused")], "ada", "9001")
    assert [o.check for o in whole] == ["total"]


def test_the_file_s_twin_column_and_a_name_that_matches_nothing(tmp_path):
    path = tmp_path / "overrides.csv"
    path.write_text(HEADER + f"ada,{R},1.23456,regraded,no\nbob,{R},1234.5678,ok,\n")
    first, second = overrides.read(path)
    assert (first.points, first.twin, second.twin) == (1.2346, False, True)  # on the grid of 0.0001
    overrides.write(tmp_path / "again.csv", [first, second])
    assert overrides.read(tmp_path / "again.csv") == [first, second] and second.points == 1234.5678
    path.write_text(HEADER + f"ada,{R},1,regraded,maybe\n")
    with pytest.raises(overrides.OverridesError, match="line 2: column twin: expected yes or no"):
        overrides.read(path)
    typo = [Override("ada", "curve_model.residuals_and_jacobian: r valeus", 1.0, "x", line=4)]
    with pytest.raises(overrides.OverridesError, match=f"{path}: line 4: column check: .* names no check of the "
                                                       f"course; close: {R}"):
        overrides.validate(typo, [R, R + HIDDEN_SUFFIX], path, "the course")


def test_a_total_override_is_the_grade_whatever_the_checks_and_the_penalty():
    tests = [{"name": n, "score": 0.0, "max_score": 3.0, "output": "wrong", "visibility": "visible",
              "extra_data": {"exercise": "e", "hidden": False, "status": "ok"}} for n in (R, R + HIDDEN_SUFFIX)]
    data = {"score": 0.0, "execution_time": 1.0, "output": "Total", "tests": tests,
            "extra_data": {"id": "1", "name": "Ada", "sid": "", "email": "", "status": "ok"}}
    given = [Override("1", "total", 5.5, "excused: illness"), Override("1", R, 3.0, "regraded")]
    late = Lateness(timedelta(days=1), 0.9, "1 day late")
    once = gradebook.adjust(data, overrides.for_student(given, "1"), late)
    assert once["score"] == 5.5 and once["extra_data"]["score_before_penalty"] == 6.0
    assert "5.5 points for the assignment instead of 5.4: excused: illness" in once["output"]
    assert [o["check"] for o in once["extra_data"]["overrides"]] == [R, R + HIDDEN_SUFFIX, "total"]
    assert gradebook.adjust(once, overrides.for_student(given, "1"), late) == once  # idempotent
    assert gradebook.adjust(once)["score"] == 0.0


def rows(out: Path) -> dict:
    with open(out / "grades.csv", newline="") as file:
        return {row["id"]: row for row in csv.DictReader(file)}


@pytest.fixture(scope="module")
def graded(tmp_path_factory):
    """The class graded once (``--overrides`` not given): ada the reference, bob a residual of the wrong sign."""
    root = tmp_path_factory.mktemp("class")
    for student in ("ada", "bob"):
        text = (REPO_ROOT / "solutions" / "curve_model.py").read_text()
        if student == "bob":
            text = text.replace("r = y_hat - y", "r = y - y_hat")
        (root / "uploads" / student).mkdir(parents=True)
        (root / "uploads" / student / "curve_model.py").write_text(text)
    out = root / "out"
    argv = [str(root / "uploads"), "--out", str(out), "--only", "curve_model", "--timeout", "10", "--no-report"]
    assert batch.main(argv) == 0
    return root, out, argv


def test_overrides_stay_with_the_class_through_plain_runs(graded, capsys):
    root, out, argv = graded
    judged = rows(out)
    assert float(judged["bob"][R]) == 0 and float(judged["bob"][R + HIDDEN_SUFFIX]) == 0
    (root / "regraded.csv").write_text(HEADER + f"bob,{R},3,the sign slip was the only one,\n")
    assert batch.main([*argv, "--overrides", str(root / "regraded.csv")]) == 0
    assert "overrides: 1 added and 0 replaced in" in capsys.readouterr().out
    assert [o.check for o in overrides.read(out / "overrides.csv")] == [R]
    kept = rows(out)
    assert float(kept["bob"][R]) == 3 and float(kept["bob"][R + HIDDEN_SUFFIX]) == 3  # the twin too
    assert float(kept["bob"]["total"]) == float(judged["bob"]["total"]) + 6

    assert batch.main(argv) == 0  # a plain run: the override stays
    assert rows(out)["bob"]["total"] == kept["bob"]["total"] and "sign slip" in rows(out)["bob"]["overrides"]

    (root / "more.csv").write_text(HEADER + f"bob,{R},1.5,half: the sign is the point,no\n"
                                            "ada,total,12,\"oral exam, whole assignment\",\n")
    assert batch.main([*argv, "--overrides", str(root / "more.csv")]) == 0
    assert "overrides: 1 added and 1 replaced" in capsys.readouterr().out
    after = rows(out)
    assert float(after["bob"][R]) == 1.5 and float(after["bob"][R + HIDDEN_SUFFIX]) == 0  # twin: no
    assert after["ada"]["total"] == "12" and after["ada"]["before_penalty"] == judged["ada"]["total"]
    assert "oral exam" in gradebook.load(out / "results" / "ada.json")["output"]
    assert batch.main(argv) == 0 and rows(out) == after


def test_a_check_name_that_matches_nothing_stops_the_run_with_the_close_names(graded, capsys):
    root, out, argv = graded
    before = (out / "overrides.csv").read_text() if (out / "overrides.csv").exists() else None
    (root / "typo.csv").write_text(HEADER + "bob,curve_model.residuals_and_jacobian: r valeus,3,typo,\n")
    with pytest.raises(SystemExit) as info:
        batch.main([*argv, "--overrides", str(root / "typo.csv")])
    assert info.value.code == 2
    err = capsys.readouterr().err
    assert "typo.csv: line 2: column check: 'curve_model.residuals_and_jacobian: r valeus' names no check" in err
    assert f"close: {R}" in err
    assert ((out / "overrides.csv").read_text() if before is not None else None) == before  # nothing stored


def test_merge_of_shards_joins_the_overrides_they_keep(tmp_path):
    from autograder.classroom import merge

    for part, line in (("p1", f"ada,{R},1,first\n"), ("p2", f"bob,{R},2,second\nada,{R},1.5,later\n")):
        (tmp_path / part / "results").mkdir(parents=True)
        (tmp_path / part / "overrides.csv").write_text(HEADER + line)
    merge.merge([tmp_path / "p1", tmp_path / "p2"], tmp_path / "out")
    kept = overrides.read(tmp_path / "out" / "overrides.csv")
    assert [(o.student, o.points) for o in kept] == [("ada", 1.5), ("bob", 2.0)]
