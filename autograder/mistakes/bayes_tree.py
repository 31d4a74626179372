# RELEASE: omit
"""Known mistakes in ``bayes_tree`` (see ``autograder.mistakes``): the Bayes tree built with one slip."""

import numpy as np

from autograder.checks.bayes_tree import TREE
from autograder.tasks.common import encode_lists


def tree(ordering, separators, *, merge="equal", parent_from="first", frontal_order="elimination",
         roots="separate", separator="created"):
    """``(frontals, separators, parents)`` with one slip or none."""
    ordering = [int(v) for v in ordering]
    position = {v: k for k, v in enumerate(ordering)}
    home, frontals, seps, parents, own = {}, [], [], [], []
    for v in reversed(ordering):
        S = [int(u) for u in separators[v]]
        if S:
            c = home[S[-1] if parent_from == "last" else S[0]]
            clique = set(frontals[c]) | (set() if merge == "frontals" else set(seps[c]))
            if set(S) == clique or (merge == "subset" and set(S) <= clique):
                frontals[c].append(v)
                own[c] |= set(S)
                home[v] = c
                continue
            parent = c
        else:
            parent = 0 if roots == "joined" and frontals else -1
        home[v] = len(frontals)
        frontals.append([v])
        seps.append(S)
        own.append(set(S))
        parents.append(parent)
    if frontal_order == "elimination":
        frontals = [sorted(F, key=position.get) for F in frontals]
    if separator == "union":
        seps = [sorted(union, key=position.get) for union in own]
    return frontals, seps, parents


SLIPS = [
    ({"merge": "subset"}, "v joins the clique of S_v[0] only when S_v EQUALS that clique's variables (frontals and "
                          "separator); a strict subset starts a child clique"),
    ({"merge": "frontals"}, "compare S_v with the clique's frontals AND its separator together, not its frontals "
                            "alone"),
    ({"parent_from": "last"}, "the parent clique is the clique of S_v's FIRST-eliminated member S_v[0], not of its "
                              "last"),
    ({"frontal_order": "added"}, "the frontals are listed in the order they were added (reverse elimination); sort "
                                 "them by elimination position, earliest first"),
    ({"roots": "joined"}, "a conditional with an empty separator starts a new ROOT (parent -1): one tree per "
                          "connected component, not every root under the first"),
    ({"separator": "union"}, "a clique's separator is S_v of the variable that created it, not the union of its "
                             "frontals' separators (which holds frontals too)"),
]


def _known(call, ref):
    ordering, separators = call.args
    out = {"frontals": [], "separators": [], "parents": []}
    for slip, why in SLIPS:
        frontals, seps, parents = tree(ordering, separators, **slip)
        out["frontals"].append((encode_lists(frontals), why))
        out["separators"].append((encode_lists(seps), why))
        out["parents"].append((np.array(parents, dtype=float), why))
    return out


MISTAKES = {f"{TREE}: {title}": _known
            for title in ("the cliques' frontals", "the cliques' separators", "the parents (the tree)")}
