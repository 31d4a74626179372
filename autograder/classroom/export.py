"""``python -m autograder export DIR [DIR ...] --canvas OUT.csv | --moodle OUT.csv``: the gradebook
file a learning platform imports, from the ``--out`` folders of ``batch`` (one per assignment).

Each DIR is one assignment: its name is the ``--assignment`` its records were graded with, else
the folder's name. Its column is named for it unless ``--column NAME=HEADER`` maps it to the
platform's name (Canvas matches ``Homework 1 (4521)`` to its assignment by the id in parentheses;
a header it does not know makes it create a new assignment); a NAME that is no DIR's assignment is
an error naming the assignments. Given Canvas' gradebook export as the roster, an assignment whose
name is a Canvas column's name without its ``(id)`` is mapped to it, and a column Canvas does not
have is named on stderr.

Every student of every DIR is one row, and so is every roster student (of ``--roster``, or the
roster rows ``batch --roster`` kept in the records); a group submission gives each submitter a row
with the group's score. The score is the record's total after the overrides and the late penalty,
with the marks of the written answers (:mod:`autograder.classroom.written`; the maximum has their
points too);
a roster student without a record in a DIR scores 0 there (``batch --roster`` writes them a ``no
submission`` record); a student in no roster without a record in a DIR has an empty cell (the
platform leaves that grade alone).

* **Canvas** (Grades, Import): columns ``Student``, ``ID`` (Canvas' user id), ``SIS User ID``,
  ``SIS Login ID``, ``Section``, then one per assignment; the second row is ``Points Possible``
  (each assignment's maximum), as Canvas' own export has it. Canvas matches a row by ``ID``,
  ``SIS User ID`` or ``SIS Login ID``: the sid of the upload goes in ``SIS User ID``; the roster
  gives the others (``canvas_id``, ``login``, ``section``: Canvas' own export as the roster gives
  them all).
* **Moodle** (Grade administration, Import, CSV file): columns ``Full name``, ``ID number``,
  ``Email address``, then one per assignment; map users "from" ``Email address`` "to" email
  address, or ``ID number`` to ID number, and each assignment column to its grade item.

A roster (``--roster``, :mod:`autograder.classroom.roster`, or the rows ``batch --roster`` kept in
each record) fills in the sid, e-mail, login, Canvas id, section and name where the uploads lack
them (a folder of uploads has only folder names: the roster's ``id`` column is that name). Rows
the platform could not match to a user are named on stderr. Every text cell a spreadsheet would run
as a formula is written as text (:func:`autograder.classroom.gradebook.cell`).
"""

import argparse
import csv
import io
import re
import sys
from dataclasses import dataclass, field
from pathlib import Path

from autograder import point_grid
from autograder.classroom import gradebook, roster
from course.core import jsonio

CANVAS_COLUMNS = ("Student", "ID", "SIS User ID", "SIS Login ID", "Section")
MOODLE_COLUMNS = ("Full name", "ID number", "Email address")


@dataclass
class Assignment:
    name: str
    header: str
    maximum: float
    records: list


@dataclass
class Person:
    """One row of the gradebook: who, and a score per assignment name."""

    name: str = ""
    sid: str = ""
    email: str = ""
    login: str = ""
    canvas_id: str = ""
    section: str = ""
    ids: list = field(default_factory=list)  # the submission ids it came from
    scores: dict = field(default_factory=dict)


def load_assignment(folder: Path, headers: dict) -> Assignment:
    """The assignment graded in ``folder`` (a ``batch --out``)."""
    folder = Path(folder)
    if not (folder / "results").is_dir():
        raise ValueError(f"{folder}: no results/ folder (not the --out of `python -m autograder batch`)")
    records = gradebook.load_all(folder / "results")
    names = sorted({r["extra_data"].get("assignment") or "" for r in records} - {""})
    if len(names) > 1:
        raise ValueError(f"{folder}: records of several assignments ({', '.join(names)}); one folder per assignment")
    name = names[0] if names else folder.resolve().name
    maximum = max((point_grid.total(t["max_score"] for t in r["tests"]) for r in records), default=0.0)
    return Assignment(name, headers.get(name, name), maximum, records)


