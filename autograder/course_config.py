"""The course configuration: the semester as assignments, read from ``autograder/course.toml``.

**Where it lives, and why.** ``autograder/course.toml``, beside the checks it gives points to:
the grader needs it wherever it grades (the instructor's tree, a student tree, the Gradescope zip),
and ``autograder/`` is the one folder that travels to all three (``pyproject.toml`` does not reach
a student tree unchanged, and ``[tool.course]`` there would make the packaging file the gradebook's
source). A released tree carries a copy holding its one assignment, and the file
``autograder/ASSIGNMENT`` naming it (:func:`current_assignment`): there ``python -m autograder``,
``make check`` and ``pytest`` grade that assignment with its points.

**The file.** TOML (``tomllib``; ``tomli`` on Python 3.10)::

    [course]
    title = "..."
    [defaults]                       # what every assignment has unless it says otherwise
    hidden_visibility = "after_published"
    hidden_counts = true
    late = { per_day = 0.1, cutoff_days = 7 }
    [assignments.ch1]                # the assignments, in release order
    title = "..."
    exercises = ["curve_model", "gauss_newton", "damping", "end_to_end"]
    optional = []                    # extra credit: graded, their points not in the maximum
    solved = []                      # earlier exercise files handed out solved (reference code)
    due = 2027-02-05T23:59:00+01:00  # ISO 8601 with an offset (a TOML date-time or a string)
    release_after = 2027-01-20T00:00:00+01:00  # not handed out before (default: see below)
    total = 100                      # scale the maximum (public + counted hidden) to this
    hidden_visibility = "after_published"   # visible | after_due_date | after_published | hidden
    hidden_counts = true             # false: the hidden checks are shown and score nothing
    late = { per_day = 0.1, per_hour = 0, cutoff_days = 7, cutoff_hours = 0 }
    [assignments.ch1.points]         # points: of a check module, an exercise or one check
    damping = 30                     # damping's checks scaled to sum to 30
    "damping.GavinType1" = 12        # an exercise (Check.exercise), scaled to 12
    "end_to_end: lm-type3" = 4       # one check, by its exact name
    [assignments.ch1.late.extensions]
    "student@example.edu" = 2027-02-08T23:59:00+01:00   # by Gradescope user id, sid or e-mail

Extensions are the instructor's: a student tree's copy of this file has none
(:mod:`autograder.release.carried_config`); the Gradescope zip keeps its assignment's and also takes
the extensions granted on Gradescope (a user's own due date in ``submission_metadata.json``),
whichever is later. An extension before its assignment's due date is an error.

Release dates: an assignment that hands out ``solved`` files gives the reference code of earlier
assignments away, so its student tree is not released before ``release_after`` (``python -m
course release`` refuses without ``--force``). Its default is when the previous assignment closes
(:attr:`Assignment.closes`: its latest due date, extensions included, plus its cutoff), or when
an assignment whose files it hands out closes, whichever is later.

An assignment's ``exercises`` are check modules (``autograder/checks/NAME.py``, :data:`ORDER
<autograder.checks.ORDER>`): an exercise file (``damping``) or a check module that runs several
together (``end_to_end``, ``pose_graph``). ``solved`` names exercise files (``exercises/NAME.py``).
A check module's ``USES`` lists the exercise files its checks run besides its own ``MODULES`` (the
dogleg's end-to-end runs solve the curve and a pose graph): each must be in the assignment or
``solved``, since in an assignment the pieces not being graded come from the solved code
(:func:`autograder.grade.grade_many`), so that the grade depends on the assignment's files alone.

Points: each check starts at its ``Check.points``; ``points`` keys set a check module's, an
exercise's (its checks scaled together) or one check's points, the most specific winning; then
``total`` scales every check so that the maximum is ``total``. The maximum is the sum over the
required (not optional) checks, public and, when ``hidden_counts``, hidden (each check's hidden
twin has its points). The public set alone, as a student tree grades it, is half of that. Points
are computed exactly, then put on a grid of 0.0001 (:mod:`autograder.point_grid`) so that the
required checks' points sum to ``total`` exactly and a full score equals its maximum.

Every mistake raises :class:`ConfigError` naming the file, the key path
(``assignments.ch2.points.pose_graph_edge``) and what was expected.

**Interface** (the batch and the gradebook use it too): :func:`load` -> :class:`Course`;
``course.assignment(name)`` -> :class:`Assignment`; ``assignment.checks()`` the checks with the
assignment's points; ``assignment.hidden_counts``, ``hidden_visibility``, ``is_extra(check)``;
``assignment.late`` (an :class:`autograder.late.LatePolicy`), ``assignment.due``;
``assignment.lateness(submitted, student=())`` (:class:`autograder.late.Lateness`);
:func:`gradescope_metadata` reads Gradescope's ``submission_metadata.json``.
``python -m autograder.course_config [FILE]`` validates a file and prints each assignment: its
exercises and points, its dates (release after, due, closes), late policy and extensions (by name:
the checker is the instructor's).
"""

