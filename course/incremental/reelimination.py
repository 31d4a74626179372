"""The re-elimination of an affected top: its variables, its factors and the orphans' cached factors.

Given the top's variables ``T`` (those of the removed cliques and the new ones), the linear factors whose
variables all lie in ``T`` (``||A delta - b||^2``: blocks per variable) and the variables that must come
last (the new factors' keys, as GTSAM's constrained ordering puts them):

1. the ordering: the implementation's ``minimum_degree_ordering`` on the top's graph (two variables
   joined when a factor holds both), then the constrained variables moved to the end, each group in the
   order it gave;
2. the structure: its ``symbolic_elimination`` and ``bayes_tree`` of that ordering;
3. the numbers, in groups of cliques from the leaves up: a clique takes in its children's groups, the
   narrowest first, while its group's frontal unknowns stay within ``GROUP_WIDTH`` (a clique of a pose
   graph holds one or two poses: one call per clique would cost a Python call per pose). A group's
   factors (those whose first-eliminated variable is a frontal of one of its cliques, and the factors the
   groups below left on their separators) are stacked as dense rows over its frontals, children's before
   parents', then its root's separator, and eliminated at once by the implementation's
   ``eliminate_variable`` (``A_x`` the frontals' columns, ``A_s`` the separator's)::

       [A_x A_s | b]  ->  R (f, f) upper triangular, S (f, s), d (f,); A_new (k, s), b_new (k,)

   The Cholesky factor of an elimination order is the same whichever way the order is cut, so each
   clique's conditional ``(R_c, S_c, d_c)`` is its rows of ``[R S | d]`` at its frontals' columns and at
   its separator's (the other columns of its rows are zero: its separator is all a clique's conditional
   reaches), what eliminating it alone gives up to rounding. The call's new factor is the root's cached
   factor and goes to the clique holding the separator's first-eliminated variable (the root's parent).
   A clique below a group's root keeps its subtree's rows (a ``PendingSummary``): its cached factor is
   eliminated from them the first time an update reads it (when it becomes an orphan), by the same
   ``eliminate_variable``.
"""

import itertools
from dataclasses import dataclass

import numpy as np

from course.core.errors import SingularSystemError
from course.incremental.bayes_tree import NumericBayesTree

#: the frontal unknowns one ``eliminate_variable`` call takes at most: a clique takes in its children's groups
#: (one dense call for the group) while it stays within it
GROUP_WIDTH = 48


@dataclass
class LinearFactor:
    """``||sum_a A_a delta_{keys[a]} - b||^2``: ``keys`` variable indices, ``A`` [(m, d_a)], ``b`` (m,)."""

    keys: tuple
    A: list
    b: np.ndarray


@dataclass
class PendingSummary:
    """A cached factor not computed yet: the rows ``(A, b)`` a group of cliques was eliminated from (its columns
    ``columns[v]`` the first of variable v's), ``rows[u]`` the slice of clique u's rows, and the clique's
    ``subtree`` (its cliques in the group, children before parents) and ``separator``. The clique's subtree rows,
    its frontals as ``A_x`` and its separator as ``A_s``, eliminated, leave its cached factor."""

    A: np.ndarray
    b: np.ndarray
    rows: dict
    columns: dict
    subtree: list
    frontals: list
    separator: list