def _members(extra: dict) -> list:
    """A :class:`roster.Student` per submitter of a record: the roster rows ``batch`` kept in it,
    else the upload's name, sid and e-mail (a group's values are "; "-joined)."""
    kept = extra.get("roster")
    if isinstance(kept, list) and kept:
        return [roster.student(row) for row in kept if isinstance(row, dict)]
    keys = ("name", "sid", "email")
    parts = [str(extra.get(key) or "").split("; ") for key in keys]
    count = max(len(p) for p in parts)
    if count > 1 and all(len(p) in (1, count) for p in parts):
        return [roster.student({key: p[i] if len(p) == count else (p[0] if key == "name" else "")
                                for key, p in zip(keys, parts)}) for i in range(count)]
    return [roster.student(extra)]


def _fill(person: Person, student: roster.Student) -> None:
    """``person``'s empty fields from ``student``."""
    for key in ("name", "sid", "email", "login", "canvas_id", "section"):
        if not getattr(person, key):
            setattr(person, key, getattr(student, key))


def people(assignments, known: roster.Roster) -> list:
    """The rows: every submitter of every assignment and every roster student, joined across
    assignments by the roster's row, else by sid, else by e-mail, else by login, else by
    submission id. A roster student scores 0 in an assignment where no record is theirs."""
    rows: dict = {}
    for assignment in assignments:
        for record in assignment.records:
            extra = record["extra_data"]
            sub_id = str(extra["id"])
            members = _members(extra)
            for member in members:
                found = known.find(member.sid, member.email, member.login, sub_id if len(members) == 1 else "")
                key: tuple
                if found is not None:
                    key = ("roster", known.students.index(found))
                else:
                    key = next(((kind, value.lower()) for kind, value in (("sid", member.sid),
                                                                          ("email", member.email),
                                                                          ("login", member.login)) if value),
                               ("id", sub_id))
                person = rows.setdefault(key, Person())
                if found is not None:
                    _fill(person, found)
                _fill(person, member)
                person.ids.append(sub_id)
                person.scores[assignment.name] = float(record["score"])
    for index, student in enumerate(known.students):
        person = rows.setdefault(("roster", index), Person())
        _fill(person, student)
        for assignment in assignments:
            person.scores.setdefault(assignment.name, 0.0)
    return sorted(rows.values(), key=lambda p: (p.name.lower(), p.sid, p.email, p.ids))


def _score(person: Person, assignment: Assignment) -> str:
    value = person.scores.get(assignment.name)
    return "" if value is None else gradebook.number(value)


def canvas(assignments, rows) -> tuple:
    """Canvas' CSV text and the rows it cannot match (no ID, SIS User ID or SIS Login ID)."""
    out = io.StringIO()
    writer = csv.writer(out, lineterminator="\n")
    writer.writerow([*CANVAS_COLUMNS, *(gradebook.cell(a.header) for a in assignments)])
    writer.writerow(["Points Possible", "", "", "", "", *(gradebook.number(a.maximum) for a in assignments)])
    unmatched = []
    for p in rows:
        writer.writerow([*map(gradebook.cell, (p.name, p.canvas_id, p.sid, p.login, p.section)),
                         *(_score(p, a) for a in assignments)])
        if not (p.canvas_id or p.sid or p.login):
            unmatched.append(p)
    return out.getvalue(), unmatched


def moodle(assignments, rows) -> tuple:
    """Moodle's CSV text and the rows it cannot match (no ID number and no e-mail)."""
    out = io.StringIO()
    writer = csv.writer(out, lineterminator="\n")
    writer.writerow([*MOODLE_COLUMNS, *(gradebook.cell(a.header) for a in assignments)])
    unmatched = []
    for p in rows:
        writer.writerow([*map(gradebook.cell, (p.name, p.sid, p.email)), *(_score(p, a) for a in assignments)])
        if not (p.sid or p.email):
            unmatched.append(p)
    return out.getvalue(), unmatched


def _headers(pairs) -> dict:
    headers = {}
    for pair in pairs or []:
        name, sep, header = pair.partition("=")
        if not sep or not name or not header:
            raise ValueError(f"--column {pair!r}: expected NAME=HEADER, e.g. ch1='Homework 1 (4521)'")
        headers[name] = header
    return headers