import difflib
import json
import sys
from dataclasses import dataclass, field, replace
from datetime import date, datetime, timedelta
from fractions import Fraction
from pathlib import Path
from types import MappingProxyType
from typing import Any

from autograder import point_grid
from autograder.late import Lateness, LatePolicy, lateness

HERE = Path(__file__).resolve().parent
#: the course's configuration
DEFAULT_PATH = HERE / "course.toml"
#: in a released tree: the name of its assignment
ASSIGNMENT_FILE = HERE / "ASSIGNMENT"
VISIBILITIES = ("visible", "after_due_date", "after_published", "hidden")

COURSE_KEYS = {"course", "defaults", "assignments"}
COURSE_TABLE_KEYS = {"title"}
DEFAULT_KEYS = {"hidden_visibility", "hidden_counts", "late"}
ASSIGNMENT_KEYS = {"title", "exercises", "optional", "solved", "due", "release_after", "total", "points",
                   "hidden_visibility", "hidden_counts", "late"}
LATE_KEYS = {"per_day", "per_hour", "cutoff_days", "cutoff_hours", "extensions"}


class ConfigError(ValueError):
    """A mistake in the course configuration: ``path``, ``key`` and what was expected."""

    def __init__(self, path, key: str, message: str):
        self.path, self.key = str(path), key
        super().__init__(f"{path}: {key}: {message}" if key else f"{path}: {message}")


def did_you_mean(name: str, choices, n: int = 4) -> str:
    """`` (did you mean a, b?)`` naming the ``choices`` closest to ``name`` ('' when none is close)."""
    near = difflib.get_close_matches(name, list(choices), n=n, cutoff=0.5)
    return f" (did you mean {', '.join(near)}?)" if near else ""


@dataclass(frozen=True)
class Assignment:
    """One assignment, resolved: every name checked, every check's points computed."""

    name: str
    title: str
    exercises: tuple  # check modules, in report order
    optional: tuple = ()
    solved: tuple = ()  # exercise files handed out solved
    due: datetime | None = None
    late: LatePolicy = field(default_factory=LatePolicy)
    hidden_visibility: str = "after_published"
    hidden_counts: bool = True
    #: ``{check name: points}`` of every check of the assignment
    points: Any = field(default_factory=dict)
    source: str = ""  # the file it was read from
    #: not handed out before this (given, or the default of the module docstring; None: no date)
    release_after: datetime | None = None
    #: where ``release_after`` comes from ("set", or the assignment whose close it is)
    release_basis: str = ""

    @property
    def closes(self) -> datetime | None:
        """When the last submission the policy still scores is in: the latest due date (extensions
        included) plus the cutoff (none: the latest due date). None without a due date."""
        if self.due is None:
            return None
        latest = max([self.due, *self.late.extensions.values()])
        return latest + (self.late.cutoff or timedelta(0))

    def checks(self) -> list:
        """The assignment's checks in report order, each with the assignment's points."""
        from autograder.checks import modules

        chosen = []
        for name, module in modules():
            if name in self.exercises:
                chosen += [replace(check, points=self.points[check.name]) for check in module.CHECKS]
        return chosen

    @property
    def modules(self) -> tuple:
        """The exercise files graded (``MODULES`` of the assignment's check modules), in order."""
        from autograder.checks import modules

        out: list = []
        for name, module in modules():
            if name in self.exercises:
                out += [m for m in module.MODULES if m not in out]
        return tuple(out)

    def is_extra(self, check) -> bool:
        """True for a check of an optional exercise (extra credit)."""
        from autograder.checks import module_of

        return module_of().get(check.name) in self.optional

    def maximum(self, which: str = "all") -> float:
        """The most a submission scores (extra credit aside) on ``which`` ("public", "hidden", "all")."""
        from autograder.checks import module_of

        owner = module_of()
        required = [p for name, p in self.points.items() if owner[name] not in self.optional]
        sets = {"public": 1, "hidden": 1 if self.hidden_counts else 0, "all": 2 if self.hidden_counts else 1}
        return point_grid.total(required * sets[which])

    def lateness(self, submitted: datetime, student: tuple = (), due: datetime | None = None,
                 granted: datetime | None = None) -> Lateness:
        """How late ``submitted`` is and what it costs (``due``: when the assignment has none;
        ``granted``: the student's own due date on the platform, :attr:`Submitted.granted`)."""
        deadline = self.due or due
        if deadline is None:
            return Lateness(timedelta(0), 1.0, "no due date")
        return lateness(submitted, deadline, self.late, student, granted)


