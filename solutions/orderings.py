"""Chapter 8 exercise: the elimination game, and a greedy minimum-degree ordering.

Eliminating the variables of a factor graph one by one (Dellaert & Kaess, "Factor Graphs for Robot
Perception", chapter 3) turns it into a Bayes net; which conditionals appear, and how dense they are,
depends on the structure only. Here the structure alone is played out: the variables are
``0..n-1``, and two variables are joined by an (undirected) edge when some factor touches both.

Eliminating a variable ``v`` from the current graph (the original edges plus the fill so far):

- its separator ``S(v)`` is the set of its neighbours that are not eliminated yet (the variables
  of its conditional ``p(v | S(v))``);
- every pair of ``S(v)`` is joined (the new factor on ``S(v)``); a pair that was not an edge of the
  original graph is fill;
- ``v`` is removed.

The elimination tree: the parent of ``v`` is the variable of ``S(v)`` eliminated first, -1 (a root)
where ``S(v)`` is empty; each connected component has one root, its last variable eliminated.

The input graph: ``edges`` (E, 2) integer pairs of ``0..n-1``. E may be 0; a pair may be given
several times, in either order (two factors on the same variables), and a pair ``(i, i)`` joins no two
variables (a factor on one variable, a prior) and is ignored. ``ordering`` (n,) is a permutation of
``0..n-1``: ``ordering[k]`` is the k-th variable eliminated.

The graphs run to a few thousand variables: an adjacency of Python sets, or a boolean matrix, is fast
enough; a Python loop over every pair of variables at every elimination (n^3 steps in all) is not.

Inputs at the edges of the contract (each is a check input):
- symbolic_elimination: one variable (n = 1, no edges)
- symbolic_elimination: two connected components (two roots)
- symbolic_elimination: a pair given twice, once in each order
- symbolic_elimination: a pair (i, i), which joins no two variables
- minimum_degree_ordering: one variable (n = 1, no edges)
- minimum_degree_ordering: two connected components
- minimum_degree_ordering: a pair given twice, once in each order
- minimum_degree_ordering: a pair (i, i), which joins no two variables

Allowed imports: numpy, scipy.
"""

import numpy as np


def check_graph(n, edges):
    """Validated ``(n, edges)``: ``n`` an int >= 1, ``edges`` an int array (E, 2) of variables of
    ``0..n-1`` (an empty input is (0, 2)); raises ``ValueError`` naming the argument and the entry."""
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 1:
        raise ValueError(f"n must be an integer >= 1 (the number of variables), got {n!r}")
    n = int(n)
    raw = np.asarray(edges)
    if raw.size == 0:
        return n, np.zeros((0, 2), dtype=np.int64)
    if raw.ndim != 2 or raw.shape[1] != 2:
        raise ValueError(f"edges must be an (E, 2) array of variable pairs, got shape {raw.shape}")
    if raw.dtype.kind not in "iu":  # not a (signed or unsigned) integer dtype
        if raw.dtype.kind != "f" or not np.all(np.isfinite(raw)) or np.any(raw != np.round(raw)):
            raise ValueError(f"edges must hold integer variable indices, got dtype {raw.dtype}")
    pairs = raw.astype(np.int64)
    if pairs.min() < 0 or pairs.max() >= n:
        row = int(np.flatnonzero(np.any((pairs < 0) | (pairs >= n), axis=1))[0])
        raise ValueError(f"edges[{row}] = ({pairs[row, 0]}, {pairs[row, 1]}) names a variable outside 0..{n - 1}")
    return n, pairs


def check_ordering(n, ordering):
    """Validated ``ordering``, an int array (n,), a permutation of ``0..n-1``; raises ``ValueError``
    naming the entry out of range, the variable repeated or the variable missing."""
    raw = np.asarray(ordering)
    if raw.ndim != 1 or len(raw) != n:
        raise ValueError(f"ordering must be a permutation of 0..{n - 1} (shape ({n},)), got shape {raw.shape}")
    if raw.dtype.kind not in "iu":  # not a (signed or unsigned) integer dtype
        if raw.dtype.kind != "f" or not np.all(np.isfinite(raw)) or np.any(raw != np.round(raw)):
            raise ValueError(f"ordering must hold integer variable indices, got dtype {raw.dtype}")
    order = raw.astype(np.int64)
    if order.min() < 0 or order.max() >= n:
        k = int(np.flatnonzero((order < 0) | (order >= n))[0])
        raise ValueError(f"ordering[{k}] = {order[k]} is not a variable of 0..{n - 1}")
    counts = np.bincount(order, minlength=n)
    if np.any(counts != 1):
        repeated, missing = int(np.flatnonzero(counts > 1)[0]), int(np.flatnonzero(counts == 0)[0])
        at = np.flatnonzero(order == repeated)
        raise ValueError(f"ordering must be a permutation of 0..{n - 1}: it repeats variable {repeated} "
                         f"(at positions {at[0]} and {at[1]}) and misses variable {missing}")
    return order


