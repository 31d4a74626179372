"""The rubric of an assignment's written questions: ``solutions/rubrics/<assignment>.toml``.

One table per question id (:mod:`autograder.classroom.questions`), its maximum and its rubric items::

    [ch1-q1]
    points = 4
    items = [
      { id = "linearised", points = 2, text = "the GN step minimises the linearised cost; chi2 explodes" },
      { id = "trust-region", points = 2, text = "a larger lambda is a smaller, steeper trust-region step" },
    ]

``points`` (a number > 0) is what the question is worth; ``items`` (optional) the rubric items, each
an ``id`` (letters, digits, ``-`` and ``_``; unique in its question), its ``points`` (> 0) and its
``text``; the items' points sum to the question's. A mark (:mod:`autograder.classroom.marks`) gives
a question's points directly or as the items the answer earned. A question without a table, or an
assignment without a file, has the default rubric (:func:`default`: 4 points in three items that
point the grader to the reference answer, ``solutions/answers/chapterN.md``);
``python -m autograder.classroom.written rubric`` writes it out to edit. Its items say what a good
answer holds, so the file is the reference's: under ``solutions/``, which no student tree holds and
the sandbox keeps from the students' code (Gradescope's zip included), and with the release's omit
mark (:data:`OMIT`) as its first line, so that the release renders nothing of it into ``exercises/``.
A mistake is a :class:`RubricError` naming the file, the key and the field.
"""

import re
import sys
from dataclasses import dataclass
from pathlib import Path

from autograder.course_config import did_you_mean
from course.core.impl import REPO_ROOT

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - Python 3.10
    import tomli as tomllib

FOLDER = REPO_ROOT / "solutions" / "rubrics"
OMIT = "# RELEASE: omit"
ITEM_ID = re.compile(r"[A-Za-z0-9_-]+")
#: the default rubric of a question: (id, points, text); {answers} is the reference answer's place
DEFAULT_ITEMS = (
    ("argument", 2.0, "the key argument of the reference answer ({answers}, its points in bold)"),
    ("evidence", 1.0, "uses the lesson's own runs: the numbers, figures or tables the question names"),
    ("correct", 1.0, "no wrong claim; the terms used as the lesson defines them"),
)


class RubricError(ValueError):
    """A mistake in a rubric file: the file, the key and the field."""


@dataclass(frozen=True)
class Item:
    id: str
    points: float
    text: str


@dataclass(frozen=True)
class Rubric:
    """One question's: its maximum and items."""

    question: str
    points: float
    items: tuple = ()

    def item(self, item_id: str) -> Item | None:
        return next((i for i in self.items if i.id == item_id), None)


def path_of(assignment_name: str, folder: Path = FOLDER) -> Path:
    return Path(folder) / f"{assignment_name}.toml"


def default(question) -> Rubric:
    """The default rubric of ``question`` (:class:`autograder.classroom.questions.Question`)."""
    answers = f"solutions/answers/chapter{question.chapter[2:]}.md, question {question.number}"
    items = tuple(Item(i, p, text.format(answers=answers)) for i, p, text in DEFAULT_ITEMS)
    return Rubric(question.id, sum(i.points for i in items), items)


def _positive(value, path, key) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not value > 0 or value != value:
        raise RubricError(f"{path}: {key}: expected a number > 0, got {value!r}")
    return float(value)


def parse(data: dict, questions, path="<rubric>") -> dict:
    """``{question id: Rubric}`` of every question in ``questions``, from the TOML tables ``data``."""
    known = {q.id: q for q in questions}
    for key in data:
        if key not in known:
            raise RubricError(f"{path}: [{key}]: no written question has this id{did_you_mean(key, known, n=3)}; "
                              f"this assignment's are {', '.join(known) or 'none'}")
    out = {}
    for qid, question in known.items():
        if qid not in data:
            out[qid] = default(question)
            continue
        table = data[qid]
        if not isinstance(table, dict):
            raise RubricError(f"{path}: {qid}: expected a table [{qid}] with points and items, got {table!r}")
        for field in table:
            if field not in ("points", "items"):
                near = did_you_mean(field, ("points", "items"), n=3)
                raise RubricError(f"{path}: [{qid}].{field}: unknown field{near}; "
                                  "expected points and items")
        if "points" not in table:
            raise RubricError(f"{path}: [{qid}].points: missing (what the question is worth, > 0)")
        points = _positive(table["points"], path, f"[{qid}].points")
        raw = table.get("items", [])
        if not isinstance(raw, list):
            raise RubricError(f"{path}: [{qid}].items: expected a list of {{ id, points, text }}, got {raw!r}")
        items: list = []
        for k, entry in enumerate(raw):
            key = f"[{qid}].items[{k}]"
            if not isinstance(entry, dict):
                raise RubricError(f"{path}: {key}: expected {{ id = ..., points = ..., text = ... }}, got {entry!r}")
            for field in entry:
                if field not in ("id", "points", "text"):
                    raise RubricError(f"{path}: {key}.{field}: unknown field; expected id, points, text")
            for field in ("id", "points", "text"):
                if field not in entry:
                    raise RubricError(f"{path}: {key}.{field}: missing")
            item_id, text = entry["id"], entry["text"]
            if not isinstance(item_id, str) or not ITEM_ID.fullmatch(item_id):
                raise RubricError(f"{path}: {key}.id: expected letters, digits, - and _, got {item_id!r}")
            if any(i.id == item_id for i in items):
                raise RubricError(f"{path}: {key}.id: {item_id!r} is already an item of {qid}")
            if not isinstance(text, str) or not text.strip():
                raise RubricError(f"{path}: {key}.text: expected what the answer must hold, got {text!r}")
            items.append(Item(item_id, _positive(entry["points"], path, f"{key}.points"), text.strip()))
        total = sum(i.points for i in items)
        if items and abs(total - points) > 1e-9 * max(1.0, points):
            raise RubricError(f"{path}: [{qid}].points: {points:g}, but its items' points sum to {total:g}")
        out[qid] = Rubric(qid, points, tuple(items))
    return out


def read(assignment_name: str, questions, folder: Path = FOLDER) -> dict:
    """``{question id: Rubric}`` of the assignment: its file's, the default where it has none."""
    path = path_of(assignment_name, folder)
    if not path.is_file():
        return parse({}, questions, path)
    try:
        with open(path, "rb") as handle:
            data = tomllib.load(handle)
    except (OSError, tomllib.TOMLDecodeError) as exc:
        raise RubricError(f"{path}: not a readable TOML file ({exc})") from None
    return parse(data, questions, path)


def _string(text: str) -> str:
    return '"' + text.replace("\\", "\\\\").replace('"', '\\"') + '"'


def text_of(assignment_name: str, questions, rubrics: dict) -> str:
    """``rubrics`` as the TOML file :func:`read` reads (each question's text as a comment above it)."""
    out = [OMIT, f"# The rubric of assignment {assignment_name}'s written questions "
                 "(autograder/classroom/rubric.py says what each key means).", ""]
    for q in questions:
        r = rubrics[q.id]
        out.append(f"# {q.id}: {q.text[:150]}{'...' if len(q.text) > 150 else ''}")
        out += [f"[{q.id}]", f"points = {r.points:g}", "items = ["]
        out += [f"  {{ id = {_string(i.id)}, points = {i.points:g}, text = {_string(i.text)} }}," for i in r.items]
        out += ["]", ""]
    return "\n".join(out)
