"""The implementation's ``affected_cliques`` handed a cut of a large tree, with the whole tree's answer.

``affected_cliques`` marks the cliques holding a new key as a frontal or a relinearised variable as a frontal
or in their separator, closes them upwards (the top) and lists the top's other children (the orphans). Only
the cliques that hold those variables, their ancestors and their ancestors' children can take part; handing
it the whole tree costs a pass over every clique. The cut:

1. the cliques that hold a new key (its home) or a relinearised variable (its home and the cliques below
   it holding it in their separator, ``NumericBayesTree.holding``), and every ancestor of theirs;
2. their children (the possible orphans);

with the cut's cliques numbered 0..C'-1 and its variables (their frontals) 0..n'-1. A separator lies within
its clique's ancestors, so the cut is a tree of the same contract; a clique is marked in it exactly when it is
in the whole tree, so its top and orphans are the whole tree's.
"""

import numpy as np


def affected_in_cut(affected_cliques, tree, new_keys, relinearised, holding=None) -> tuple:
    """``(top, orphans)`` (sorted clique numbers of ``tree``), as ``affected_cliques(tree.frontals,
    tree.separators, tree.parents, new_keys, relinearised)`` on the whole tree. ``holding``: v -> the
    cliques holding v (default ``tree.holding``; the smoother passes the walks it has already made)."""
    holding = holding or tree.holding
    n = len(tree.home)
    seeds = [tree.home[v] for v in new_keys if v < n]
    for v in relinearised:
        seeds += holding(v)
    path: dict = {}  # the seeds and their ancestors, each once
    for c in seeds:
        while c >= 0 and c not in path:
            path[c] = True
            c = int(tree.parents[c])
    cliques = list(path) + [ch for c in path for ch in tree.children[c] if ch not in path]
    variables = [v for c in cliques for v in tree.frontals[c]]
    local = {v: k for k, v in enumerate(variables)}
    number = {c: k for k, c in enumerate(cliques)}
    frontals = [[local[v] for v in tree.frontals[c]] for c in cliques]
    separators = [[local[v] for v in tree.separators[c]] for c in cliques]
    parents = np.array([number[int(tree.parents[c])] if tree.parents[c] >= 0 else -1 for c in cliques], dtype=int)
    n_cut = len(variables)
    # a new key outside the tree stays outside the cut's variables (it joins the top)
    keys = [local[v] if v < n else n_cut + k for k, v in enumerate(new_keys)]
    top, orphans = affected_cliques(frontals, separators, parents, keys, [local[v] for v in relinearised])
    return sorted(cliques[int(c)] for c in top), sorted(cliques[int(c)] for c in orphans)
