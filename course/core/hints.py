"""The exercises' hints, in three levels: read from a module's source, formatted, and put into
its docstrings by the release.

An exercise's docstrings give the definitions, conventions, shapes and the contract, and say what
to derive; the derived results live in the module's ``HINTS`` dictionary, which maps a docstring's
owner (``""`` for the module, ``"function"`` or ``"Class.method"``) to three texts:

1. the approach (what to write down, in which order);
2. the key identity (the one step the derivation turns on);
3. the result (the formulas, as the reference uses them).

``HINTS`` sits outside the solution blocks; the release takes it out of the stubs and writes every
module's hints to ``exercises/hints.json`` (:data:`HINTS_FILE`), so that they ship in the student
tree without sitting under the TODO; ``python -m autograder hint NAME [LEVEL]`` prints one level
at a time, and the release can print levels 1 to N into the stubs' docstrings (``--hints N``;
0, the default, none). Everything here reads source text: nothing imports the student's code.
"""

import ast
import re
import textwrap

#: the levels, in order, and what each gives
LEVELS = {1: "the approach", 2: "the key identity", 3: "the result"}
#: the file of ``exercises/`` that holds every module's hints: ``{module: {owner: [l1, l2, l3]}}``
HINTS_FILE = "hints.json"
#: how ``exercises/__init__.py`` records the level its docstrings were released with
LEVEL_LINE = "HINTS_LEVEL = "


class HintError(ValueError):
    """A malformed ``HINTS`` dictionary, or a hint for a docstring that does not exist."""


def read_hints(source: str, path="<source>") -> dict:
    """``{owner: (level 1, level 2, level 3)}`` of a module's source text ({} without ``HINTS``)."""
    tree = ast.parse(source, filename=str(path))
    for node in tree.body:
        if isinstance(node, ast.Assign) and any(isinstance(t, ast.Name) and t.id == "HINTS" for t in node.targets):
            try:
                hints = ast.literal_eval(node.value)
            except ValueError as exc:
                raise HintError(f"{path}:{node.lineno}: HINTS must be a literal dictionary ({exc})") from None
            _validate(hints, path)
            return hints
    return {}


def without_hints(source: str, path="<source>") -> str:
    """``source`` without its ``HINTS`` assignment and the comment lines right above it (the release
    ships the hints in a file of their own, so the stubs do not show the results below the TODO)."""
    tree = ast.parse(source, filename=str(path))
    lines = source.splitlines(keepends=True)
    for node in tree.body:
        if isinstance(node, ast.Assign) and any(isinstance(t, ast.Name) and t.id == "HINTS" for t in node.targets):
            start = node.lineno - 1
            while start > 0 and lines[start - 1].lstrip().startswith("#"):
                start -= 1
            kept = lines[:start] + lines[node.end_lineno or start:]
            return "".join(kept).rstrip("\n") + "\n"
    return source


def _validate(hints, path) -> None:
    if not isinstance(hints, dict):
        raise HintError(f"{path}: HINTS must be a dictionary")
    for owner, levels in hints.items():
        if not isinstance(owner, str) or not isinstance(levels, tuple) or len(levels) != len(LEVELS) \
                or not all(isinstance(text, str) and text.strip() for text in levels):
            raise HintError(f"{path}: HINTS[{owner!r}] must be {len(LEVELS)} non-empty strings (the approach, "
                            "the key identity, the result)")


def level_text(text: str) -> str:
    """One hint's text without the indentation of its source lines (first line kept as is)."""
    first, _, rest = text.strip("\n").partition("\n")
    return (first.strip() + ("\n" + textwrap.dedent(rest) if rest else "")).rstrip()


def format_levels(levels: tuple, upto: int, indent: str = "") -> str:
    """Hints 1..``upto`` as docstring text, each line after ``indent``."""
    out = []
    for level in range(1, upto + 1):
        body = level_text(levels[level - 1]).splitlines()
        out.append(f"Hint {level} ({LEVELS[level]}): {body[0]}")
        out.extend(f"    {line}" if line.strip() else "" for line in body[1:])
    return "\n".join(f"{indent}{line}" if line else "" for line in out)


def _docstring_nodes(tree) -> dict:
    """``{owner: docstring Constant node}`` for the module, its functions, classes and methods."""
    found = {}

    def visit(node, prefix):
        body = getattr(node, "body", [])
        if body and isinstance(body[0], ast.Expr) and isinstance(body[0].value, ast.Constant) \
                and isinstance(body[0].value.value, str):
            found[prefix.rstrip(".")] = body[0].value
        for child in body:
            if isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
                visit(child, f"{prefix}{child.name}.")

    visit(tree, "")
    return found


def insert_hints(source: str, upto: int, path="<source>") -> str:
    """``source`` with hints 1..``upto`` appended to each docstring ``HINTS`` names (unchanged for 0)."""
    if upto not in (0, *LEVELS):
        raise HintError(f"hint level {upto}: choose 0 (none) or one of {', '.join(map(str, LEVELS))}")
    hints = read_hints(source, path)
    if not upto or not hints:
        return source
    docstrings = _docstring_nodes(ast.parse(source, filename=str(path)))
    missing = sorted(set(hints) - set(docstrings))
    if missing:
        raise HintError(f"{path}: HINTS names {', '.join(map(repr, missing))}, which have no docstring here")
    lines = source.splitlines(keepends=True)
    # from the bottom up, so that the line numbers above stay valid
    for owner in sorted(hints, key=lambda o: docstrings[o].end_lineno or 0, reverse=True):
        node = docstrings[owner]
        row = (node.end_lineno or 0) - 1
        line = lines[row]
        quote = node.end_col_offset - 3
        if line[quote:quote + 3] not in ('"""', "'''"):
            raise HintError(f"{path}:{row + 1}: the docstring of {owner or 'the module'} must end with triple quotes")
        start = lines[node.lineno - 1]
        indent = "" if not owner else start[: len(start) - len(start.lstrip())]
        text = format_levels(hints[owner], upto, indent)
        before = line[:quote]
        if before.strip():  # the closing quotes follow text on the same line
            lines[row] = f"{before.rstrip()}\n\n{text}\n{indent}{line[quote:]}"
        else:
            lines[row] = f"\n{text}\n{line}"
    return "".join(lines)


def recorded_level(init_text: str) -> int:
    """The hint level an ``exercises/__init__.py`` records (0 when it records none)."""
    match = re.search(rf"^{re.escape(LEVEL_LINE)}(\d+)\s*$", init_text, flags=re.M)
    return int(match.group(1)) if match else 0


def record_level(init_text: str, level: int) -> str:
    """``exercises/__init__.py``'s text with ``level`` recorded (replacing any recorded before)."""
    text = re.sub(rf"\n*#: [^\n]*\n{re.escape(LEVEL_LINE)}\d+\s*$", "", init_text.rstrip("\n"), flags=re.S)
    return (f"{text}\n\n#: the hint level the release printed into these docstrings (``--hints N``)\n"
            f"{LEVEL_LINE}{level}\n")