@dataclass(frozen=True)
class Course:
    title: str
    assignments: Any  # {name: Assignment}, in release order
    source: str = ""

    def assignment(self, name: str) -> Assignment:
        if name not in self.assignments:
            raise ConfigError(self.source, f"assignments.{name}", "no such assignment; the assignments are "
                              f"{', '.join(self.assignments)}{did_you_mean(name, self.assignments)}")
        return self.assignments[name]

    def owner(self, module: str) -> str:
        """The assignment whose exercises hold check module or exercise file ``module`` ('' if none)."""
        for assignment in self.assignments.values():
            if module in assignment.exercises or module in assignment.modules:
                return assignment.name
        return ""

    def earlier(self, name: str) -> list:
        """The names of the assignments released before ``name``."""
        names = list(self.assignments)
        return names[: names.index(name)]


# ---------------------------------------------------------------- reading


def load(path=None) -> Course:
    """The course configuration at ``path`` (default ``autograder/course.toml``), validated."""
    if sys.version_info >= (3, 11):  # imported here: grading the whole course reads no configuration
        import tomllib
    else:  # pragma: no cover - Python 3.10
        import tomli as tomllib
    path = Path(path) if path is not None else DEFAULT_PATH
    try:
        with open(path, "rb") as handle:
            data = tomllib.load(handle)
    except OSError as exc:
        raise ConfigError(path, "", f"cannot read it ({exc.strerror or exc})") from None
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(path, "", f"not valid TOML ({exc})") from None
    return parse(data, path)


