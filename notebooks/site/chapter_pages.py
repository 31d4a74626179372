"""A page per chapter: its lesson, its exercises with hints 1 and 2, and its assignment.

The chapters and their exercises are :data:`course.core.chapters.CHAPTERS`; an exercise's summary is
the first paragraph of its stub's docstring (``exercises/NAME.py``; for a check module that runs
several files together, ``autograder/checks/NAME.py``), its hints come from ``exercises/hints.json``
(what every tree ships), levels 1 (the approach) and 2 (the key identity) only: level 3 is the
result, which stays off the site. The assignment of the same name in ``autograder/course.toml`` gives
the title, the due date, the points and the late policy.
"""

import ast
import json
import posixpath
import textwrap
from pathlib import Path

from course.core import chapters
from course.core.hints import HINTS_FILE, LEVELS
from course.core.impl import REPO_ROOT

#: the hint levels the site shows
SHOWN_LEVELS = (1, 2)


def lesson_of(chapter, root: Path = REPO_ROOT) -> str | None:
    """The repository path of ``chapter``'s lesson notebook (``notebooks/chapterN_*.ipynb``), if any."""
    found = [rel for rel in chapters.files(chapter, root) if rel.startswith("notebooks/") and rel.endswith(".ipynb")]
    return found[0] if found else None


def _summary(name: str, root: Path) -> tuple:
    """``(first paragraph of the exercise's docstring, repository path of its file or None)``."""
    for rel in (f"exercises/{name}.py", f"autograder/checks/{name}.py"):
        path = root / rel
        if path.is_file():
            doc = ast.get_docstring(ast.parse(path.read_text(encoding="utf-8"))) or ""
            first = " ".join(doc.split("\n\n")[0].split())
            return first, rel if rel.startswith("exercises/") else None
    return "", None


def _hint_text(text: str) -> str:
    """A hint as plain text: its continuation lines dedented, reST's ``::`` and double backquotes dropped."""
    first, _, rest = text.partition("\n")
    body = (first + "\n" + textwrap.dedent(rest)).strip()
    return body.replace("::\n", ":\n").replace("``", "")


def _fence(text: str) -> str:
    ticks = "```"
    while ticks in text:
        ticks += "`"
    return f"{ticks}text\n{text}\n{ticks}"


def _link(rel: str | None, page_dir: str, source_url: str | None) -> str:
    if rel is None:
        return ""
    if source_url:
        return f"[`{rel}`]({source_url.rstrip('/')}/{rel})"
    return f"`{rel}`"


def _assignment_section(name: str, root: Path) -> list:
    from autograder.course_config import ConfigError, load

    try:
        assignment = load(root / "autograder" / "course.toml").assignment(name)
    except (ConfigError, KeyError):
        return []
    lines = ["## The assignment", "", f"**{assignment.title}** (`{assignment.name}` in the course configuration)", ""]
    if assignment.due is not None:
        lines.append(f"- Due: {assignment.due.isoformat(sep=' ', timespec='minutes')}")
    if assignment.maximum():
        lines.append(f"- Points: {assignment.maximum():g} (the public checks, which a student's tree grades: "
                     f"{assignment.maximum('public'):g})")
    graded = ", ".join(f"[`{e}`](#{e})" for e in assignment.exercises)
    lines.append(f"- Graded: {graded}")
    if assignment.optional:
        lines.append(f"- Extra credit: {', '.join(f'`{e}`' for e in assignment.optional)}")
    if assignment.solved:
        lines.append(f"- Handed out solved: {', '.join(f'`{e}`' for e in assignment.solved)}")
    late = assignment.late
    if late.per_day or late.per_hour:
        lines.append(f"- Late: {late.per_day * 100:g}% a day" if late.per_day
                     else f"- Late: {late.per_hour * 100:g}% an hour")
    lines += ["", "In the assignment's tree, `make check` (or `python -m autograder`) grades the public checks; "
              "the hidden checks, with inputs of their own, run where you hand it in.", ""]
    return lines


def chapter_page(chapter, lesson_site_path: str | None, source_url: str | None = None,
                 root: Path = REPO_ROOT) -> str:
    """The markdown of ``chapter``'s page (at ``chapters/NAME.md`` on the site)."""
    hints = json.loads((root / "exercises" / HINTS_FILE).read_text(encoding="utf-8"))
    page_dir = "chapters"
    number = chapter.name[2:]
    lines = [f"# Chapter {number}: {chapter.title}", ""]
    if lesson_site_path:
        lesson = posixpath.relpath(lesson_site_path, page_dir)
        lines += [f"The lesson: [the theory, the figures and the experiments]({lesson}), as a student's tree "
                  "runs it once the exercises are written.", ""]
        lines += ["```{toctree}", ":hidden:", "", lesson[:-len(".ipynb")], "```", ""]
    assignment = _assignment_section(chapter.name, root)
    exercises = ", ".join(f"[`{name}`](#{name})" for name in chapter.exercises)
    lines += [f"On this page: the exercises ({exercises}), each with its hints 1 and 2"
              + (", and [the assignment](#the-assignment)." if assignment else "."), ""]
    lines += ["## The exercises", "",
              "Each exercise is a file of `exercises/` with a TODO to write; `python -m autograder --only NAME` "
              "grades one, `python -m autograder hint NAME LEVEL` prints its hints (level 3, the result, "
              "is not on this site).", ""]
    for name in chapter.exercises:
        summary, rel = _summary(name, root)
        lines += [f"### {name}", "", summary, ""]
        if rel:
            lines += [f"File: {_link(rel, page_dir, source_url)}; graded by `python -m autograder --only {name}`.", ""]
        for owner, levels in hints.get(name, {}).items():
            where = f"{name}.{owner}" if owner else f"{name} (the module)"
            for level in SHOWN_LEVELS:
                lines += [f"**Hint {level} ({LEVELS[level]}), `{where}`**", "", _fence(_hint_text(levels[level - 1])),
                          ""]
    lines += assignment
    return "\n".join(lines).rstrip() + "\n"
