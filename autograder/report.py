"""The results, for a terminal and for Gradescope (``results.json``)."""

import shutil

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


def total(results) -> str:
    """The points of ``results`` as the table's last lines print them: ``"14 / 30"``."""
    return f"{points(sum(r.score for r in results))} / {points(sum(r.max_score for r in results))}"


def summary(results) -> str:
    lines = [f"Total: {total(results)}"]
    todos = not_implemented(results)
    if todos:
        lines.append(f"Not implemented ({len(todos)}):")
        lines += [f"  TODO {name}: not implemented" for name in todos]
    return "\n".join(lines)


SET_TEXT = {
    "public": "public checks (the inputs shipped with the course)",
    "hidden": "hidden checks (fresh inputs, judged with the reference)",
    "all": "public and hidden checks",
}


def table(results, impl: str, seconds: float, workers: int, which: str = "public") -> str:
    width = shutil.get_terminal_size((120, 24)).columns
    message_width = max(30, width - NAME_WIDTH - 16)
    out = [f"Autograder: implementation {impl}, {SET_TEXT.get(which, which)}", ""]
    out.append(f"{'check':<{NAME_WIDTH}} {'points':>6} {'max':>5}  message")
    out.append("-" * min(width, NAME_WIDTH + 16 + message_width))
    exercises = []
    for result in results:
        if result.exercise not in exercises:
            exercises.append(result.exercise)
    for exercise in exercises:
        rows = [r for r in results if r.exercise == exercise]
        score, maximum = sum(r.score for r in rows), sum(r.max_score for r in rows)
        out.append(f"{exercise:<{NAME_WIDTH}} {points(score):>6} {points(maximum):>5}")
        for r in rows:
            name = _short("  " + r.title, NAME_WIDTH)
            out.append(f"{name:<{NAME_WIDTH}} {points(r.score):>6} {points(r.max_score):>5}  "
                       f"{_short(r.message, message_width)}")
    out.append("-" * min(width, NAME_WIDTH + 16 + message_width))
    details = [r for r in results if not r.full and not r.not_implemented]
    if details:
        out += ["", "Details:"]
        for r in details:
            out.append(f"* {r.name} ({points(r.score)}/{points(r.max_score)})")
            out += [f"    {line}" for line in r.message.splitlines()]
    out += ["", summary(results)]
    out.append(f"Elapsed: {seconds:.1f} s ({len(results)} checks, {workers} workers)")
    return "\n".join(out)


def gradescope(results, seconds: float) -> dict:
    """Gradescope's results.json: score, execution_time, output, tests[]."""
    tests = []
    for r in results:
        tests.append({
            "name": r.name,
            "score": round(r.score, 4),
            "max_score": r.max_score,
            "output": r.message,
            "visibility": "after_published" if r.hidden else "visible",
        })
    return {
        "score": round(sum(r.score for r in results), 4),
        "execution_time": round(seconds, 3),
        "output": summary(results),
        "tests": tests,
    }


def write_json(path, data) -> None:
    jsonio.write_json(path, data, indent=2, newline=True)
