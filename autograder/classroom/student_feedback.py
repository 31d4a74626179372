"""The feedback returned to each student after offline grading: ``DIR/feedback/<id>/``.

For every record of ``DIR/results/`` (:mod:`autograder.classroom.gradebook`), after the overrides
and the late penalty, a folder named for the submission's id holds

* ``feedback.txt``: what Gradescope shows the student once the grades are published: the
  total, the submission's output (the late penalty and overrides first), then each test with its
  score, its maximum and its output; a test whose visibility is ``hidden`` is left out, as
  Gradescope never shows it;
* ``results.json``: the same as Gradescope's ``results.json`` (score, output, tests with name,
  score, max_score, output, visibility), without the instructor's ``extra_data``.

``DIR/feedback/index.csv`` has one row per folder: folder, name, sid, email, total, max (a group's
members "; "-joined), for sending each folder to its student(s). ``batch`` and ``merge`` write them
again on every run; a folder whose record is gone is removed.
"""

import csv
import io
import shutil
from pathlib import Path

from autograder.classroom import gradebook
from course.core import jsonio

FOLDER = "feedback"
FILES = ("feedback.txt", "results.json")
INDEX = "index.csv"
#: tests Gradescope never shows a student
NEVER_SHOWN = "hidden"


def shown(data: dict) -> dict:
    """The student's ``results.json`` of the record ``data``: no ``extra_data``, no test they never see."""
    tests = [{key: test[key] for key in ("name", "score", "max_score", "output", "visibility") if key in test}
             for test in data["tests"] if test.get("visibility") != NEVER_SHOWN]
    return {"score": data["score"], "execution_time": data.get("execution_time", 0.0),
            "output": data.get("output", ""), "tests": tests}


def text(data: dict) -> str:
    """``feedback.txt`` of the record ``data``: the total, the output, then each test shown."""
    extra = data["extra_data"]
    student = shown(data)
    maximum = sum(float(t["max_score"]) for t in data["tests"])
    who = extra.get("name") or extra["id"]
    title = f"{extra['assignment']}: " if extra.get("assignment") else ""
    lines = [f"{title}{who}", f"Total: {gradebook.number(student['score'])} / {gradebook.number(maximum)}", ""]
    if student["output"]:
        lines += [student["output"].rstrip(), ""]
    for test in student["tests"]:
        lines.append(f"{test['name']}: {gradebook.number(test['score'])} / {gradebook.number(test['max_score'])}")
        lines += ["    " + line if line else "" for line in str(test.get("output") or "").rstrip().splitlines()]
        lines.append("")
    return "\n".join(lines).rstrip() + "\n"


def write(out: Path) -> Path:
    """``out/feedback/``: a folder per record of ``out/results/`` and ``index.csv``; returns the folder."""
    out = Path(out)
    folder = out / FOLDER
    folder.mkdir(exist_ok=True)
    records = gradebook.load_all(out / "results")
    index = io.StringIO()
    writer = csv.writer(index, lineterminator="\n")
    writer.writerow(["folder", "name", "sid", "email", "total", "max"])
    names = set()
    for data in records:
        extra = data["extra_data"]
        name = str(extra["id"])
        names.add(name)
        (folder / name).mkdir(exist_ok=True)
        jsonio.write_text(folder / name / "feedback.txt", text(data))
        jsonio.write_json(folder / name / "results.json", shown(data), indent=2, newline=True)
        writer.writerow([*map(gradebook.cell, (name, extra.get("name", ""), extra.get("sid", ""),
                                               extra.get("email", ""))),
                         gradebook.number(data["score"]),
                         gradebook.number(sum(float(t["max_score"]) for t in data["tests"]))])
    for stale in folder.iterdir():  # a record gone (a roster student who has now submitted, under another id)
        if stale.is_dir() and stale.name not in names and {p.name for p in stale.iterdir()} <= set(FILES):
            shutil.rmtree(stale)
    jsonio.write_text(folder / INDEX, index.getvalue())
    return folder
