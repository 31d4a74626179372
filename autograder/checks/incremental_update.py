"""Checks of ``incremental_update`` (chapter 8): fluid relinearisation, the affected top and its orphans,
reattaching the orphans, and the wildfire update of the steps.

Every output is unique under the contract: the lists are compared exactly, the steps with ``rtol`` 1e-9 and
``atol`` 1e-10 times the largest step (their scale).

The inputs are real updates of real Bayes trees. A linear least-squares problem (a factor per variable
tuple, random blocks, the last variable's block dominated by an identity so that it is well posed) is
ordered by a minimum-degree ordering, eliminated symbolically and grouped into a Bayes tree by the
reference's ``orderings`` and ``bayes_tree`` (instructor side: inside the builders); each clique's
conditional ``(R, S, d)`` is read off a QR factorisation of the problem with its columns in elimination
order, and the steps ``delta`` are the problem's solution. Then new factors arrive: the reference's
``affected_cliques`` gives the top, its variables (with any new ones) are ordered and eliminated again
together with the orphans' summaries on their separators, the reference's ``orphan_parents`` hangs the
orphans from the new cliques, and the new tree's conditionals come from the QR of the new problem in the
combined order (the orphans' subtrees first, in their old order, then the top's new order). The partial
update's threshold is one the reference's update splits the tree with, 10% away from any decision.

Public: a 2D pose graph of 10 poses with loop closures 0-5, 2-8 and 4-9 (variables of size 3) that gets
a new pose by odometry 9-10 and a loop closure 10-3; the same graph near convergence (its old factors
nearly agree: small steps) with a new loop closure that does not (the partial update only); a graph of
12 variables of sizes 1, 3 and 6 in two components that gets a factor between two of its variables.
Hidden: pose graphs of 10 to 16 poses with random loop closures and a random graph of sizes 1, 3 and 6,
updated the same ways, from the hidden seed. ``relinearised_keys`` gets the solutions of these problems
with thresholds between their entries, and steps written exactly at the threshold; ``orphan_parents``
also gets a made-up top whose orphans' separators are first eliminated elsewhere than at their smallest
index and listed in another order.
"""

from functools import cache

import numpy as np

from autograder.checks import Call, Verdict
from autograder.checks.common import check, failed
from autograder.checks.edges import Edge
from autograder.feedback import call_fields, compare

MODULES = ("incremental_update",)
RELIN = "incremental_update.relinearised_keys"
AFFECTED = "incremental_update.affected_cliques"
ORPHANS = "incremental_update.orphan_parents"
WILDFIRE = "incremental_update.wildfire_update"
RELIN_TASK = "@autograder.tasks.incremental_update:relinearised"
AFFECTED_TASK = "@autograder.tasks.incremental_update:affected"
WILDFIRE_TASK = "@autograder.tasks.incremental_update:wildfire"
ORPHANS_TARGET = "incremental_update:orphan_parents"

RTOL = 1e-9
#: relative to the largest reference step of the call
ATOL = 1e-10

# ---------------------------------------------------------------- problems and their trees


def _factor(rng, variables, sizes):
    """One linear factor ``(variables, blocks, rhs)``: as many rows as the last variable's size, random
    blocks with an identity added to the last one's (so that a chain of factors is well posed)."""
    rows = sizes[variables[-1]]
    blocks = []
    for v in variables:
        block = rng.normal(0.0, 0.5, (rows, sizes[v]))
        if v == variables[-1]:
            block += np.eye(rows)
        blocks.append(block)
    return tuple(variables), blocks, rng.normal(0.0, 1.0, rows)


def _system(factors, sizes):
    """``A`` (m, N) and ``b`` (m,) of ``factors`` over variables of ``sizes``."""
    starts = np.concatenate([[0], np.cumsum(sizes)]).astype(int)
    m = sum(len(rhs) for _, _, rhs in factors)
    A, b, at = np.zeros((m, starts[-1])), np.zeros(m), 0
    for variables, blocks, rhs in factors:
        for v, block in zip(variables, blocks):
            A[at:at + len(rhs), starts[v]:starts[v + 1]] = block
        b[at:at + len(rhs)] = rhs
        at += len(rhs)
    return A, b


def _steps(x, sizes):
    starts = np.concatenate([[0], np.cumsum(sizes)]).astype(int)
    return [x[starts[v]:starts[v + 1]].copy() for v in range(len(sizes))]


