# RELEASE: omit
"""Known mistakes in ``incremental_update`` (see ``autograder.mistakes``): each function with one slip."""

import numpy as np
import scipy.linalg

from autograder.checks.incremental_update import AFFECTED, ORPHANS, RELIN, WILDFIRE


def relinearised(delta, threshold, *, measure="largest", strict=True):
    """The relinearised keys with the step measured by ``measure`` and compared strictly or not."""
    size = {"largest": lambda s: np.max(np.abs(s)), "norm": np.linalg.norm, "signed": np.max,
            "sum": lambda s: np.sum(np.abs(s))}[measure]
    keys = []
    for v, step in enumerate(delta):
        value = float(size(np.asarray(step, dtype=float))) if np.size(step) else 0.0
        if value > threshold or (not strict and value == threshold and np.size(step)):
            keys.append(v)
    return keys


RELIN_SLIPS = [
    ({"measure": "norm"}, "compare the largest absolute entry max(abs(delta[v])) with the threshold, not the "
                          "Euclidean norm"),
    ({"measure": "signed"}, "take the largest ABSOLUTE entry: a large negative entry is a large step too"),
    ({"measure": "sum"}, "compare the largest absolute entry with the threshold, not the sum of the entries' "
                         "absolute values"),
    ({"strict": False}, "compare strictly (> threshold): a step whose largest entry equals the threshold is not "
                        "relinearised"),
]


def _relin_known(call, ref):
    delta, threshold = call.args
    return {"keys": [(np.array(relinearised(delta, threshold, **slip), dtype=float), why)
                     for slip, why in RELIN_SLIPS]}


def affected(frontals, separators, parents, new_keys, relin, *, separator=True, ancestors=True,
             orphans="children"):
    """``(top, orphans)`` with one slip or none."""
    n = sum(len(F) for F in frontals)
    home = {v: c for c, F in enumerate(frontals) for v in F}
    marked = {home[k] for k in new_keys if k < n}
    marked |= {c for c, (F, S) in enumerate(zip(frontals, separators))
               if set(relin) & (set(F) | (set(S) if separator else set()))}
    top = set(marked)
    if ancestors:
        for c in marked:
            while c != -1:
                top.add(c)
                c = int(parents[c])
    below = [c for c in range(len(frontals)) if c not in top and parents[c] in top]
    if orphans == "descendants":
        below = [c for c in range(len(frontals)) if c not in top and any(
            p in top for p in _ancestors(parents, c))]
    return sorted(top), sorted(below)


def _ancestors(parents, c):
    out = []
    while parents[c] != -1:
        c = int(parents[c])
        out.append(c)
    return out


AFFECTED_SLIPS = [
    ({"separator": False}, "a relinearised variable changes every factor on it, so mark the cliques that hold it in "
                           "their SEPARATOR too, not only those with it as a frontal"),
    ({"ancestors": False}, "the top is the marked cliques AND all their ancestors up to the root: a changed clique "
                           "changes the factor it passes to its parent"),
    ({"orphans": "descendants"}, "the orphans are the top's children outside it, not every clique below the top: "
                                 "each orphan keeps its subtree whole"),
]


def _affected_known(call, ref):
    out = {"top": [], "orphans": []}
    for slip, why in AFFECTED_SLIPS:
        top, below = affected(*call.args, **slip)
        out["top"].append((np.array(top, dtype=float), why))
        out["orphans"].append((np.array(below, dtype=float), why))
    return out


def attach(separators, ordering, new_frontals, *, pick="first"):
    """Each orphan's parent with the separator's member chosen by ``pick``."""
    position = {v: k for k, v in enumerate(ordering)}
    home = {v: c for c, F in enumerate(new_frontals) for v in F}
    if pick == "variable":
        return [min(S, key=position.get) for S in separators]
    choose = {"first": lambda S: min(S, key=position.get), "smallest": min, "listed": lambda S: S[0],
              "last": lambda S: max(S, key=position.get)}[pick]
    return [home[choose(S)] for S in separators]


