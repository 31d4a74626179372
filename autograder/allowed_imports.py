"""What an exercise file may import: its contract, and the check that refuses anything else
before any of the file runs.

A grade is earned by deriving: a file that imports the framework's machinery (the automatic
Jacobians of chapter 7, a peer's back end, a problem's own linearisation) computes the answer
without the derivation. So each exercise's module docstring names what it may import, on one
line of its contract (``solutions/NAME.py``, hence the stub)::

    Allowed imports: numpy, scipy, course.solver.unique

Entries are module names (a package allows its submodules: ``scipy`` allows ``scipy.sparse``)
and sibling exercise files, written as they are imported, relatively (``.pose_graph_edge``).
Besides them every file may import the harmless part of the standard library,
:data:`STANDARD`; nothing else: not the rest of ``course``, nor ``autograder``, ``solutions``,
``exercises``, the peers (pyceres, pycolmap, g2o, gtsam; ``ceres_edge_cost``, a Ceres cost, names
pyceres) or JAX, nor ``importlib``, ``os``, ``sys``, ``subprocess``, ``ctypes``, ``inspect`` (they
reach every loaded module). A framework module the contract names gives its public names only.

:func:`scan` reads a file's syntax tree, never runs it: ``import`` and ``from ... import``
statements (relative ones too), and ``__import__("x")`` / ``importlib.import_module("x")``
with a constant name, read as imports; a dynamic import whose name is not a constant, ``eval``,
``exec``, ``compile`` and the attributes that lead to every loaded module (``__builtins__``,
``__globals__``, ``__subclasses__``, ``__loader__``, ``__spec__``) are refused too. It is a
contract, not a sandbox: the children still run under the sandbox's limits.

``python -m course release`` writes every exercise's contract to ``autograder/imports.json``
(:func:`contracts`), which the grader reads in every tree (the student's, where ``exercises/``
is the student's own, too). :func:`refusals` checks the files of an implementation;
:func:`neutralise` replaces a refused file in the grader's staged copy by a module whose every
function is an unwritten TODO naming the refusal, so that the checks of other exercises that
use it see it unwritten. Standard library only (and ``course.core.impl`` for the tree's root).
"""

import ast
import functools
import json
from dataclasses import dataclass
from pathlib import Path

#: the line of an exercise's module docstring that holds its contract
PREFIX = "Allowed imports:"
#: the standard library's modules any exercise may import: no file, process or interpreter access
STANDARD = ("__future__", "abc", "bisect", "cmath", "collections", "contextlib", "copy", "dataclasses", "enum",
            "functools", "heapq", "itertools", "math", "numbers", "operator", "typing", "warnings")
#: the contract of an implementation's ``__init__.py`` (it runs before every module of the package)
PACKAGE_INIT = ("numpy", "scipy")
#: where the release writes every exercise's contract (``{"format": 1, "modules": {name: [entries]}}``)
CONTRACT_FILE = Path(__file__).resolve().parent / "imports.json"
FORMAT = 1
#: the top-level packages of the framework and the grader, whose private names no exercise may take
FRAMEWORK = ("course", "autograder", "solutions", "exercises")
#: names that lead to every loaded module, or run code from a string
ESCAPES = ("__builtins__", "__globals__", "__subclasses__", "__loader__", "__spec__")
RUNS_STRINGS = ("eval", "exec", "compile")


class ContractError(ValueError):
    """A contract line that is missing or malformed, or a contract file that is stale."""


@dataclass(frozen=True)
class Refused:
    """One import a file may not make."""

    line: int
    what: str  # the module (or construct) imported
    why: str = ""  # a word on how to write it instead, when there is one


# ---------------------------------------------------------------- the contract


def contract_of(source: str, path="<source>") -> tuple:
    """The entries of the ``Allowed imports:`` line of the module docstring of ``source`` (it
    may continue on the next lines, up to an empty one)."""
    tree = ast.parse(source, filename=str(path))
    doc = ast.get_docstring(tree) or ""
    lines = doc.splitlines()
    for number, line in enumerate(lines):
        if line.strip().startswith(PREFIX):
            text = line.strip()[len(PREFIX):]
            for more in lines[number + 1:]:
                if not more.strip():
                    break
                text += " " + more.strip()
            entries = tuple(e.strip() for e in text.strip().rstrip(".").split(",") if e.strip())
            bad = [e for e in entries if not all(part.isidentifier() for part in e.lstrip(".").split("."))
                   or e.startswith("..")]
            if not entries or bad:
                raise ContractError(f"{path}: the {PREFIX!r} line of the module docstring is malformed "
                                    f"({', '.join(bad) or 'empty'}): module names separated by commas")
            return entries
    raise ContractError(f"{path}: the module docstring has no {PREFIX!r} line (the modules the exercise may "
                        "import, e.g. 'Allowed imports: numpy, scipy, course.geometry.so3')")


