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
    raise NotImplementedError("TODO orderings.symbolic_elimination: not implemented yet")


def minimum_degree_ordering(n, edges):
    """A greedy minimum-degree elimination ordering, an int array (n,).

    Repeatedly eliminate (as in ``symbolic_elimination``, fill included) the variable not eliminated yet
    with the fewest neighbours among the variables not eliminated yet in the current graph; ties go to
    the smallest index. Raises ValueError as ``check_graph``.
    """
    n, edges = check_graph(n, edges)
    raise NotImplementedError("TODO orderings.minimum_degree_ordering: not implemented yet")