class Reeliminator:
    """The implementation's pieces of chapter 8 (``elimination``, ``orderings``, ``bayes_tree``) applied to a
    top; ``names`` (variable -> key) name a variable in an error."""

    def __init__(self, impl, names):
        self.impl = impl
        self.names = names

    def ordering(self, variables, factors, constrained) -> tuple:
        """``(ordering (n,) of the top's variables by local index, local index by variable, edges (E, 2) local)``:
        each pair of variables some factor holds is one edge, ``a < b``."""
        local = {v: k for k, v in enumerate(variables)}
        pairs = set()  # (a, b), a < b: each pair once, however many factors join it
        for f in factors:
            if len(f.keys) == 2:  # most factors: one pair
                a, b = local[f.keys[0]], local[f.keys[1]]
                if a != b:
                    pairs.add((a, b) if a < b else (b, a))
                continue
            ks = sorted({local[v] for v in f.keys})
            pairs.update((a, b) for i, a in enumerate(ks) for b in ks[i + 1:])
        edges = np.fromiter(itertools.chain.from_iterable(pairs), dtype=np.int64, count=2 * len(pairs)).reshape(-1, 2)
        order = self.impl.module("orderings").minimum_degree_ordering(len(variables), edges)
        order = np.asarray(order, dtype=np.int64)
        last = np.zeros(len(variables), dtype=bool)
        last[[local[v] for v in constrained if v in local]] = True
        order = np.concatenate([order[~last[order]], order[last[order]]])
        return order, local, edges

    def eliminate(self, variables, factors, constrained, dims) -> tuple:
        """Re-eliminate the top: ``(tree, ordering, groups)``, the new cliques (``NumericBayesTree`` over the
        global variable indices, parents within it), the ordering used (global indices) and the groups
        eliminated together: ``(cliques (root first), frontals, the root's separator, (R, S, d))``, the
        conditional of the group's frontals in that order."""
        order, _, edges = self.ordering(variables, factors, constrained)
        n = len(variables)
        separators, _, _ = self.impl.module("orderings").symbolic_elimination(n, edges, order)
        frontals, clique_separators, parents = self.impl.module("bayes_tree").bayes_tree(order, separators)
        parents = np.asarray(parents, dtype=int)
        glob = np.asarray(variables, dtype=np.int64)
        names = glob.tolist()
        # each factor to the clique holding its first-eliminated variable (dicts by global index: they are read
        # one entry at a time)
        position = dict(zip(glob[order].tolist(), range(n)))
        home = {names[v]: c for c, F in enumerate(frontals) for v in F}
        waiting: list = [[] for _ in frontals]
        for f in factors:
            waiting[home[min(f.keys, key=position.__getitem__)]].append(f)
        C = len(frontals)
        F_of = [[names[v] for v in F] for F in frontals]
        S_of = [[names[v] for v in S] for S in clique_separators]
        # the groups, from the leaves up (a clique's number is above its parent's): each clique starts one, and
        # takes in its children's groups, the narrowest first, while it stays within GROUP_WIDTH
        width = [sum(dims[v] for v in F) for F in F_of]
        member_of: list = [[c] for c in range(C)]
        kids: list = [[] for _ in range(C)]
        for c in range(C):
            if parents[c] >= 0:
                kids[parents[c]].append(c)
        roots = []
        for c in range(C - 1, -1, -1):
            for ch in sorted(kids[c], key=width.__getitem__):
                if width[c] + width[ch] <= GROUP_WIDTH:
                    width[c] += width[ch]
                    member_of[c] += member_of[ch]
                    member_of[ch] = []
                else:
                    roots.append(ch)
            if parents[c] < 0:
                roots.append(c)
        # each group's cliques in order (its root first, a parent before its children); the groups by their
        # roots' numbers, so that a group comes after every group hanging below it when taken backwards
        members = [sorted(member_of[r]) for r in sorted(roots)]
        conditionals: list = [None] * C
        cached: list = [None] * C
        groups: list = [None] * len(members)
        for g in range(len(members) - 1, -1, -1):  # a group after every group hanging below it
            groups[g] = self._eliminate_group(members[g], F_of, S_of, parents, waiting, dims, conditionals, cached)
        tree = NumericBayesTree(F_of, S_of, parents, conditionals, cached)
        return tree, glob[order].tolist(), groups

    def _eliminate_group(self, group, F_of, S_of, parents, waiting, dims, conditionals, cached) -> tuple:
        """Eliminate the cliques ``group`` (its root first, each clique's parent before it) in one call of
        ``eliminate_variable``: their frontals (children's before parents') are ``A_x``, the root's separator
        ``A_s``. The call's ``R`` is upper triangular in that order, so each clique's conditional is its rows of
        ``[R S]`` at its frontals' and its separator's columns (what eliminating it alone gives, up to rounding);
        the call's new factor is the root's cached factor, and goes to the root's parent. A clique below the root
        keeps its subtree's rows in the group (a ``PendingSummary``), eliminated when first read. Returns
        ``(group, its frontals in that order, the root's separator, (R, S, d))``."""
        root = group[0]
        cliques = group[::-1]  # children before parents
        column: dict = {}
        width = 0
        span: dict = {}  # each variable's columns, as a range and as a slice
        at: dict = {}
        for v in [v for c in cliques for v in F_of[c]] + S_of[root]:
            column[v] = width
            span[v] = range(width, width + dims[v])
            at[v] = slice(width, width + dims[v])
            width += dims[v]
        f = width - sum(dims[v] for v in S_of[root])
        stacked = [fac for c in cliques for fac in waiting[c]]
        b = np.concatenate([fac.b for fac in stacked]) if stacked else np.zeros(0)
        rows, start = {}, 0  # each clique's rows (its factors are stacked one after another)
        for c in cliques:
            count = sum(len(fac.b) for fac in waiting[c])
            rows[c] = slice(start, start + count)
            start += count
        A = np.zeros((len(b), width))
        r = 0
        for fac in stacked:
            m = len(fac.b)
            if len(set(fac.keys)) == len(fac.keys):
                for v, block in zip(fac.keys, fac.A):
                    A[r:r + m, at[v]] = block
            else:  # a variable twice in one factor: its blocks add
                for v, block in zip(fac.keys, fac.A):
                    A[r:r + m, at[v]] += block
            r += m
        try:
            R, S, d, A_new, b_new = self.impl.module("elimination").eliminate_variable(A[:, :f], A[:, f:], b)
        except SingularSystemError as exc:
            names = ", ".join(repr(self.names[v]) for c in cliques for v in F_of[c])
            raise SingularSystemError(f"the factors on {names} do not determine them ({exc}): a variable "
                                      "needs a prior or enough measurements") from None
        T = np.hstack([np.asarray(R, dtype=float), np.asarray(S, dtype=float).reshape(f, width - f)])
        d = np.asarray(d, dtype=float).reshape(f)
        subtree: dict = {}  # clique -> the group's cliques in its subtree
        for c in cliques:
            subtree.setdefault(c, []).append(c)  # children before parents
            if c != root:
                subtree.setdefault(int(parents[c]), []).extend(subtree[c])
            lo = column[F_of[c][0]]
            hi = lo + sum(dims[v] for v in F_of[c])
            seps = [i for v in S_of[c] for i in span[v]]
            conditionals[c] = (T[lo:hi, lo:hi], T[lo:hi, seps], d[lo:hi])
            if c != root:
                cached[c] = PendingSummary(A, b, rows, column, subtree[c],
                                           [v for u in subtree[c] for v in F_of[u]], S_of[c])
        b_new = np.asarray(b_new, dtype=float).reshape(-1)
        A_new = np.asarray(A_new, dtype=float).reshape(len(b_new), width - f)
        cached[root] = (A_new, b_new)
        if S_of[root] and len(b_new):
            blocks, start = [], 0
            for v in S_of[root]:
                blocks.append(A_new[:, start:start + dims[v]])
                start += dims[v]
            waiting[parents[root]].append(LinearFactor(tuple(S_of[root]), blocks, b_new))
        return group, [v for c in cliques for v in F_of[c]], S_of[root], (T[:, :f], T[:, f:], d)

    @staticmethod
    def _columns(keys, column, dims) -> list:
        """The columns of the variables ``keys`` (``column[v]`` the first of v's), in their order."""
        return [i for v in keys for i in range(column[v], column[v] + dims[v])]

    def summary(self, tree, c, dims) -> tuple:
        """Clique ``c``'s cached factor ``(A, b)`` on its separator; one still pending is eliminated now (its
        subtree's rows, the subtree's frontals ``A_x``, the separator ``A_s``) and kept."""
        entry = tree.cached[c]
        if isinstance(entry, PendingSummary):
            inside = np.zeros(len(entry.b), dtype=bool)
            for u in entry.subtree:
                inside[entry.rows[u]] = True
            rows = entry.A[inside]
            A_x = rows[:, self._columns(entry.frontals, entry.columns, dims)]
            A_s = rows[:, self._columns(entry.separator, entry.columns, dims)]
            _, _, _, A_new, b_new = self.impl.module("elimination").eliminate_variable(A_x, A_s, entry.b[inside])
            b_new = np.asarray(b_new, dtype=float).reshape(-1)
            entry = (np.asarray(A_new, dtype=float).reshape(len(b_new), A_s.shape[1]), b_new)
            tree.cached[c] = entry
        return entry