def contracts(solutions_dir) -> dict:
    """``{module: entries}`` of every exercise module of ``solutions_dir`` (for the release)."""
    out = {}
    for path in sorted(Path(solutions_dir).glob("*.py")):
        if path.name != "__init__.py":
            out[path.stem] = contract_of(path.read_text(), path)
    return out


def contract_text(solutions_dir) -> str:
    """The text of :data:`CONTRACT_FILE` for ``solutions_dir`` (stable, so that staleness is a text diff)."""
    body = {"format": FORMAT, "modules": {k: list(v) for k, v in contracts(solutions_dir).items()}}
    return json.dumps(body, indent=1, sort_keys=True) + "\n"


def load_contracts(path=CONTRACT_FILE) -> dict:
    """``{module: entries}`` as the release wrote them."""
    try:
        body = json.loads(Path(path).read_text())
    except FileNotFoundError:
        raise ContractError(f"{path} is missing: run `python -m course release` (instructor)") from None
    except (OSError, ValueError) as exc:
        raise ContractError(f"{path}: unreadable ({exc})") from None
    if not isinstance(body, dict) or body.get("format") != FORMAT or not isinstance(body.get("modules"), dict):
        raise ContractError(f"{path}: not a contract file of format {FORMAT}")
    return {str(k): tuple(str(e) for e in v) for k, v in body["modules"].items()}


def shown(entries) -> str:
    """The allowed list as a refusal says it."""
    return f"{', '.join(entries)}; from the standard library {', '.join(m for m in STANDARD if m != '__future__')}"


# ---------------------------------------------------------------- reading a file


def _allows(entries, name: str) -> bool:
    absolute = [e for e in entries if not e.startswith(".")] + list(STANDARD)
    return any(name == e or name.startswith(e + ".") for e in absolute)


def _is_module(name: str) -> bool:
    """Whether ``name`` (``course.solver.per_pattern``) is a module or package of this tree."""
    from course.core.impl import REPO_ROOT

    path = REPO_ROOT.joinpath(*name.split("."))
    return path.is_dir() or path.with_suffix(".py").is_file()


def _from_import(node: ast.ImportFrom, entries) -> list:
    siblings = {e[1:] for e in entries if e.startswith(".")}
    names = [alias.name for alias in node.names]
    if node.level:
        if node.level > 1:
            return [Refused(node.lineno, "." * node.level + (node.module or ""), "reaches outside the exercises")]
        if node.module:
            return [] if node.module.split(".")[0] in siblings else [Refused(node.lineno, "." + node.module)]
        return [Refused(node.lineno, "." + name) for name in names if name not in siblings]
    module = node.module or ""
    framework = module.split(".")[0] in FRAMEWORK
    out = []
    for name in names:
        full = f"{module}.{name}"
        if name != "*" and full in entries:
            continue  # ``from course.solver import unique``: the module itself is allowed
        if not _allows(entries, module) and not (name != "*" and _allows(entries, full)):
            out.append(Refused(node.lineno, module if name == "*" else full))
        elif framework and name.startswith("_"):
            out.append(Refused(node.lineno, full, "a private name"))
        elif framework and name != "*" and _is_module(full):
            out.append(Refused(node.lineno, full, "a module the contract does not name"))
    return out


def _constant_name(call: ast.Call):
    """The module a dynamic import names: its first argument when a string constant, else None."""
    if call.args and isinstance(call.args[0], ast.Constant) and isinstance(call.args[0].value, str):
        return call.args[0].value
    return None


def _dynamic(node: ast.AST, entries) -> list:
    if isinstance(node, ast.Call):
        func = node.func
        name = func.id if isinstance(func, ast.Name) else func.attr if isinstance(func, ast.Attribute) else ""
        if name in ("__import__", "import_module"):
            target = _constant_name(node)
            if target is None:
                return [Refused(node.lineno, f"{name}(...)", "a dynamic import whose name is not a constant")]
            return [] if _allows(entries, target) else [Refused(node.lineno, target)]
        if isinstance(func, ast.Name) and name in RUNS_STRINGS:
            return [Refused(node.lineno, f"{name}(...)", "runs code from a string, which may import anything")]
        return []
    if isinstance(node, ast.Name) and node.id in ESCAPES + ("__import__",):
        return [Refused(node.lineno, node.id, "leads to every loaded module")]
    if isinstance(node, ast.Attribute) and node.attr in ESCAPES:
        return [Refused(node.lineno, f".{node.attr}", "leads to every loaded module")]
    return []


