"""``python -m autograder hint NAME [LEVEL]``: the hints of an exercise, one level at a time.

NAME is an exercise (``pose_graph_edge``), a function or method (``edge_errors_and_jacobians``,
``GavinType3.update``, ``damping.GavinType3.update``) or a class (``GavinType3``: its methods'
hints). LEVEL is 1 (the approach, the default), 2 (the key identity) or 3 (the result).
The hints are read from the reference's source text where this tree has ``solutions/``, else from
``exercises/hints.json``, which the release writes (:mod:`course.core.hints`); nothing is imported.
"""

import argparse
import json
import sys
from pathlib import Path

from course.core.hints import HINTS_FILE, LEVELS, HintError, format_levels, read_hints
from course.core.impl import REPO_ROOT


def hint_sources(root: Path = REPO_ROOT) -> dict:
    """``{exercise: {owner: levels}}`` of every module with hints: the reference's ``HINTS`` where this
    tree has ``solutions/``, else the released ``exercises/hints.json``."""
    if (root / "solutions" / "__init__.py").is_file():
        found = {}
        for path in sorted((root / "solutions").glob("*.py")):
            hints = read_hints(path.read_text(), path) if path.name != "__init__.py" else {}
            if hints:
                found[path.stem] = hints
        return found
    path = root / "exercises" / HINTS_FILE
    if not path.is_file():
        raise HintError(f"{path} is missing: it ships with the exercises (python -m course release writes it)")
    try:
        data = json.loads(path.read_text())
    except ValueError as exc:
        raise HintError(f"{path}: not the hints file the release writes ({exc})") from None
    return {module: {owner: tuple(levels) for owner, levels in owners.items()} for module, owners in data.items()}


def lookup(name: str, sources: dict) -> list:
    """``[(exercise, owner, levels)]`` that ``name`` selects, in file order."""
    module, _, rest = name.partition(".")
    if module in sources:
        owners = sources[module]
        if not rest:
            return [(module, owner, levels) for owner, levels in owners.items()]
        name = rest
    else:
        owners = None
    picked = []
    for exercise, hints in sources.items():
        if owners is not None and hints is not owners:
            continue
        for owner, levels in hints.items():
            if owner == name or owner.split(".")[-1] == name or owner.split(".")[0] == name:
                picked.append((exercise, owner, levels))
    return picked


def text(name: str, level: int, root: Path = REPO_ROOT) -> str:
    """What ``hint NAME LEVEL`` prints."""
    if level not in LEVELS:
        raise HintError(f"level {level}: choose one of {', '.join(map(str, LEVELS))}")
    sources = hint_sources(root)
    picked = lookup(name, sources)
    if not picked:
        raise HintError(f"no hints for {name!r}; exercises with hints: {', '.join(sources) or 'none'}")
    out = []
    for exercise, owner, levels in picked:
        where = f"{exercise}.{owner}" if owner else f"{exercise} (the module)"
        out.append(f"{where}, hint {level} of {len(LEVELS)}:")
        out.append(_one_level(levels, level))
    if level < len(LEVELS):
        out.append(f"(more: python -m autograder hint {name} {level + 1})")
    return "\n".join(out)


def _one_level(levels: tuple, level: int) -> str:
    """Level ``level`` alone, indented."""
    whole = format_levels(levels, level, "    ")
    return whole[whole.index(f"    Hint {level} ("):]


def main(argv=None) -> int:
    p = argparse.ArgumentParser(prog="python -m autograder hint", description=(
        "Print an exercise's hints, one level at a time: 1 the approach, 2 the key identity, 3 the result."))
    p.add_argument("name", metavar="NAME", help="an exercise (pose_graph_edge), a function or method "
                                                "(edge_errors_and_jacobians, GavinType3.update) or a class")
    p.add_argument("level", metavar="LEVEL", nargs="?", type=int, default=1, help="1, 2 or 3 (default 1)")
    args = p.parse_args(argv)
    try:
        print(text(args.name, args.level))
    except HintError as exc:
        print(f"autograder hint: {exc}", file=sys.stderr)
        return 2
    return 0
