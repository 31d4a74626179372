"""The students' filled answer sheets, gathered for marking one question at a time.

Each submission (a folder of uploads or Gradescope's export, :mod:`autograder.classroom.intake`)
holds its sheet as ``answers.md`` (:func:`autograder.classroom.questions.sheet`), at its top or in
a subfolder. :func:`gather` reads them all; :func:`documents` writes one markdown document per
question: its text, its rubric items (the ids a mark names) and every student's answer under the
student's id, the order of the marks file. A submission without a sheet, or with a sheet whose
headings were changed, is named in the problems (the student scores 0 there unless marked).
"""

from dataclasses import dataclass, field
from pathlib import Path

from autograder.classroom import questions

SHEET = "answers.md"


@dataclass
class Gathered:
    answers: dict = field(default_factory=dict)  # {submission id: {question id: answer}}
    names: dict = field(default_factory=dict)  # {submission id: name}
    problems: list = field(default_factory=list)  # one sentence each


def find_sheet(folder: Path) -> Path | None:
    """The submission's ``answers.md``: the shallowest one (case-insensitive), None without one."""
    found = [p for p in Path(folder).rglob("*") if p.is_file() and p.name.lower() == SHEET]
    return min(found, key=lambda p: (len(p.parts), str(p))) if found else None


def gather(subs, asked) -> Gathered:
    """The sheets of the submissions ``subs`` for the questions ``asked``."""
    out = Gathered()
    for sub in subs:
        out.names[sub.id] = sub.name
        path = find_sheet(sub.path)
        if path is None:
            out.problems.append(f"{sub.id}: no {SHEET} in the submission")
            continue
        try:
            text = path.read_text(encoding="utf-8-sig")
            got = questions.parse_sheet(text, path, asked)
        except (OSError, UnicodeDecodeError, questions.QuestionsError) as exc:
            out.problems.append(f"{sub.id}: {exc}")
            continue
        missing = [q.id for q in asked if q.id not in got]
        if missing:
            out.problems.append(f"{sub.id}: {path}: no heading ## {', ## '.join(missing)}")
        out.answers[sub.id] = got
    return out


def documents(asked, rubrics: dict, gathered: Gathered) -> dict:
    """``{file name: markdown}``: one document per question with every student's answer."""
    files = {}
    for q in asked:
        r = rubrics[q.id]
        lines = [f"# {q.id}: {r.points:g} points", "", f"**Question {q.number}** (`{q.lesson}`). {q.text}", "",
                 "Rubric items (the `items` of a mark):", ""]
        lines += [f"- `{item.id}` ({item.points:g}): {item.text}" for item in r.items] or ["- (none: give points)"]
        lines.append("")
        for sub_id, name in gathered.names.items():
            answer = gathered.answers.get(sub_id, {}).get(q.id, "")
            lines += [f"## {sub_id}" + (f" ({name})" if name and name != sub_id else ""), "",
                      answer or "*(no answer)*", ""]
        files[f"{q.id}.md"] = "\n".join(lines)
    return files