ATTACH_SLIPS = [
    ("smallest", "take the separator's member eliminated first in the NEW ordering, not its smallest index"),
    ("listed", "the separator lists its members in the OLD elimination order: take the member eliminated first in "
               "the new ordering, not the one listed first"),
    ("last", "an orphan hangs from the clique of its separator's FIRST-eliminated member, not its last"),
    ("variable", "return the index of the CLIQUE (in new_frontals) that holds the member, not the member itself"),
]


def _attach_known(call, ref):
    return {"value": [(np.array(attach(*call.args, pick=pick), dtype=float), why) for pick, why in ATTACH_SLIPS]}


def wildfire(frontals, separators, parents, conditionals, delta, replaced, threshold, *, skip=True,
             against="old", replaced_alone=True):
    """``(new steps stacked, recomputed)`` with one slip or none: ``skip=False`` recomputes every clique;
    ``against="zero"`` measures the change from zero; ``replaced_alone=False`` recomputes a replaced clique only
    when its separator changed."""
    old = [np.asarray(s, dtype=float) for s in delta]
    new = [s.copy() for s in old]
    children = [[] for _ in frontals]
    for c, p in enumerate(parents):
        if p != -1:
            children[int(p)].append(c)
    changed, recomputed = set(), []
    stack = [c for c in range(len(frontals)) if parents[c] == -1]
    while stack:
        c = stack.pop()
        touched = bool(changed & set(separators[c]))
        if skip and not touched and not (replaced_alone and c in set(replaced)):
            continue
        R, S, d = (np.asarray(b, dtype=float) for b in conditionals[c])
        s = np.concatenate([new[v] for v in separators[c]]) if separators[c] else np.zeros(0)
        x = scipy.linalg.solve_triangular(R, d - S @ s) if len(d) else np.zeros(0)
        at = 0
        for v in frontals[c]:
            step = x[at:at + old[v].size]
            at += old[v].size
            base = old[v] if against == "old" else 0.0
            if step.size and float(np.max(np.abs(step - base))) > threshold:
                changed.add(v)
            new[v] = step
        recomputed.append(c)
        stack.extend(children[c])
    return np.concatenate(new) if new else np.zeros(0), sorted(recomputed)


WILDFIRE_SLIPS = [
    ({"skip": False}, "skip a clique that is not replaced and whose separator's steps did not change by more than the "
                      "threshold (and its subtree): that is what makes the update partial"),
    ({"against": "zero"}, "a variable has changed when its NEW step differs from its OLD step by more than the "
                          "threshold, not when the new step itself is larger than it"),
    ({"replaced_alone": False}, "a replaced clique has a new conditional: recompute it even when its separator did "
                                "not change (a root has no separator at all)"),
]


def _wildfire_known(call, ref):
    out = {"delta": [], "recomputed": []}
    for slip, why in WILDFIRE_SLIPS:
        steps, recomputed = wildfire(*call.args, **slip)
        out["delta"].append((steps, why))
        out["recomputed"].append((np.array(recomputed, dtype=float), why))
    return out


MISTAKES = {
    f"{RELIN}: the largest absolute entry against the threshold": _relin_known,
    f"{RELIN}: strictly above the threshold": _relin_known,
    f"{AFFECTED}: the top of new factors (their cliques and the paths to the roots)": _affected_known,
    f"{AFFECTED}: relinearised variables in frontals or separators": _affected_known,
    f"{AFFECTED}: the orphans (the top's children outside it)": _affected_known,
    f"{ORPHANS}: each orphan's parent in the new top": _attach_known,
    f"{WILDFIRE}: the full back-substitution (every clique replaced, threshold 0)": _wildfire_known,
    f"{WILDFIRE}: the steps of a partial update": _wildfire_known,
    f"{WILDFIRE}: the recomputed cliques": _wildfire_known,
}