#: Canvas' assignment column: its name, then its id in parentheses
CANVAS_ASSIGNMENT = re.compile(r"^(.*\S)\s+\((\d+)\)$")


def mapped(assignments, headers: dict, platform_columns) -> list:
    """``assignments`` with their columns: ``headers`` (``--column``; a name no assignment has is a
    ``ValueError`` naming the assignments), else the platform's column whose name without its
    ``(id)`` is the assignment's (``platform_columns``: Canvas' export's assignment columns)."""
    names = [a.name for a in assignments]
    unknown = [name for name in headers if name not in names]
    if unknown:
        raise ValueError(f"--column {unknown[0]}={headers[unknown[0]]}: no assignment {unknown[0]!r} in the DIRs; "
                         f"their assignments (the names --column maps) are: {', '.join(names)}")
    by_name: dict = {}
    for column in platform_columns:
        m = CANVAS_ASSIGNMENT.match(column)
        if m:
            by_name.setdefault(m.group(1).lower(), []).append(column)
    out = []
    for a in assignments:
        header = headers.get(a.name)
        if header is None:
            candidates = by_name.get(a.name.lower(), [])
            header = candidates[0] if len(candidates) == 1 else a.name
        out.append(Assignment(a.name, header, a.maximum, a.records))
    return out


def main(argv=None) -> int:
    p = argparse.ArgumentParser(prog="python -m autograder export", description=__doc__.splitlines()[0])
    p.add_argument("dirs", nargs="+", metavar="DIR", help="the --out folders of batch runs, one per assignment")
    p.add_argument("--canvas", metavar="OUT.csv", help="write Canvas' gradebook import file")
    p.add_argument("--moodle", metavar="OUT.csv", help="write Moodle's grade import file")
    p.add_argument("--roster", metavar="CSV", help="every student of the class (0 where no record), their ids, "
                   "e-mails, logins, sections: the course's roster, or Canvas' or Gradescope's grades export")
    p.add_argument("--column", action="append", metavar="NAME=HEADER",
                   help="the platform's column of assignment NAME, e.g. ch1='Homework 1 (4521)' (repeatable); "
                        "default: its name, or the Canvas export's column NAME (id)")
    args = p.parse_args(argv)
    if not args.canvas and not args.moodle:
        p.error("say what to write: --canvas OUT.csv and/or --moodle OUT.csv")
    try:
        headers = _headers(args.column)
        known = roster.read(args.roster) if args.roster else roster.Roster()
        assignments = [load_assignment(Path(d), {}) for d in args.dirs]
    except ValueError as exc:  # RosterError too
        p.error(str(exc))
    names = [a.name for a in assignments]
    twice = sorted({n for n in names if names.count(n) > 1})
    if twice:
        p.error(f"assignment {', '.join(twice)} is in more than one DIR")
    try:
        assignments = mapped(assignments, headers, known.assignments)
    except ValueError as exc:
        p.error(str(exc))
    if args.canvas and known.assignments:
        for a in assignments:
            if a.header not in known.assignments:
                print(f"export: {args.canvas}: column {a.header!r} (assignment {a.name}) is not an assignment of "
                      f"{args.roster}: Canvas would create a new one; map it with --column {a.name}=HEADER, one of: "
                      f"{', '.join(known.assignments) or 'none'}", file=sys.stderr)
    rows = people(assignments, known)
    for flag, write, needs in ((args.canvas, canvas, "ID, SIS User ID or SIS Login ID"),
                               (args.moodle, moodle, "ID number or e-mail address")):
        if not flag:
            continue
        text, unmatched = write(assignments, rows)
        jsonio.write_text(Path(flag), text)
        for person in unmatched:
            print(f"export: {flag}: {person.name or ', '.join(person.ids)} has no {needs}: the import cannot "
                  "match this row to a user (give them in --roster)", file=sys.stderr)
        print(f"wrote {flag}: {len(rows)} students, {len(assignments)} assignments ({', '.join(names)})")
    return 0
