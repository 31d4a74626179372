"""The numeric Bayes tree the smoother keeps: cliques with their conditionals and cached factors.

Clique ``c`` holds its frontal variables ``frontals[c]`` (in elimination order), its separator
``separators[c]`` (in elimination order), its parent ``parents[c]`` (-1 for a root), its Gaussian
conditional ``(R, S, d)``::

    p(F_c | S_c) ~ exp(-1/2 ||R delta_F + S delta_S - d||^2)     R (f, f) upper triangular, S (f, s), d (f,)

(``f``, ``s`` the summed tangent sizes of the frontals and of the separator, stacked in their orders),
and its cached factor ``(A, b)`` on the separator, ``||A delta_S - b||^2`` (k, s): what eliminating the
clique's subtree left on its separator, which an update that keeps the subtree whole (an orphan) reads
instead of the subtree's factors (or a ``reelimination.PendingSummary`` that gives it when first read).
The lists are those the implementation's ``incremental_update`` and ``bayes_tree`` functions take: cliques
numbered ``0..C-1``, variables ``0..n-1``.

Kept with them, so that an update costs nothing per clique it does not touch: each clique's ``children``,
each variable's ``home`` (the clique holding it as a frontal) and each clique's ``created`` rank (the order
cliques were made in, which the smoother lists a top in). ``replace_top`` gives the new cliques the removed
ones' numbers and moves the last cliques into any numbers left free.
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
    children: list = field(default_factory=list)  # clique -> its children, kept with ``parents``
    home: list = field(default_factory=list)  # variable -> the clique holding it as a frontal
    created: list = field(default_factory=list)  # clique -> when it was created (its rank among all cliques)
    count: int = 0  # the cliques created so far

    def __post_init__(self):
        if len(self.frontals) and not self.children:
            self.children = [[] for _ in self.frontals]
            for c, p in enumerate(np.asarray(self.parents).tolist()):
                if p >= 0:
                    self.children[p].append(c)

    def __len__(self) -> int:
        return len(self.frontals)

    def holding(self, v: int) -> list:
        """The cliques holding variable ``v`` (its home, then those with ``v`` in their separator): they
        form a subtree below its home, walked down through the cliques holding it."""
        out, stack = [], [self.home[v]]
        while stack:
            c = stack.pop()
            out.append(c)
            stack.extend(ch for ch in self.children[c] if v in self.separators[ch])
        return out

    def replace_top(self, top, orphans, orphan_parents, new) -> list:
        """The tree with the cliques ``top`` removed and the cliques ``new`` (a ``NumericBayesTree`` whose
        parents index ``new`` itself) added; each orphan hangs from the new clique ``orphan_parents[k]``.
        The new cliques take the removed ones' numbers, then new numbers; where fewer, the last cliques move
        into the free numbers (the cliques stay numbered 0..C-1, and no other clique is touched). Returns the
        new cliques' numbers (the ones re-eliminated)."""
        free = sorted(int(c) for c in top)
        C = len(self)
        slots = free[:len(new)] + list(range(C, C + max(0, len(new) - len(free))))
        grow = len(slots) - len(free[:len(new)])
        self.frontals += [None] * grow
        self.separators += [None] * grow
        self.conditionals += [None] * grow
        self.cached += [None] * grow
        self.children += [[] for _ in range(grow)]
        self.created += [0] * grow
        parents = np.concatenate([self.parents, np.full(grow, -1, dtype=int)]) if grow else self.parents
        removed = set(free)
        for c in free:  # detach the top from the parents it keeps
            p = int(parents[c])
            if p >= 0 and p not in removed:
                self.children[p].remove(c)
        for k, c in enumerate(slots):
            p = int(new.parents[k])
            parents[c] = slots[p] if p >= 0 else -1
            self.frontals[c] = new.frontals[k]
            self.separators[c] = new.separators[k]
            self.conditionals[c] = new.conditionals[k]
            self.cached[c] = new.cached[k]
            self.children[c] = []
            self.created[c] = self.count + k
        self.count += len(slots)
        for c in slots:
            if parents[c] >= 0:
                self.children[parents[c]].append(c)
        need = max((v for F in new.frontals for v in F), default=-1) + 1
        if need > len(self.home):
            self.home += [-1] * (need - len(self.home))
        for k, c in enumerate(slots):
            for v in new.frontals[k]:
                self.home[v] = c
        for orphan, p in zip(orphans, orphan_parents):
            parents[orphan] = slots[int(p)]
            self.children[slots[int(p)]].append(int(orphan))
        self.parents = parents
        # the numbers left free: the live cliques past the new size move into those below it
        holes = set(free[len(new):])
        size = len(self) - len(holes)
        movers = [c for c in range(size, len(self)) if c not in holes]
        for c, to in zip(movers, sorted(h for h in holes if h < size)):
            self._move(c, to)
        for name in ("frontals", "separators", "conditionals", "cached", "children", "created"):
            del getattr(self, name)[size:]
        self.parents = self.parents[:size]
        return slots

    def _move(self, c: int, to: int) -> None:
        """Clique ``c`` renumbered ``to`` (a free number)."""
        p = int(self.parents[c])
        if p >= 0:
            siblings = self.children[p]
            siblings[siblings.index(c)] = to
        for ch in self.children[c]:
            self.parents[ch] = to
        for v in self.frontals[c]:
            self.home[v] = to
        self.parents[to] = p
        self.frontals[to] = self.frontals[c]
        self.separators[to] = self.separators[c]
        self.conditionals[to] = self.conditionals[c]
        self.cached[to] = self.cached[c]
        self.children[to] = self.children[c]
        self.created[to] = self.created[c]

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
