"""The gradebook: one student's graded record, ``results/<id>.json``, and the class table, ``grades.csv``.

The record is Gradescope's ``results.json`` (score, execution_time, output, tests[]) with
``extra_data`` at the top (id, name, sid, email, status, seconds, what was graded, the
set and ``--only`` it was graded with) and in each test (exercise, hidden, status, the
known mistake it matched). ``status`` of a submission: ``ok``, ``timed out`` (a check ran
out of time), ``crashed`` (a child died), ``no files`` (no exercise file in the upload) or ``no
submission`` (a roster student who sent nothing: every check 0, :func:`no_submission`). Where a
roster names the student, ``extra_data["roster"]`` holds their rows (name, sid, email, login,
canvas_id, section; one per member of a group): ``export`` takes the platforms' ids from there.

After grading, :func:`adjust` applies the instructor's overrides (a check's points, with a
reason, or the total) and the late penalty to a record, from the scores the judge gave (kept in the record), so
that it can run again on every batch run: an override survives a regrade, and a changed due date
or policy changes the penalty without grading anyone again. ``extra_data`` then also holds
``graded_score`` (the judge's total), ``score_before_penalty`` (with the overrides), ``late``
(submission time, due date, how late, the fraction kept, the penalty in points) and ``overrides``.

``grades.csv``: one row per record (:func:`row`); columns id, name, sid, email, status, total (after overrides
and penalty), max, before_penalty, penalty, submitted, days_late, assignment, overrides, one per
exercise, one per check (in the registry's order, public then hidden). The marks of the written
answers (:mod:`autograder.classroom.marks`) are tests of exercise ``written``: a column with their
sum, one per question, and in the total. A text cell a spreadsheet
would run as a formula is written as text (:func:`cell`).
"""

import csv
import io
import json
from pathlib import Path

from autograder import point_grid, report
from autograder.late import ASSIGNMENT_DUE
from course.core import jsonio

STATUSES = ("ok", "refused imports", "timed out", "crashed", "no files", "no submission")
NO_SUBMISSION = "no submission"
#: what a record keeps of each roster row of its student(s)
ROSTER_FIELDS = ("name", "sid", "email", "login", "canvas_id", "section")
FIXED_COLUMNS = ("id", "name", "sid", "email", "status", "total", "max", "before_penalty", "penalty", "submitted",
                 "days_late", "assignment", "overrides")
#: a cell starting with one of these is a formula to a spreadsheet (=1+1, +cmd, -2+3, @SUM, a tab, a CR)
FORMULA_START = ("=", "+", "-", "@", "\t", "\r")


def cell(value) -> str:
    """``value`` as a CSV cell a spreadsheet shows as text: one that would start a formula (a name
    or a folder name from an upload: ``=HYPERLINK(...)``) gets a leading single quote, the usual
    defence against CSV injection. Numbers we write are formatted by :func:`number`, not here."""
    text = "" if value is None else str(value)
    return "'" + text if text.startswith(FORMULA_START) else text


def status_of(results) -> str:
    """The submission's status from its check results (:class:`autograder.grade.CheckResult`): a file
    refused for its imports (:mod:`autograder.allowed_imports`) is "refused imports", for the instructor
    to see in ``grades.csv`` beside the 0 of its checks."""
    kinds = {r.status for r in results}
    if "timeout" in kinds or any(r.status == "not run" and "timed out" in r.message for r in results):
        return "timed out"
    if "crashed" in kinds:
        return "crashed"
    return "refused imports" if "refused" in kinds else "ok"


def record(sub, results, seconds: float, graded: str, grading: dict) -> dict:
    """The record of ``sub`` (:class:`autograder.classroom.intake.Submission`) graded to
    ``results``; ``grading``: how (``{"set": ..., "only": [...]}``)."""
    data = report.gradescope(results, seconds)
    for test, result in zip(data["tests"], results):
        extra = {"exercise": result.exercise, "hidden": result.hidden, "status": result.status}
        if result.mistake:
            extra["mistake"] = result.mistake
        test["extra_data"] = extra
    data["output"] = graded + "\n\n" + data["output"]
    data["extra_data"] = {"id": sub.id, "name": sub.name, "sid": sub.sid, "email": sub.email,
                          "status": status_of(results), "seconds": round(seconds, 3), "graded": graded, **grading}
    return data


def no_files(sub, message: str, tasks, grading: dict) -> dict:
    """The record of an upload with no exercise file: every check 0, and why.
    ``tasks``: ``(name, exercise, points, hidden)`` of each check graded for the others."""
    tests = [{"name": name, "score": 0.0, "max_score": float(points), "output": message,
              "visibility": "after_published" if hidden else "visible",
              "extra_data": {"exercise": exercise, "hidden": hidden, "status": "not run"}}
             for name, exercise, points, hidden in tasks]
    return {"score": 0.0, "execution_time": 0.0, "output": message, "tests": tests,
            "extra_data": {"id": sub.id, "name": sub.name, "sid": sub.sid, "email": sub.email, "status": "no files",
                           "seconds": 0.0, "graded": message, **grading}}


