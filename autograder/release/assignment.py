"""One assignment handed out: ``python -m course release --assignment NAME --student DIR | --gradescope FILE.zip``.

The assignment comes from the course configuration (:mod:`autograder.course_config`). What a
student tree of assignment NAME holds, beside the framework:

* ``exercises/``: the stubs of NAME's exercise files; the files NAME hands out ``solved``, as the
  reference code (a solution as it is released after its due date: the code between the solution
  markers kept, the marker lines dropped); the stubs of earlier assignments' other files (students
  may still write them); ``hints.json``, the hints of those stubs. No file of a later assignment.
* ``autograder/``: the public data (``expected/``) of NAME's check modules only; no check module or
  task of a later assignment; ``course.toml`` holding NAME alone and no personal data (no extensions:
  :mod:`autograder.release.carried_config`); ``ASSIGNMENT`` naming it, so that
  ``python -m autograder``, ``make check`` and ``pytest`` grade NAME with its points; ``given/``, the
  solved files the grader composes with the student's (:func:`autograder.grade.compose`).
* the framework of the chapters up to the latest one NAME or an earlier assignment hands out exercises
  of, and of no later chapter (no later problem family, peers, engine, notebook or notebook helper):
  ``course.core.chapters`` says which paths each chapter adds; a command that needs a later one says
  that chapter is not handed out yet.
* ``README.md``: the student's, opening with what the assignment asks, gives and when it is due.

The Gradescope zip of NAME is the whole grader (the reference too, for the hidden checks) with
``exercises/`` holding NAME's stubs alone (what a student uploads; nothing else is asked for), and
the same ``ASSIGNMENT``, ``course.toml`` (with NAME's extensions: the zip is the instructor's, never
shown to students) and ``given/``: ``run_autograder`` grades NAME only, with its points, visibilities
and late policy (from Gradescope's ``submission_metadata.json``, whose per-user due dates are
Gradescope's extensions).
"""

import json
import shutil
from pathlib import Path

from autograder.release.carried_config import config_text
from autograder.release.stubs import BEGIN, END
from course.core import chapters
from course.core.hints import HINTS_FILE
from course.core.impl import REPO_ROOT


def released(source: str) -> str:
    """A reference file as it is handed out solved: the solution markers' lines dropped."""
    return "".join(line for line in source.splitlines(keepends=True) if line.strip() not in (BEGIN, END))


def _owner_files(course) -> dict:
    """``{exercise file: assignment name}``."""
    return {module: a.name for a in course.assignments.values() for module in a.modules}


def _check_owner(course) -> dict:
    """``{check module: assignment name}``."""
    return {exercise: a.name for a in course.assignments.values() for exercise in a.exercises}


def exercise_files(course, assignment, stubs: dict, root: Path = REPO_ROOT) -> dict:
    """``{file name: text}`` of the assignment's ``exercises/`` (see the module docstring); ``stubs``
    is :func:`autograder.release.stubs.render` of ``solutions/``."""
    earlier = set(course.earlier(assignment.name))
    owners = _owner_files(course)
    files = {"__init__.py": stubs["__init__.py"]}
    for rel, text in stubs.items():
        module = rel[:-3] if rel.endswith(".py") and "/" not in rel else ""
        if not module or module in assignment.solved:
            continue
        if module in assignment.modules or owners.get(module) in earlier:
            files[rel] = text
    for module in assignment.solved:
        files[f"{module}.py"] = released(Path(root, "solutions", f"{module}.py").read_text())
    if HINTS_FILE in stubs:  # ``python -m autograder hint`` reads it: the hints of the stubs handed out
        hints = {module: owners for module, owners in json.loads(stubs[HINTS_FILE]).items()
                 if f"{module}.py" in files and module not in assignment.solved}
        files[HINTS_FILE] = json.dumps(hints, indent=1, sort_keys=True) + "\n"
    return dict(sorted(files.items()))


def given_files(assignment, root: Path = REPO_ROOT) -> dict:
    """``{file name: text}`` of ``autograder/given/``: the solved files, as released."""
    files = {"__init__.py": '"""The solved exercise files handed out with this assignment (reference code)."""\n'}
    for module in assignment.solved:
        files[f"{module}.py"] = released(Path(root, "solutions", f"{module}.py").read_text())
    return files


def later(course, name: str) -> list:
    names = list(course.assignments)
    return names[names.index(name) + 1:]


def dropped(course, assignment, root: Path = REPO_ROOT) -> list:
    """Paths (relative to the repository) a student tree of ``assignment`` does not hold."""
    out = []
    owners = _check_owner(course)
    for path in sorted(Path(root, "autograder", "expected").glob("*.json")):
        if path.stem not in assignment.exercises:
            out.append(f"autograder/expected/{path.name}")
    after = later(course, assignment.name)
    for module, owner in owners.items():
        if owner in after:
            for folder in ("checks", "tasks"):
                if Path(root, "autograder", folder, f"{module}.py").is_file():
                    out.append(f"autograder/{folder}/{module}.py")
    handed = chapters.up_to(handed_out_exercises(course, assignment))
    for one in chapters.CHAPTERS[len(handed):]:
        out += chapters.files(one, root)
    return out


