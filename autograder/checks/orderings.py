"""Checks of ``orderings`` (chapter 8): the elimination game played on a graph's structure, and a
greedy minimum-degree ordering.

Both answers are unique and integers: they are compared exactly. ``symbolic_elimination`` is called through
a task that returns its three outputs as arrays (the separators, lists of different lengths, encoded by
``autograder.tasks.orderings``), and each output is its own check: a slip in the parents costs the parents'
check only. Public inputs: a chain in natural order (no fill) and eliminated from the middle outwards; a star
eliminated centre first (its leaves become a clique) and leaves first; a 4 x 4 grid in natural order (much
fill); a pose graph of 30 poses with loop closures in a random order; two components (a cycle and a chain,
their labels interleaved); one variable; a small graph whose pairs are given twice, in both orders, with
self-pairs (as a Python list). ``minimum_degree_ordering`` gets the same graphs. A check of each function on
a pose graph of 2000 poses with short loop closures (natural order for the elimination) is what a Python loop
over every pair of variables per elimination fails: it runs out of the time limit. Hidden: the same kinds of
graphs, their sizes, labels, loop closures and orderings drawn from the hidden seed.
"""

from functools import cache

import numpy as np

from autograder.checks import Call, Verdict
from autograder.checks.common import check, failed
from autograder.checks.edges import Edge
from autograder.feedback import call_fields, compare
from autograder.tasks.common import decode_lists

MODULES = ("orderings",)
ELIMINATION = "orderings.symbolic_elimination"
MINIMUM_DEGREE = "orderings.minimum_degree_ordering"
TASK = "@autograder.tasks.orderings:eliminate_task"
MD_TARGET = "orderings:minimum_degree_ordering"
#: the poses of the large pose graph (the contract's "a few thousand variables")
LARGE = 2000


def _rng(seed, salt):
    return np.random.default_rng(83 + salt if seed is None else [seed, 409, salt])


def _pairs(rows) -> np.ndarray:
    return np.array(rows, dtype=np.int64).reshape(-1, 2)


def chain(n):
    return _pairs([(k, k + 1) for k in range(n - 1)])


def star(centre, n):
    return _pairs([(centre, v) for v in range(n) if v != centre])


def grid(rows, cols):
    pairs = [(r * cols + c, r * cols + c + 1) for r in range(rows) for c in range(cols - 1)]
    pairs += [(r * cols + c, (r + 1) * cols + c) for r in range(rows - 1) for c in range(cols)]
    return _pairs(sorted(pairs))


def pose_graph(rng, n, closures, reach):
    """Odometry (k, k + 1) and ``closures`` loop closures from a pose to one at most ``reach`` poses back
    (``reach`` = n: anywhere), some written from the later pose to the earlier."""
    pairs = [(k, k + 1) for k in range(n - 1)]
    for _ in range(closures):
        j = int(rng.integers(2, n))
        i = int(rng.integers(max(0, j - reach), j - 1))
        pairs.append((j, i) if rng.random() < 0.5 else (i, j))
    return _pairs(pairs)


def two_components(rng, sizes):
    """A cycle of ``sizes[0]`` variables and a chain of ``sizes[1]``, their labels interleaved at random."""
    labels = rng.permutation(sum(sizes))
    cycle, path = labels[:sizes[0]], labels[sizes[0]:]
    pairs = [(cycle[k], cycle[(k + 1) % len(cycle)]) for k in range(len(cycle))]
    pairs += [(path[k], path[k + 1]) for k in range(len(path) - 1)]
    return _pairs(pairs)


