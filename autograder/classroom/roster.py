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

Two platforms' own files are rosters as they are (recognised by their header):

* **Canvas' gradebook export** (Grades, Export): ``Student`` (the name, "Last, First"), ``ID``
  (Canvas' user id), ``SIS User ID`` (the sid), ``SIS Login ID`` (the login), ``Section``, then
  one column per Canvas assignment (``Homework 1 (4521)``: its name and Canvas' id, kept in
  :attr:`Roster.assignments`); the ``Points Possible`` row and Canvas' test student
  (``Student, Test``) are not students.
* **Gradescope's grades export** (an assignment's or the course's "Download Grades"): ``First
  Name`` and ``Last Name`` (or ``Name``), ``SID``, ``Email``, ``Sections``; every student of the
  course is a row, with or without a submission.

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
#: Canvas' gradebook export: its identity columns (the rest are assignments and totals)
CANVAS_IDENTITY = {"Student": "name", "ID": "canvas_id", "SIS User ID": "sid", "SIS Login ID": "login",
                   "Section": "section", "Integration ID": ""}
#: Canvas' columns after the assignments that are not assignments (scores it computes)
CANVAS_COMPUTED = ("Current Points", "Final Points", "Current Score", "Final Score", "Unposted Current Score",
                   "Unposted Final Score", "Current Grade", "Final Grade", "Unposted Current Grade",
                   "Unposted Final Grade", "Override Score", "Override Grade")
CANVAS_TEST_STUDENT = "Student, Test"
#: Gradescope's grades export: its columns a roster needs
GRADESCOPE_IDENTITY = {"sid": "sid", "email": "email", "sections": "section", "section": "section"}


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

    def keys(self) -> set:
        """What names this student in an upload or on the command line, lower case: the id, sid,
        e-mail and login (Canvas' own id is not matched: an export's submission numbers could
        take it)."""
        return {k.lower() for k in (self.id, self.sid, self.email, self.login) if k}

    def key(self) -> str:
        """The student's id in the gradebook when they have no submission: the first of id, sid,
        login, e-mail and Canvas id."""
        return next(k for k in (self.id, self.sid, self.login, self.email, self.canvas_id) if k)


def student(values: dict) -> Student:
    """The :class:`Student` of the text fields ``values`` (name, sid, email, login, canvas_id, section, id)."""
    text = {key: str(values.get(key) or "") for key in ("id", "sid", "email", "name", "section", "login", "canvas_id")}
    return Student(id=text["id"], sid=text["sid"], email=text["email"], name=text["name"], section=text["section"],
                   login=text["login"], canvas_id=text["canvas_id"])


def _wanted(keys) -> set:
    return {part.strip().lower() for key in keys if key for part in str(key).split(";") if part.strip()}


@dataclass
class Roster:
    students: list = field(default_factory=list)
    #: the learning platform's assignment columns in the file (Canvas' export: ``Homework 1 (4521)``)
    assignments: list = field(default_factory=list)

    def find(self, *keys) -> Student | None:
        """The row matching any of ``keys`` (an id, a sid, an e-mail, a login; a group's
        "; "-joined values are tried one by one), the first in the file's order."""
        found = self.matches(*keys)
        return found[0] if found else None

    def matches(self, *keys) -> list:
        """Every row matching any of ``keys`` (a group's submission matches each member's row)."""
        wanted = _wanted(keys)
        return [student for student in self.students if student.keys() & wanted]


def read(path) -> Roster:
    """The roster at ``path`` (see the module docstring)."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8-sig")
    except (OSError, UnicodeDecodeError) as exc:
        raise RosterError(f"{path}: not readable ({exc})") from None
    reader = csv.DictReader(text.splitlines())
    fields = [(name or "").strip() for name in reader.fieldnames or []]
    if {"Student", "ID"} <= set(fields) and {"SIS User ID", "SIS Login ID"} & set(fields):
        return _canvas(path, reader, fields)
    lowered = {name.lower() for name in fields}
    if {"sid", "email"} <= lowered and ({"first name", "last name"} <= lowered or (
            "name" in lowered and {"sections", "total score", "max points", "status"} & lowered)):
        return _gradescope(path, reader)
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


def _canvas(path: Path, reader, fields: list) -> Roster:
    """The students of Canvas' gradebook export (see the module docstring)."""
    names = {name.strip(): name for name in reader.fieldnames or []}
    roster = Roster(assignments=[f for f in fields if f and f not in CANVAS_IDENTITY and f not in CANVAS_COMPUTED
                                 and not f.endswith((" Current Points", " Final Points", " Current Score",
                                                     " Final Score", " Unposted Current Score",
                                                     " Unposted Final Score"))])
    for row in reader:
        values = {column: (row.get(names[field_name]) or "").strip()
                  for field_name, column in CANVAS_IDENTITY.items() if column and field_name in names}
        if values.get("name", "") in ("Points Possible", CANVAS_TEST_STUDENT) or not (
                values.get("canvas_id") or values.get("sid") or values.get("login")):
            continue  # Canvas' points row, its muted row of old exports, its test student
        roster.students.append(student(values))
    if not roster.students:
        raise RosterError(f"{path}: Canvas' gradebook export with no student (no row with an ID, SIS User ID or "
                          "SIS Login ID)")
    return roster


def _gradescope(path: Path, reader) -> Roster:
    """The students of Gradescope's grades export (see the module docstring)."""
    names = {(name or "").strip().lower(): name for name in reader.fieldnames or []}
    roster = Roster()
    for row in reader:
        values = {column: (row.get(names[key]) or "").strip() for key, column in GRADESCOPE_IDENTITY.items()
                  if key in names}
        if "name" in names:
            values["name"] = (row.get(names["name"]) or "").strip()
        else:
            values["name"] = " ".join(part for part in ((row.get(names["first name"]) or "").strip(),
                                                        (row.get(names["last name"]) or "").strip()) if part)
        if values.get("sid") or values.get("email"):
            roster.students.append(student(values))
    if not roster.students:
        raise RosterError(f"{path}: Gradescope's grades export with no student (no row with an SID or Email)")
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
