"""The Gradescope autograder bundle: ``python -m course release --gradescope FILE.zip``.

The zip holds, at its top level, the three scripts of ``autograder/release/gradescope_bundle/``
(``setup.sh``, ``run_autograder``, ``requirements.txt``) and the grader's source:
``course/``, ``autograder/`` (all of it, the reference side included), ``solutions/``,
``exercises/`` and ``pyproject.toml``; no tests, notebooks, version control or caches.

Gradescope unpacks the zip into ``/autograder/source``, runs ``setup.sh`` once when it
builds the image (it installs ``requirements.txt``: what grading imports, pinned to
releases with CPython 3.10 wheels, the Python of Gradescope's Ubuntu 22.04 image), then
``run_autograder`` for each submission. ``run_autograder`` calls this module twice:

* ``python3 -m autograder.release.gradescope stage``: find the folder of the submission that holds
  the exercise files (:func:`autograder.submission.locate_submission`) and copy it into a fresh package
  (:func:`autograder.submission.stage_submission`): only regular files named like a module of ``exercises/``,
  the unwritten stub for each module the student did not send, ``exercises/__init__.py``
  when the student sent none;
* ``python3 -m autograder.release.gradescope finish``: after ``python3 -m autograder --impl STAGED
  --json results.json``, check that results.json is the grader's and well formed, put in
  front of its ``output`` what was graded, or, when grading did not finish, write a
  results.json with score 0 and the error (:func:`finish`), so that Gradescope always
  gets results.

This module imports only the standard library (and ``course``, whose ``__init__`` sets
the BLAS threads, and ``autograder.submission``, standard library only), so that ``finish``
still works when grading could not start.
"""

import argparse
import json
import math
import os
import secrets
import stat
import sys
import time
import zipfile
from dataclasses import dataclass, field
from pathlib import Path

from autograder.submission import exercise_modules, locate_submission, stage_submission
from course.core.impl import REPO_ROOT
from course.core.jsonio import write_json

#: the bundle's scripts, copied to the top of the zip
TEMPLATES = Path(__file__).resolve().parent / "gradescope_bundle"
#: scripts that must be executable in the zip
EXECUTABLE = ("setup.sh", "run_autograder")
#: what of the repository goes into the zip (under ``source/`` once Gradescope unpacks it)
SOURCE_PATHS = ("course", "autograder", "solutions", "exercises", "pyproject.toml")
#: names skipped at any depth
SKIPPED_NAMES = {"__pycache__", ".pytest_cache", ".mypy_cache", ".ruff_cache", ".ipynb_checkpoints",
                 ".git", ".venv", "out", "build", ".DS_Store"}
SKIPPED_SUFFIXES = (".pyc", ".pyo", ".egg-info")
#: a fixed timestamp for every member, so that the same tree gives the same zip
ZIP_DATE = (2020, 1, 1, 0, 0, 0)
#: lines of the grader's error output quoted in a results.json when grading failed
LOG_LINES = 40
VISIBILITIES = {"visible", "hidden", "after_due_date", "after_published"}


class BundleError(ValueError):
    """The bundle cannot be built from this tree."""


# ---------------------------------------------------------------- the zip


@dataclass
class Bundle:
    path: Path
    size: int
    members: list = field(default_factory=list)


def _skipped(path: Path) -> bool:
    return path.name in SKIPPED_NAMES or path.name.endswith(SKIPPED_SUFFIXES)


def source_files(root: Path = REPO_ROOT) -> list:
    """``(path on disk, name in the zip)`` of the grader's source, sorted."""
    root = Path(root)
    files = []
    for top in SOURCE_PATHS:
        path = root / top
        if not path.exists():
            raise BundleError(f"{path} is missing: the bundle needs {', '.join(SOURCE_PATHS)}")
        if path.is_file():
            files.append((path, top))
            continue
        for directory, dirs, names in os.walk(path):
            dirs[:] = sorted(d for d in dirs if not _skipped(Path(directory, d)))
            for name in sorted(names):
                item = Path(directory, name)
                if _skipped(item) or item.is_symlink() or not item.is_file():
                    continue
                files.append((item, item.relative_to(root).as_posix()))
    return files


def _add(archive: zipfile.ZipFile, path: Path, name: str, mode: int) -> None:
    info = zipfile.ZipInfo(name, date_time=ZIP_DATE)
    info.external_attr = (stat.S_IFREG | mode) << 16
    info.compress_type = zipfile.ZIP_DEFLATED
    archive.writestr(info, path.read_bytes())


#: the bundle's file holding the seed of its hidden checks' inputs
SEED_FILE = "hidden_seed"


