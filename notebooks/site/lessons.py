"""The lessons executed as a student's tree runs them, each execution cached.

A student tree (``autograder.release.stubs.release(check=True, student_dir=...)``: what ``python -m course
release --student DIR`` writes, outside the repository) whose ``exercises/`` hold the reference's
files with their ``HINTS`` taken out: the lessons' experiments and figures run as in the tree of a
student who wrote every exercise, and the tree holds no level-3 hint to print. There ``python -m
notebooks.build --execute [--small] --out DIR`` runs the lessons (the tree's own build, kernel and
settings). An executed lesson is kept in the cache folder under a key of its source, the framework's
and the reference's sources and the setting, so that a build whose sources did not change executes
nothing.
"""

import hashlib
import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

import nbformat

from course.core.errors import CourseError
from course.core.hints import without_hints
from course.core.impl import REPO_ROOT
from notebooks import build as notebook_build

#: the folders and files whose sources an execution depends on (with the lesson's own source)
DEPENDS_ON = ("course", "solutions", "autograder", "notebooks/build.py")


class LessonError(CourseError):
    """A lesson that did not run to the end in the student tree."""


def sources_digest(root: Path = REPO_ROOT) -> str:
    """A hash of the ``.py`` and ``.toml`` files under ``DEPENDS_ON`` (paths and contents), but those a student
    tree leaves out (``INSTRUCTOR_ONLY``: the release itself, the known mistakes), which no lesson runs."""
    from autograder.release.stubs import INSTRUCTOR_ONLY

    skipped = tuple(f"{rel}/" for rel in INSTRUCTOR_ONLY if rel != "solutions")
    digest = hashlib.sha256()
    for folder in DEPENDS_ON:
        where = Path(root, folder)
        for path in sorted(where.rglob("*")) if where.is_dir() else [where]:
            if path.relative_to(root).as_posix().startswith(skipped):
                continue
            if path.suffix in (".py", ".toml") and "__pycache__" not in path.parts:
                digest.update(path.relative_to(root).as_posix().encode() + b"\0" + path.read_bytes() + b"\0")
    return digest.hexdigest()


def cache_key(notebook: Path, small: bool, digest: str) -> str:
    """The key of one execution: the lesson's py:percent source, the setting and ``digest``."""
    source = notebook_build.NOTEBOOKS[notebook]
    return hashlib.sha256(source.read_bytes() + f"\0small={small}\0{digest}".encode()).hexdigest()[:16]


def write_student_tree(target: Path) -> Path:
    """A student tree at ``target`` (a new folder outside the repository) whose ``exercises/`` hold the
    reference without its hints."""
    from autograder.release import stubs

    stubs.release(check=True, student_dir=target)
    for path in sorted((REPO_ROOT / "solutions").glob("*.py")):
        if path.name != "__init__.py":
            (target / "exercises" / path.name).write_text(without_hints(path.read_text(), path))
    return target


def _run_in_tree(tree: Path, stems: list, small: bool, out: Path, log, on_written) -> None:
    """``python -m notebooks.build --execute`` in ``tree`` for ``stems``; ``on_written(path)`` as each is written."""
    from course.core.data import data_dir

    env = {k: v for k, v in os.environ.items() if not k.startswith(("PYTHON", "COURSE_IMPL"))}
    env["PYTHONPATH"] = str(tree)
    if data_dir().is_dir():  # the tree is elsewhere: point it at this repository's data folder
        env["COURSE_DATA"] = str(data_dir())
    argv = [sys.executable, "-m", "notebooks.build", "--execute", "--out", str(out), "--only", *stems]
    if small:
        argv.append("--small")
    log(f"executing {', '.join(stems)} in a student tree{' (small setting)' if small else ''}")
    tail: list = []
    with subprocess.Popen(argv, cwd=tree, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                          text=True) as run:
        assert run.stderr is not None
        for line in run.stderr:
            line = line.rstrip("\n")
            tail = (tail + [line])[-20:]
            if line.startswith(("wrote ", "not written", "failed")):
                log(line)
            if line.startswith("wrote "):
                on_written(Path(line[len("wrote "):].split(":")[0]))
    if run.returncode != 0:
        raise LessonError(f"python -m notebooks.build in the student tree exited {run.returncode}:\n"
                          + "\n".join(tail))


def executed(notebooks, cache: Path, small: bool = False, log=print) -> dict:
    """``{notebook: the executed .ipynb}`` for each of ``notebooks`` (keys of ``notebooks.build.NOTEBOOKS``),
    executed in a student tree where ``cache`` has no execution under the current key. A lesson whose
    cell fails (for any reason: every exercise is written) is an error naming the cell."""
    cache.mkdir(parents=True, exist_ok=True)
    digest = sources_digest()
    wanted = {nb: cache / f"{nb.stem}-{cache_key(nb, small, digest)}.ipynb" for nb in notebooks}
    missing = [nb for nb, path in wanted.items() if not path.is_file()]
    for nb in notebooks:
        if nb not in missing:
            log(f"{nb.name}: executed before (cached {wanted[nb].name})")
    if missing:
        failed: list = []

        def keep(path: Path) -> None:  # into the cache as soon as it is written: a stopped build resumes
            nb = next(nb for nb in missing if nb.name == path.name)
            found = notebook_build.failures(nbformat.read(path, as_version=4))
            bad = found["todo"] + found["after_todo"] + found["error"]
            if bad:
                failed.append(f"{nb.name}: cell {bad[0][0]} failed in the student tree: {bad[0][1]}")
                return
            for old in cache.glob(f"{nb.stem}-*.ipynb"):
                old.unlink()
            shutil.copyfile(path, wanted[nb])

        with tempfile.TemporaryDirectory(prefix="course-site-") as tmp:
            tree = write_student_tree(Path(tmp) / "tree")
            _run_in_tree(tree, [nb.stem for nb in missing], small, Path(tmp) / "executed", log, keep)
        if failed:
            raise LessonError("\n".join(failed))
    return wanted