def parse(data: dict, path="<course.toml>") -> Course:
    """A :class:`Course` from the TOML's contents (``path`` names the file in errors)."""
    from autograder.checks import modules

    _known(data, COURSE_KEYS, "", path, "the top-level tables course, defaults and assignments")
    course = _table(data.get("course", {}), "course", path)
    _known(course, COURSE_TABLE_KEYS, "course", path, "title")
    defaults = _table(data.get("defaults", {}), "defaults", path)
    _known(defaults, DEFAULT_KEYS, "defaults", path, ", ".join(sorted(DEFAULT_KEYS)))
    assignments = _table(data.get("assignments"), "assignments", path)
    if not assignments:
        raise ConfigError(path, "assignments", "expected at least one [assignments.NAME] table")
    registry = {name: module for name, module in modules()}
    files = {m for module in registry.values() for m in module.MODULES}
    owners: dict = {}
    out = {}
    for name, raw in assignments.items():
        key = f"assignments.{name}"
        raw = _table(raw, key, path)
        _known(raw, ASSIGNMENT_KEYS, key, path, ", ".join(sorted(ASSIGNMENT_KEYS)))
        exercises = _names(raw.get("exercises"), f"{key}.exercises", path, registry, "check module")
        if not exercises:
            raise ConfigError(path, f"{key}.exercises", "expected a non-empty list of exercises")
        for exercise in exercises:
            if exercise in owners:
                raise ConfigError(path, f"{key}.exercises", f"{exercise!r} is already in assignments.{owners[exercise]}"
                                  "; an exercise belongs to one assignment")
            owners[exercise] = name
        optional = _names(raw.get("optional", []), f"{key}.optional", path, registry, "check module")
        for exercise in optional:
            if exercise not in exercises:
                raise ConfigError(path, f"{key}.optional", f"{exercise!r} is not one of this assignment's exercises "
                                  f"({', '.join(exercises)})")
        graded = [m for exercise in exercises for m in registry[exercise].MODULES]
        solved = _names(raw.get("solved", []), f"{key}.solved", path, {f: None for f in files}, "exercise file")
        for module in solved:
            if module in graded:
                raise ConfigError(path, f"{key}.solved", f"{module!r} is graded in this assignment; it cannot also be "
                                  "handed out solved")
        for exercise in exercises:
            needs = [m for m in getattr(registry[exercise], "USES", ()) if m not in graded and m not in solved]
            if needs:
                raise ConfigError(path, f"{key}.solved", f"the checks of {exercise!r} run {', '.join(needs)}, which "
                                  "this assignment does not grade: add them to solved (handed out as reference "
                                  "code) or add their exercises to this assignment")
        visibility = raw.get("hidden_visibility", defaults.get("hidden_visibility", "after_published"))
        where = f"{key}.hidden_visibility" if "hidden_visibility" in raw else "defaults.hidden_visibility"
        if visibility not in VISIBILITIES:
            raise ConfigError(path, where, f"expected one of {', '.join(VISIBILITIES)}, got {visibility!r}")
        counts = raw.get("hidden_counts", defaults.get("hidden_counts", True))
        if not isinstance(counts, bool):
            where = f"{key}.hidden_counts" if "hidden_counts" in raw else "defaults.hidden_counts"
            raise ConfigError(path, where, f"expected true or false, got {counts!r}")
        late_key = f"{key}.late" if "late" in raw else "defaults.late"
        late = _late(raw.get("late", defaults.get("late", {})), late_key, path)
        due = _moment(raw["due"], f"{key}.due", path) if "due" in raw else None
        for who, when in late.extensions.items():
            if due is not None and when < due:
                raise ConfigError(path, f"{late_key}.extensions.{who}", f"the extension {when.isoformat()} is before "
                                  f"the due date of {key} ({due.isoformat()}): an extension gives more time")
        release = _moment(raw["release_after"], f"{key}.release_after", path) if "release_after" in raw else None
        points = _points(raw, key, path, exercises, registry, optional, counts)
        title = raw.get("title", name)
        if not isinstance(title, str):
            raise ConfigError(path, f"{key}.title", f"expected a string, got {title!r}")
        out[name] = Assignment(name, title, tuple(e for e in registry if e in exercises), tuple(optional),
                               tuple(solved), due, late, visibility, counts, MappingProxyType(points), str(path),
                               release, "set" if release is not None else "")
    for name, assignment in out.items():
        later = list(out)[list(out).index(name) + 1:]
        for module in assignment.solved:
            owner = next((n for n in later if module in out[n].modules), "")
            if owner:
                raise ConfigError(path, f"assignments.{name}.solved", f"{module!r} is graded in assignments.{owner}, "
                                  "which comes later: handing it out solved now gives its answer away")
    _release_dates(out)
    title = course.get("title", "")
    if not isinstance(title, str):
        raise ConfigError(path, "course.title", f"expected a string, got {title!r}")
    return Course(title, MappingProxyType(out), str(path))


def _release_dates(out: dict) -> None:
    """Give each assignment without ``release_after`` its default (the module docstring)."""
    names = list(out)
    for index, name in enumerate(names):
        assignment = out[name]
        if assignment.release_after is not None:
            continue
        owners = [names[index - 1]] if index else []
        owners += [n for n in names[:index] if set(out[n].modules) & set(assignment.solved) and n not in owners]
        closes = [(out[n].closes, n) for n in owners if out[n].closes is not None]
        if closes:
            moment, owner = max(closes)
            out[name] = replace(assignment, release_after=moment, release_basis=f"when {owner} closes")


def _table(value, key, path) -> dict:
    if value is None:
        return {}
    if not isinstance(value, dict):
        raise ConfigError(path, key, f"expected a table, got {type(value).__name__} {value!r}")
    return value


def _known(table: dict, allowed: set, key: str, path, expected: str) -> None:
    for name in table:
        if name not in allowed:
            where = f"{key}.{name}" if key else name
            raise ConfigError(path, where, f"unknown key{did_you_mean(name, allowed)}; expected {expected}")


def _names(value, key, path, known, what) -> list:
    if not isinstance(value, list) or not all(isinstance(v, str) for v in value):
        raise ConfigError(path, key, f"expected a list of {what} names, got {value!r}")
    for index, name in enumerate(value):
        if name not in known:
            raise ConfigError(path, f"{key}[{index}]", f"unknown {what} {name!r}{did_you_mean(name, known)}; "
                              f"expected one of {', '.join(known)}")
        if value.index(name) != index:
            raise ConfigError(path, f"{key}[{index}]", f"{name!r} is listed twice")
    return list(value)


