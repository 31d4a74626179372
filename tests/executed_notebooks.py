"""One execution of each notebook per test run, shared by the test files that read its outputs.

``executed_small(path)`` runs ``notebooks.build.execute(..., small=True)`` on the notebook of ``path``
(a key of ``notebooks.build.NOTEBOOKS``) once per test run: the first worker to ask executes it and
writes it to a folder the run's workers share (``SHARED``, in pytest's temporary folder of the run), the
others wait for it and read it. Without xdist it is kept in this process. Each call returns a fresh
copy, so a test may change what it gets.
"""

import copy
import os
import tempfile
import time
from pathlib import Path

import nbformat

from notebooks import build

_HERE: dict = {}


#: the folder the run's xdist workers share (set by conftest's ``shared_notebooks``: in the run's temporary
#: folder, which pytest removes with the older runs'); None without xdist
SHARED: Path | None = None


def _shared_folder() -> Path | None:
    if SHARED is not None:
        SHARED.mkdir(exist_ok=True)
    return SHARED


def _execute(path):
    nb = build.read(build.NOTEBOOKS[path])
    build.execute(nb, timeout=300, small=True)
    return nb


def executed_small(path) -> nbformat.NotebookNode:
    """The notebook of ``path`` executed in the small setting (a copy)."""
    folder = _shared_folder()
    if folder is None:
        if path not in _HERE:
            _HERE[path] = _execute(path)
        return copy.deepcopy(_HERE[path])
    target = folder / f"{Path(path).stem}.ipynb"

    def make(where: Path):
        partial = target.with_suffix(".partial")
        nbformat.write(_execute(path), partial)
        os.replace(partial, target)

    _locked(folder, Path(path).stem, make)
    return nbformat.read(target, as_version=4)


def _locked(folder: Path, name: str, make):
    """``make(folder)`` once per test run under the lock ``name`` (another worker waits and reuses it)."""
    lock, done = folder / f"{name}.lock", folder / f"{name}.done"
    while True:
        try:
            handle = os.open(lock, os.O_CREAT | os.O_EXCL | os.O_WRONLY)
            break
        except FileExistsError:
            time.sleep(0.2)
    try:
        if not done.is_file():
            make(folder)
            done.write_text("")
    finally:
        os.close(handle)
        os.unlink(lock)


def chapter_1_student_build(python: str) -> dict:
    """A student tree with chapter 1 written (the reference's three modules) whose every notebook was
    built by ``python -m notebooks.build --execute --small`` (the command of ``make notebooks``, quick
    setting; the data folder where it is here), once per test run: ``{"tree", "out" (the folder of the
    .ipynb), "returncode", "output"}``."""
    import json
    import shutil
    import subprocess

    from autograder.release import stubs as release
    from course.core.data import data_dir
    from course.core.impl import REPO_ROOT

    folder = _shared_folder() or Path(tempfile.mkdtemp(prefix="course-chapter-1-build-"))

    def make(where: Path):
        tree, out = where / "tree", where / "out"
        shutil.rmtree(tree, ignore_errors=True)
        release.release(check=True, student_dir=tree)
        for name in ("curve_model", "gauss_newton", "damping"):
            shutil.copy(REPO_ROOT / "solutions" / f"{name}.py", tree / "exercises" / f"{name}.py")
        env = {k: v for k, v in os.environ.items() if not k.startswith(("PYTHON", "COURSE_IMPL"))}
        env["PYTHONPATH"] = str(tree)
        if data_dir().is_dir():  # the tree is elsewhere: point it at the data folder
            env["COURSE_DATA"] = str(data_dir())
        done = subprocess.run([python, "-m", "notebooks.build", "--execute", "--small", "--out", str(out)],
                              cwd=tree, env=env, capture_output=True, text=True, timeout=900)
        (where / "build.json").write_text(json.dumps({"returncode": done.returncode,
                                                      "output": done.stdout + done.stderr}))

    if _shared_folder() is None and "chapter_1_build" in _HERE:
        return _HERE["chapter_1_build"]
    _locked(folder, "chapter-1-build", make)
    result = {"tree": folder / "tree", "out": folder / "out", **json.loads((folder / "build.json").read_text())}
    _HERE["chapter_1_build"] = result
    return result


def cell_text(nb) -> dict:
    """``{code cell id: its printed text, then its result's text}``."""
    return {c.id: "\n".join(o.get("text", "") for o in c.outputs if o.output_type == "stream") + "\n".join(
        o["data"].get("text/plain", "") for o in c.outputs if o.output_type == "execute_result")
        for c in nb.cells if c.cell_type == "code"}


def cell_outputs(nb) -> tuple:
    """``(outputs, text, results)``, each ``{code cell id: ...}``: the outputs, the printed text, the results' text."""
    outputs = {c.id: c.outputs for c in nb.cells if c.cell_type == "code"}
    text = {k: "".join(o.get("text", "") for o in v if o.output_type == "stream") for k, v in outputs.items()}
    results = {k: "".join(o["data"].get("text/plain", "") for o in v if o.output_type == "execute_result")
               for k, v in outputs.items()}
    return outputs, text, results


def assert_hints_and_checks_at_full_marks(nb, cells) -> None:
    """No cell of ``nb`` (run with the reference) failed; for each ``(hint id, check id, exercise)`` of ``cells``
    the hint cell printed level 1 alone, the check cell graded ``exercise`` to full marks, both before the
    experiments."""
    errors = [(c.id, o.get("ename"), o.get("evalue")) for c in nb.cells if c.cell_type == "code"
              for o in c.outputs if o.output_type == "error"]
    assert not errors, errors
    text = cell_text(nb)
    order = [c.id for c in nb.cells]
    for hint_id, check_id, exercise in cells:
        assert "hint 1 of 3" in text[hint_id] and "Hint 2" not in text[hint_id], hint_id
        assert "Autograder: implementation solutions, public checks" in text[check_id]
        assert f"{exercise} (solutions): " in text[check_id]
        assert "full marks on the public checks" in text[check_id], text[check_id]
        assert order.index(hint_id) < order.index(check_id) < order.index("experiments-md")


def assert_no_level_3_hint_line(lesson: str, exercises, strip: str = " :`") -> int:
    """No line of the exercises' level-3 hints (those longer than 24 characters that hold a formula: ``=``,
    ``^`` or ``(``) stands in ``lesson`` (its text, whitespace folded): the lesson stops where the
    exercise starts. Returns how many hint lines were looked for."""
    from autograder.hints import hint_sources

    lesson = " ".join(lesson.split())
    sources = hint_sources()
    checked = 0
    for exercise in exercises:
        for owner, levels in sources[exercise].items():
            for line in levels[2].splitlines():
                line = " ".join(line.strip(strip).split())
                if len(line) > 24 and any(c in line for c in "=^("):
                    assert line not in lesson, (exercise, owner, line)
                    checked += 1
    return checked
