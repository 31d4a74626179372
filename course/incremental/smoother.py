"""An iSAM2-like incremental smoother on the chapter-7 factor graph (Kaess et al., IJRR 2012).

The smoother keeps every variable's linearisation point ``theta_v`` and step ``delta_v`` (its kind's
tangent size), every factor with its linearisation at ``theta`` (``course.incremental.factors``) and the
Bayes tree of the linearised system (``course.incremental.bayes_tree``). ``update(new_factors,
new_values)``:

1. the new variables join at their given values (``delta = 0``), the new factors are stored;
2. fluid relinearisation: the variables whose step's largest entry exceeds ``relinearize_threshold``
   (the implementation's ``relinearised_keys``; checked every update, GTSAM's ``relinearizeSkip = 1``)
   move their linearisation point, ``theta_v <- theta_v (+) delta_v``, ``delta_v <- 0``, and every factor
   on them is linearised again (with GTSAM's rule, by default: also the frontals of every clique whose
   separator holds such a variable); the new factors are linearised;
3. the affected top and its orphans (``affected_cliques``, on the whole tree): the top's cliques are
   removed, its variables and the new ones re-eliminated (``course.incremental.reelimination``) from the factors whose
   variables all lie in the top and the orphans' cached factors, the new factors' variables ordered
   last; each orphan hangs from its new parent (``orphan_parents``);
4. the wildfire update of the steps (``wildfire_update``, ``wildfire_threshold``), handed the tree front
   by front (``course.incremental.wildfire``).

``estimate()`` is ``theta (+) delta``. ``marginal(key)``/``marginals(keys)``: the covariance of the
current linearised system from the tree's conditionals (the implementation's ``marginal_covariances``).
Variables fixed in a graph and robust losses are not taken: anchor a graph with a prior.

Cost (``python -m course online intel --no-batch``, three runs, then ``m3500 --no-batch`` and ``sphere2500
--poses 1000 --no-batch``, one run each, on a shared 2-core machine, GTSAM's ISAM2 in the same run; its own time
moves by a third between runs): over intel's 729 steps 6.0 s in all against ISAM2's 0.59 s (medians; 10.0x to
10.5x by run; median step 5.8 against 0.41 ms); on all of M3500 80 s against 7.6 s (10.6x; median 3.2 against
0.36 ms, p90 71 against 4.0); sphere2500's first 1000 poses 84 s against 8.1 s (10.3x). No loop of the framework
visits every clique in an update (the implementation's ``affected_cliques`` reads the whole tree: 0.6 ms a call
at 1779 cliques). What is left is Python per call of the implementation (``online DATASET --breakdown`` times each
call: on intel the 17.8 calls of an update take 60% of its time, six times GTSAM's whole run): an update makes
about nine ``eliminate_variable`` calls (0.13 to 0.25 ms each from M3500's calls to sphere2500's, about 40 us of it the
given input checks), two ``wildfire_update`` calls, the ordering, symbolic elimination and Bayes tree of its
top, and the framework stacks each group's rows factor by factor. A loop closure on M3500 that re-eliminates
1500 of 1900 poses takes about 0.2 s (GTSAM's ISAM2 about 20 ms): 0.09 s the top's re-elimination (100 groups),
the rest the relinearisation of its factors, the wildfire and the tree's bookkeeping.
"""

from dataclasses import dataclass

import numpy as np

from course.core import impl as impl_loader
from course.incremental.bayes_tree import NumericBayesTree
from course.incremental.factors import FactorStore
from course.incremental.reelimination import LinearFactor, Reeliminator
from course.incremental.wildfire import wildfire_in_fronts


@dataclass
class UpdateResult:
    """What one update did: variables relinearised, re-eliminated (the top's and the new ones),
    cliques recomputed by the wildfire update, and the cliques in the tree after it."""

    relinearized: int
    reeliminated: int
    recomputed: int
    cliques: int