def symbolic_elimination(n, edges, ordering):
    """Eliminate the variables in ``ordering``: ``(separators, parents, fill)``.

    Args: n, the number of variables; edges (E, 2) int pairs; ordering (n,) a permutation of 0..n-1.

    Returns:
    - ``separators``: a list of n lists; ``separators[v]`` is the separator ``S(v)``, sorted by
      elimination position (the variable eliminated earliest first);
    - ``parents``: an int array (n,), ``parents[v]`` the variable of ``S(v)`` eliminated first, -1 where
      ``S(v)`` is empty;
    - ``fill``: an int array (F, 2) of the fill edges, ``i < j`` in each row, the rows sorted
      lexicographically, each once ((0, 2) when there is none).

    Raises ValueError for n < 1, an edge naming a variable outside 0..n-1, or an ordering that is not a
    permutation of 0..n-1 (``check_graph``, ``check_ordering``).
    """
    n, edges = check_graph(n, edges)
    ordering = check_ordering(n, ordering)
    # BEGIN SOLUTION
    position = [0] * n
    for k, v in enumerate(ordering.tolist()):
        position[v] = k
    later = [set() for _ in range(n)]  # each variable's neighbours in the graph that are eliminated after it
    for i, j in edges.tolist():
        if position[i] < position[j]:
            later[i].add(j)
        elif position[j] < position[i]:  # (a pair (i, i) is neither)
            later[j].add(i)
    # Eliminating v joins every pair of S(v). Its first member p is the next of them eliminated, and every
    # other member is in S(p) then: handing S(v) to p alone is enough, p hands it on in turn. So S(v) is v's
    # later neighbours together with what was handed to v: S(c) without v for every c whose parent is v.
    joined = [set() for _ in range(n)]
    separators = [[] for _ in range(n)]
    parents = np.full(n, -1, dtype=np.int64)
    fill = set()
    for v in ordering.tolist():
        S = later[v] | joined[v]
        separator = sorted(S, key=position.__getitem__)
        separators[v] = separator
        if separator:
            p = separator[0]
            parents[v] = p
            joined[p] |= S
            joined[p].discard(p)
        # v's fill edges: the variables joined to v that are not its neighbours in the graph
        fill.update((v, u) if v < u else (u, v) for u in joined[v] - later[v])
    fill = np.array(list(fill), dtype=np.int64).reshape(-1, 2)
    return separators, parents, fill[np.lexsort((fill[:, 1], fill[:, 0]))]  # the rows sorted
    # END SOLUTION


def minimum_degree_ordering(n, edges):
    """A greedy minimum-degree elimination ordering, an int array (n,).

    Repeatedly eliminate (as in ``symbolic_elimination``, fill included) the variable not eliminated yet
    with the fewest neighbours among the variables not eliminated yet in the current graph; ties go to
    the smallest index. Raises ValueError as ``check_graph``.
    """
    n, edges = check_graph(n, edges)
    # BEGIN SOLUTION
    neighbours = [set() for _ in range(n)]
    for i, j in edges.tolist():
        if i != j:
            neighbours[i].add(j)
            neighbours[j].add(i)
    degree = np.array([len(s) for s in neighbours], dtype=np.int64)
    ordering = np.empty(n, dtype=np.int64)
    for k in range(n):
        v = int(degree.argmin())  # the first of the smallest: ties go to the smallest index
        ordering[k] = v
        degree[v] = n  # above any degree: never the minimum again
        separator = neighbours[v]
        for i in separator:
            current = neighbours[i]  # joined to the rest of the separator, in place: no new set
            current |= separator
            current.discard(i)
            current.discard(v)
            degree[i] = len(current)
        neighbours[v] = set()
    return ordering
    # END SOLUTION


#: the derived results, in three levels (``python -m autograder hint NAME LEVEL``; the release
#: prints levels 1..N into the docstrings with ``--hints N``, course.core.hints)
HINTS = {
    "symbolic_elimination": (
        """Keep, for every variable, the set of its neighbours that are not eliminated yet, starting from the
        edges (each pair both ways, self-pairs skipped; a set absorbs the repeats). Then walk the ordering: the
        separator of v is just its set at that moment.""",
        """Eliminating v: S(v) = the current neighbours of v. Remove v from each of their sets; join every pair
        (i, j) of S(v) (add j to i's set and i to j's). A pair that is not in i's set before you add it is
        fill: an original edge between two variables not eliminated yet is still there, so nothing else is
        new. Sort S(v) by position in the ordering (the inverse permutation, position[ordering[k]] = k); the
        parent is its first entry.""",
        """Pseudo-code::

            position[ordering[k]] = k
            nbrs[v] = {u : (u, v) or (v, u) in edges, u != v}
            for v in ordering:
                S = sorted(nbrs[v], key=position)
                separators[v] = S;  parents[v] = S[0] if S else -1
                for a, i in enumerate(S):
                    nbrs[i].remove(v)
                    for j in S[a+1:]:
                        if j not in nbrs[i]:
                            nbrs[i].add(j); nbrs[j].add(i); fill.add((min(i, j), max(i, j)))
            fill = sorted(fill) as an (F, 2) array""",
    ),
    "minimum_degree_ordering": (
        """Play the same game as symbolic_elimination, choosing the next variable as you go: the degree of a
        variable is the size of its current neighbour set (the variables not eliminated yet, fill included),
        so it changes every time one of its neighbours is eliminated.""",
        """Only the separator's variables change degree when v is eliminated: each loses v and gains the other
        separator variables it was not joined to yet. A linear scan for the minimum (degree, index) over the
        remaining variables is O(n^2) and fast enough here; a heap of (degree, index) with stale entries
        skipped on the way out is faster.""",
        """Pseudo-code::

            nbrs[v] = {u : (u, v) or (v, u) in edges, u != v};  remaining = {0..n-1}
            while remaining:
                v = min(remaining, key=lambda u: (len(nbrs[u]), u))
                ordering.append(v);  remaining.remove(v)
                S = nbrs[v]
                for i in S:
                    nbrs[i].remove(v);  nbrs[i] |= S - {i}""",
    ),
}
