"""The results, for a terminal and for Gradescope (``results.json``)."""

import shutil

from autograder import point_grid
from course.core import jsonio

NAME_WIDTH = 44


def _short(text: str, width: int) -> str:
    line = text.splitlines()[0] if text else ""
    return line if len(line) <= width else line[: width - 3] + "..."


def points(x: float) -> str:
    """A score as the table prints it: 3, 2.5 -> "2.50"."""
    return f"{x:g}" if abs(x - round(x)) < 1e-9 else f"{x:.2f}"


def not_implemented(results) -> list:
    """The TODOs whose stub was hit, once each, in order."""
    seen = []
    for result in results:
        for name in result.not_implemented:
            if name not in seen:
                seen.append(name)
    return seen


def earned(results) -> float:
    """The points earned: every counted check's, extra credit included (exact: :mod:`autograder.point_grid`)."""
    return point_grid.total(r.score for r in results if getattr(r, "counted", True))


def maximum(results) -> float:
    """The most ``results`` can earn: counted checks, extra credit aside."""
    return point_grid.total(r.max_score for r in results
                            if getattr(r, "counted", True) and not getattr(r, "extra", False))


def total(results) -> str:
    """The points of ``results`` as the table's last lines print them: ``"14 / 30"`` (and the extra
    credit in them, in an assignment with optional exercises)."""
    text = f"{points(earned(results))} / {points(maximum(results))}"
    extra = [r for r in results if getattr(r, "extra", False) and getattr(r, "counted", True)]
    if extra:
        text += (f" (extra credit included: {points(point_grid.total(r.score for r in extra))} of "
                 f"{points(point_grid.total(r.max_score for r in extra))})")
    return text


def late_line(lateness, before: float) -> str:
    """The line saying how late a submission was, against which due date (the assignment's or an
    extension, and whose), and what it cost."""
    due = f" (due {lateness.due.isoformat()}, {lateness.basis})" if getattr(lateness, "due", None) else ""
    if lateness.fraction >= 1.0:
        return f"Submitted: {lateness.note}{due}"
    after = point_grid.scaled(before, lateness.fraction)
    return f"Late: {lateness.note}{due}: {points(before)} -> {points(after)} points"


def summary(results, lateness=None) -> str:
    lines = [f"Total: {total(results)}"]
    if lateness is not None:
        lines.append(late_line(lateness, earned(results)))
    todos = not_implemented(results)
    if todos:
        lines.append(f"Not implemented ({len(todos)}):")
        lines += [f"  TODO {name}: not implemented" for name in todos]
    return "\n".join(lines)


def _units():
    """Every exercise unit (``damping.GavinType1``, ``end_to_end``) in report order, with its check
    module: ``[(unit, module), ...]``."""
    from autograder.checks import modules

    units: dict = {}
    for name, module in modules():
        for check in module.CHECKS:
            units.setdefault(check.exercise, name)
    return list(units.items())


def next_step(results) -> str:
    """The grader's last line: what to do next.

    The first exercise graded here that is not at full marks (``next: finish damping.GavinType2
    (2 / 5 points)``); when every one is, the exercise after the last graded, in the course's order
    (``checks.ORDER``), and, where that starts another chapter, the chapter's lesson (its notebook)
    first. Empty when nothing was graded."""
    from autograder.checks import CHAPTER, LESSONS

    graded: dict = {}
    for r in results:
        score, maximum = graded.get(r.exercise, (0.0, 0.0))
        graded[r.exercise] = (point_grid.total((score, r.score)), point_grid.total((maximum, r.max_score)))
    if not graded:
        return ""
    units = _units()
    order = [unit for unit, _ in units]
    module = dict(units)
    for unit in sorted(graded, key=lambda u: order.index(u) if u in order else len(order)):
        score, maximum = graded[unit]
        if score < maximum:
            return (f"next: finish {unit} ({points(score)} / {points(maximum)} points; "
                    f"`python -m autograder --only {unit}`)")
    last = max(order.index(u) for u in graded if u in order) if any(u in order for u in graded) else -1
    later = order[last + 1:]
    done_chapter = CHAPTER.get(module.get(order[last], ""), "") if last >= 0 else ""
    if not later:
        lesson = LESSONS.get(done_chapter)
        return "next: every exercise is at full marks" + (f"; the last lesson is {lesson}" if lesson else "")
    following = later[0]
    chapter = CHAPTER.get(module[following], "")
    where = f"`python -m autograder --only {following}`"
    if done_chapter and chapter != done_chapter and done_chapter in LESSONS:
        return (f"next: chapter {done_chapter}'s lesson, {LESSONS[done_chapter]} (`make notebooks`), then "
                f"{following} (chapter {chapter}; {where})")
    return f"next: {following} (chapter {chapter}; {where})"