class IncrementalSmoother:
    """``IncrementalSmoother(impl="solutions", relinearize_threshold=0.01, wildfire_threshold=0.001,
    relinearize_neighbours=True)``.

    ``relinearize_neighbours``: as GTSAM's ISAM2 does, a variable whose step crossed the threshold also
    relinearises the frontal variables of every clique that holds it in its separator (those cliques are
    re-eliminated anyway); False relinearises the variables past the threshold alone."""

    def __init__(self, impl="solutions", relinearize_threshold: float = 0.01, wildfire_threshold: float = 0.001,
                 relinearize_neighbours: bool = True):
        self.impl = impl_loader.load(impl)
        self.relinearize_neighbours = bool(relinearize_neighbours)
        self.relinearize_threshold = float(relinearize_threshold)
        self.wildfire_threshold = float(wildfire_threshold)
        self.keys: list = []
        self.index: dict = {}
        self.kinds: list = []
        self.dims: list = []
        self.theta: list = []
        self.delta: list = []
        self.factors = FactorStore(self.impl)
        self.tree = NumericBayesTree()
        self._reeliminator = Reeliminator(self.impl, self.keys)
        self._changed: set = set()  # the variables whose step the last update recomputed
        self._checked_at = self.relinearize_threshold  # the threshold of the last check

    # ------------------------------------------------------------ the update

    def update(self, new_factors=None, new_values=None) -> UpdateResult:
        """Add ``new_factors`` (a ``course.factorgraph.FactorGraph`` whose variables name the keys and
        kinds its factors use; the values it holds are not read) and ``new_values`` (key -> value, the
        initial value of every variable new to the smoother), and update the solution."""
        added = self._add(new_factors, {} if new_values is None else dict(new_values))
        new_vars, new_ids = added
        n_tree = len(self.keys) - len(new_vars)
        incremental = self.impl.module("incremental_update")
        # only the steps the last wildfire update recomputed can have crossed the threshold since the last
        # check (any other is as it was then, at or below it): those alone are checked, unless the threshold
        # has been lowered since
        if self.relinearize_threshold < self._checked_at:
            self._changed = set(range(n_tree))
        self._checked_at = self.relinearize_threshold
        candidates = sorted(v for v in self._changed if v < n_tree)
        relin = [candidates[k] for k in incremental.relinearised_keys([self.delta[v] for v in candidates],
                                                                      self.relinearize_threshold)]
        if relin and self.relinearize_neighbours:
            relin = self._with_neighbours(relin)
        new_keys = sorted({v for i in new_ids for v in self.factors.keys[i]})
        if len(self.tree):
            # the whole tree: its lists are kept as they are, so handing them over costs nothing
            top, orphans = incremental.affected_cliques(self.tree.frontals, self.tree.separators, self.tree.parents,
                                                        new_keys, relin)
            # in the order the cliques were created (the re-elimination's ordering breaks its ties by it)
            top = sorted(top, key=self.tree.created.__getitem__)
            orphans = sorted(orphans, key=self.tree.created.__getitem__)
        else:
            top, orphans = [], []
        # the relinearisation: new linearisation points, their factors linearised again
        relinearise = set(new_ids)
        by_kind: dict = {}
        for v in relin:
            by_kind.setdefault(self.kinds[v].name, []).append(v)
        for vs in by_kind.values():  # one retraction per kind
            kind = self.kinds[vs[0]]
            moved = np.asarray(kind.retract(np.stack([self.theta[v] for v in vs]),
                                            np.stack([self.delta[v] for v in vs])), dtype=float)
            for k, v in enumerate(vs):
                self.theta[v] = moved[k]
                self.delta[v] = np.zeros(self.dims[v])
                relinearise.update(self.factors.of_variable[v])
        self.factors.linearise(sorted(relinearise), self.theta, self.kinds)
        # the top's variables, its factors, the orphans' cached factors
        variables = [v for c in top for v in self.tree.frontals[c]] + new_vars
        inside = set(variables)
        touching = set().union(*[self.factors.of_variable[v] for v in variables])
        ids = sorted([i for i in touching if inside.issuperset(self.factors.keys[i])])
        linear = [LinearFactor(self.factors.keys[i], self.factors.A[i], self.factors.b[i]) for i in ids]
        for o in orphans:
            A, b = self._reeliminator.summary(self.tree, o, self.dims)
            if len(b):
                blocks, start = [], 0
                for v in self.tree.separators[o]:
                    blocks.append(A[:, start:start + self.dims[v]])
                    start += self.dims[v]
                linear.append(LinearFactor(tuple(self.tree.separators[o]), blocks, b))
        replaced: list = []
        groups: list = []
        if variables:
            new_tree, ordering, groups = self._reeliminator.eliminate(variables, linear, new_keys, self.dims)
            parents_of_orphans = incremental.orphan_parents([self.tree.separators[o] for o in orphans], ordering,
                                                            new_tree.frontals) if orphans else []
            replaced = self.tree.replace_top(top, orphans, parents_of_orphans, new_tree)
            groups = [([replaced[k] for k in members], F, S, conditional) for members, F, S, conditional in groups]
        recomputed: list = []
        if len(self.tree):
            self.delta, recomputed = wildfire_in_fronts(incremental.wildfire_update, self.tree, self.delta, replaced,
                                                        self.wildfire_threshold, self.dims, groups)
            self._changed = {v for c in recomputed for v in self.tree.frontals[c]}
        return UpdateResult(len(relin), len(variables), len(recomputed), len(self.tree))

    def _with_neighbours(self, relin: list) -> list:
        """``relin`` and the frontals of every clique whose separator holds one of them, sorted."""
        out = set(relin)
        if 8 * len(relin) > len(self.tree):  # many (a large loop closure): one pass over the separators is cheaper
            hit = set(relin)
            for F, S in zip(self.tree.frontals, self.tree.separators):
                if not hit.isdisjoint(S):
                    out.update(F)
            return sorted(out)
        for v in relin:
            for c in self.tree.holding(v)[1:]:  # past its home
                out.update(self.tree.frontals[c])
        return sorted(out)

    def _add(self, graph, values: dict) -> tuple:
        """Check, then store, the new variables and factors: ``(new variable indices, new factor ids)``."""
        for key in values:
            if key in self.index:
                raise ValueError(f"new_values: variable {key!r} is already in the smoother (a key is added once)")
        if graph is None:
            if values:
                raise ValueError(f"new_values: {next(iter(values))!r} has no kind: give the new variables with a "
                                 "FactorGraph of the factors on them")
            return [], []
        if graph.fixed or graph.fixed_dofs:
            raise ValueError(f"{graph.name}: the incremental smoother takes no fixed variables: anchor the graph "
                             "with a prior factor")
        for group in graph.groups.values():
            if group.loss is not None:
                raise ValueError(f"{graph.name}: {group.type.name}: the incremental smoother takes no robust "
                                 "loss (least squares only)")
        used = {graph.keys[v] for group in graph.groups.values() for keys in group.keys for v in np.ravel(keys)}
        for key in values:
            if key not in graph.index:
                raise ValueError(f"new_values: {key!r} is not a variable of {graph.name!r}: its kind is unknown")
        missing = [key for key in graph.keys if key in used and key not in self.index and key not in values]
        if missing:
            raise ValueError(f"{graph.name}: a factor is on {missing[0]!r}, which has no value: give it in new_values "
                             "(a variable new to the smoother needs an initial value)")
        checked = {}
        for key, value in values.items():
            kind = graph.kinds[graph.index[key]]
            checked[key] = kind.check(value, f"new_values[{key!r}]")
        for key in graph.keys:
            if key in self.index and graph.kinds[graph.index[key]] != self.kinds[self.index[key]]:
                raise ValueError(f"{graph.name}: variable {key!r} is a {graph.kinds[graph.index[key]].name} there "
                                 f"but a {self.kinds[self.index[key]].name} in the smoother")
        from course.factorgraph import noise  # chapter 7's (imported where used: this package loads in any tree)

        groups = []
        for group in graph.groups.values():
            keys, z, info = group.arrays()
            W = noise.whitening(info, group.type.dim, len(keys), f"{graph.name}: {group.type.name}")
            groups.append((group.type, keys, z, W))
        new_vars = []
        for key, value in checked.items():
            kind = graph.kinds[graph.index[key]]
            self.index[key] = len(self.keys)
            new_vars.append(len(self.keys))
            self.keys.append(key)
            self.kinds.append(kind)
            self.dims.append(kind.dim)
            self.theta.append(value)
            self.delta.append(np.zeros(kind.dim))
            self.factors.add_variable()
        new_ids = []
        for ftype, keys, z, W in groups:
            for row, k in enumerate(keys):
                new_ids.append(self.factors.add(ftype, [self.index[graph.keys[v]] for v in k], z[row],
                                                None if W is None else W[row]))
        return new_vars, new_ids

    def _retract(self, v: int, step) -> np.ndarray:
        kind = self.kinds[v]
        return np.asarray(kind.retract(self.theta[v][None], np.asarray(step, dtype=float)[None]),
                          dtype=float).reshape(kind.shape)

    # ------------------------------------------------------------ the solution

    def estimate(self) -> dict:
        """Every variable's value ``theta (+) delta``, by key (stored values, the kind's shape)."""
        return {key: self._retract(v, self.delta[v]) for v, key in enumerate(self.keys)}

    def estimate_of(self, v: int) -> np.ndarray:
        """Variable ``v``'s value ``theta_v (+) delta_v`` (by index, the order added)."""
        return self._retract(v, self.delta[v])

    def estimate_list(self) -> list:
        """The estimate as a list by variable index (the order added)."""
        return [self._retract(v, self.delta[v]) for v in range(len(self.keys))]

    def chi2(self, values=None) -> float:
        """``sum |W r|^2`` over every factor at ``values`` (key -> value; default the estimate)."""
        theta = self.estimate_list() if values is None else [np.asarray(values[key], dtype=float)
                                                             for key in self.keys]
        return self.factors.chi2(theta)

    def linear_step(self) -> dict:
        """The current step ``delta`` by key (the tangent step at the linearisation point)."""
        return {key: self.delta[v].copy() for v, key in enumerate(self.keys)}

    def linearization_point(self) -> dict:
        return {key: self.theta[v].copy() for v, key in enumerate(self.keys)}

    def marginals(self, keys) -> np.ndarray:
        """The joint covariance of ``keys`` (sum d, sum d) in the current linearised system, by the
        implementation's ``marginal_covariances.joint_marginal`` on the tree's square-root information."""
        if not len(self.tree):
            raise ValueError("marginals: the smoother holds no variable yet")
        for key in keys:
            if key not in self.index:
                raise ValueError(f"marginals: no variable {key!r} in the smoother")
        R, order, sizes = self.tree.square_root_information(self.dims)
        position = {v: k for k, v in enumerate(order)}
        return self.impl.module("marginal_covariances").joint_marginal(
            R, sizes, [position[self.index[key]] for key in keys])

    def marginal(self, key) -> np.ndarray:
        """The marginal covariance (d, d) of ``key``."""
        return self.marginals([key])
