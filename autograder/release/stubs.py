"""Generate ``exercises/`` from ``solutions/``.

Code between ``# BEGIN SOLUTION`` and ``# END SOLUTION`` is replaced by a
``raise NotImplementedError`` naming the TODO (``module.Class.method``); signatures,
docstrings and hints stay. A file whose first lines hold ``# RELEASE: omit`` is kept
out of the student tree (e.g. reference answers to written questions, the reference side
of the autograder), wherever it is.

Hints (``course.core.hints``): ``render(..., hints=N)`` prints levels 1 to N of each module's
``HINTS`` into the docstrings they belong to (0: none), moves ``HINTS`` out of the stubs into
``exercises/hints.json`` (read by ``python -m autograder hint``) and records N in ``exercises/__init__.py``;
``release`` without a level keeps the one ``exercises/`` records, so ``release --check`` compares
with the level the committed exercises were released with.

``write_student_tree`` writes the tree a student receives: the repository without
``solutions/``, ``tests/``, ``.ci/``, ``autograder/mistakes/``, ``autograder/release/`` (this tooling),
omitted files and local clutter (``.git``, ``.venv``, ``out``, caches), with the student's ``README.md``
and ``Makefile`` from ``autograder/release/student_tree/`` in place of the instructor's, and the
instructor's ``pyproject.toml`` without the entry points into what it leaves out (:func:`student_pyproject`:
the ``release`` command).
"""

import ast
import json
import re
import shutil
from pathlib import Path

from course.core.hints import (
    HINTS_FILE,
    HintError,
    insert_hints,
    read_hints,
    record_level,
    recorded_level,
    without_hints,
)
from course.core.impl import REPO_ROOT

BEGIN, END, OMIT = "# BEGIN SOLUTION", "# END SOLUTION", "# RELEASE: omit"

#: the student's README.md and Makefile, copied over the instructor's
STUDENT_TEMPLATES = Path(__file__).resolve().parent / "student_tree"
#: paths (relative to the repository) that are the instructor's alone
#: (the guides under docs/ are written for this repository; the student tree's README is the student's guide)
INSTRUCTOR_ONLY = ("solutions", "tests", ".ci", "autograder/mistakes", "CONTRIBUTING.md", "autograder/release",
                   "docs", "notebooks/site")
#: the docstring of the student's ``exercises/__init__.py`` (the reference's speaks of the release)
STUDENT_INIT = ('"""Your implementations of the course\'s exercises: replace each '
                '``raise NotImplementedError("TODO ...")``\nwith your code and keep the signatures; '
                '``python -m autograder`` grades them."""\n')
#: names skipped at any depth: version control, environments, outputs, caches
LOCAL_CLUTTER = (".git", ".venv", "out", "build", "__pycache__", ".pytest_cache", ".mypy_cache",
                 ".import_linter_cache", ".ruff_cache", ".ipynb_checkpoints", "*.egg-info", "*.pyc")


#: a TOML table's header line, e.g. ``[project.entry-points."course.commands"]``
TABLE = re.compile(r"^\s*\[")
#: an entry point's line, ``name = "package.module:attr"``
ENTRY_POINT = re.compile(r"""^\s*[\w.-]+\s*=\s*["']([\w.]+)(?::[\w.]+)?["']""")


class ReleaseError(ValueError):
    """Unbalanced or misplaced solution markers."""


def _enclosing_functions(tree) -> dict:
    """Map every line number to the qualified name of the innermost def around it."""
    names = {}

    def visit(node, prefix):
        for child in ast.iter_child_nodes(node):
            if isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
                qual = f"{prefix}{child.name}"
                if not isinstance(child, ast.ClassDef):
                    for line in range(child.lineno, child.end_lineno + 1):
                        names[line] = qual
                visit(child, qual + ".")
            else:
                visit(child, prefix)

    visit(tree, "")
    return names