def handed_out_exercises(course, assignment) -> list:
    """The check modules of ``assignment`` and of the assignments before it, those it gives solved included:
    the tree holds the framework of their chapters (:func:`course.core.chapters.up_to`) and no later one's."""
    names = [name for other in course.earlier(assignment.name) for name in course.assignment(other).exercises]
    return names + list(assignment.exercises) + [m for m in assignment.solved if m in _check_owner(course)]


# ---------------------------------------------------------------- the configuration it carries


def assignment_files(course, assignment, root: Path = REPO_ROOT, personal: bool = False) -> dict:
    """``{path relative to the tree: text}`` that make a tree grade ``assignment``; its configuration
    keeps the extensions only when ``personal`` (the Gradescope zip's, never a student tree's)."""
    files = {"autograder/ASSIGNMENT": assignment.name + "\n",
             "autograder/course.toml": config_text(Path(assignment.source), assignment.name, personal)}
    files.update({f"autograder/given/{rel}": text for rel, text in given_files(assignment, root).items()})
    return files


# ---------------------------------------------------------------- the student tree


def readme_section(assignment, course=None) -> str:
    late = assignment.late
    if late.per_day or late.per_hour:
        rate = f"{100 * (late.per_day or late.per_hour):g}% per started {'day' if late.per_day else 'hour'} late"
    else:
        rate = "no penalty for lateness"
    if late.cutoff is not None:
        rate += f", nothing after {late.cutoff.total_seconds() / 86400:g} days late"
    lines = [f"## This assignment: {assignment.name}, {assignment.title}", "",
             f"Write: {', '.join(f'`exercises/{m}.py`' for m in assignment.modules)}."]
    optional = [m for name in assignment.optional for m in [name]]
    if optional:
        lines.append(f"Optional (extra credit, not in the maximum): {', '.join(f'`{m}`' for m in optional)}.")
    if assignment.solved:
        lines.append("Given solved (the reference code, as released after its due date): "
                     f"{', '.join(f'`exercises/{m}.py`' for m in assignment.solved)}.")
    due = assignment.due.isoformat() if assignment.due else "not set"
    lines += [f"Due {due}; {rate}.",
              f"`make check` and `pytest` grade this assignment only: {assignment.maximum('public'):g} points on the "
              "public checks; the hidden checks run when you submit.", ""]
    if course is not None:
        held = chapters.up_to(handed_out_exercises(course, assignment))
        if held and held[-1] is not chapters.CHAPTERS[-1]:
            lines[-1:] = [f"This tree holds the course up to chapter {held[-1].name[2:]} ({held[-1].title}); the "
                          "later chapters come with their assignments (their commands say so here).", ""]
    return "\n".join(lines) + "\n"


def write_student_tree(target, course, assignment, stub_files: dict, root: Path = REPO_ROOT) -> None:
    """The student tree of ``assignment`` at the new directory ``target`` (see the module docstring)."""
    from autograder.release.stubs import write_student_tree as write_tree

    target, root = Path(target), Path(root).resolve()
    write_tree(target, exercise_files(course, assignment, stub_files, root), root)
    for rel in dropped(course, assignment, root):
        path = target / rel
        if path.is_dir():
            shutil.rmtree(path)
        elif path.exists():
            path.unlink()
    for rel, text in assignment_files(course, assignment, root).items():
        path = target / rel
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text)
    readme = target / "README.md"
    text = readme.read_text()
    hints = target / "exercises" / HINTS_FILE
    hinted = json.loads(hints.read_text()) if hints.is_file() else {}
    example = next((m for m in assignment.modules if m in hinted), "")
    if example:  # the README's hint commands name an exercise and a function of this tree
        text = text.replace("hint pose_graph_edge 1", f"hint {example} 1")
        function = next((owner for owner in hinted[example] if owner), "")
        if function:
            text = text.replace("hint dogleg_step 2", f"hint {function.split('.')[-1]} 2")
    head, _, rest = text.partition("\n\n")
    readme.write_text(f"{head}\n\n{readme_section(assignment, course)}\n{rest}")


def bundle_overlay(course, assignment, stub_files: dict, root: Path = REPO_ROOT) -> dict:
    """``{member of the Gradescope zip: text}`` replacing its ``exercises/`` and adding the assignment's
    files (the zip keeps the rest of the grader, the reference included)."""
    files = {f"exercises/{rel}": text for rel, text in stub_files.items()
             if rel == "__init__.py" or rel[:-3] in assignment.modules}
    files.update(assignment_files(course, assignment, root, personal=True))
    return files
