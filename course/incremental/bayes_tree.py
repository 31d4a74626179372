"""The numeric Bayes tree the smoother keeps: cliques with their conditionals and cached factors.

Clique ``c`` holds its frontal variables ``frontals[c]`` (in elimination order), its separator
``separators[c]`` (in elimination order), its parent ``parents[c]`` (-1 for a root), its Gaussian
conditional ``(R, S, d)``::

    p(F_c | S_c) ~ exp(-1/2 ||R delta_F + S delta_S - d||^2)     R (f, f) upper triangular, S (f, s), d (f,)

(``f``, ``s`` the summed tangent sizes of the frontals and of the separator, stacked in their orders),
and its cached factor ``(A, b)`` on the separator, ``||A delta_S - b||^2`` (k, s): what eliminating the
clique's subtree left on its separator, which an update that keeps the subtree whole (an orphan) reads
instead of the subtree's factors. The lists are those the implementation's ``incremental_update`` and
``bayes_tree`` functions take: cliques numbered ``0..C-1``, variables ``0..n-1``.
"""

from dataclasses import dataclass, field

import numpy as np
import scipy.sparse as sp


@dataclass
class NumericBayesTree:
    """The cliques, as parallel lists (``parents`` an int array)."""

    frontals: list = field(default_factory=list)
    separators: list = field(default_factory=list)
    parents: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=int))
    conditionals: list = field(default_factory=list)
    cached: list = field(default_factory=list)

    def __len__(self) -> int:
        return len(self.frontals)

    def replace_top(self, top, orphans, orphan_parents, new) -> list:
        """The tree with the cliques ``top`` removed and the cliques ``new`` (a ``NumericBayesTree`` whose
        parents index ``new`` itself) added after the kept ones; each orphan hangs from the new clique
        ``orphan_parents[k]``. Returns the new cliques' numbers (the ones re-eliminated)."""
        C = len(self)
        keep = np.ones(C, dtype=bool)
        keep[list(top)] = False
        kept = np.flatnonzero(keep)
        number = np.full(C + 1, -1, dtype=int)  # old number -> new number; entry C for -1 (a root)
        number[kept] = np.arange(len(kept))
        offset = len(kept)
        parents = number[self.parents[kept]] if len(kept) else np.zeros(0, dtype=int)
        for orphan, p in zip(orphans, orphan_parents):
            parents[number[orphan]] = offset + int(p)
        new_parents = np.where(new.parents >= 0, new.parents + offset, -1)
        self.frontals = [self.frontals[c] for c in kept] + new.frontals
        self.separators = [self.separators[c] for c in kept] + new.separators
        self.conditionals = [self.conditionals[c] for c in kept] + new.conditionals
        self.cached = [self.cached[c] for c in kept] + new.cached
        self.parents = np.concatenate([parents, new_parents]).astype(int)
        return list(range(offset, offset + len(new)))

    def elimination_order(self) -> list:
        """An elimination order of the tree's variables: every clique's frontals (in their order) after
        those of all its descendants (children before parents)."""
        children: list = [[] for _ in self.frontals]
        roots: list = []
        for c, p in enumerate(self.parents.tolist()):
            (roots if p < 0 else children[p]).append(c)
        order, stack = [], list(roots)
        while stack:  # a pre-order from the roots, reversed: parents after children
            c = stack.pop()
            order.append(c)
            stack.extend(children[c])
        return [v for c in reversed(order) for v in self.frontals[c]]

    def square_root_information(self, dims) -> tuple:
        """``(R (N, N) CSR, order, sizes)``: the tree's conditionals as one upper-triangular square-root
        information over the variables in :meth:`elimination_order` (``dims`` their tangent sizes by
        variable), its dense blocks stored whole (a pattern closed under elimination)."""
        order = self.elimination_order()
        sizes = np.array([dims[v] for v in order], dtype=int)
        start = np.zeros(len(dims) + 1, dtype=int)
        start[np.array(order, dtype=int)] = np.concatenate([[0], np.cumsum(sizes)[:-1]])
        rows, cols, vals = [], [], []
        for F, Sep, (R, S, _) in zip(self.frontals, self.separators, self.conditionals):
            index = np.concatenate([start[v] + np.arange(dims[v]) for v in F + Sep])
            f = R.shape[0]
            block = np.hstack([np.triu(R), S])
            r = np.repeat(index[:f], block.shape[1])
            c = np.tile(index, f)
            upper = c >= r  # R's lower triangle is not part of the pattern
            rows.append(r[upper])
            cols.append(c[upper])
            vals.append(block.ravel()[upper])
        N = int(sizes.sum())
        R = sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(N, N))
        return R, order, sizes
