"""The re-elimination of an affected top: its variables, its factors and the orphans' cached factors.

Given the top's variables ``T`` (those of the removed cliques and the new ones), the linear factors whose
variables all lie in ``T`` (``||A delta - b||^2``: blocks per variable) and the variables that must come
last (the new factors' keys, as GTSAM's constrained ordering puts them):

1. the ordering: the implementation's ``minimum_degree_ordering`` on the top's graph (two variables
   joined when a factor holds both), then the constrained variables moved to the end, each group in the
   order it gave;
2. the structure: its ``symbolic_elimination`` and ``bayes_tree`` of that ordering;
3. the numbers, cliques from the leaves up: each clique's factors (those whose first-eliminated variable
   is one of its frontals, and the factors its children left on their separators) stacked as dense rows
   over its frontals then its separator, and eliminated at once by the implementation's
   ``eliminate_variable`` (``A_x`` the frontals' columns, ``A_s`` the separator's): the conditional
   ``(R, S, d)`` and the new factor on the separator, which goes to the clique holding the separator's
   first-eliminated variable (the parent).
"""

from dataclasses import dataclass

import numpy as np

from course.core.errors import SingularSystemError
from course.incremental.bayes_tree import NumericBayesTree


@dataclass
class LinearFactor:
    """``||sum_a A_a delta_{keys[a]} - b||^2``: ``keys`` variable indices, ``A`` [(m, d_a)], ``b`` (m,)."""

    keys: tuple
    A: list
    b: np.ndarray


class Reeliminator:
    """The implementation's pieces of chapter 8 (``elimination``, ``orderings``, ``bayes_tree``) applied to a
    top; ``names`` (variable -> key) name a variable in an error."""

    def __init__(self, impl, names):
        self.impl = impl
        self.names = names

    def ordering(self, variables, factors, constrained) -> tuple:
        """``(ordering of the top's variables (global indices), local index by variable, edges (E, 2) local)``."""
        local = {v: k for k, v in enumerate(variables)}
        pairs = []
        for f in factors:
            ks = sorted({local[v] for v in f.keys})
            pairs += [(a, b) for i, a in enumerate(ks) for b in ks[i + 1:]]
        edges = np.array(pairs, dtype=np.int64).reshape(-1, 2)
        order = self.impl.module("orderings").minimum_degree_ordering(len(variables), edges)
        last = np.zeros(len(variables), dtype=bool)
        last[[local[v] for v in constrained if v in local]] = True
        order = np.asarray(order, dtype=np.int64)
        order = np.concatenate([order[~last[order]], order[last[order]]])
        return order, local, edges

    def eliminate(self, variables, factors, constrained, dims) -> tuple:
        """Re-eliminate the top: ``(tree, ordering)``, the new cliques (``NumericBayesTree`` over the
        global variable indices, parents within it) and the ordering used (global indices)."""
        order, local, edges = self.ordering(variables, factors, constrained)
        n = len(variables)
        separators, _, _ = self.impl.module("orderings").symbolic_elimination(n, edges, order)
        frontals, clique_separators, parents = self.impl.module("bayes_tree").bayes_tree(order, separators)
        position = np.empty(n, dtype=np.int64)
        position[order] = np.arange(n)
        home = np.empty(n, dtype=np.int64)
        for c, F in enumerate(frontals):
            home[F] = c
        # each factor to the clique holding its first-eliminated variable
        waiting: list = [[] for _ in frontals]
        for f in factors:
            first = min((local[v] for v in f.keys), key=position.__getitem__)
            waiting[home[first]].append(f)
        glob = np.asarray(variables, dtype=np.int64)
        eliminate_variable = self.impl.module("elimination").eliminate_variable
        C = len(frontals)
        conditionals: list = [None] * C
        cached: list = [None] * C
        for c in range(C - 1, -1, -1):  # created parents first: backwards, children before their parents
            F = glob[frontals[c]].tolist()
            Sep = glob[clique_separators[c]].tolist()
            column = {}
            width = 0
            for v in F + Sep:
                column[v] = width
                width += dims[v]
            f = sum(dims[v] for v in F)
            rows = sum(len(fac.b) for fac in waiting[c])
            A = np.zeros((rows, width))
            b = np.empty(rows)
            r = 0
            for fac in waiting[c]:
                m = len(fac.b)
                for v, block in zip(fac.keys, fac.A):
                    A[r:r + m, column[v]:column[v] + dims[v]] += block
                b[r:r + m] = fac.b
                r += m
            try:
                R, S, d, A_new, b_new = eliminate_variable(A[:, :f], A[:, f:], b)
            except SingularSystemError as exc:
                names = ", ".join(repr(self.names[v]) for v in F)
                raise SingularSystemError(f"the factors on {names} do not determine them ({exc}): a variable "
                                          "needs a prior or enough measurements") from None
            conditionals[c] = (np.asarray(R, dtype=float), np.asarray(S, dtype=float).reshape(f, width - f),
                               np.asarray(d, dtype=float).reshape(f))
            b_new = np.asarray(b_new, dtype=float).reshape(-1)
            A_new = np.asarray(A_new, dtype=float).reshape(len(b_new), width - f)
            cached[c] = (A_new, b_new)
            if Sep and len(b_new):
                blocks, start = [], 0
                for v in Sep:
                    blocks.append(A_new[:, start:start + dims[v]])
                    start += dims[v]
                waiting[parents[c]].append(LinearFactor(tuple(Sep), blocks, b_new))
        tree = NumericBayesTree([glob[F].tolist() for F in frontals], [glob[S].tolist() for S in clique_separators],
                                np.asarray(parents, dtype=int), conditionals, cached)
        return tree, glob[order].tolist()