def _moment(value, key, path) -> datetime:
    """A date and time with an offset, from a TOML date-time or an ISO 8601 string."""
    moment = value
    if isinstance(value, str):
        try:
            moment = datetime.fromisoformat(value.strip().replace("Z", "+00:00"))
        except ValueError:
            moment = None
    if not isinstance(moment, datetime):
        kind = "a date without a time" if isinstance(value, date) else repr(value)
        raise ConfigError(path, key, f"expected an ISO 8601 date and time with an offset "
                          f"(2027-02-05T23:59:00+01:00), got {kind}")
    if moment.tzinfo is None or moment.utcoffset() is None:
        raise ConfigError(path, key, f"expected an ISO 8601 date and time with an offset "
                          f"(2027-02-05T23:59:00+01:00), got {value} without one")
    return moment


def _number(value, key, path, what="a number >= 0") -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not value >= 0 or value == float("inf"):
        raise ConfigError(path, key, f"expected {what}, got {value!r}")
    return float(value)


def _late(raw, key, path) -> LatePolicy:
    raw = _table(raw, key, path)
    _known(raw, LATE_KEYS, key, path, ", ".join(sorted(LATE_KEYS)))
    rates = {}
    for name in ("per_day", "per_hour"):
        if name in raw:
            rates[name] = _number(raw[name], f"{key}.{name}", path, "a fraction in [0, 1] (0.1 is 10%)")
            if rates[name] > 1:
                raise ConfigError(path, f"{key}.{name}", "expected a fraction in [0, 1] (0.1 is 10%), got "
                                  f"{raw[name]!r}")
    if rates.get("per_day") and rates.get("per_hour"):
        raise ConfigError(path, key, "give per_day or per_hour, not both")
    cutoff = None
    if "cutoff_days" in raw and "cutoff_hours" in raw:
        raise ConfigError(path, key, "give cutoff_days or cutoff_hours, not both")
    if "cutoff_days" in raw:
        cutoff = timedelta(days=_number(raw["cutoff_days"], f"{key}.cutoff_days", path))
    if "cutoff_hours" in raw:
        cutoff = timedelta(hours=_number(raw["cutoff_hours"], f"{key}.cutoff_hours", path))
    extensions = _table(raw.get("extensions", {}), f"{key}.extensions", path)
    moments = {str(who): _moment(when, f"{key}.extensions.{who}", path) for who, when in extensions.items()}
    return LatePolicy(rates.get("per_day", 0.0), rates.get("per_hour", 0.0), cutoff, MappingProxyType(moments))


def _points(raw, key, path, exercises, registry, optional, counts) -> dict:
    """``{check name: points}`` of the assignment's checks (see the module docstring), computed exactly
    and then put on the grid of :mod:`autograder.point_grid`: the required checks' points sum to
    ``total`` exactly (to their exact sum rounded to the grid without one)."""
    checks = [check for exercise in exercises for check in registry[exercise].CHECKS]
    owner = {check.name: exercise for exercise in exercises for check in registry[exercise].CHECKS}
    points = {check.name: point_grid.exact(check.points) for check in checks}
    given = _table(raw.get("points", {}), f"{key}.points", path)
    exercise_names = {check.exercise for check in checks}
    known = list(exercises) + sorted(exercise_names) + list(points)
    for name, value in given.items():
        where = f"{key}.points.{name}"
        if name not in known:
            raise ConfigError(path, where, f"unknown name{did_you_mean(name, known)}; expected one of this "
                              "assignment's check modules, exercises or check names: " + ", ".join(known))
        _number(value, where, path, "a number of points >= 0")
    for level in ("module", "exercise", "check"):
        for name, value in given.items():
            if level == "module" and name in exercises:
                members = [c.name for c in checks if owner[c.name] == name]
            elif level == "exercise" and name in exercise_names and name not in exercises:
                members = [c.name for c in checks if c.exercise == name]
            elif level == "check" and name in points and name not in exercises and name not in exercise_names:
                members = [name]
            else:
                continue
            base = sum(points[m] for m in members)
            for member in members:
                share = points[member] / base if base else Fraction(1, len(members))
                points[member] = point_grid.exact(value) * share
    sets = 2 if counts else 1
    if "total" in raw:
        total = _number(raw["total"], f"{key}.total", path, "a number of points > 0")
        required = sum(p for name, p in points.items() if owner[name] not in optional) * sets
        if total <= 0 or required <= 0:
            raise ConfigError(path, f"{key}.total", f"expected a number of points > 0 with some required points, "
                              f"got {raw['total']!r}")
        if (point_grid.exact(raw["total"]) * point_grid.STEPS / sets).denominator != 1:
            raise ConfigError(path, f"{key}.total", f"expected a multiple of {sets / point_grid.STEPS:g} points "
                              f"(the public and the hidden checks get half each), got {raw['total']!r}")
        points = {name: p * point_grid.exact(raw["total"]) / required for name, p in points.items()}
    grid = {**point_grid.apportion({n: p for n, p in points.items() if owner[n] not in optional}),
            **point_grid.apportion({n: p for n, p in points.items() if owner[n] in optional})}
    return {name: grid[name] for name in points}


