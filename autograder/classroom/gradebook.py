"""The gradebook: one student's graded record, ``results/<id>.json``, and the class table, ``grades.csv``.

The record is Gradescope's ``results.json`` (score, execution_time, output, tests[]) with
``extra_data`` at the top (id, name, sid, email, status, seconds, what was graded, the
set and ``--only`` it was graded with) and in each test (exercise, hidden, status, the
known mistake it matched). ``status`` of a submission: ``ok``, ``timed out`` (a check ran
out of time), ``crashed`` (a child died) or ``no files`` (no exercise file in the upload).

``grades.csv``: one row per record; columns id, name, sid, email, status, total, max, one
per exercise, one per check (in the registry's order, public then hidden).
"""

import csv
import io
import json
from pathlib import Path

from autograder import report
from course.core import jsonio

STATUSES = ("ok", "timed out", "crashed", "no files")
FIXED_COLUMNS = ("id", "name", "sid", "email", "status", "total", "max")


def status_of(results) -> str:
    """The submission's status from its check results (:class:`autograder.grade.CheckResult`)."""
    kinds = {r.status for r in results}
    if "timeout" in kinds or any(r.status == "not run" and "timed out" in r.message for r in results):
        return "timed out"
    return "crashed" if "crashed" in kinds else "ok"


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


def table(records) -> str:
    """``grades.csv``'s text."""
    checks: list = []
    exercises: list = []
    for data in records:
        for test in data["tests"]:
            if test["name"] not in checks:
                checks.append(test["name"])
            exercise = test.get("extra_data", {}).get("exercise", "")
            if exercise and exercise not in exercises:
                exercises.append(exercise)
    out = io.StringIO()
    writer = csv.writer(out, lineterminator="\n")
    writer.writerow([*FIXED_COLUMNS, *exercises, *checks])
    for data in records:
        extra = data["extra_data"]
        scores = {test["name"]: test["score"] for test in data["tests"]}
        by_exercise = dict.fromkeys(exercises, 0.0)
        for test in data["tests"]:
            exercise = test.get("extra_data", {}).get("exercise", "")
            if exercise:
                by_exercise[exercise] += test["score"]
        maximum = sum(test["max_score"] for test in data["tests"])
        writer.writerow([extra["id"], extra.get("name", ""), extra.get("sid", ""), extra.get("email", ""),
                         extra.get("status", ""), _number(data["score"]), _number(maximum),
                         *(_number(by_exercise[e]) for e in exercises), *(_number(scores.get(c, "")) for c in checks)])
    return out.getvalue()


def _number(x) -> str:
    if x == "":
        return ""
    return f"{float(x):.4f}".rstrip("0").rstrip(".")


def write_table(out: Path) -> Path:
    """``out/grades.csv`` from ``out/results/*.json``, written atomically."""
    return jsonio.write_text(Path(out) / "grades.csv", table(load_all(Path(out) / "results")))