def repeated(rng, n):
    """A connected graph of ``n`` variables (a chain and two chords) as a Python list of pairs, each pair
    given twice (once in each order, a third time for one) and two self-pairs (i, i), shuffled."""
    labels = rng.permutation(n).tolist()
    pairs = [(labels[k], labels[k + 1]) for k in range(n - 1)] + [(labels[0], labels[n // 2]),
                                                                   (labels[1], labels[n - 1])]
    rows = pairs + [(j, i) for i, j in pairs] + [pairs[0]]
    rows += [(labels[2], labels[2]), (labels[n - 1], labels[n - 1])]
    return [list(rows[k]) for k in rng.permutation(len(rows))]


def middle_out(n):
    """The middle variable of a chain first, then outwards, alternately on either side."""
    m = n // 2
    order = [m]
    for step in range(1, n):
        order += [v for v in (m - step, m + step) if 0 <= v < n]
    return np.array(order, dtype=np.int64)


@cache
def graphs(seed=None):
    """``[(graph, order, n, edges, ordering)]``: every kind of graph the checks use (``graph`` and ``order``
    describe them), with its ordering."""
    rng = _rng(seed, 1)
    hidden = seed is not None
    out = []
    n = int(rng.integers(5, 12)) if hidden else 6
    out.append((f"a chain of {n} variables", "in natural order", n, chain(n), np.arange(n)))
    n = int(rng.integers(7, 13)) if hidden else 7
    out.append((f"a chain of {n} variables", "from the middle outwards", n, chain(n), middle_out(n)))
    n = int(rng.integers(5, 10)) if hidden else 6
    centre = int(rng.integers(0, n)) if hidden else 2
    leaves = rng.permutation([v for v in range(n) if v != centre]).tolist()
    out.append((f"a star of {n} variables (centre {centre})", "centre first", n, star(centre, n),
                np.array([centre] + leaves, dtype=np.int64)))
    out.append((f"a star of {n} variables (centre {centre})", "leaves first", n, star(centre, n),
                np.array(leaves[::-1] + [centre], dtype=np.int64)))
    rows, cols = (int(rng.integers(3, 6)), int(rng.integers(3, 6))) if hidden else (4, 4)
    out.append((f"a {rows} x {cols} grid (variable r * {cols} + c)", "in natural order", rows * cols,
                grid(rows, cols), np.arange(rows * cols)))
    n = int(rng.integers(25, 41)) if hidden else 30
    closures = int(rng.integers(4, 9)) if hidden else 6
    out.append((f"a pose graph of {n} poses with {closures} loop closures", "in a random order", n,
                pose_graph(rng, n, closures, n), rng.permutation(n)))
    sizes = (int(rng.integers(3, 7)), int(rng.integers(2, 6))) if hidden else (4, 3)
    edges = two_components(rng, sizes)
    out.append((f"two components (a cycle of {sizes[0]} and a chain of {sizes[1]} variables, labels mixed)",
                "in a random order", sum(sizes), edges, rng.permutation(sum(sizes))))
    out.append(("one variable (n = 1) and no edges", "", 1, np.zeros((0, 2), dtype=np.int64),
                np.zeros(1, dtype=np.int64)))
    n = int(rng.integers(6, 10)) if hidden else 7
    out.append((f"a graph of {n} variables whose pairs are given twice (in both orders) with self-pairs (i, i), "
                "as a Python list", "in a random order", n, repeated(rng, n), rng.permutation(n)))
    return out


@cache
def large_graph(seed=None):
    """A pose graph of :data:`LARGE` poses with short loop closures, in natural order (little fill)."""
    rng = _rng(seed, 2)
    return [(f"a pose graph of {LARGE} poses with {LARGE // 10} loop closures at most 12 poses back",
             "in natural order", LARGE, pose_graph(rng, LARGE, LARGE // 10, 12), np.arange(LARGE))]


def _eliminations(cases):
    return [Call(TASK, (n, edges, ordering), returns="dict", label=ELIMINATION,
                 where=f"on {graph}" + (f" eliminated {order} (ordering {_show(ordering.tolist())})" if order else ""))
            for graph, order, n, edges, ordering in cases]


def _minimum_degree_calls(cases):
    calls, seen = [], set()
    for graph, _, n, edges, _ in cases:
        if graph not in seen:  # the star, once
            seen.add(graph)
            calls.append(Call(MD_TARGET, (n, edges), where=f"on {graph}", label=MINIMUM_DEGREE))
    return calls


@cache
def eliminations(seed=None):
    return _eliminations(graphs(seed))


@cache
def large_elimination(seed=None):
    return _eliminations(large_graph(seed))


@cache
def minimum_degree_calls(seed=None):
    return _minimum_degree_calls(graphs(seed))


@cache
def large_minimum_degree(seed=None):
    return _minimum_degree_calls(large_graph(seed))


def _edge_set(call):
    return {(min(i, j), max(i, j)) for i, j in np.asarray(call.args[1], dtype=np.int64).reshape(-1, 2).tolist()
            if i != j}


def _show(values, limit=12) -> str:
    values = list(values)
    more = f", ... ({len(values) - limit} more)" if len(values) > limit else ""
    return "[" + ", ".join(str(v) for v in values[:limit]) + more + "]"


def _same(value, got) -> bool:
    return np.shape(value) == np.shape(got) and np.array_equal(np.asarray(value), np.asarray(got))


def _cause(ctx, key, outputs, first) -> str:
    """The why of a known mistake that gives the student's output ``outputs[first]`` on call ``first``, preferring
    one that gives the student's outputs on every call (two slips may agree on a small graph), '' when none."""

    def gives(index, why):
        values = [value for value, other in ctx.known(index).get(key, ()) if other == why]
        return not values or any(_same(value, outputs[index]) for value in values)

    candidates = [why for value, why in ctx.known(first).get(key, ()) if _same(value, outputs[first])]
    return next((why for why in candidates if all(gives(k, why) for k in range(len(outputs)))),
                candidates[0] if candidates else "")


def _separator_text(call, mine, ref):
    """``(what differs, why)``, the why from the properties the contract states ('' when none tells)."""
    n, ordering = call.args[0], np.asarray(call.args[2])
    if len(mine) != len(ref):
        return f"separators has {len(mine)} lists, expected {n}", "one per variable, separators[v] for variable v"
    wrong = [v for v in range(n) if mine[v] != ref[v]]
    v = min(wrong, key=lambda u: int(np.flatnonzero(ordering == u)[0]))  # the first eliminated that differs
    text = (f"separators[{v}] = {_show(mine[v])}, expected {_show(ref[v])} ({len(wrong)} of {n} separators "
            f"differ; the first eliminated shown)")
    position = {int(u): k for k, u in enumerate(ordering.tolist())}
    if sorted(mine[v], key=str) == sorted(ref[v], key=str):
        return text, "the same variables in another order: sort each separator by elimination position"
    gone = [u for u in mine[v] if u not in ref[v] and u in position and position[u] < position[v]]
    if gone:
        return text, (f"variable {gone[0]} was eliminated before {v}; the separator holds only variables not "
                      "eliminated yet")
    edges = _edge_set(call)
    joined = [u for u in ref[v] if u not in mine[v] and (min(u, v), max(u, v)) not in edges]
    if joined:
        return text, (f"{v} and {joined[0]} are joined by fill (an earlier elimination joined every pair of its "
                      "separator): the separator is read from the current graph, fill included")
    return text, ""


def _verdict(text, why, where):
    return Verdict(0.0, f"{text} {where}" + (f": {why}" if why else ""))


def separators_judge(ctx):
    triples, failure = call_fields(ctx, failed=failed)
    outputs = [got["separators"] for _, got, _ in triples]
    for index, (call, got, want) in enumerate(triples):
        mine, ref = decode_lists(got["separators"]), decode_lists(want["separators"])
        if mine == ref:
            continue
        text, diagnosis = _separator_text(call, mine, ref)
        return _verdict(text, _cause(ctx, "separators", outputs, index) or diagnosis, call.where)
    return failure or Verdict(1.0, "ok")


def _exact(key, label, cause):
    """A judge comparing the output ``key`` exactly, the likely cause from the known mistakes or ``cause``."""

    def judge(ctx):
        triples, failure = call_fields(ctx, failed=failed)
        outputs = [got[key] for _, got, _ in triples]
        for index, (call, got, want) in enumerate(triples):
            text = compare(got[key], want[key], label, 0.0, 0.0, call.where)
            if text:
                text = text.replace("; rtol=0, atol=0", "")  # integers, compared exactly
                return Verdict(0.0, f"{text}: {_cause(ctx, key, outputs, index) or cause}")
        return failure or Verdict(1.0, "ok")

    return judge


PARENTS_CAUSE = ("parents[v] is the variable of v's separator eliminated first (separators[v][0]), -1 where "
                 "the separator is empty")
parents_judge = _exact("parents", "parents", PARENTS_CAUSE)


def _fill_text(call, got, want):
    """``(what differs, why)``, the why from the properties the contract states."""
    if got.ndim != 2 or got.shape[1:] != (2,):
        return f"fill has shape {got.shape}, expected ({len(want)}, 2)", "one row (i, j) per fill edge"
    size = f"fill has {len(got)} rows, expected {len(want)}" if len(got) != len(want) else "fill differs"
    rows = [tuple(int(x) if float(x).is_integer() else x for x in row) for row in got.tolist()]
    flipped = [r for r in rows if r[0] >= r[1]]
    if flipped:
        return size, f"fill row {flipped[0]} is not written with i < j"
    if len(set(rows)) < len(rows):
        twice = next(r for r in rows if rows.count(r) > 1)
        return size, f"fill lists {twice} {rows.count(twice)} times; each fill edge once"
    original = sorted(set(rows) & _edge_set(call))
    if original:
        return size, (f"fill holds {original[0]}, an edge of the original graph; fill is only the pairs joined that "
                      "were not edges before")
    expected = {tuple(int(x) for x in row) for row in want.tolist()}
    missing, extra = sorted(expected - set(rows)), sorted(set(rows) - expected)
    if missing:
        return size, f"fill misses {missing[0]} ({len(missing)} pairs missing)"
    if extra:
        return size, f"fill holds {extra[0]}, which no elimination joins"
    return size, "the right pairs, but the rows are not sorted lexicographically (by i, then j)"


def fill_judge(ctx):
    triples, failure = call_fields(ctx, failed=failed)
    outputs = [got["fill"] for _, got, _ in triples]
    for index, (call, got, want) in enumerate(triples):
        mine, ref = np.asarray(got["fill"]), np.asarray(want["fill"])
        if _same(mine, ref):
            continue
        text, diagnosis = _fill_text(call, mine, ref)
        return _verdict(text, _cause(ctx, "fill", outputs, index) or diagnosis, call.where)
    return failure or Verdict(1.0, "ok")


MD_CAUSE = ("eliminate the variable with the fewest neighbours among those not eliminated yet, in the current graph "
            "(fill included), ties to the smallest index; then update its separator's degrees")

def large_judge(ctx):
    """All three outputs on the large graph: what this check adds is the time."""
    for judge in (separators_judge, parents_judge, fill_judge):
        verdict = judge(ctx)
        if verdict.fraction < 1.0:
            return verdict
    return Verdict(1.0, "ok")


MD_JUDGE = _exact("value", "ordering", MD_CAUSE)
LARGE_TITLE = f"a pose graph of {LARGE} poses in time"

CHECKS = [
    check(ELIMINATION, "separators", 3, eliminations, separators_judge),
    check(ELIMINATION, "elimination tree (parents)", 2, eliminations, parents_judge),
    check(ELIMINATION, "fill edges", 2, eliminations, fill_judge),
    check(ELIMINATION, LARGE_TITLE, 1, large_elimination, large_judge),
    check(MINIMUM_DEGREE, "greedy minimum-degree ordering", 3, minimum_degree_calls, MD_JUDGE),
    check(MINIMUM_DEGREE, LARGE_TITLE, 1, large_minimum_degree, MD_JUDGE),
]


def _components(call) -> int:
    n = call.args[0]
    parent = list(range(n))

    def root(v):
        while parent[v] != v:
            parent[v] = parent[parent[v]]
            v = parent[v]
        return v

    for i, j in _edge_set(call):
        parent[root(i)] = root(j)
    return len({root(v) for v in range(n)})


def _rows(call):
    return [tuple(int(x) for x in row) for row in np.asarray(call.args[1], dtype=np.int64).reshape(-1, 2).tolist()]


def _twice_both_ways(call):
    rows = _rows(call)
    return any((j, i) in rows for i, j in rows if i != j)


def _self_pair(call):
    return any(i == j for i, j in _rows(call))


EDGES = tuple(
    Edge(f"{name}: {text}", target, holds)
    for name, target in (("symbolic_elimination", TASK), ("minimum_degree_ordering", MD_TARGET))
    for text, holds in (
        ("one variable (n = 1, no edges)", lambda c: c.args[0] == 1 and len(_rows(c)) == 0),
        ("two connected components (two roots)" if target == TASK else "two connected components",
         lambda c: _components(c) == 2),
        ("a pair given twice, once in each order", _twice_both_ways),
        ("a pair (i, i), which joins no two variables", _self_pair),
    )
)