def _conditionals(factors, sizes, ordering, frontals, clique_separators):
    """Each clique's ``(R, S, d)`` from the QR of the problem with its columns in ``ordering``'s order."""
    A, b = _system(factors, sizes)
    starts = np.concatenate([[0], np.cumsum(sizes)]).astype(int)
    columns = np.concatenate([np.arange(starts[v], starts[v + 1]) for v in ordering])
    Q, R = np.linalg.qr(A[:, columns])
    d = Q.T @ b
    at = np.empty(len(sizes), dtype=int)  # where each variable's rows and columns start in R
    at[list(ordering)] = np.concatenate([[0], np.cumsum([sizes[v] for v in ordering])])[:-1]

    def index(variables):
        return np.concatenate([np.arange(at[v], at[v] + sizes[v]) for v in variables]) if variables else \
            np.zeros(0, dtype=int)

    out = []
    for F, S in zip(frontals, clique_separators):
        rows, cols = index(F), index(S)
        rest = np.setdiff1d(np.arange(R.shape[1]), np.concatenate([rows, cols]))
        if np.max(np.abs(R[np.ix_(rows, rest)]), initial=0.0) > 1e-9 * np.max(np.abs(R)):
            raise AssertionError(f"the clique of frontals {F} has entries outside its separator {S}")
        out.append((R[np.ix_(rows, rows)].copy(), R[np.ix_(rows, cols)].copy(), d[rows].copy()))
    return out, _steps(np.linalg.lstsq(A, b, rcond=None)[0], sizes)


def _eliminate(variables, pairs):
    """``(ordering, frontals, clique_separators, parents)`` of the graph on ``variables`` (a list) joined by
    ``pairs``, by the reference (minimum degree, symbolic elimination, Bayes tree); in ``variables``' names."""
    from autograder import reference

    orderings, tree = reference.solutions_module("orderings"), reference.solutions_module("bayes_tree")
    local = {v: k for k, v in enumerate(variables)}
    edges = np.array([(local[i], local[j]) for i, j in pairs], dtype=np.int64).reshape(-1, 2)
    n = len(variables)
    ordering = orderings.minimum_degree_ordering(n, edges)
    separators, _, _ = orderings.symbolic_elimination(n, edges, ordering)
    frontals, seps, parents = tree.bayes_tree(ordering, separators)

    def name(lists):
        return [[variables[int(k)] for k in items] for items in lists]

    return ([variables[int(k)] for k in ordering], name(frontals), name(seps), [int(p) for p in parents])


def _pairs(factors):
    return [(i, j) for variables, _, _ in factors for a, i in enumerate(variables) for j in variables[a + 1:]]


def _closure(rng, n, factors):
    """The pose a new pose's loop closure goes to: the first, in a random order, whose update leaves at least
    two cliques of the tree as they are (a partial update), else the one that leaves the most."""
    from autograder import reference

    affected = reference.solutions_module("incremental_update").affected_cliques
    frontals, seps, parents = _eliminate(list(range(n)), _pairs(factors))[1:]
    best, kept = 0, -1
    for k in rng.permutation(n - 2):
        top, _ = affected(frontals, seps, parents, [int(k), n - 1, n], [])
        if len(frontals) - len(top) > kept:
            best, kept = int(k), len(frontals) - len(top)
        if kept >= 2:
            break
    return best