def no_submission(sub, tasks, grading: dict) -> dict:
    """The record of a roster student who sent nothing (``sub``: a
    :class:`autograder.classroom.intake.Submission` made from the roster row): every check 0."""
    data = no_files(sub, "No submission.", tasks, grading)
    data["extra_data"]["status"] = NO_SUBMISSION
    return data


def with_roster(data: dict, students) -> dict:
    """``data`` with ``extra_data["roster"]``: the rows of ``students``
    (:class:`autograder.classroom.roster.Student`) that name its submitter(s); none removes it."""
    data = dict(data, extra_data=dict(data["extra_data"]))
    rows = [{key: getattr(s, key) for key in ROSTER_FIELDS} for s in students]
    if rows:
        data["extra_data"]["roster"] = rows
    else:
        data["extra_data"].pop("roster", None)
    return data


def _total(tests) -> float:
    return point_grid.total(t["score"] for t in tests)


def adjust(data: dict, overrides=(), lateness=None, due=None, submitted=None, source: str = "") -> dict:
    """``data`` (a record) with ``overrides`` and the late penalty applied, from the judge's scores.

    ``overrides``: :class:`autograder.classroom.overrides.Override` of this student (a check's
    points and the reason); ``lateness``: :class:`autograder.late.Lateness` or None (no policy);
    ``due``, ``submitted``: datetimes or None; ``source``: where the submission time comes from.
    Idempotent: the judge's score and output of every check are kept in the record
    (``graded_score``, ``graded_output``) and everything is derived from them again."""
    data = json.loads(json.dumps(data))  # a copy
    extra = data["extra_data"]
    extra.setdefault("graded_output", data.get("output", ""))
    notes = []
    by_name = {t["name"]: t for t in data["tests"]}
    for test in data["tests"]:
        test_extra = test.setdefault("extra_data", {})
        if "graded_score" in test_extra:
            test["score"] = test_extra.pop("graded_score")
            test["output"] = test_extra.pop("graded_output", test.get("output", ""))
        test_extra.pop("override", None)
    applied = []
    whole = [item for item in overrides if item.check == "total"]  # the assignment's total (overrides.TOTAL)
    for item in overrides:
        test = by_name.get(item.check) if item.check != "total" else None
        if test is None:
            continue
        test_extra = test["extra_data"]
        test_extra["graded_score"] = test["score"]
        test_extra["graded_output"] = test.get("output", "")
        test_extra["override"] = {"points": item.points, "reason": item.reason}
        line = (f"Override by the instructor: {number(item.points)} points instead of "
                f"{number(test['score'])}: {item.reason}")
        test["output"] = line + ("\n\n" + test["output"] if test.get("output") else "")
        test["score"] = point_grid.on_grid(item.points)
        applied.append({"check": item.check, "points": item.points, "graded": test_extra["graded_score"],
                        "reason": item.reason})
        notes.append(f"{item.check}: {line}")
    extra["graded_score"] = _total([{"score": t["extra_data"].get("graded_score", t["score"])}
                                    for t in data["tests"]])
    before = _total(data["tests"])
    extra["score_before_penalty"] = before
    extra["overrides"] = applied
    extra["submitted_at"] = submitted.isoformat() if submitted is not None else None
    extra["submitted_from"] = source if submitted is not None else ""
    score = before
    if lateness is not None:
        score = point_grid.scaled(before, lateness.fraction)
        due_applied = lateness.due if getattr(lateness, "due", None) is not None else due
        extended = getattr(lateness, "basis", "") not in ("", ASSIGNMENT_DUE)
        extra["late"] = {"due": due_applied.isoformat() if due_applied is not None else None,
                         "basis": getattr(lateness, "basis", ""),
                         "days": round(lateness.late.total_seconds() / 86400.0, 4),
                         "fraction": lateness.fraction, "penalty": point_grid.total((before, -score)),
                         "note": lateness.note}
        whose = f" ({lateness.basis})" if extended else ""
        if lateness.late.total_seconds() > 0:
            notes.insert(0, f"Late: submitted {extra['submitted_at']}, due {extra['late']['due']}{whose}: "
                            f"{lateness.note}; {number(before)} points before the penalty, {number(score)} after.")
        elif extended:
            notes.insert(0, f"Submitted: on time (submitted {extra['submitted_at']}, "
                            f"due {extra['late']['due']}{whose}).")
    else:
        extra["late"] = None
    for item in whole[-1:]:  # the instructor's total replaces what the checks and the penalty give
        line = f"Override by the instructor: {number(item.points)} points for the assignment instead of {number(score)}"
        notes.append(f"{line}: {item.reason}")
        applied.append({"check": item.check, "points": item.points, "graded": score, "reason": item.reason})
        score = point_grid.on_grid(item.points)
    data["score"] = score
    extra["adjustments"] = notes
    data["output"] = "\n".join(notes) + ("\n\n" if notes else "") + extra["graded_output"]
    return data


