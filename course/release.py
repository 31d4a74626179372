"""Generate ``exercises/`` from ``solutions/``.

Code between ``# BEGIN SOLUTION`` and ``# END SOLUTION`` is replaced by a
``raise NotImplementedError`` naming the TODO (``module.Class.method``); signatures,
docstrings and hints stay. A file whose first lines hold ``# RELEASE: omit`` is kept
out of the student tree (e.g. reference answers to written questions).
"""

import ast
import shutil
from pathlib import Path

from course.impl import REPO_ROOT

BEGIN, END, OMIT = "# BEGIN SOLUTION", "# END SOLUTION", "# RELEASE: omit"


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


def render(solutions_dir: Path) -> dict:
    """``{relative path: text}`` of the student tree for ``solutions_dir``."""
    files = {}
    for path in sorted(solutions_dir.rglob("*")):
        if path.is_dir() or "__pycache__" in path.parts or path.suffix == ".pyc":
            continue
        rel = path.relative_to(solutions_dir)
        text = path.read_text()
        if _omitted(text):
            continue
        if path.suffix == ".py":
            module = ".".join(rel.with_suffix("").parts)
            text = strip_solutions(text, module, path)
            if rel.name == "__init__.py":
                text = text.replace("Reference implementations", "Your implementations", 1)
        files[str(rel)] = text
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


def release(check=False, student_dir=None, root: Path = REPO_ROOT) -> list:
    """Regenerate ``exercises/`` (or only check it); optionally write a student tree.

    Returns the list of stale paths (empty when up to date).
    """
    files = render(root / "solutions")
    exercises = root / "exercises"
    stale = stale_files(exercises, files)
    if not check and stale:
        write(exercises, files)
    if student_dir is not None:
        write_student_tree(Path(student_dir), files, root)
    return stale


def write_student_tree(target: Path, exercise_files: dict, root: Path) -> None:
    """A copy of the repository for students: no ``solutions/`` (so no reference answers)
    and no ``tests/`` or ``.ci/`` (they test the reference). The autograder needs the
    reference, so it runs on the course's side (e.g. Gradescope), not in this tree."""
    if target.exists():
        raise ReleaseError(f"{target} already exists; choose a new directory")
    ignore = shutil.ignore_patterns(".git", ".venv", "__pycache__", "out", "solutions", "tests", ".ci",
                                    "*.egg-info", ".pytest_cache")
    shutil.copytree(root, target, ignore=ignore)
    write(target / "exercises", exercise_files)
