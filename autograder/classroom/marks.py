"""The instructor's marks of the written answers, one CSV for the class, and their place in the records.

``DIR/written.csv`` (``DIR`` the ``--out`` folder of ``batch``; ``python -m autograder.classroom.written
merge --marks FILE`` copies FILE there), a header row and one mark a line::

    id,name,question,points,items,comment
    ada,Ada,ch1-q1,,linearised;trust-region,
    bob,Bob,ch1-q1,1.5,,"the step is right, the reason is not"

``id`` is the submission's id, the student's sid or e-mail (as in ``overrides.csv``); ``name`` is for
the reader and not read; ``question`` a question id of the assignment (``ch1-q1``); ``points`` the
points given (0 to the question's maximum), or ``items`` the ``;``-separated ids of the rubric items
the answer earned (:mod:`autograder.classroom.rubric`), their points summed; both given must agree.
A row with neither is not marked yet. ``comment`` goes into the student's feedback. A mistake (an
unknown student or question, points above the maximum, an unknown item, a question marked twice) is
a :class:`MarksError` naming the file, the line and the column.

In a record (``results/<id>.json``) each written question is one more test, ``written: <id>``, its
``extra_data`` with ``exercise = "written"``, ``marked`` and the ``items`` earned: ``grades.csv`` gets a
``written`` column (their sum) and a column per question, and the record's total, ``export``'s Canvas
and Moodle files and the report count them like a check (the late penalty applies to the whole).
:func:`keep` carries them over when ``batch`` grades a student again; :func:`readjust` recomputes a
record's total after new marks.
"""

import csv
import math
from dataclasses import dataclass
from datetime import datetime, timedelta
from pathlib import Path

from autograder.classroom import gradebook
from autograder.classroom.overrides import Override
from autograder.course_config import did_you_mean
from autograder.late import Lateness

COLUMNS = ("id", "name", "question", "points", "items", "comment")
REQUIRED = ("id", "question")
EXERCISE = "written"
PREFIX = "written: "
FILE = "written.csv"


class MarksError(ValueError):
    """The marks file is wrong; the message names the file, the line and the column."""


@dataclass(frozen=True)
class Mark:
    student: str
    question: str
    points: float | None  # None: not marked yet
    items: tuple = ()
    comment: str = ""
    line: int = 0


def keys_of(record: dict) -> set:
    """The names of a record's student(s): id, sids and e-mails (a group's "; "-joined), lower case."""
    extra = record["extra_data"]
    return {part.strip().lower() for key in ("id", "sid", "email") for part in str(extra.get(key) or "").split(";")
            if part.strip()}