SET_TEXT = {
    "public": "public checks (the inputs shipped with the course)",
    "hidden": "hidden checks (fresh inputs, judged with the reference)",
    "all": "public and hidden checks",
}


def table(results, impl: str, seconds: float, workers: int, which: str = "public", lateness=None,
          title: str = "") -> str:
    width = shutil.get_terminal_size((120, 24)).columns
    message_width = max(30, width - NAME_WIDTH - 16)
    out = [f"Autograder: implementation {impl}, {SET_TEXT.get(which, which)}" + (f"; {title}" if title else ""), ""]
    out.append(f"{'check':<{NAME_WIDTH}} {'points':>6} {'max':>5}  message")
    out.append("-" * min(width, NAME_WIDTH + 16 + message_width))
    exercises = []
    for result in results:
        if result.exercise not in exercises:
            exercises.append(result.exercise)
    for exercise in exercises:
        rows = [r for r in results if r.exercise == exercise]
        score, most = point_grid.total(r.score for r in rows), point_grid.total(r.max_score for r in rows)
        extra = " (extra credit)" if rows and all(getattr(r, "extra", False) for r in rows) else ""
        out.append(f"{exercise:<{NAME_WIDTH}} {points(score):>6} {points(most):>5}{extra}")
        for r in rows:
            name = _short("  " + r.title, NAME_WIDTH)
            shown = r.message if getattr(r, "counted", True) else "(not counted) " + r.message
            out.append(f"{name:<{NAME_WIDTH}} {points(r.score):>6} {points(r.max_score):>5}  "
                       f"{_short(shown, message_width)}")
    out.append("-" * min(width, NAME_WIDTH + 16 + message_width))
    details = [r for r in results if not r.full and not r.not_implemented]
    if details:
        out += ["", "Details:"]
        for r in details:
            out.append(f"* {r.name} ({points(r.score)}/{points(r.max_score)})")
            out += [f"    {line}" for line in r.message.splitlines()]
    out += ["", summary(results, lateness)]
    out.append(f"Elapsed: {seconds:.1f} s ({len(results)} checks, {workers} workers)")
    step = next_step(results)
    if step:
        out.append(step)
    return "\n".join(out)


def gradescope(results, seconds: float, lateness=None) -> dict:
    """Gradescope's results.json: score, execution_time, output, tests[].

    In an assignment (results marked by :func:`autograder.grade.mark`): each test's visibility is its
    own; an extra-credit test has ``max_score`` 0 (its points above the maximum); a hidden test that
    does not count scores 0 of 0 and says what it would have scored. ``lateness``
    (:class:`autograder.late.Lateness`) scales the score and says so in the output.
    """
    tests = []
    for r in results:
        score, most, output, name = point_grid.on_grid(r.score), point_grid.on_grid(r.max_score), r.message, r.name
        if not getattr(r, "counted", True):
            output = f"Not counted in the grade ({points(score)} / {points(most)}).\n{output}"
            score, most = 0.0, 0.0
        elif getattr(r, "extra", False):
            name, most = f"{name} (extra credit, {points(most)} points)", 0.0
        tests.append({
            "name": name,
            "score": score,
            "max_score": most,
            "output": output,
            "visibility": getattr(r, "visibility", "") or ("after_published" if r.hidden else "visible"),
        })
    return {
        "score": point_grid.scaled(earned(results), lateness.fraction if lateness is not None else 1),
        "execution_time": round(seconds, 3),
        "output": "\n".join(filter(None, [summary(results, lateness), next_step(results)])),
        "tests": tests,
    }


def write_json(path, data) -> None:
    jsonio.write_json(path, data, indent=2, newline=True)