def scan(source: str, entries) -> list:
    """Every :class:`Refused` import of ``source`` under the contract ``entries``, by line."""
    return list(_scan(source, tuple(entries)))


# a class's implementations are mostly the same files (stubs left as they are, variants of one reference)
@functools.lru_cache(maxsize=512)
def _scan(source: str, entries: tuple) -> tuple:
    try:
        tree = ast.parse(source)
    except SyntaxError:
        return ()  # the child reports the syntax error with its line, as for any file
    out: list = []
    called = {id(node.func) for node in ast.walk(tree) if isinstance(node, ast.Call)}
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for alias in node.names:
                if not _allows(entries, alias.name):
                    out.append(Refused(node.lineno, alias.name))
                elif alias.asname is None and "." in alias.name and alias.name.split(".")[0] in FRAMEWORK:
                    parent, _, child = alias.name.rpartition(".")
                    out.append(Refused(node.lineno, alias.name, f"it binds the name {alias.name.split('.')[0]}, "
                                                                f"which reaches the whole framework: write "
                                                                f"`from {parent} import {child}`"))
        elif isinstance(node, ast.ImportFrom):
            out += _from_import(node, entries)
        elif isinstance(node, ast.Name) and id(node) in called and node.id == "__import__":
            continue  # read with its call
        else:
            out += _dynamic(node, entries)
    return tuple(sorted(set(out), key=lambda r: (r.line, r.what)))


def message(display: str, module: str, refused: list, entries) -> str:
    """The one line a refused file's checks show."""
    first = refused[0]
    why = f" ({first.why})" if first.why else ""
    more = ""
    if len(refused) > 1:
        rest = refused[1:]
        more = (f"; and {len(rest)} more: " + ", ".join(f"line {r.line} {r.what}" for r in rest[:4])
                + (", ..." if len(rest) > 4 else ""))
    if module == "__init__":
        owner, outcome = "the package's __init__.py", "It is not run: the package is graded without it"
    else:
        owner = f"{module}'s contract"
        outcome = ("Its checks score 0 until the file imports only these (derive the answer; do not call the "
                   "framework's)")
    return (f"{display}:{first.line}: refused before running: imports {first.what}{why}, which {owner} does not "
            f"allow{more}. Allowed: {shown(entries)}. {outcome}")


def refusals(folder, display: str = "", contracts_by_module: dict | None = None) -> dict:
    """``{module: message}`` of the files of the implementation ``folder`` that import what their
    contract does not allow (``__init__`` for the package's own ``__init__.py``). ``display``
    names the folder in the messages (default: its name)."""
    folder = Path(folder)
    display = display or folder.name
    known = load_contracts() if contracts_by_module is None else contracts_by_module
    out = {}
    for path in sorted(folder.glob("*.py")):
        module = path.stem
        entries = PACKAGE_INIT if module == "__init__" else known.get(module)
        if entries is None or not path.is_file() or path.is_symlink():
            continue  # not an exercise file: reachable only through an import this check refuses
        found = scan(path.read_text(errors="replace"), entries)
        if found:
            out[module] = message(f"{display}/{path.name}", module, found, entries)
    return out


def neutralise(folder, refused: dict) -> None:
    """Replace each refused file of ``folder`` (a copy the grader owns) by a module that runs
    nothing: every name taken from it raises the ``NotImplementedError`` of an unwritten TODO that
    gives the refusal; a refused ``__init__.py`` becomes empty."""
    for module, why in refused.items():
        path = Path(folder) / f"{module}.py"
        if module == "__init__":
            path.write_text('"""The package\'s own __init__.py was refused by the grader."""\n')
            continue
        path.write_text(
            f'"""{module}: refused by the grader (its imports); nothing of the file runs."""\n\n'
            f"_WHY = {why!r}\n\n\n"
            "def __getattr__(name):\n"
            "    if name.startswith('__'):\n"
            "        raise AttributeError(name)\n"
            f"    raise NotImplementedError(f'TODO {module}.{{name}}: refused: ' + _WHY)\n")