def build_bundle(target, root: Path = REPO_ROOT, hidden_seed=None, overlay=None) -> Bundle:
    """Write the Gradescope zip to ``target`` (replaced if it exists) from the tree ``root``.

    ``hidden_seed`` (an int) draws the hidden checks' inputs; by default a fresh random one,
    so the hidden inputs differ from the repository's default (which anyone can read) and
    from every other bundle. ``run_autograder`` exports it as ``AUTOGRADER_HIDDEN_SEED``.

    ``overlay`` (``{member: text}``, an assignment's: :func:`autograder.release.assignment.bundle_overlay`)
    adds or replaces members; when it holds ``exercises/`` files, they are the zip's whole ``exercises/``.
    """
    overlay = dict(overlay or {})
    target = Path(target)
    root = Path(root).resolve()
    if target.suffix != ".zip":
        raise BundleError(f"{target}: Gradescope takes a .zip file")
    if not (root / "solutions").is_dir():
        raise BundleError(f"{root} has no solutions/: the bundle grades with the reference")
    scripts = [TEMPLATES / name for name in ("setup.sh", "run_autograder", "requirements.txt")]
    missing = [str(p) for p in scripts if not p.is_file()]
    if missing:
        raise BundleError(f"the bundle's scripts are missing: {', '.join(missing)}")
    files = source_files(root)
    if any(name.startswith("exercises/") for name in overlay):
        files = [(path, name) for path, name in files if not name.startswith("exercises/")]
    files = [(path, name) for path, name in files if name not in overlay]
    target.parent.mkdir(parents=True, exist_ok=True)
    partial = target.with_name(target.name + ".partial")
    members = []
    with zipfile.ZipFile(partial, "w") as archive:
        for path in scripts:
            _add(archive, path, path.name, 0o755 if path.name in EXECUTABLE else 0o644)
            members.append(path.name)
        for path, name in files:
            _add(archive, path, name, 0o644)
            members.append(name)
        for name, text in sorted(overlay.items()):
            info = zipfile.ZipInfo(name, date_time=ZIP_DATE)
            info.external_attr = (stat.S_IFREG | 0o644) << 16
            info.compress_type = zipfile.ZIP_DEFLATED
            archive.writestr(info, text)
            members.append(name)
        seed = secrets.randbelow(2**31) if hidden_seed is None else int(hidden_seed)
        info = zipfile.ZipInfo(SEED_FILE, date_time=ZIP_DATE)
        info.external_attr = (stat.S_IFREG | 0o600) << 16
        archive.writestr(info, f"{seed}\n")
        members.append(SEED_FILE)
    os.replace(partial, target)
    return Bundle(target, target.stat().st_size, members)


# ---------------------------------------------------------------- results.json


def results_problem(data) -> str:
    """Why ``data`` is not a results.json Gradescope takes ('' when it is)."""
    def number(x):
        return isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x)

    if not isinstance(data, dict):
        return "not a JSON object"
    if "score" in data and not number(data["score"]):
        return "score is not a number"
    tests = data.get("tests")
    if not isinstance(tests, list):
        return "no tests list"
    if "score" not in data and not tests:
        return "neither a score nor tests"
    for test in tests:
        if not isinstance(test, dict):
            return "a test is not an object"
        if not number(test.get("score")) or not number(test.get("max_score")):
            return f"test {test.get('name')!r} has no numeric score and max_score"
        if not isinstance(test.get("name"), str) or not isinstance(test.get("output", ""), str):
            return "a test's name or output is not text"
        if test.get("visibility", "visible") not in VISIBILITIES:
            return f"test {test.get('name')!r} has visibility {test.get('visibility')!r}"
    return ""


def _tail(path, lines=LOG_LINES) -> str:
    try:
        text = Path(path).read_text(errors="replace")
    except OSError:
        return ""
    kept = text.strip().splitlines()[-lines:]
    return "\n".join(kept)


def failed(output: str, seconds: float) -> dict:
    return {"score": 0, "execution_time": round(seconds, 3), "output": output, "tests": []}


def finish(results, note: str, status: str, log=None, started=None) -> dict:
    """Make ``results`` a valid results.json: the grader's with ``note`` in front of its
    output when grading ran (``status`` "0"), else score 0 and what went wrong."""
    results = Path(results)
    seconds = time.time() - started if started else 0.0
    if status == "no-submission":
        data = failed(note, seconds)
    elif status != "0":
        tail = _tail(log) if log else ""
        data = failed("The autograder failed; this is not a grade of your work. Please tell the course staff."
                      f"\n(grading exited with status {status})" + (f"\n\n{tail}" if tail else ""), seconds)
        if note:
            data["output"] = note + "\n\n" + data["output"]
    else:
        data = {}
        try:
            data = json.loads(results.read_text())
            problem = results_problem(data)
        except (OSError, ValueError) as exc:
            problem = f"unreadable ({exc})"
        if problem:
            tail = _tail(log) if log else ""
            data = failed(f"The autograder wrote no valid results ({problem}); this is not a grade of your work. "
                          "Please tell the course staff." + (f"\n\n{tail}" if tail else ""), seconds)
        elif note:
            data["output"] = note + "\n\n" + str(data.get("output", ""))
    write_json(results, data, indent=2, newline=True)
    return data


# ---------------------------------------------------------------- command line


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python3 -m autograder.release.gradescope",
                                     description="the two steps of run_autograder around the grading")
    sub = parser.add_subparsers(dest="command", required=True)
    stage = sub.add_parser("stage", help="find the exercise files in the submission and stage them as a package")
    stage.add_argument("--source", required=True, help="the unpacked bundle (/autograder/source)")
    stage.add_argument("--submission", required=True, help="the student's upload (/autograder/submission)")
    stage.add_argument("--target", required=True, help="a new directory for the staged package")
    stage.add_argument("--note", required=True, help="a file for the line that says what is graded")
    done = sub.add_parser("finish", help="check results.json, or write one with score 0 and the error")
    done.add_argument("--results", required=True)
    done.add_argument("--note", default=None, help="the note written by stage")
    done.add_argument("--status", required=True, help="0, no-submission, or how grading ended")
    done.add_argument("--log", default=None, help="the grader's error output, quoted when it failed")
    done.add_argument("--started", type=float, default=None, help="seconds since the epoch when the run began")
    args = parser.parse_args(argv)
    if args.command == "stage":
        located = locate_submission(args.submission, exercise_modules(args.source))
        Path(args.note).write_text(located.message)
        print(located.message)
        if located.folder is None:
            return 3
        stage_submission(located, args.source, args.target)
        return 0
    note = ""
    if args.note:
        try:
            note = Path(args.note).read_text()
        except OSError:
            note = ""
    data = finish(args.results, note, args.status, args.log, args.started)
    print(f"results.json: score {data.get('score')}, {len(data.get('tests', []))} tests")
    return 0


if __name__ == "__main__":
    sys.exit(main())
