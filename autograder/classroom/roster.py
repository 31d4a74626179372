"""The instructor's roster: a CSV that says who each submission is, when it was handed in, and
how the learning platforms know the student.

Columns (a header row; names case-insensitive, any order, all optional but one of the first three):

* ``id``: the submission's id in the batch (the upload's folder name, or the export's
  submission number), ``sid`` (student id, also Canvas' "SIS User ID" and Moodle's "ID
  number"), ``email``: a row is the student whose submission matches any of them;
* ``name``, ``section``, ``login`` (Canvas' "SIS Login ID"), ``canvas_id`` (Canvas' own user
  "ID"): filled in where the uploads lack them;
* ``submitted``: the submission's time (overrides the export's or the file's), ``due``: the
  student's own due date (an extension), both ISO 8601 (``2026-10-01T23:59:00+02:00``).

``python -m autograder batch --roster FILE`` and ``python -m autograder export --roster FILE``
read it. A malformed file or time is a ``RosterError`` naming the file, the line and the column.
"""

import csv
from dataclasses import dataclass, field, replace
from datetime import datetime
from pathlib import Path

from autograder.classroom.intake import parse_time

KEYS = ("id", "sid", "email")
COLUMNS = (*KEYS, "name", "section", "login", "canvas_id", "submitted", "due")


class RosterError(ValueError):
    """The roster cannot be read; the message names the file, the line and what is wrong."""


@dataclass(frozen=True)
class Student:
    """One row of the roster."""

    id: str = ""
    sid: str = ""
    email: str = ""
    name: str = ""
    section: str = ""
    login: str = ""
    canvas_id: str = ""
    submitted: datetime | None = None
    due: datetime | None = None


@dataclass
class Roster:
    students: list = field(default_factory=list)

    def find(self, *keys) -> Student | None:
        """The row matching any of ``keys`` (an id, a sid, an e-mail; a group's "; "-joined
        values are tried one by one), the first in the file's order."""
        wanted = {part.strip().lower() for key in keys if key for part in str(key).split(";") if part.strip()}
        for student in self.students:
            if {k.lower() for k in (student.id, student.sid, student.email) if k} & wanted:
                return student
        return None


def read(path) -> Roster:
    """The roster at ``path`` (see the module docstring)."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8-sig")
    except (OSError, UnicodeDecodeError) as exc:
        raise RosterError(f"{path}: not readable ({exc})") from None
    reader = csv.DictReader(text.splitlines())
    header = {(name or "").strip().lower(): name for name in reader.fieldnames or []}
    if not set(KEYS) & set(header):
        raise RosterError(f"{path}: line 1: no column id, sid or email (the header has: "
                          f"{', '.join(reader.fieldnames or []) or 'nothing'})")
    unknown = sorted(set(header) - set(COLUMNS))
    if unknown:
        raise RosterError(f"{path}: line 1: unknown column(s) {', '.join(unknown)}; expected some of "
                          f"{', '.join(COLUMNS)}")
    roster = Roster()
    for line, row in enumerate(reader, 2):
        values = {column: (row.get(name) or "").strip() for column, name in header.items()}
        if not any(values.get(k) for k in KEYS):
            continue  # a blank line
        times = {}
        for column in ("submitted", "due"):
            try:
                times[column] = parse_time(values[column]) if values.get(column) else None
            except ValueError as exc:
                raise RosterError(f"{path}: line {line}: column {column}: {exc}") from None
        text = {k: values.get(k, "") for k in COLUMNS if k not in times}
        roster.students.append(Student(id=text["id"], sid=text["sid"], email=text["email"], name=text["name"],
                                       section=text["section"], login=text["login"], canvas_id=text["canvas_id"],
                                       submitted=times["submitted"], due=times["due"]))
    return roster


def apply(sub, student: Student | None):
    """``sub`` (:class:`autograder.classroom.intake.Submission`) with what the roster row adds:
    the name where the upload gave only a folder name, the sid and e-mail where it gave none, and
    the submission time the instructor gives."""
    if student is None:
        return sub
    changes: dict = {}
    if student.name and sub.name in ("", sub.path.name):
        changes["name"] = student.name
    if student.sid and not sub.sid:
        changes["sid"] = student.sid
    if student.email and not sub.email:
        changes["email"] = student.email
    if student.submitted is not None:
        changes.update(submitted=student.submitted, submitted_from="roster")
    return replace(sub, **changes)
