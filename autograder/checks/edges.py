"""The edges of an exercise's contract, and the check inputs that sit on them.

An exercise's module docstring lists what its contract allows at its edges (the smallest
sizes, information that is diagonal but anisotropic or full, blocks nearly singular on either
side of a threshold, angles at +-pi), one ``- `` item each, under a line that starts with
:data:`HEADING`. Its check module (``autograder/checks/<exercise>.py``) lists the same edges in
``EDGES``: each an :class:`Edge`, with the call target it concerns and a predicate on a call that
is true where the call's inputs sit on that edge. ``tests/test_contract_edges.py`` holds the two
lists together and requires, for every edge, a public input on it or one in every hidden set.
"""

import re
from collections.abc import Callable
from dataclasses import dataclass

from autograder.records import Call

HEADING = "Inputs at the edges of the contract"


@dataclass(frozen=True)
class Edge:
    """``name``: the item as the docstring words it; ``target``: the ``Call.target`` it concerns;
    ``holds(call)``: whether that call's inputs sit on the edge."""

    name: str
    target: str
    holds: Callable[[Call], bool]


def listed(docstring: str) -> list:
    """The items under :data:`HEADING` in ``docstring``, whitespace collapsed (an item runs on
    over indented lines; a blank line or an unindented line that is no item ends the list)."""
    lines = (docstring or "").splitlines()
    start = next((k for k, line in enumerate(lines) if line.strip().startswith(HEADING)), None)
    if start is None:
        return []
    items: list = []
    indent = None  # of the items' "- "
    for line in lines[start + 1:]:
        stripped = line.strip()
        depth = len(line) - len(line.lstrip())
        if not stripped:
            break
        if stripped.startswith("- ") and (indent is None or depth == indent):
            items.append(stripped[2:])
            indent = depth
        elif items and indent is not None and depth > indent:
            items[-1] += " " + stripped
        else:
            break
    return [re.sub(r"\s+", " ", item).strip() for item in items]


def reached(edge: Edge, calls) -> bool:
    """Whether one of ``calls`` targets ``edge.target`` and sits on the edge."""
    return any(call.target == edge.target and edge.holds(call) for call in calls)
