"""``python -m autograder export DIR [DIR ...] --canvas OUT.csv | --moodle OUT.csv``: the gradebook
file a learning platform imports, from the ``--out`` folders of ``batch`` (one per assignment).

Each DIR is one assignment: its name is the ``--assignment`` its records were graded with, else
the folder's name (``--column NAME=HEADER`` renames its column, e.g. to Canvas' ``Homework 1
(4521)``, which matches an existing Canvas assignment by its id). Every student of every DIR is one
row; a group submission gives each submitter a row with the group's score. The score is the
record's total after the overrides and the late penalty, with the marks of the written answers
(:mod:`autograder.classroom.written`; the maximum has their points too). A student without a record in a DIR has
an empty cell (the platform leaves that grade alone).

* **Canvas** (Grades, Import): columns ``Student``, ``ID`` (Canvas' user id), ``SIS User ID``,
  ``SIS Login ID``, ``Section``, then one per assignment; the second row is ``Points Possible``
  (each assignment's maximum), as Canvas' own export has it. Canvas matches a row by ``ID``,
  ``SIS User ID`` or ``SIS Login ID``: the sid of the upload goes in ``SIS User ID``; the roster
  gives the others (``canvas_id``, ``login``, ``section``).
* **Moodle** (Grade administration, Import, CSV file): columns ``Full name``, ``ID number``,
  ``Email address``, then one per assignment; map users "from" ``Email address`` "to" email
  address, or ``ID number`` to ID number, and each assignment column to its grade item.

A roster (``--roster``, :mod:`autograder.classroom.roster`) fills in the sid, e-mail, login,
Canvas id, section and name where the uploads lack them (a folder of uploads has only folder
names: the roster's ``id`` column is that name). Rows the platform could not match to a user are
named on stderr. Every text cell a spreadsheet would run as a formula is written as text
(:func:`autograder.classroom.gradebook.cell`).
"""

import argparse
import csv
import io
import sys
from dataclasses import dataclass, field
from pathlib import Path

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
    maximum = max((sum(float(t["max_score"]) for t in r["tests"]) for r in records), default=0.0)
    return Assignment(name, headers.get(name, name), maximum, records)


def _members(extra: dict) -> list:
    """``(name, sid, email)`` of each submitter of a record (a group's values are "; "-joined)."""
    parts = [str(extra.get(key) or "").split("; ") for key in ("name", "sid", "email")]
    count = max(len(p) for p in parts)
    if count > 1 and all(len(p) in (1, count) for p in parts):
        return [tuple(p[i] if len(p) == count else (p[0] if i == 0 else "") for p in parts) for i in range(count)]
    return [tuple(str(extra.get(key) or "") for key in ("name", "sid", "email"))]


def people(assignments, known: roster.Roster) -> list:
    """The rows: every submitter of every assignment, joined across assignments by the roster's
    row, else by sid, else by e-mail, else by submission id."""
    rows: dict = {}
    for assignment in assignments:
        for record in assignment.records:
            extra = record["extra_data"]
            sub_id = str(extra["id"])
            for name, sid, email in _members(extra):
                found = known.find(sid, email, sub_id if len(_members(extra)) == 1 else "")
                key: tuple
                if found is not None:
                    key = ("roster", known.students.index(found))
                else:
                    key = ("sid", sid.lower()) if sid else ("email", email.lower()) if email else ("id", sub_id)
                person = rows.setdefault(key, Person())
                person.name = person.name or (found.name if found and found.name else name)
                person.sid = person.sid or (found.sid if found else "") or sid
                person.email = person.email or (found.email if found else "") or email
                if found is not None:
                    person.login = person.login or found.login
                    person.canvas_id = person.canvas_id or found.canvas_id
                    person.section = person.section or found.section
                person.ids.append(sub_id)
                person.scores[assignment.name] = float(record["score"])
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


def main(argv=None) -> int:
    p = argparse.ArgumentParser(prog="python -m autograder export", description=__doc__.splitlines()[0])
    p.add_argument("dirs", nargs="+", metavar="DIR", help="the --out folders of batch runs, one per assignment")
    p.add_argument("--canvas", metavar="OUT.csv", help="write Canvas' gradebook import file")
    p.add_argument("--moodle", metavar="OUT.csv", help="write Moodle's grade import file")
    p.add_argument("--roster", metavar="CSV", help="ids, e-mails, logins, sections where the uploads lack them")
    p.add_argument("--column", action="append", metavar="NAME=HEADER",
                   help="the column of assignment NAME (repeatable); default: its name")
    args = p.parse_args(argv)
    if not args.canvas and not args.moodle:
        p.error("say what to write: --canvas OUT.csv and/or --moodle OUT.csv")
    try:
        headers = _headers(args.column)
        known = roster.read(args.roster) if args.roster else roster.Roster()
        assignments = [load_assignment(Path(d), headers) for d in args.dirs]
    except ValueError as exc:  # RosterError too
        p.error(str(exc))
    names = [a.name for a in assignments]
    twice = sorted({n for n in names if names.count(n) > 1})
    if twice:
        p.error(f"assignment {', '.join(twice)} is in more than one DIR")
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
