"""Late work: how late a submission is and what that costs under an assignment's policy.

The policy (``LatePolicy``) comes from the course configuration; the submission's time from
Gradescope's ``submission_metadata.json`` (``created_at``, with the assignment's ``due_date``) or
an export's ``submission_metadata.yml`` (``:created_at:``), a file's time or a roster. Lateness
counts started units: a submission 1 second late under 10% per day loses 10%, one 2 days late
exactly loses 20%. After ``cutoff`` past the (extended) due date the score is 0.

A student's due date is the latest of the assignment's, their extension in the policy (the course
configuration, a roster) and one the platform granted (``granted``: Gradescope's own extension, a
per-user due date in ``submission_metadata.json``); :class:`Lateness` says which applied.
"""

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from datetime import datetime, timedelta, timezone


@dataclass(frozen=True)
class LatePolicy:
    """``per_day`` / ``per_hour``: the fraction of the score lost per started day / hour late (0.1
    is 10%; at most one of them non-zero); ``cutoff``: past the due date by more than this, the
    score is 0 (None: never); ``extensions``: a student's own due date, by id, sid or email."""

    per_day: float = 0.0
    per_hour: float = 0.0
    cutoff: timedelta | None = None
    extensions: Mapping[str, datetime] = field(default_factory=dict)

    def __post_init__(self):
        for name in ("per_day", "per_hour"):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and 0.0 <= value <= 1.0):
                raise ValueError(f"{name} must be a fraction in [0, 1] (0.1 is 10%), got {value!r}")
        if self.per_day and self.per_hour:
            raise ValueError("give per_day or per_hour, not both")
        if self.cutoff is not None and self.cutoff < timedelta(0):
            raise ValueError(f"cutoff must not be negative, got {self.cutoff}")


@dataclass(frozen=True)
class Lateness:
    """What the policy made of one submission: ``late`` (zero when on time), the ``fraction`` of the
    score kept, and a sentence for the feedback and the gradebook."""

    late: timedelta
    fraction: float
    note: str
    #: the due date applied, and where it came from (:data:`BASES`)
    due: datetime | None = None
    basis: str = ""


#: where a student's due date comes from
ASSIGNMENT_DUE = "the assignment's due date"
CONFIGURED = "an extension in the course configuration or the roster"
GRANTED = "an extension on Gradescope"
BASES = (ASSIGNMENT_DUE, CONFIGURED, GRANTED)


def aware(moment: datetime) -> datetime:
    """``moment`` with a time zone (UTC where it has none)."""
    return moment if moment.tzinfo is not None else moment.replace(tzinfo=timezone.utc)


def deadline(due: datetime, policy: LatePolicy, student: tuple = (), granted: datetime | None = None) -> tuple:
    """``(due date, basis)`` of the student known by any of ``student`` (id, sid, email): the latest of
    ``due``, their extension in ``policy`` and ``granted`` (the platform's), with where it came from
    (a tie goes to the earlier of :data:`BASES`)."""
    best = (aware(due), ASSIGNMENT_DUE)
    for key in student:
        if key and key in policy.extensions:
            if aware(policy.extensions[key]) > best[0]:
                best = (aware(policy.extensions[key]), CONFIGURED)
            break
    if granted is not None and aware(granted) > best[0]:
        best = (aware(granted), GRANTED)
    return best


def due_for(due: datetime, policy: LatePolicy, student: tuple = ()) -> datetime:
    """The due date of the student known by any of ``student`` (id, sid, email): their extension's
    when it is later, else ``due``."""
    return deadline(due, policy, student)[0]


def lateness(submitted: datetime, due: datetime, policy: LatePolicy, student: tuple = (),
             granted: datetime | None = None) -> Lateness:
    """How late ``submitted`` is against the student's due date (:func:`deadline`) and the fraction kept."""
    due, basis = deadline(due, policy, student, granted)
    late = max(aware(submitted) - due, timedelta(0))
    if late == timedelta(0):
        return Lateness(late, 1.0, "on time", due, basis)
    if policy.cutoff is not None and late > policy.cutoff:
        return Lateness(late, 0.0, f"{_span(late)} late, past the cutoff of {_span(policy.cutoff)}: 0 points",
                        due, basis)
    unit, rate = (timedelta(days=1), policy.per_day) if policy.per_day else (timedelta(hours=1), policy.per_hour)
    started = math.ceil(late / unit)
    kept = max(0.0, 1.0 - started * rate)
    what = "day" if unit == timedelta(days=1) else "hour"
    cost = f"{started} started {what}{'s' if started != 1 else ''} at {100 * rate:g}%" if rate else "no penalty"
    return Lateness(late, kept, f"{_span(late)} late: {cost}, {100 * kept:g}% of the score kept", due, basis)


def _span(delta: timedelta) -> str:
    hours = delta.total_seconds() / 3600.0
    return f"{hours / 24:.2f} days" if hours >= 24 else f"{hours:.2f} hours"