def read(path, rubrics: dict, records) -> list:
    """The marks in ``path`` checked against ``rubrics`` (``{question id: Rubric}``) and the class's
    ``records`` (every mark names a graded student)."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8-sig")
    except (OSError, UnicodeDecodeError) as exc:
        raise MarksError(f"{path}: not readable ({exc})") from None
    reader = csv.DictReader(text.splitlines())
    header = {(name or "").strip().lower(): name for name in reader.fieldnames or []}
    unknown = [name for name in header if name not in COLUMNS]
    if unknown:
        raise MarksError(f"{path}: line 1: unknown column {unknown[0]!r}{did_you_mean(unknown[0], COLUMNS, n=3)}; "
                         f"expected {','.join(COLUMNS)}")
    missing = [c for c in REQUIRED if c not in header] or ([] if {"points", "items"} & set(header) else ["points"])
    if missing:
        raise MarksError(f"{path}: line 1: missing column(s) {', '.join(missing)}; expected {','.join(COLUMNS)}")
    students: dict = {}
    for record in records:
        for key in keys_of(record):
            students[key] = record["extra_data"]["id"]
    found: list = []
    seen: dict = {}
    for line, row in enumerate(reader, 2):
        values = {c: (row.get(header[c]) or "").strip() if c in header else "" for c in COLUMNS}
        if not any(values.values()):
            continue
        where = f"{path}: line {line}"
        for column in REQUIRED:
            if not values[column]:
                raise MarksError(f"{where}: column {column} is empty")
        student = students.get(values["id"].lower())
        if student is None:
            raise MarksError(f"{where}: column id: {values['id']!r} is no graded student (no record in results/ has "
                             f"this id, sid or e-mail){did_you_mean(values['id'].lower(), students, n=3)}")
        qid = values["question"]
        rubric = rubrics.get(qid)
        if rubric is None:
            raise MarksError(f"{where}: column question: {qid!r} is no written question of this assignment"
                             f"{did_you_mean(qid, rubrics, n=3)}; its questions are {', '.join(rubrics)}")
        if (student, qid) in seen:
            raise MarksError(f"{where}: column question: {qid} of {values['id']} is marked already on line "
                             f"{seen[(student, qid)]}")
        seen[(student, qid)] = line
        items = tuple(i.strip() for i in values["items"].split(";") if i.strip())
        for item in items:
            if rubric.item(item) is None:
                ids = [i.id for i in rubric.items]
                near = did_you_mean(item, ids, n=3)
                raise MarksError(f"{where}: column items: {item!r} is no rubric item of {qid}{near}; "
                                 f"its items are {', '.join(ids) or 'none (give points)'}")
        if len(set(items)) != len(items):
            raise MarksError(f"{where}: column items: an item is given twice ({values['items']})")
        from_items = sum(item.points for item in rubric.items if item.id in items)
        points: float | None = None
        if values["points"]:
            try:
                points = float(values["points"])
            except ValueError:
                points = math.nan
            if not math.isfinite(points) or points < 0:
                raise MarksError(f"{where}: column points: expected a number >= 0, got {values['points']!r}")
            if points > rubric.points + 1e-9:
                raise MarksError(f"{where}: column points: {points:g} is above the maximum of {qid}, "
                                 f"{rubric.points:g}")
            if items and abs(points - from_items) > 1e-9:
                raise MarksError(f"{where}: column points: {points:g}, but the items {';'.join(items)} are worth "
                                 f"{from_items:g}")
        elif items:
            points = from_items
        found.append(Mark(student, qid, points, items, values["comment"], line))
    return found


def tests(record: dict, rubrics: dict, marks) -> list:
    """The written tests of ``record``'s student from ``marks`` (every question, 0 where not marked)."""
    mine = {m.question: m for m in marks if m.student == record["extra_data"]["id"]}
    out = []
    for qid, rubric in rubrics.items():
        mark = mine.get(qid)
        if mark is None or mark.points is None:
            score, items, marked = 0.0, (), False
            lines = [f"Written answer {qid}: not marked yet (0 of {gradebook.number(rubric.points)} points)."]
        else:
            score, items, marked = float(mark.points), mark.items, True
            lines = [f"Written answer {qid}: {gradebook.number(score)} of {gradebook.number(rubric.points)} points."]
            if items:
                lines += [f"{'+' if item.id in items else '-'} {gradebook.number(item.points)} {item.id}: {item.text}"
                          for item in rubric.items]
            if mark.comment:
                lines.append(f"Comment: {mark.comment}")
        out.append({"name": PREFIX + qid, "score": score, "max_score": float(rubric.points),
                    "output": "\n".join(lines), "visibility": "visible",
                    "extra_data": {"exercise": EXERCISE, "hidden": False, "status": "ok", "marked": marked,
                                   "items": list(items)}})
    return out


def is_written(test: dict) -> bool:
    return test.get("extra_data", {}).get("exercise") == EXERCISE and str(test.get("name", "")).startswith(PREFIX)


def with_marks(record: dict, written: list) -> dict:
    """``record`` with its written tests replaced by ``written``."""
    return {**record, "tests": [t for t in record["tests"] if not is_written(t)] + written}


def keep(record: dict, previous: Path) -> dict:
    """``record`` (a new grading) with the written tests of the record it replaces at ``previous``."""
    try:
        old = gradebook.load(previous)
    except ValueError:  # none yet, or unreadable: nothing to keep
        return record
    return with_marks(record, [t for t in old["tests"] if is_written(t)])


def readjust(record: dict) -> dict:
    """``record``'s total after its tests changed: :func:`autograder.classroom.gradebook.adjust` again,
    with the overrides and the lateness the record holds."""
    extra = record["extra_data"]
    student = str(extra["id"])
    found = [Override(student, o["check"], float(o["points"]), o["reason"]) for o in extra.get("overrides") or []]
    late = extra.get("late")
    lateness = None if not late else Lateness(timedelta(days=float(late["days"])), float(late["fraction"]),
                                              late.get("note", ""))
    due = datetime.fromisoformat(late["due"]) if late and late.get("due") else None
    submitted = datetime.fromisoformat(extra["submitted_at"]) if extra.get("submitted_at") else None
    return gradebook.adjust(record, found, lateness, due=due, submitted=submitted,
                            source=extra.get("submitted_from", ""))


def template(records, questions) -> str:
    """A marks file to fill: a row per student and question, points and items empty."""
    import io

    out = io.StringIO()
    writer = csv.writer(out, lineterminator="\n")
    writer.writerow(COLUMNS)
    for record in records:
        extra = record["extra_data"]
        for q in questions:
            writer.writerow([gradebook.cell(extra["id"]), gradebook.cell(extra.get("name", "")), q.id, "", "", ""])
    return out.getvalue()
