"""The instructor's overrides, kept with the class: ``DIR/overrides.csv`` in the graded folder.

**Where.** The ``--out`` folder of ``batch`` (``DIR``, beside ``grades.csv`` and ``results/``)
keeps them in ``DIR/overrides.csv``, and every ``batch`` run into ``DIR`` applies them, a plain
one too. ``batch --overrides FILE`` adds FILE's lines to that file: a line for a student and check
already there replaces it (:func:`merge`), the others are appended, and the file is written
before anything is graded. To drop an override, delete its line in ``DIR/overrides.csv``. A CSV
(not TOML) since the lines are a spreadsheet's rows: one per student and check.

**The file.** A header row, then one override a line::

    id,check,points,reason,twin
    17,damping.GavinType1: update (accepted step),1,"right idea, regraded by hand (email of 3 Oct)",
    17,total,40,"excused: documented illness",
    ada@uni.edu,curve_model.residuals_and_jacobian: r values,2,"sign slip only",no

- ``id``: the submission's id, the student's sid or e-mail;
- ``check``: the exact name of a check as in ``grades.csv``, or ``total`` (:data:`TOTAL`): the
  student's score for the whole assignment, whatever the checks and the late penalty give (the
  checks and their own overrides are still shown in the feedback);
- ``points``: what it is worth for that student (not negative; above the check's maximum is extra
  credit), put on the grid of :mod:`autograder.point_grid`;
- ``reason``: required; it shows in the student's feedback and in ``grades.csv``;
- ``twin`` (optional column): an override naming a check covers its hidden twin
  (``NAME (hidden inputs)``) with the same points, unless ``twin`` is ``no``; a line naming the
  twin itself wins over it.

A check name that names no check of the assignment graded (its public and hidden names, and
``total``) is an error naming the file, the line and the close names (:func:`validate`); ``batch``
then stops before grading (exit status 2). Overrides are applied after grading, on every run of
``batch``, from the judge's scores kept in the record: they survive ``--regrade``.
"""

import csv
import difflib
import io
import math
from dataclasses import dataclass, replace
from pathlib import Path

from autograder import point_grid
from autograder.grade import HIDDEN_SUFFIX
from course.core import jsonio

COLUMNS = ("id", "check", "points", "reason")
#: the optional column: ``yes`` (default) or ``no``
TWIN = "twin"
#: the check name of an override of the whole assignment
TOTAL = "total"
#: the file a graded folder keeps them in
FILE_NAME = "overrides.csv"


class OverridesError(ValueError):
    """The overrides file is malformed; the message names the file, the line and the column."""


@dataclass(frozen=True)
class Override:
    student: str
    check: str
    points: float
    reason: str
    line: int = 0
    twin: bool = True  # covers the check's hidden twin too

    @property
    def key(self) -> tuple:
        """What a later line for the same override replaces: the student and the check."""
        return self.student.lower(), self.check


def stored(folder) -> Path:
    """The overrides file a graded folder keeps: ``folder/overrides.csv``."""
    return Path(folder) / FILE_NAME


def read(path) -> list:
    """The overrides in ``path`` (none when the file does not exist)."""
    path = Path(path)
    if not path.exists():
        return []
    try:
        text = path.read_text(encoding="utf-8-sig")
    except (OSError, UnicodeDecodeError) as exc:
        raise OverridesError(f"{path}: not readable ({exc})") from None
    reader = csv.DictReader(text.splitlines())
    header = {(name or "").strip().lower(): name for name in reader.fieldnames or []}
    missing = [c for c in COLUMNS if c not in header]
    if missing:
        raise OverridesError(f"{path}: line 1: missing column(s) {', '.join(missing)}; expected {','.join(COLUMNS)}"
                             f"[,{TWIN}]")
    found = []
    for line, row in enumerate(reader, 2):
        values = {c: (row.get(header[c]) or "").strip() for c in (*COLUMNS, TWIN) if c in header}
        if not any(values.values()):
            continue
        for column in ("id", "check", "reason"):
            if not values[column]:
                raise OverridesError(f"{path}: line {line}: column {column} is empty")
        try:
            points = float(values["points"])
        except ValueError:
            points = math.nan
        if not math.isfinite(points) or points < 0:
            raise OverridesError(f"{path}: line {line}: column points: expected a number >= 0, "
                                 f"got {values['points']!r}")
        twin = values.get(TWIN, "").lower()
        if twin not in ("", "yes", "no"):
            raise OverridesError(f"{path}: line {line}: column {TWIN}: expected yes or no (empty: yes), got "
                                 f"{values[TWIN]!r}")
        found.append(Override(values["id"], values["check"], point_grid.on_grid(points), values["reason"], line,
                              twin != "no"))
    return found


def write(path, overrides) -> Path:
    """Write ``overrides`` to ``path`` (atomically), with every column."""
    out = io.StringIO()
    writer = csv.writer(out, lineterminator="\n")
    writer.writerow([*COLUMNS, TWIN])
    for item in overrides:
        points = f"{item.points:.{point_grid.DECIMALS}f}".rstrip("0").rstrip(".")
        writer.writerow([item.student, item.check, points, item.reason, "" if item.twin else "no"])
    return jsonio.write_text(Path(path), out.getvalue())


def merge(kept, added) -> tuple:
    """``(overrides, added, replaced)``: ``kept`` with each of ``added`` replacing the one of the same
    student and check in place, or appended; the counts of each."""
    merged = list(kept)
    where = {item.key: index for index, item in enumerate(merged)}
    new = replaced = 0
    for item in added:
        if item.key in where:
            merged[where[item.key]] = item
            replaced += 1
        else:
            where[item.key] = len(merged)
            merged.append(item)
            new += 1
    return merged, new, replaced


def validate(overrides, names, path, what: str = "the checks graded") -> None:
    """``OverridesError`` for the first override whose check is none of ``names`` (nor ``total``),
    naming the file, the line and the close names."""
    known = [*names, TOTAL]
    for item in overrides:
        if item.check in known:
            continue
        near = difflib.get_close_matches(item.check, known, n=4, cutoff=0.6)
        hint = f"; close: {', '.join(near)}" if near else "; the exact name, as in grades.csv, or total"
        raise OverridesError(f"{path}: line {item.line}: column check: {item.check!r} names no check of "
                             f"{what}{hint}")


def for_student(overrides, *keys) -> list:
    """The overrides naming any of ``keys`` (id, sid, e-mail; a group's "; "-joined values one by
    one), one per check: a later line for the same check wins, and an override of a check covers its
    hidden twin (unless its ``twin`` is no, or a line names the twin)."""
    wanted = {part.strip().lower() for key in keys if key for part in str(key).split(";") if part.strip()}
    chosen: dict = {}
    for item in overrides:
        if item.student.lower() in wanted:
            chosen[item.check] = item
    twins = {item.check + HIDDEN_SUFFIX: replace(item, check=item.check + HIDDEN_SUFFIX, twin=False)
             for item in chosen.values()
             if item.twin and item.check != TOTAL and not item.check.endswith(HIDDEN_SUFFIX)}
    return [*chosen.values(), *(item for name, item in twins.items() if name not in chosen)]
