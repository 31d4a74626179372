"""The written questions of an assignment, taken from its lessons, and the answer sheet students fill.

A lesson (``notebooks/chapterN_*.py``, the py:percent source of ``chapterN_*.ipynb``) asks its
written questions in the markdown cell ``id="questions-md"``, one paragraph each, starting
``**Question K.**``. Its question ids are ``chN-qK`` (``ch3b-q2`` for chapter 3b's second), unique
across the course. A lesson belongs to the assignments whose exercises it checks (its
``check("NAME")`` cells name them; ``autograder/course.toml`` gives each assignment's exercises): the
written questions of an assignment are those of its lessons, in chapter order.

The answer sheet (:func:`sheet`) is one markdown file per assignment, ``answers.md``: a heading per
question id with the question's text under it and a place to write. Each student hands in their
filled copy with their code; :func:`parse_sheet` reads one back (``{question id: answer text}``).
The sheet holds the questions and nothing of the reference answers (``solutions/answers/``, the
instructor's).
"""

import re
from dataclasses import dataclass
from pathlib import Path

from course.core.impl import REPO_ROOT

#: the markdown cell of a lesson that asks its questions
CELL_ID = "questions-md"
QUESTION = re.compile(r"\*\*Question (\d+)\.\*\*\s*")
CHECK = re.compile(r"""\bcheck\(\s*["']([a-z_0-9]+)["']""")
#: under each heading of a sheet, where the student writes
PLACEHOLDER = "*(your answer)*"
HEADING = re.compile(r"^## +(\S*)(.*)$", re.M)
QUESTION_ID = re.compile(r"[a-z0-9]+-q\d+")


class QuestionsError(ValueError):
    """A lesson's questions or an answer sheet cannot be read; the message names the file and line."""


@dataclass(frozen=True)
class Question:
    id: str  # "ch1-q1"
    chapter: str  # "ch1"
    number: int
    text: str  # the question as the lesson asks it (markdown)
    lesson: str  # the lesson's notebook, notebooks/chapterN_*.ipynb


def chapter_of(source: Path) -> str:
    """``ch3b`` for ``notebooks/chapter3b_initialisation.py``."""
    match = re.match(r"chapter(\w+?)_", Path(source).name)
    if not match:
        raise QuestionsError(f"{source}: not a lesson (its name does not start chapterN_)")
    return "ch" + match.group(1)


def lessons(root: Path = REPO_ROOT) -> list:
    """The lessons' py:percent sources, in chapter order."""
    def key(path):
        match = re.match(r"chapter(\d+)(\w*?)_", path.name)
        return (int(match.group(1)), match.group(2)) if match else (10**6, path.name)

    return sorted((p for p in Path(root, "notebooks").glob("chapter*_*.py")), key=key)


def checked_exercises(source: Path) -> set:
    """The exercises a lesson checks (its ``check("NAME")`` cells)."""
    return set(CHECK.findall(Path(source).read_text(encoding="utf-8")))


def _cell(text: str, cell_id: str) -> tuple:
    """``(first line number, markdown text)`` of the markdown cell ``cell_id`` of py:percent ``text``."""
    lines = text.splitlines()
    for index, line in enumerate(lines):
        if line.startswith("# %%") and f'id="{cell_id}"' in line:
            body = []
            for following in lines[index + 1:]:
                if following.startswith("# %%"):
                    break
                body.append(following[2:] if following.startswith("# ") else following.lstrip("#"))
            return index + 2, "\n".join(body).strip()
    return 0, ""


def read_lesson(source: Path) -> list:
    """The questions of the lesson ``source`` (none when it asks none)."""
    source = Path(source)
    start, text = _cell(source.read_text(encoding="utf-8"), CELL_ID)
    if not text:
        return []
    chapter = chapter_of(source)
    where = f"notebooks/{source.with_suffix('.ipynb').name}"
    parts = QUESTION.split(text)
    found: list = []
    for number, body in zip(parts[1::2], parts[2::2]):
        number = int(number)
        if number != len(found) + 1:
            raise QuestionsError(f"{source}: line {start}: cell {CELL_ID}: question {number} follows question "
                                 f"{len(found)}; number them 1, 2, ...")
        found.append(Question(f"{chapter}-q{number}", chapter, number, " ".join(body.split()), where))
    return found


def chapters_of(assignment, root: Path = REPO_ROOT) -> list:
    """The lessons (sources) of ``assignment`` (:class:`autograder.course_config.Assignment`): those that
    check one of its exercises."""
    wanted = set(assignment.exercises)
    return [p for p in lessons(root) if checked_exercises(p) & wanted]


def of_assignment(assignment, root: Path = REPO_ROOT) -> list:
    """The written questions of ``assignment``, in chapter order."""
    return [q for source in chapters_of(assignment, root) for q in read_lesson(source)]


def sheet(assignment, questions, points: dict | None = None) -> str:
    """The answer sheet of ``assignment``: markdown, a ``## <id>`` heading per question (with its
    points when ``points`` gives them), the question, and the place to answer."""
    out = [f"# {assignment.name}: written answers", "",
           f"{assignment.title}. Write your answer under each question, in place of `{PLACEHOLDER}`, "
           "in a few sentences (markdown and $math$ are fine; ### for headings of your own); keep the `## ` "
           "headings as they are. "
           "Hand this file in, named `answers.md`, with your code.", ""]
    for q in questions:
        worth = f" ({points[q.id]:g} points)" if points and q.id in points else ""
        out += [f"## {q.id}{worth}", "", f"**Question {q.number}** (from `{q.lesson}`). {q.text}", "",
                "**Answer:**", "", PLACEHOLDER, ""]
    return "\n".join(out)


def parse_sheet(text: str, path="answers.md", questions=()) -> dict:
    """``{question id: answer}`` of a filled answer sheet (the text after ``**Answer:**`` under each
    ``## <id>`` heading; '' where the student left the placeholder). A ``## `` heading that names no
    question (of ``questions``, when given) or one seen twice is a :class:`QuestionsError` naming the line."""
    known = {q.id for q in questions}
    answers: dict = {}
    matches = list(HEADING.finditer(text))
    for k, match in enumerate(matches):
        qid = match.group(1)
        line = text.count("\n", 0, match.start()) + 1
        if not QUESTION_ID.fullmatch(qid) or (known and qid not in known):
            raise QuestionsError(f"{path}: line {line}: heading {match.group(0).strip()!r} names no question of this "
                                 f"assignment (expected ## followed by one of {', '.join(sorted(known)) or 'chN-qK'}; "
                                 "use ### for headings of your own)")
        if qid in answers:
            raise QuestionsError(f"{path}: line {line}: question {qid} answered twice")
        body = text[match.end():matches[k + 1].start() if k + 1 < len(matches) else len(text)]
        _, mark, answer = body.partition("**Answer:**")
        answer = (answer if mark else body).strip()
        answers[qid] = "" if answer in ("", PLACEHOLDER) else answer
    return answers
