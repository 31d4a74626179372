"""When an assignment's student tree may be released: not before its ``release_after`` when it hands
out solved code (the reference of earlier assignments' files, which late or extended submissions of
those assignments may still be graded on). :mod:`autograder.course_config` gives the date."""

from datetime import datetime, timezone


def handed_out(course, assignment) -> list:
    """``exercises/NAME.py (reference code of ASSIGNMENT)`` for each file ``assignment`` hands out solved."""
    owners = {module: a.name for a in course.assignments.values() for module in a.modules}
    return [f"exercises/{m}.py (reference code of {owners.get(m, 'no assignment')})" for m in assignment.solved]


def early_release(course, assignment, now: datetime | None = None) -> str:
    """Why releasing ``assignment``'s student tree at ``now`` (default: the current time) is too early,
    '' when it is not (it hands out no solved code, has no ``release_after``, or that is past)."""
    now = now or datetime.now(timezone.utc)
    if not assignment.solved or assignment.release_after is None or now >= assignment.release_after:
        return ""
    basis = f" ({assignment.release_basis})" if assignment.release_basis != "set" else ""
    return (f"assignment {assignment.name} is released after {assignment.release_after.isoformat()}{basis}, and it "
            f"is {now.astimezone(assignment.release_after.tzinfo).isoformat(timespec='minutes')}: its tree hands out "
            f"solved {', '.join(handed_out(course, assignment))}")