def strip_solutions(source: str, module: str, path="<source>") -> str:
    """The student version of one solutions module's source text."""
    lines = source.splitlines(keepends=True)
    owners = _enclosing_functions(ast.parse(source, filename=str(path)))
    out, inside = [], None
    for number, line in enumerate(lines, start=1):
        stripped = line.strip()
        if stripped == BEGIN:
            if inside is not None:
                raise ReleaseError(f"{path}:{number}: {BEGIN} inside another solution block")
            if number not in owners:
                raise ReleaseError(f"{path}:{number}: {BEGIN} outside a function")
            inside = number
            indent = line[: len(line) - len(line.lstrip())]
            todo = f"{module}.{owners[number]}"
            out.append(f'{indent}raise NotImplementedError("TODO {todo}: not implemented yet")\n')
        elif stripped == END:
            if inside is None:
                raise ReleaseError(f"{path}:{number}: {END} without {BEGIN}")
            inside = None
        elif inside is None:
            out.append(line)
    if inside is not None:
        raise ReleaseError(f"{path}:{inside}: {BEGIN} never closed")
    return "".join(out)


def _omitted(text: str) -> bool:
    return any(line.strip() == OMIT for line in text.splitlines()[:5])


def render(solutions_dir: Path, hints: int = 0) -> dict:
    """``{relative path: text}`` of the student tree for ``solutions_dir``, hints 1..``hints`` in
    the docstrings, and every module's ``HINTS`` in ``hints.json`` instead of the module."""
    files: dict = {}
    collected: dict = {}
    for path in sorted(solutions_dir.rglob("*")):
        if path.is_dir() or "__pycache__" in path.parts or path.suffix == ".pyc":
            continue
        rel = path.relative_to(solutions_dir)
        text = path.read_text()
        if _omitted(text):
            continue
        if path.suffix == ".py":
            module = ".".join(rel.with_suffix("").parts)
            try:
                found = read_hints(text, path)
                text = without_hints(insert_hints(text, hints, path), path)
            except HintError as exc:
                raise ReleaseError(str(exc)) from None
            if found:
                collected[module] = {owner: list(levels) for owner, levels in found.items()}
            text = strip_solutions(text, module, path)
            if str(rel) == "__init__.py":
                text = record_level(STUDENT_INIT, hints)
        files[str(rel)] = text
    if collected:
        files[HINTS_FILE] = json.dumps(collected, indent=1, sort_keys=True) + "\n"
    return files


def write(target: Path, files: dict) -> None:
    """Replace ``target`` with exactly ``files``."""
    if target.exists():
        shutil.rmtree(target)
    for rel, text in files.items():
        dest = target / rel
        dest.parent.mkdir(parents=True, exist_ok=True)
        dest.write_text(text)


def stale_files(target: Path, files: dict) -> list:
    """Paths whose content in ``target`` differs from ``files`` (missing or extra too)."""
    present = {
        str(p.relative_to(target))
        for p in target.rglob("*")
        if p.is_file() and "__pycache__" not in p.parts
    } if target.exists() else set()
    stale = [rel for rel, text in files.items() if rel not in present or (target / rel).read_text() != text]
    return sorted(stale + sorted(present - set(files)))


def hints_level(root: Path = REPO_ROOT) -> int:
    """The hint level ``root``'s ``exercises/`` was released with (0 when there is none)."""
    init = Path(root) / "exercises" / "__init__.py"
    return recorded_level(init.read_text()) if init.is_file() else 0


def release(check=False, student_dir=None, root: Path = REPO_ROOT, hints: int | None = None) -> list:
    """Regenerate ``exercises/`` (or only check it); optionally write a student tree.

    ``hints``: the level printed into the docstrings (0-3); None keeps the level ``exercises/``
    records. Returns the list of stale paths (empty when up to date).
    """
    exercises = root / "exercises"
    files = render(root / "solutions", hints_level(root) if hints is None else hints)
    stale = stale_files(exercises, files)
    if not check and stale:
        write(exercises, files)
    if student_dir is not None:
        write_student_tree(Path(student_dir), files, root)
    return stale


