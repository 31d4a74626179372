"""The instructor's overrides: a check's points for one student, and why.

``DIR/overrides.csv`` (or ``batch --overrides FILE``), a header row and then one override a line::

    id,check,points,reason
    17,damping.GavinType1: update (accepted step),1,"right idea, regraded by hand (email of 3 Oct)"

``id`` is the submission's id, the student's sid or e-mail; ``check`` the exact name of a check
as in ``grades.csv`` (its hidden twin is another check); ``points`` what the check is worth for
that student (not negative; above the check's maximum is extra credit); ``reason`` is required and
shows in the student's feedback and in ``grades.csv``. Overrides are applied after grading, on
every run of ``batch``, from the judge's scores kept in the record: they survive ``--regrade``.
"""

import csv
import math
from dataclasses import dataclass
from pathlib import Path

COLUMNS = ("id", "check", "points", "reason")


class OverridesError(ValueError):
    """The overrides file is malformed; the message names the file, the line and the column."""


@dataclass(frozen=True)
class Override:
    student: str
    check: str
    points: float
    reason: str
    line: int = 0


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
        raise OverridesError(f"{path}: line 1: missing column(s) {', '.join(missing)}; expected {','.join(COLUMNS)}")
    found = []
    for line, row in enumerate(reader, 2):
        values = {c: (row.get(header[c]) or "").strip() for c in COLUMNS}
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
        found.append(Override(values["id"], values["check"], points, values["reason"], line))
    return found


def for_student(overrides, *keys) -> list:
    """The overrides naming any of ``keys`` (id, sid, e-mail; a group's "; "-joined values one by
    one); a later line for the same check wins."""
    wanted = {part.strip().lower() for key in keys if key for part in str(key).split(";") if part.strip()}
    chosen: dict = {}
    for item in overrides:
        if item.student.lower() in wanted:
            chosen[item.check] = item
    return list(chosen.values())