# ---------------------------------------------------------------- a released tree, a submission


def current_assignment(path=None) -> str:
    """The assignment a released tree grades (``autograder/ASSIGNMENT``), '' in the course's own tree."""
    path = Path(path) if path is not None else ASSIGNMENT_FILE
    try:
        return path.read_text().strip()
    except OSError:
        return ""


@dataclass(frozen=True)
class Submitted:
    """What Gradescope's ``submission_metadata.json`` says of a submission."""

    created_at: datetime
    due: datetime | None
    students: tuple  # ids, sids and e-mails of the submitters (for extensions)
    #: a submitter's own due date on Gradescope (an extension granted there), the latest of the group's
    #: when later than the assignment's; None when none is
    granted: datetime | None = None


def gradescope_metadata(path) -> Submitted:
    """``created_at``, ``assignment.due_date``, the users' ids, sids and e-mails and their own due
    dates (``users[].assignment.due_date``, which Gradescope sets to a user's extension) of
    Gradescope's ``submission_metadata.json``. A user's ``late_due_date`` is when Gradescope stops
    taking submissions; the late policy counts from the due date, so it is not read."""
    data = json.loads(Path(path).read_text())
    created = _moment(data.get("created_at"), "created_at", path)
    due_text = (data.get("assignment") or {}).get("due_date")
    due = _moment(due_text, "assignment.due_date", path) if due_text else None
    keys: list = []
    granted = None
    for index, user in enumerate(data.get("users") or []):
        keys += [str(user[k]) for k in ("id", "sid", "email") if user.get(k) not in (None, "")]
        own = (user.get("assignment") or {}).get("due_date")
        if own:
            moment = _moment(own, f"users[{index}].assignment.due_date", path)
            if (due is None or moment > due) and (granted is None or moment > granted):
                granted = moment
    return Submitted(created, due, tuple(keys), granted)


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    try:
        course = load(argv[0] if argv else None)
    except ConfigError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    print(f"{course.title} ({course.source})")
    for a in course.assignments.values():
        extra = f", optional {', '.join(a.optional)}" if a.optional else ""
        solved = f", solved {', '.join(a.solved)}" if a.solved else ""
        print(f"  {a.name}: {', '.join(a.exercises)}{extra}{solved}; max {a.maximum():g} "
              f"(public {a.maximum('public'):g})")
        print(f"      {dates_line(a)}")
        print(f"      late: {policy_line(a.late)}")
        for who, when in sorted(a.late.extensions.items(), key=lambda item: item[1]):
            print(f"        extension: {who} until {when.isoformat()}")
    return 0


def _when(moment) -> str:
    return moment.isoformat() if moment is not None else "-"


def dates_line(a: Assignment) -> str:
    """``release_after ..., due ..., closes ...`` of assignment ``a``, as the checker prints it."""
    basis = f" ({a.release_basis})" if a.release_basis else ""
    return f"release after {_when(a.release_after)}{basis}; due {_when(a.due)}; closes {_when(a.closes)}"


def policy_line(late: LatePolicy) -> str:
    """The late policy in words, with the number of extensions."""
    if late.per_day or late.per_hour:
        text = f"{100 * (late.per_day or late.per_hour):g}% per started {'day' if late.per_day else 'hour'}"
    else:
        text = "no penalty"
    if late.cutoff is not None:
        hours = late.cutoff.total_seconds() / 3600
        text += f", cutoff {hours / 24:g} days" if hours % 24 == 0 else f", cutoff {hours:g} hours"
    else:
        text += ", no cutoff"
    count = len(late.extensions)
    return text + f"; {count} extension{'s' if count != 1 else ''}"


if __name__ == "__main__":
    sys.exit(main())