def _file_omitted(path: Path) -> bool:
    """True when one of the file's first five lines is ``# RELEASE: omit``."""
    with open(path, "rb") as handle:
        head = handle.read(4096).decode("utf-8", errors="replace")
    return _omitted(head)


def _student_ignore(root: Path):
    """A ``shutil.copytree`` ignore function for the student tree of ``root``."""
    clutter = shutil.ignore_patterns(*LOCAL_CLUTTER)

    def ignore(directory, names):
        where = Path(directory)
        rel = where.relative_to(root)
        skipped = set(clutter(directory, names))
        for name in names:
            if name in skipped:
                continue
            if (rel / name).as_posix() in INSTRUCTOR_ONLY:
                skipped.add(name)
            elif (where / name).is_file() and _file_omitted(where / name):
                skipped.add(name)
        return skipped

    return ignore


def _instructor_only_module(module: str) -> bool:
    """Whether the dotted ``module`` lies in a path the student tree leaves out (``autograder.release.command``)."""
    parts = module.split(".")
    return any("/".join(parts[:n]) in INSTRUCTOR_ONLY for n in range(1, len(parts) + 1))


def student_pyproject(text: str) -> str:
    """The instructor's ``pyproject.toml`` text for a student tree: every entry point whose module the tree
    leaves out is dropped (``release`` of ``course.commands``), and a ``[project.entry-points.*]`` table left
    empty goes with the comment lines just above it; every other line is kept as it is."""
    lines = text.splitlines(keepends=True)
    tables: list = []  # [header index, end index] of each table
    for number, line in enumerate(lines):
        if TABLE.match(line):
            tables.append([number, len(lines)])
            if len(tables) > 1:
                tables[-2][1] = number
    drop: set = set()
    for start, end in tables:
        if not lines[start].strip().startswith("[project.entry-points."):
            continue
        modules = {n: found.group(1) for n in range(start + 1, end) if (found := ENTRY_POINT.match(lines[n]))}
        entries = list(modules)
        gone = [n for n, module in modules.items() if _instructor_only_module(module)]
        drop.update(gone)
        if gone and len(gone) == len(entries):
            drop.update(range(start, end))
            above = start - 1
            while above >= 0 and lines[above].lstrip().startswith("#"):
                drop.add(above)
                above -= 1
    return "".join(line for number, line in enumerate(lines) if number not in drop)


def _without_personal_data(config: Path) -> None:
    """Rewrite the tree's course configuration without extensions or rosters (and without its
    comments, where an instructor may have left one commented out)."""
    from autograder.release.carried_config import config_text

    if config.is_file():
        config.write_text(config_text(config))


def write_student_tree(target: Path, exercise_files: dict, root: Path) -> None:
    """A copy of the repository for students (see the module docstring).

    No ``solutions/`` (no reference answers, no reference code), no ``tests/`` or
    ``.ci/`` (they test the reference), no ``autograder/mistakes/`` and no file marked
    ``# RELEASE: omit`` (e.g. ``autograder/oracle.py``, the reference side of grading); the
    course configuration without personal data (:mod:`autograder.release.carried_config`).
    ``exercises/`` is ``exercise_files``; ``README.md`` and ``Makefile`` are the student's.
    Students grade the public checks themselves (``python -m autograder``, from the data
    in ``autograder/expected/``); the hidden checks run on the course's side."""
    target = Path(target)
    root = Path(root).resolve()
    if target.exists():
        raise ReleaseError(f"{target} already exists; choose a new directory")
    if target.resolve().is_relative_to(root):
        raise ReleaseError(f"{target} is inside the repository {root}; choose a directory outside it")
    shutil.copytree(root, target, ignore=_student_ignore(root))
    write(target / "exercises", exercise_files)
    _without_personal_data(target / "autograder" / "course.toml")
    if (target / "pyproject.toml").is_file():
        (target / "pyproject.toml").write_text(student_pyproject((target / "pyproject.toml").read_text()))
    for template in sorted(STUDENT_TEMPLATES.iterdir()):
        if template.is_file() and template.name != "__init__.py":
            shutil.copyfile(template, target / template.name)
