# RELEASE: omit
"""Known mistakes in ``orderings`` (see ``autograder.mistakes``): the elimination game and the
minimum-degree ordering played with one slip."""

import numpy as np

from autograder.checks.orderings import ELIMINATION, MINIMUM_DEGREE
from autograder.tasks.common import encode_lists


def _neighbours(n, edges, multi=False):
    """Adjacency sets (lists with every repeat and self-pair where ``multi``)."""
    nbrs = [[] if multi else set() for _ in range(n)]
    for i, j in np.asarray(edges, dtype=np.int64).reshape(-1, 2).tolist():
        if multi:
            nbrs[i].append(j)
            nbrs[j].append(i)
        elif i != j:
            nbrs[i].add(j)
            nbrs[j].add(i)
    return nbrs


def eliminate(n, edges, ordering, *, drop_eliminated=True, add_fill=True, sort="position"):
    """``(separators, [the pairs joined, in order, as (S[a], S[b]) with a < b])``: the game with one slip
    or none. ``drop_eliminated=False``: v stays in its neighbours' sets (as the reference's code without
    its ``discard``); ``add_fill=False``: no pair is joined; ``sort="index"``: separators sorted by index."""
    ordering = np.asarray(ordering, dtype=np.int64).tolist()
    position = {v: k for k, v in enumerate(ordering)}
    nbrs = _neighbours(n, edges)
    separators, joined = [[] for _ in range(n)], []
    for v in ordering:
        separator = sorted(nbrs[v], key=position.__getitem__ if sort == "position" else None)
        separators[v] = separator
        for a, i in enumerate(separator):
            if drop_eliminated:
                nbrs[i].discard(v)
            for j in separator[a + 1:] if add_fill else ():
                joined.append((i, j, j not in nbrs[i]))
                nbrs[i].add(j)
                nbrs[j].add(i)
        nbrs[v] = set()
    return separators, joined


def _parents(separators, pick="first", root=-1):
    out = np.full(len(separators), -1.0 if root == "self" else root, dtype=float)
    for v, separator in enumerate(separators):
        if separator:
            out[v] = {"first": separator[0], "last": separator[-1], "smallest": min(separator),
                      "largest": max(separator)}[pick]
        elif root == "self":
            out[v] = v
    return out


def _fill_array(rows):
    return np.array(rows, dtype=float).reshape(-1, 2)


def _args(call):
    return call.args[0], call.args[1], call.args[2]


KEEP = "the separator holds only the neighbours not eliminated yet: remove v from its neighbours when it is eliminated"
NO_FILL = ("eliminating v joins every pair of its separator (the new factor on them): later separators are read "
           "from the graph with that fill, not from the original edges")
BY_INDEX = "each separator is sorted by elimination position (the variable eliminated first, first), not by index"


def _separator_slips(call):
    n, edges, ordering = _args(call)
    return [(eliminate(n, edges, ordering, drop_eliminated=False)[0], KEEP),
            (eliminate(n, edges, ordering, add_fill=False)[0], NO_FILL),
            (eliminate(n, edges, ordering, sort="index")[0], BY_INDEX)]


def known_separators(call, want):
    return {"separators": [(encode_lists(s), why) for s, why in _separator_slips(call)]}


def known_parents(call, want):
    n, edges, ordering = _args(call)
    separators = eliminate(n, edges, ordering)[0]
    slips = [
        (_parents(separators, "last"), "the parent is the separator's variable eliminated FIRST, not the last"),
        (_parents(separators, "smallest"), "the parent is the separator's variable eliminated first, not the "
                                           "smallest index"),
        (_parents(separators, "largest"), "the parent is the separator's variable eliminated first, not the "
                                          "largest index"),
        (_parents(separators, root=0), "a root (an empty separator) has parent -1, not 0"),
        (_parents(separators, root="self"), "a root (an empty separator) has parent -1, not itself"),
    ]
    slips += [(_parents(s), f"the parents follow from wrong separators: {why}") for s, why in _separator_slips(call)]
    return {"parents": slips}


def known_fill(call, want):
    n, edges, ordering = _args(call)
    original = {(min(i, j), max(i, j)) for i, j in np.asarray(edges, dtype=np.int64).reshape(-1, 2).tolist()}
    _, joined = eliminate(n, edges, ordering)
    every = sorted({(min(i, j), max(i, j)) for i, j, _ in joined})
    new = [(min(i, j), max(i, j)) for i, j, fresh in joined if fresh]
    repeats = sorted((min(i, j), max(i, j)) for i, j, _ in joined if (min(i, j), max(i, j)) not in original)
    _, kept = eliminate(n, edges, ordering, drop_eliminated=False)
    slips = [
        (_fill_array(every), "fill is only the pairs joined that were not edges of the original graph"),
        (_fill_array(repeats), "each fill edge once: a pair joined again by a later elimination is no new fill"),
        (_fill_array(sorted((i, j) for i, j, fresh in joined if fresh)),
         "write each fill edge (i, j) with i < j (min, max), whatever the order in the separator"),
        (_fill_array(new), "sort the fill's rows lexicographically (by i, then j)"),
        (_fill_array([]), "eliminating v joins every pair of its separator: the pairs that were not joined before "
                          "are the fill"),
        (_fill_array(sorted({(min(i, j), max(i, j)) for i, j, fresh in kept if fresh})),
         f"the fill follows from wrong separators: {KEEP}"),
    ]
    return {"fill": slips}


def minimum_degree(n, edges, *, update=True, fill=True, count_eliminated=False, ties="smallest", multi=False):
    """The greedy ordering with one slip or none."""
    nbrs = _neighbours(n, edges, multi)
    alive = [True] * n
    original = [len(s) for s in nbrs]
    order = []
    for _ in range(n):
        def degree(u):
            if not update:
                return original[u]
            return len(nbrs[u]) if count_eliminated or multi else sum(alive[w] for w in nbrs[u])

        candidates = [u for u in range(n) if alive[u]]
        best = min(degree(u) for u in candidates)
        ties_at = [u for u in candidates if degree(u) == best]
        v = ties_at[0] if ties == "smallest" else ties_at[-1]
        order.append(v)
        alive[v] = False
        separator = sorted({u for u in nbrs[v] if alive[u]})
        for i in separator:
            if multi:
                nbrs[i] = [w for w in nbrs[i] if w != v]
            if fill:
                for j in separator:
                    if j != i and j not in nbrs[i]:
                        nbrs[i].append(j) if multi else nbrs[i].add(j)
    return np.array(order, dtype=float)


def known_minimum_degree(call, want):
    n, edges = call.args
    slips = [
        (minimum_degree(n, edges, update=False), "the degrees change as variables are eliminated: count the "
                                                  "neighbours in the current graph, not the original degrees"),
        (minimum_degree(n, edges, ties="largest"), "ties go to the smallest index (np.argmin gives the first)"),
        (minimum_degree(n, edges, count_eliminated=True), "the degree counts only the neighbours not eliminated yet"),
        (minimum_degree(n, edges, fill=False), "eliminating a variable joins its neighbours (fill): their degrees "
                                               "grow; count them in the graph with the fill so far"),
        (minimum_degree(n, edges, multi=True), "a pair given twice is one edge, and a pair (i, i) none: count "
                                               "distinct neighbours"),
    ]
    return {"value": slips}


MISTAKES = {
    f"{ELIMINATION}: separators": known_separators,
    f"{ELIMINATION}: elimination tree (parents)": known_parents,
    f"{ELIMINATION}: fill edges": known_fill,
    f"{MINIMUM_DEGREE}: greedy minimum-degree ordering": known_minimum_degree,
}
