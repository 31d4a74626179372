"""The layout's rules that import-linter does not check: no module uses another module's private
name (``from m import _x``, or ``m._x`` on an imported first-party module); and the contracts in
pyproject.toml hold, and fail when broken."""

import ast
import importlib.util
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
FIRST_PARTY = ("course", "autograder", "solutions", "exercises", "notebooks")
#: the folders whose code must keep to the rule (the tests may reach into what they test)
CHECKED = ("course", "autograder", "solutions", "notebooks")


def _private(name: str) -> bool:
    return name.startswith("_") and not (name.startswith("__") and name.endswith("__"))


def _module_of(path: Path) -> str:
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _is_module(name: str) -> bool:
    try:
        return importlib.util.find_spec(name) is not None
    except (ImportError, ValueError):
        return False


def private_uses(path: Path) -> list[str]:
    """``file:line: what`` for each private name of another first-party module used in ``path``."""
    tree = ast.parse(path.read_text(), filename=str(path))
    here = _module_of(path)
    package = here if path.name == "__init__.py" else here.rpartition(".")[0]
    modules: dict[str, str] = {}  # local name -> first-party module it is bound to
    found = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for alias in node.names:
                if alias.name.split(".")[0] in FIRST_PARTY:
                    modules[alias.asname or alias.name.split(".")[0]] = alias.name if alias.asname else \
                        alias.name.split(".")[0]
        elif isinstance(node, ast.ImportFrom):
            source = node.module or ""
            if node.level:
                base = package.split(".")[: len(package.split(".")) - node.level + 1]
                source = ".".join(base + ([source] if source else []))
            if source.split(".")[0] not in FIRST_PARTY:
                continue
            for alias in node.names:
                if _private(alias.name):
                    found.append(f"{path.relative_to(ROOT)}:{node.lineno}: from {source} import {alias.name}")
                elif _is_module(f"{source}.{alias.name}"):
                    modules[alias.asname or alias.name] = f"{source}.{alias.name}"
    for node in ast.walk(tree):
        if isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name) and _private(node.attr):
            target = modules.get(node.value.id)
            if target is not None and target != here:
                found.append(f"{path.relative_to(ROOT)}:{node.lineno}: {node.value.id}.{node.attr} ({target})")
    return found


def test_no_module_uses_another_modules_private_name():
    files = [p for folder in CHECKED for p in sorted((ROOT / folder).rglob("*.py")) if "__pycache__" not in p.parts]
    assert len(files) > 100
    found = [line for path in files for line in private_uses(path)]
    assert found == [], "\n".join(found)


def test_the_private_name_check_catches_both_forms(tmp_path, monkeypatch):
    monkeypatch.setattr(sys.modules[__name__], "ROOT", tmp_path)
    (tmp_path / "course").mkdir()
    bad = tmp_path / "course" / "bad.py"
    bad.write_text("from course.problems.bal.dataset import _NAMED\nfrom course.core import impl\nimpl._x\n")
    assert [line.split(": ", 1)[1] for line in private_uses(bad)] == [
        "from course.problems.bal.dataset import _NAMED", "impl._x (course.core.impl)"]


def _lint_imports(root: Path) -> subprocess.CompletedProcess:
    exe = shutil.which("lint-imports", path=str(Path(sys.executable).parent))
    if exe is None:
        pytest.skip("import-linter is not installed here (the dev extra)")
    return subprocess.run([exe, "--no-cache"], cwd=root, capture_output=True, text=True, timeout=300)


def test_the_import_contracts_hold():
    result = _lint_imports(ROOT)
    assert result.returncode == 0, result.stdout + result.stderr
    assert "0 broken" in result.stdout


@pytest.mark.parametrize(("module", "line", "contract"), [
    ("course/core/errors.py", "from course.app import cli", "course/ is layered"),
    ("course/problems/bal/gauge.py", "from course.problems.vio import sim", "problem families do not import"),
    ("course/solver/options.py", "import solutions.damping", "only the implementation loader"),
    ("course/solver/options.py", "from course.solver import minimizer", "no import cycles"),
    ("course/notebook_helpers/lesson.py", "from autograder.lesson import check", "course does not import autograder"),
    ("autograder/report.py", "from course.app import cli", "the grader stands on the framework's lower layers"),
])
def test_a_broken_contract_fails_the_lint(tmp_path, module, line, contract):
    """Each contract, broken in a copy of the tree by one import, fails ``lint-imports``."""
    copy = tmp_path / "repo"
    ignore = shutil.ignore_patterns("__pycache__", ".venv", ".git", "*.ipynb", "out", "tests")
    for name in ("course", "autograder", "solutions", "exercises", "notebooks"):
        shutil.copytree(ROOT / name, copy / name, ignore=ignore)
    shutil.copy(ROOT / "pyproject.toml", copy / "pyproject.toml")
    target = copy / module
    target.write_text(target.read_text() + f"\n{line}\n")
    result = _lint_imports(copy)
    assert result.returncode != 0
    assert contract in " ".join(result.stdout.split()), result.stdout
