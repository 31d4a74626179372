"""One submission's files: find the folder of an upload that holds the exercise modules,
and copy them into a fresh package the grader can load.

A student uploads their exercise files at the top level or inside one folder, perhaps with
other files beside them (a zip's ``__MACOSX``, caches, a virtual environment).
:func:`locate_submission` picks the folder holding the most files named like a module of
``exercises/``; :func:`stage_submission` copies only those (regular files, never symlinks)
and the unwritten stub for every module the student did not send. Used for one submission
on Gradescope (``autograder.release.gradescope``) and for a whole class
(:mod:`autograder.classroom`). Standard library only.
"""

import hashlib
import os
import shutil
import stat
from dataclasses import dataclass, field
from pathlib import Path

#: folders of an upload that never hold the student's work
IGNORED_UPLOAD_DIRS = {"__MACOSX", "__pycache__", ".git", ".ipynb_checkpoints", ".venv", "venv"}


def exercise_modules(source: Path) -> list:
    """File names of the exercise modules (``damping.py``, ...), without ``__init__.py``."""
    return sorted(p.name for p in Path(source, "exercises").glob("*.py") if p.name != "__init__.py")


@dataclass
class Located:
    """The folder of a submission that holds the exercise files, or why there is none."""

    folder: Path | None = None
    found: list = field(default_factory=list)  # exercise file names in that folder
    message: str = ""


def _regular(path: Path) -> bool:
    try:
        return stat.S_ISREG(os.lstat(path).st_mode)
    except OSError:
        return False


def locate_submission(submission, modules, graded=None) -> Located:
    """The folder under ``submission`` (itself included) holding the most files named like
    an exercise module (regular files, not symlinks); ties go to the shallowest, then to
    the first by name. ``message`` says what was found, or that nothing was, and which of
    ``graded`` (the files an assignment grades; default every module) are missing."""
    submission = Path(submission)
    wanted = set(modules)
    best = None
    if submission.is_dir():
        for directory, dirs, names in os.walk(submission):  # does not follow symlinks
            dirs[:] = sorted(d for d in dirs if d not in IGNORED_UPLOAD_DIRS and not d.startswith("."))
            found = sorted(n for n in names if n in wanted and _regular(Path(directory, n)))
            if not found:
                continue
            where = Path(directory)
            key = (-len(found), len(where.relative_to(submission).parts), str(where))
            if best is None or key < best[0]:
                best = (key, where, found)
    if best is None:
        uploaded = _listing(submission)
        return Located(message=(
            "No exercise file found in the submission. Upload your exercise files as they are named in "
            f"exercises/ ({', '.join(sorted(wanted))}), at the top level or inside one folder. "
            + (f"The submission holds: {uploaded}." if uploaded else "The submission is empty.")))
    _, where, found = best
    shown = where.relative_to(submission).as_posix()
    shown = "the top level of the submission" if shown == "." else f"{shown}/"
    missing = sorted((wanted if graded is None else set(graded)) - set(found))
    message = f"Graded the exercise files in {shown}: {', '.join(found)}."
    if missing:
        message += (f"\nNot in the submission, graded as the unwritten stubs (0 points): {', '.join(missing)}.")
    return Located(folder=where, found=found, message=message)


def _listing(submission: Path, limit=20) -> str:
    names = []
    if submission.is_dir():
        for directory, dirs, files in os.walk(submission):
            dirs.sort()
            for name in sorted(files):
                names.append(Path(directory, name).relative_to(submission).as_posix())
    shown = ", ".join(names[:limit])
    return shown + (f" and {len(names) - limit} more" if len(names) > limit else "")


def stage_submission(located: Located, source, target) -> Path:
    """A fresh package at ``target``: the student's exercise files (copied, regular files
    only), the stub from ``exercises/`` for each module missing, and ``__init__.py`` (the
    student's when it is in the same folder, else ``exercises/__init__.py``)."""
    source, target = Path(source), Path(target)
    if located.folder is None:
        raise ValueError("nothing to stage: " + located.message)
    target.mkdir(parents=True)
    stubs = Path(source, "exercises")
    for name in exercise_modules(source) + ["__init__.py"]:
        student = located.folder / name
        origin = student if _regular(student) else stubs / name
        shutil.copyfile(origin, target / name, follow_symlinks=False)
        os.chmod(target / name, 0o644)
    return target


def content_hash(located: Located) -> str:
    """A hash of what is graded of a submission: the names and bytes of its exercise files (the
    stubs put in for the others are not the student's). Equal hashes, equal grading input."""
    digest = hashlib.sha256()
    if located.folder is not None:
        for name in sorted(located.found):
            data = (located.folder / name).read_bytes()
            digest.update(f"{name}\0{len(data)}\0".encode())
            digest.update(data)
    return "sha256:" + digest.hexdigest()