@cache
def problem(kind, seed=None):
    """A problem, its Bayes tree and solution, and an update by new factors, as a dict: ``sizes``,
    ``factors``, ``tree`` (frontals, separators, parents), ``conditionals``, ``delta`` (the solution),
    ``new`` (the new factors), ``new_keys``, ``top``, ``orphans``, ``ordering`` (the top's new order),
    ``new_frontals`` (the new top's cliques), ``attach`` (the orphans' new parents), ``updated`` (the new
    tree, its conditionals, the steps before the wildfire and the replaced cliques), ``solution`` (the new
    problem's) and ``what``. ``kind``: ``"poses"`` or ``"mixed"``."""
    from autograder import reference

    update = reference.solutions_module("incremental_update")
    code = {"poses": 821, "mixed": 823, "settled": 825}[kind]
    rng = np.random.default_rng(code if seed is None else [seed, code])
    if kind in ("poses", "settled"):
        n = 10 if seed is None else int(rng.integers(10, 17))
        sizes = [3] * n
        factors = [_factor(rng, (0,), sizes)] + [_factor(rng, (v - 1, v), sizes) for v in range(1, n)]
        loops = [(0, 5), (2, 8), (4, 9)] if seed is None else sorted(
            {tuple(sorted(rng.choice(n, 2, replace=False).tolist())) for _ in range(n // 3)})
        factors += [_factor(rng, (i, j), sizes) for i, j in loops if j - i >= 2]
        if kind == "settled":  # the old factors nearly agree (small steps), the new loop closure does not
            factors = [(variables, blocks, rhs / 100) for variables, blocks, rhs in factors]
        sizes_new = sizes + [3]
        k = 3 if seed is None else _closure(rng, n, factors)
        new = [_factor(rng, (n - 1, n), sizes_new), _factor(rng, (k, n), sizes_new)]
        small = " near convergence (small steps)" if kind == "settled" else ""
        what = (f"a pose graph of {n} poses{small} with loop closures {[lp for lp in loops if lp[1] - lp[0] >= 2]}, "
                f"updated by odometry {n - 1}-{n} and a loop closure {n}-{k}")
    else:
        n = 12 if seed is None else int(rng.integers(10, 16))
        sizes = [int(d) for d in rng.choice([1, 3, 6], n)]
        sizes[:3] = [1, 3, 6]
        cut = n // 3  # two components: 0..cut-1 and cut..n-1
        factors = [_factor(rng, (0,), sizes), _factor(rng, (cut,), sizes)]
        factors += [_factor(rng, (v - 1, v), sizes) for v in range(1, n) if v != cut]
        for _ in range(n // 3):
            lo, hi = (cut, n) if rng.random() < 0.75 else (0, cut)
            i, j = sorted(rng.choice(np.arange(lo, hi), 2, replace=False).tolist())
            factors.append(_factor(rng, (i, j), sizes))
        i, j = sorted(rng.choice(np.arange(cut, n), 2, replace=False).tolist())
        sizes_new = list(sizes)
        new = [_factor(rng, (i, j), sizes_new)]
        what = (f"a graph of {n} variables of sizes {sizes} in two components (0-{cut - 1} and {cut}-{n - 1}), "
                f"updated by a factor {i}-{j}")
    ordering, frontals, seps, parents = _eliminate(list(range(n)), _pairs(factors))
    conditionals, delta = _conditionals(factors, sizes, ordering, frontals, seps)
    new_keys = sorted({v for variables, _, _ in new for v in variables})
    top, orphans = update.affected_cliques(frontals, seps, parents, new_keys, [])
    # the top's variables, eliminated again with the orphans' summaries and the new factors
    inside = sorted({v for c in top for v in frontals[c]} | set(range(n, len(sizes_new))))
    kept = set(inside)
    pairs = [(i, j) for i, j in _pairs(factors + new) if i in kept and j in kept]
    pairs += [(i, j) for c in orphans for a, i in enumerate(seps[c]) for j in seps[c][a + 1:]]
    top_order, top_frontals, top_seps, top_parents = _eliminate(inside, pairs)
    attach = [int(p) for p in update.orphan_parents([seps[c] for c in orphans], top_order, top_frontals)]
    # the new tree: the new top's cliques, then the cliques below the old top, renumbered in order
    below = [c for c in range(len(frontals)) if c not in set(top)]
    number = {c: len(top_frontals) + k for k, c in enumerate(below)}
    new_frontals = top_frontals + [frontals[c] for c in below]
    new_seps = top_seps + [seps[c] for c in below]
    new_parents = top_parents + [attach[orphans.index(c)] if c in orphans else number.get(parents[c], -1)
                                for c in below]
    combined = [v for v in ordering if v not in kept] + top_order
    new_conditionals, solution = _conditionals(factors + new, sizes_new, combined, new_frontals, new_seps)
    start = delta + [np.zeros(d) for d in sizes_new[n:]]
    return {"sizes": sizes, "factors": factors, "tree": (frontals, seps, parents), "conditionals": conditionals,
            "delta": delta, "new": new, "new_keys": new_keys, "top": top, "orphans": orphans,
            "ordering": top_order, "orphan_separators": [seps[c] for c in orphans], "new_frontals": top_frontals,
            "attach": attach, "updated": ((new_frontals, new_seps, new_parents), new_conditionals, start,
                                          list(range(len(top_frontals)))),
            "solution": solution, "what": what}


def _threshold(p):
    """A threshold for the partial update of ``p``'s new tree that lets some change through and stops
    another (by the reference, among the midpoints between the variables' changes): the one that best
    splits the cliques not replaced, among those whose outcome stays the same 10% either side (no rounding
    decides it)."""
    from autograder import reference

    update = reference.solutions_module("incremental_update")
    (frontals, seps, parents), conditionals, start, replaced = p["updated"]

    def recomputed(t):
        return update.wildfire_update(frontals, seps, parents, conditionals, start, replaced, t)[1]

    changes = [float(np.max(np.abs(a - b))) for a, b in zip(p["solution"], start) if np.size(a)]
    changes = sorted(x for x in set(changes) if x > 1e-6 * max(changes))  # rounding is no change
    best, score = 1.0, -1
    for lo, hi in zip(changes, changes[1:]):
        t = float(f"{np.sqrt(lo * hi):.2g}")
        if hi < 1.3 * lo or not lo < t < hi:
            continue
        chosen = recomputed(t)
        value = min(len(chosen) - len(replaced), len(frontals) - len(chosen))
        if value > score and recomputed(0.9 * t) == chosen == recomputed(1.1 * t):
            best, score = t, value
    return best


# ---------------------------------------------------------------- calls


def _relin_call(delta, threshold, what):
    steps = [np.asarray(s, dtype=float) for s in delta]
    return Call(RELIN_TASK, (steps, float(threshold)), returns="dict", label=RELIN,
                where=f"on {what} (threshold {threshold:g})")


def _largest_calls(seed=None):
    """The problems' solutions with a threshold between their entries, and made-up steps where the largest
    entry, a norm and a signed maximum disagree."""
    rng = np.random.default_rng(831 if seed is None else [seed, 831])
    calls = []
    for kind in ("poses", "mixed"):
        delta = problem(kind, seed)["delta"]
        largest = sorted({float(np.max(np.abs(s))) for s in delta})
        gaps = [k for k in range(1, len(largest)) if largest[k] > 1.05 * largest[k - 1]]
        k = int(rng.choice(gaps))
        t = float(f"{(largest[k - 1] + largest[k]) / 2:.3g}")  # a step away from any step's largest entry
        calls.append(_relin_call(delta, t, f"the steps of {problem(kind, seed)['what'].split(', updated')[0]}"))
    t = 0.25
    steps = []
    for d in rng.permutation([6, 6, 3, 3, 3, 1, 1, 6]):
        kind = int(rng.integers(4))
        if kind == 0:  # every entry below, the norm above
            step = rng.choice([-1.0, 1.0], int(d)) * 0.1875
        elif kind == 1:  # one negative entry above
            step = np.round(rng.uniform(-0.2, 0.2, int(d)) * 64) / 64
            step[int(rng.integers(d))] = -0.5
        elif kind == 2:  # one positive entry above
            step = np.round(rng.uniform(-0.2, 0.2, int(d)) * 64) / 64
            step[int(rng.integers(d))] = 0.375
        else:  # all small
            step = np.round(rng.uniform(-0.2, 0.2, int(d)) * 64) / 64
        steps.append(step)
    calls.append(_relin_call(steps, t, "made-up steps where the largest entry, the norm and the signed maximum "
                                       "disagree"))
    return calls


def _strict_calls(seed=None):
    """Steps written exactly at the threshold, and threshold 0 with steps exactly zero."""
    rng = np.random.default_rng(833 if seed is None else [seed, 833])
    t = float(rng.choice([0.125, 0.25, 0.5]))
    steps = [np.zeros(3), np.zeros(6), np.array([1.5 * t]), np.zeros(3), np.zeros(6), np.zeros(1)]
    steps[0][int(rng.integers(3))] = t  # its norm is t too: only the comparison decides
    steps[1][int(rng.integers(6))] = -t
    for step in steps[3:]:
        step[int(rng.integers(step.size))] = float(rng.choice([-0.5, 0.25, 0.5])) * t
    zeros = [np.zeros(3), np.zeros(1), np.array([0.0, 2.0 ** -30, 0.0]), np.zeros(6),
             np.array([-(2.0 ** -40)]), np.array([0.0, 0.0, 0.0, 0.0, 0.5, 0.0])]
    order = [int(k) for k in rng.permutation(len(zeros))]
    return [_relin_call(steps, t, "steps with entries exactly at the threshold"),
            _relin_call([zeros[k] for k in order], 0.0, "steps exactly zero and steps of 2^-30 and 2^-40")]


def _affected_call(p, new_keys, relinearised):
    frontals, seps, parents = p["tree"]
    return Call(AFFECTED_TASK, (frontals, seps, np.array(parents, dtype=np.int64), list(new_keys),
                                list(relinearised)), returns="dict", label=AFFECTED,
                where=f"on the Bayes tree of {p['what'].split(', updated')[0]} (frontals {frontals}, separators "
                      f"{seps}, parents {list(parents)}), new keys {list(new_keys)}, relinearised "
                      f"{list(relinearised)}")


def _new_calls(seed=None):
    poses, mixed = problem("poses", seed), problem("mixed", seed)
    return [_affected_call(poses, poses["new_keys"], []),
            _affected_call(mixed, mixed["new_keys"], []),
            _affected_call(mixed, [], [])]


def _in_separators(p, rng, count):
    """``count`` variables that sit in some clique's separator (so a clique holds them there only)."""
    _, seps, _ = p["tree"]
    candidates = sorted({v for S in seps for v in S})
    return sorted(int(v) for v in rng.choice(candidates, min(count, len(candidates)), replace=False))


def _relinearised_calls(seed=None):
    rng = np.random.default_rng(835 if seed is None else [seed, 835])
    poses, mixed = problem("poses", seed), problem("mixed", seed)
    return [_affected_call(poses, [], _in_separators(poses, rng, 1)),
            _affected_call(mixed, [], _in_separators(mixed, rng, 2)),
            _affected_call(poses, poses["new_keys"], _in_separators(poses, rng, 1))]


def _orphan_calls(seed=None):
    return _new_calls(seed) + _relinearised_calls(seed)


def _attach_call(separators, ordering, new_frontals, where):
    return Call(ORPHANS_TARGET, ([list(S) for S in separators], list(ordering), [list(F) for F in new_frontals]),
                label=ORPHANS, where=where)


def _made_up_top(rng):
    """A top of 8 to 12 variables named at random, its cliques cut from a random order, and orphans' separators
    of one to three members."""
    n = int(rng.integers(8, 13))
    names = [int(v) for v in rng.choice(40, n, replace=False)]
    ordering = [names[k] for k in rng.permutation(n)]
    cliques, at = [], 0
    while at < n:
        k = int(rng.integers(1, 4))
        cliques.append(ordering[at:at + k])
        at += k
    cliques = [cliques[k] for k in rng.permutation(len(cliques))]
    position = {v: k for k, v in enumerate(ordering)}
    separators = [[int(v) for v in rng.choice(names, int(rng.integers(1, 4)), replace=False)] for _ in range(6)]
    # one separator whose first-eliminated member is not its smallest, in another clique than the smallest
    home = {v: c for c, F in enumerate(cliques) for v in F}
    pair = next(((a, b) for i, a in enumerate(ordering) for b in ordering[i + 1:] if a > b and home[a] != home[b]),
                None)
    if pair is not None:
        separators[int(rng.integers(6))] = list(pair)
    return [sorted(S, key=lambda v: -position[v]) for S in separators], ordering, cliques  # last eliminated first


def _attach_calls(seed=None):
    rng = np.random.default_rng(837 if seed is None else [seed, 837])
    calls = []
    for kind in ("poses", "mixed"):
        p = problem(kind, seed)
        calls.append(_attach_call(p["orphan_separators"], p["ordering"], p["new_frontals"],
                                  f"after {p['what']} (orphans' separators {p['orphan_separators']}, the top's new "
                                  f"ordering {p['ordering']}, its cliques' frontals {p['new_frontals']})"))
    separators, ordering, cliques = _made_up_top(rng)
    calls.append(_attach_call(separators, ordering, cliques,
                              f"on a made-up top (orphans' separators {separators}, ordering {ordering}, new "
                              f"frontals {cliques})"))
    return calls


def _wildfire_call(tree, conditionals, delta, replaced, threshold, what):
    frontals, seps, parents = tree
    return Call(WILDFIRE_TASK, (frontals, seps, np.array(parents, dtype=np.int64),
                                [tuple(np.array(b) for b in triple) for triple in conditionals],
                                [np.array(s) for s in delta], list(replaced), float(threshold)),
                returns="dict", label=WILDFIRE,
                where=f"{what} (frontals {frontals}, separators {seps}, parents {list(parents)}, replaced "
                      f"{list(replaced)}, threshold {threshold:g})")


def _full_calls(seed=None):
    """Every clique replaced, threshold 0: the old trees from zero steps, the new trees from the old steps."""
    calls = []
    for kind in ("poses", "mixed"):
        p = problem(kind, seed)
        tree, conditionals, start, _ = p["updated"]
        calls.append(_wildfire_call(tree, conditionals, start, range(len(tree[0])), 0.0, f"after {p['what']}"))
        calls.append(_wildfire_call(p["tree"], p["conditionals"], [np.zeros_like(s) for s in p["delta"]],
                                    range(len(p["tree"][0])), 0.0,
                                    f"on {p['what'].split(', updated')[0]}, from zero steps"))
    return calls


def _partial_calls(seed=None):
    """The new trees, their top replaced, the old steps, a threshold that stops the update somewhere."""
    calls = []
    for kind in ("poses", "mixed", "settled"):
        p = problem(kind, seed)
        tree, conditionals, start, replaced = p["updated"]
        calls.append(_wildfire_call(tree, conditionals, start, replaced, _threshold(p), f"after {p['what']}"))
    return calls


def _recomputed_calls(seed=None):
    return _partial_calls(seed) + _full_calls(seed)


# ---------------------------------------------------------------- judges


def _ints(values) -> list:
    return [int(x) for x in np.ravel(np.asarray(values, dtype=float))]


def _same(mine, value) -> bool:
    mine, value = np.ravel(np.asarray(mine, dtype=float)), np.ravel(np.asarray(value, dtype=float))
    return mine.shape == value.shape and np.array_equal(mine, value)


def _causes(ctx, triples, index, field, default, same=_same):
    """The sentences of the known mistakes whose ``field`` matches the student's on call ``index``, without
    those another call rules out (listed there, but not what the student returned); ``default`` when none."""
    ruled_out = {why for k, (_, got, _) in enumerate(triples)
                 for value, why in ctx.known(k).get(field, ()) if not same(got[field], value)}
    _, got, _ = triples[index]
    matching = list(dict.fromkeys(why for value, why in ctx.known(index).get(field, ()) if same(got[field], value)))
    whys = [why for why in matching if why not in ruled_out] or matching
    return "; or ".join(whys) if whys else default


def _lists_judge(field, name, cause):
    """Compare the sorted list ``field`` exactly, naming what is missing and what is extra."""

    def judge(ctx):
        triples, failure = call_fields(ctx, failed=failed)
        if failure:
            return failure
        for index, (call, got, want) in enumerate(triples):
            mine, ref = _ints(got[field]), _ints(want[field])
            if mine == ref:
                continue
            why = _causes(ctx, triples, index, field, cause)
            if mine != sorted(mine) or len(set(mine)) != len(mine):
                return Verdict(0.0, f"{name} = {mine} is not sorted ascending without repeats (expected {ref}) "
                                    f"{call.where}")
            missing, extra = sorted(set(ref) - set(mine)), sorted(set(mine) - set(ref))
            parts = [f"missing {missing}" if missing else "", f"not expected {extra}" if extra else ""]
            return Verdict(0.0, f"{name} = {mine}, expected {ref} ({', '.join(p for p in parts if p)}) "
                                f"{call.where}: {why}")
        return failure or Verdict(1.0, "ok")

    return judge


_ORPHANS_CAUSE = "the orphans are the cliques outside the top whose parent is in the top (not their descendants)"


def _orphans_judge(ctx):
    """The orphans against the reference's where the top is the reference's; where it is not (the top checks
    say so), against the student's own top, so that a wrong top costs the top's checks only."""
    triples, failure = call_fields(ctx, failed=failed)
    if failure:
        return failure
    for index, (call, got, want) in enumerate(triples):
        mine, top = _ints(got["orphans"]), _ints(got["top"])
        if top == _ints(want["top"]):
            ref = _ints(want["orphans"])
        else:
            parents = [int(p) for p in call.args[2]]
            ref = [c for c in range(len(parents)) if c not in set(top) and parents[c] in set(top)]
        if mine != ref:
            why = _causes(ctx, triples, index, "orphans", _ORPHANS_CAUSE)
            return Verdict(0.0, f"orphans = {mine}, expected {ref} (for the top {top}) {call.where}: {why}")
    return failure or Verdict(1.0, "ok")


def _attach_judge(ctx):
    triples, failure = call_fields(ctx, failed=failed)
    if failure:
        return failure
    for index, (call, got, want) in enumerate(triples):
        mine, ref = np.ravel(np.asarray(got["value"], dtype=float)), np.ravel(np.asarray(want["value"], dtype=float))
        if mine.shape != ref.shape:
            return Verdict(0.0, f"orphan_parents returned {mine.size} parents, expected one per orphan ({ref.size}) "
                                f"{call.where}")
        wrong = np.flatnonzero(mine != ref)
        if wrong.size:
            i = int(wrong[0])
            why = _causes(ctx, triples, index, "value",
                          "its parent is the clique holding, as a frontal, the separator's member eliminated FIRST in "
                          "the new ordering")
            return Verdict(0.0, f"orphan {i}'s parent is {mine[i]:g}, expected {ref[i]:g} (separator "
                                f"{call.args[0][i]}) {call.where}: {why}")
    return failure or Verdict(1.0, "ok")


_STEPS_CAUSE = ("from the roots down, a clique in `replaced`, or with a separator variable whose step changed by more "
                "than the threshold (largest absolute entry, against its old step), gets delta_F = R^-1 (d - S "
                "delta_S); any other clique, and its subtree, keep their steps")


def _close(mine, value) -> bool:
    mine, value = np.asarray(mine, dtype=float), np.asarray(value, dtype=float)
    atol = ATOL * max(float(np.max(np.abs(value), initial=0.0)), 1.0)
    return mine.shape == value.shape and bool(np.allclose(mine, value, rtol=RTOL, atol=atol))


def _steps_judge(ctx):
    triples, failure = call_fields(ctx, failed=failed)
    if failure:
        return failure
    for index, (call, got, want) in enumerate(triples):
        sizes = [np.size(s) for s in call.args[4]]
        starts = np.concatenate([[0], np.cumsum(sizes)]).astype(int)
        mine, ref = np.asarray(got["delta"], dtype=float), np.asarray(want["delta"], dtype=float)
        atol = ATOL * max(float(np.max(np.abs(ref), initial=0.0)), 1.0)
        text = compare(mine, ref, "new_delta (stacked)", RTOL, atol, call.where)
        if text is None:
            continue
        if mine.shape == ref.shape:
            bad = np.abs(mine - ref) > atol + RTOL * np.abs(ref)
            v = int(np.searchsorted(starts, int(np.flatnonzero(bad)[0]), side="right") - 1)
            a, b = starts[v], starts[v + 1]
            text = compare(mine[a:b], ref[a:b], f"new_delta[{v}]", RTOL, atol, call.where)
        why = _causes(ctx, triples, index, "delta", _STEPS_CAUSE, _close)
        return Verdict(0.0, f"{text}: {why}")
    return failure or Verdict(1.0, "ok")


def _kept_judge(ctx):
    triples, failure = call_fields(ctx, failed=failed)
    if failure:
        return failure
    for call, got, _ in triples:
        if not float(np.ravel(got["kept"])[0]):
            return Verdict(0.0, f"wildfire_update changed the delta it was given {call.where}: build a new list of "
                                "new arrays (new = [step.copy() for step in delta]); the smoother keeps the old "
                                "steps to compare with")
    return failure or Verdict(1.0, "ok")


CHECKS = [
    check(RELIN, "the largest absolute entry against the threshold", 2, _largest_calls,
          _lists_judge("keys", "the relinearised keys",
                       "v is relinearised when max(abs(delta[v])) > threshold: the largest ABSOLUTE entry, not a "
                       "norm")),
    check(RELIN, "strictly above the threshold", 1, _strict_calls,
          _lists_judge("keys", "the relinearised keys",
                       "compare strictly: a step whose largest absolute entry equals the threshold is not marked"),
          exact_inputs=True),
    check(AFFECTED, "the top of new factors (their cliques and the paths to the roots)", 2, _new_calls,
          _lists_judge("top", "top",
                       "mark the clique holding each new key (< n) as a frontal, then add every ancestor up to its "
                       "root")),
    check(AFFECTED, "relinearised variables in frontals or separators", 2, _relinearised_calls,
          _lists_judge("top", "top",
                       "a relinearised variable marks every clique whose frontals OR separator hold it, and each "
                       "marked clique brings its ancestors up to the root")),
    check(AFFECTED, "the orphans (the top's children outside it)", 2, _orphan_calls, _orphans_judge),
    check(ORPHANS, "each orphan's parent in the new top", 3, _attach_calls, _attach_judge),
    check(WILDFIRE, "the full back-substitution (every clique replaced, threshold 0)", 3, _full_calls,
          _steps_judge),
    check(WILDFIRE, "the steps of a partial update", 2, _partial_calls, _steps_judge),
    check(WILDFIRE, "the recomputed cliques", 2, _recomputed_calls,
          _lists_judge("recomputed", "recomputed",
                       "recompute a clique when it is replaced or a separator variable's step changed by more than "
                       "the threshold (against its old step); skip the rest and their subtrees")),
    check(WILDFIRE, "delta left as it was", 1, _partial_calls, _kept_judge),
]

# ---------------------------------------------------------------- the edges


def _reference_wildfire(call):
    from autograder import reference

    return reference.solutions_module("incremental_update").wildfire_update(*call.args)


def _stops(call):
    """Some clique not replaced is skipped while its parent is recomputed."""
    _, recomputed = _reference_wildfire(call)
    parents, replaced = [int(p) for p in call.args[2]], set(call.args[5])
    return any(c not in recomputed and c not in replaced and parents[c] in recomputed for c in range(len(parents)))


def _untouched_root(call):
    from autograder import reference

    top, _ = reference.solutions_module("incremental_update").affected_cliques(*call.args)
    roots = [c for c, p in enumerate(call.args[2]) if p == -1]
    return len(roots) >= 2 and any(c in top for c in roots) and any(c not in top for c in roots)


def _relinearised_in_separator(call):
    relinearised = set(call.args[4])
    return bool(relinearised) and any(relinearised & set(S) for S in call.args[1])


def _first_not_smallest(call):
    position = {v: k for k, v in enumerate(call.args[1])}
    return any(min(S, key=position.get) != min(S) for S in call.args[0])


def _largest_at_threshold(call):
    return any(np.size(s) and float(np.max(np.abs(s))) == call.args[1] for s in call.args[0])


EDGES = (
    Edge("relinearised_keys: threshold 0 (every step not exactly zero is marked)", RELIN_TASK,
         lambda c: c.args[1] == 0.0),
    Edge("relinearised_keys: a step exactly at the threshold (not marked)", RELIN_TASK, _largest_at_threshold),
    Edge("affected_cliques: a relinearised variable held in a separator (the clique holding it there is marked too)",
         AFFECTED_TASK, _relinearised_in_separator),
    Edge("affected_cliques: new keys of variables not yet in the tree (ignored: they join the top)", AFFECTED_TASK,
         lambda c: any(k >= sum(len(F) for F in c.args[0]) for k in c.args[3])),
    Edge("affected_cliques: two roots, one untouched", AFFECTED_TASK, _untouched_root),
    Edge("affected_cliques: nothing new and nothing relinearised (an empty top)", AFFECTED_TASK,
         lambda c: not c.args[3] and not c.args[4]),
    Edge("orphan_parents: a separator whose first-eliminated member in the new ordering is not its smallest index",
         ORPHANS_TARGET, _first_not_smallest),
    Edge("wildfire_update: a change below the threshold stops the update (the subtree keeps its steps)",
         WILDFIRE_TASK, _stops),
    Edge("wildfire_update: threshold 0 and every clique replaced (the full back-substitution)", WILDFIRE_TASK,
         lambda c: c.args[6] == 0.0 and set(c.args[5]) == set(range(len(c.args[0])))),
    Edge("wildfire_update: variables of sizes 1, 3 and 6 mixed", WILDFIRE_TASK,
         lambda c: {1, 3, 6} <= {int(np.size(s)) for s in c.args[4]}),
)