def table_with_adjustments(text: str, data: dict) -> str:
    """The terminal table ``results/<id>.txt`` with the record's late penalty and overrides on top
    (those of an earlier run taken off: the table starts at its ``Autograder:`` line)."""
    lines = text.splitlines()
    start = next((i for i, line in enumerate(lines) if line.startswith("Autograder: ")), 0)
    notes = list(data["extra_data"].get("adjustments") or [])
    if notes:
        notes.append(f"Total after the overrides and the penalty: {number(data['score'])}")
    return "\n".join([*notes, *([""] if notes else []), *lines[start:]]) + "\n"


def save(results_dir: Path, data: dict) -> Path:
    """Write the record ``data`` to ``results_dir/<id>.json`` atomically."""
    return jsonio.write_json(Path(results_dir) / f"{data['extra_data']['id']}.json", data, indent=2, newline=True)


def load(path: Path) -> dict:
    """A record, checked for the fields the table needs; ``ValueError`` naming the file."""
    try:
        data = json.loads(Path(path).read_text(encoding="utf-8"))
    except (OSError, ValueError) as exc:
        raise ValueError(f"{path}: not a readable record ({exc})") from None
    if not isinstance(data, dict) or not isinstance(data.get("tests"), list) or "id" not in data.get("extra_data", {}):
        raise ValueError(f"{path}: not a record of `python -m autograder batch` (no tests or extra_data.id)")
    return data


def load_all(folder: Path) -> list:
    """Every record in ``folder`` (``results/``), by id."""
    return sorted((load(path) for path in Path(folder).glob("*.json")), key=lambda d: d["extra_data"]["id"])


def columns(records) -> tuple:
    """``(exercises, checks)``: the per-exercise and per-check columns of ``records``, in order."""
    checks: list = []
    exercises: list = []
    for data in records:
        for test in data["tests"]:
            if test["name"] not in checks:
                checks.append(test["name"])
            exercise = test.get("extra_data", {}).get("exercise", "")
            if exercise and exercise not in exercises:
                exercises.append(exercise)
    return exercises, checks


def header(exercises, checks) -> list:
    """``grades.csv``'s first row."""
    return [*FIXED_COLUMNS, *map(cell, exercises), *map(cell, checks)]


def row(data: dict, exercises, checks) -> list:
    """The row of ``grades.csv`` of the record ``data`` (the cells of :func:`header`)."""
    extra = data["extra_data"]
    late = extra.get("late") or {}
    before = extra.get("score_before_penalty", data["score"])
    scores = {test["name"]: test["score"] for test in data["tests"]}
    by_exercise = {e: point_grid.total(t["score"] for t in data["tests"]
                                       if t.get("extra_data", {}).get("exercise", "") == e) for e in exercises}
    maximum = point_grid.total(test["max_score"] for test in data["tests"])
    overridden = "; ".join(f"{o['check']}: {number(o['points'])} ({o['reason']})"
                           for o in extra.get("overrides") or [])
    return [*map(cell, (extra["id"], extra.get("name", ""), extra.get("sid", ""), extra.get("email", ""),
                        extra.get("status", ""))), number(data["score"]), number(maximum),
            number(before), number(late.get("penalty", 0.0)), cell(extra.get("submitted_at") or ""),
            number(late.get("days", "")), cell(extra.get("assignment") or ""), cell(overridden),
            *(number(by_exercise[e]) for e in exercises), *(number(scores.get(c, "")) for c in checks)]


def table(records) -> str:
    """``grades.csv``'s text: :func:`header`, then a :func:`row` per record."""
    exercises, checks = columns(records)
    out = io.StringIO()
    writer = csv.writer(out, lineterminator="\n")
    writer.writerow(header(exercises, checks))
    for data in records:
        writer.writerow(row(data, exercises, checks))
    return out.getvalue()


def number(x) -> str:
    if x == "" or x is None:
        return ""
    return f"{float(x):.4f}".rstrip("0").rstrip(".")


def write_table(out: Path) -> Path:
    """``out/grades.csv`` from ``out/results/*.json``, written atomically."""
    return jsonio.write_text(Path(out) / "grades.csv", table(load_all(Path(out) / "results")))
