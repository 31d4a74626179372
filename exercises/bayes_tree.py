"""Chapter 8: the Bayes tree of an elimination (Kaess et al., iSAM2, IJRR 2012, Algorithm 2).

Eliminating the n variables of a factor graph in an ``ordering`` leaves one conditional
``p(v | S_v)`` per variable: ``S_v``, v's separator, holds the variables adjacent to v when v was
eliminated, every one of them eliminated after v. The Bayes tree groups these conditionals into
cliques: a clique holds its frontal variables F and its separator S (the joint conditional
``p(F | S)``), and its parent is the clique that holds the separator's first-eliminated member as a
frontal.

Inputs (what a symbolic elimination gives):

- ``ordering``: (n,) a permutation of 0..n-1, n >= 1; ``ordering[k]`` is the k-th variable eliminated
  (its elimination position is k);
- ``separators``: a list of n lists of ints, ``separators[v]`` = S_v sorted by elimination position,
  earliest first. The pattern is that of an elimination (chordal): for every v with S_v not empty,
  S_v without its first member p is contained in S_p.

The tree is built over the conditionals in REVERSE elimination order (the last eliminated first):

- S_v empty: v starts a new root clique (frontals [v], separator []);
- else let p = S_v[0] (the separator's member eliminated first) and C_p the clique holding p as a
  frontal: if the variables of C_p (its frontals together with its separator) are exactly the set
  S_v, v joins C_p's frontals; otherwise v starts a new clique, a child of C_p, with frontals [v] and
  separator S_v.

Outputs, unique under these conventions: the cliques numbered in the order they are created (clique
0 is the root holding the last eliminated variable); ``frontals``, a list of lists, each clique's
frontal variables sorted by elimination position (earliest first); ``clique_separators``, a list of
lists, each clique's separator as it was created (the separator of its last-eliminated frontal; a
variable that joins later never changes it), sorted by elimination position; ``parents`` (number of
cliques,) int array, -1 for a root (one root per connected component of the graph).

Inputs at the edges of the contract (each is a check input):
- a single variable (n = 1)
- a chain: every separator holds one variable, each variable the first member of one separator at most
- a complete graph: every separator holds all the variables eliminated later
- two connected components (two empty separators)
- a separator of two or more variables, a strict subset of its first member p together with S_p (a child
  clique, not a merge)
- a separator that is its first member p together with all of S_p, S_p not empty
- clique_of on one clique of one variable

Allowed imports: numpy, scipy.
"""

import numpy as np


def _positions(ordering):
    """The elimination position of each variable, (n,) int; ValueError unless ``ordering`` is a permutation
    of 0..n-1 with n >= 1."""
    order = np.asarray(ordering)
    if order.ndim != 1 or order.size == 0:
        raise ValueError(f"ordering must be a non-empty 1-D sequence of ints, got shape {order.shape}")
    if order.dtype.kind not in "iu":
        raise ValueError(f"ordering must hold ints, got dtype {order.dtype}")
    n = order.size
    if np.any(order < 0) or np.any(order >= n) or np.unique(order).size != n:
        raise ValueError(f"ordering must be a permutation of 0..{n - 1}, got {order.tolist()}")
    position = np.empty(n, dtype=int)
    position[order] = np.arange(n)
    return position


def _check_separators(separators, position):
    """ValueError naming v and the entry when S_v has a variable out of range, one eliminated before v,
    is not sorted by elimination position, or breaks the elimination's pattern (S_v without its first
    member p not inside S_p)."""
    n = len(position)
    if len(separators) != n:
        raise ValueError(f"separators must hold one list per variable ({n}), got {len(separators)}")
    position = position.tolist()  # a list: indexing it by a Python int is what the loop does most
    ints = (int, np.integer)
    for v, S in enumerate(separators):
        last = position[v]
        for k, u in enumerate(S):
            if not (isinstance(u, ints) and 0 <= u < n):
                raise ValueError(f"separators[{v}][{k}] = {u!r} is not a variable (an int in 0..{n - 1})")
            if position[u] <= last:  # last is v's position at k = 0, the previous entry's after
                if position[u] <= position[v]:
                    raise ValueError(f"separators[{v}][{k}] = {u} is eliminated at position {position[u]}, not "
                                     f"after {v} (position {position[v]})")
                raise ValueError(f"separators[{v}] is not sorted by elimination position: separators[{v}][{k}] = "
                                 f"{u} (position {position[u]}) comes after a variable at position {last}")
            last = position[u]
        if len(S) > 1 and not set(separators[S[0]]).issuperset(S[1:]):
            extra = sorted(set(S[1:]) - set(separators[S[0]]))
            raise ValueError(f"separators[{v}] = {list(S)} is not the separator of an elimination: {extra} not in "
                             f"separators[{S[0]}] = {list(separators[S[0]])}")


def bayes_tree(ordering, separators):
    """The Bayes tree's cliques from the conditionals of an elimination.

    Args: ordering (n,) ints, a permutation of 0..n-1 (the k-th eliminated first); separators, n lists
    of ints, ``separators[v]`` = S_v sorted by elimination position. Returns ``(frontals,
    clique_separators, parents)``: two lists of lists (one per clique, in order of creation, each sorted
    by elimination position) and a (number of cliques,) int array, -1 for a root. See the module's
    docstring for the rule; ValueError for an input that is not an elimination's (naming v and the
    entry).
    """
    _check_separators(separators, _positions(ordering))
    raise NotImplementedError("TODO bayes_tree.bayes_tree: not implemented yet")


def clique_of(frontals, n):
    """The clique holding each variable as a frontal, (n,) int: ``out[v] = c`` where v is in
    ``frontals[c]``. ValueError unless the frontals hold every variable of 0..n-1 exactly once."""
    seen = [int(v) for F in frontals for v in F]
    if sorted(seen) != list(range(n)):
        raise ValueError(f"frontals must hold every variable of 0..{n - 1} exactly once, got {sorted(seen)}")
    raise NotImplementedError("TODO bayes_tree.clique_of: not implemented yet")
