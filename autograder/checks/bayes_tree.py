"""Checks of ``bayes_tree`` (chapter 8): the Bayes tree's cliques from an elimination's conditionals.

The output is unique under the contract's conventions (cliques in order of creation, variables sorted by
elimination position), so each part is compared exactly: the cliques' frontals, their separators, the
parents, each in a check of its own (a slip in the frontals' order costs the frontals only), and
``clique_of`` alone. The lists of lists come back from the child packed as numbers
(``autograder.tasks.bayes_tree``).

Public inputs are written out below, derived by hand from small graphs: a single variable, a chain, a
complete graph, a star eliminated leaves first and centre first, two components, a pose graph of 10 poses
with three loop closures under a minimum-degree order, and a pattern where a separator is a strict subset
of its parent clique. Hidden inputs, as many: six of the same patterns with the variables renamed at
random, and two random elimination patterns grown from the last eliminated variable down (each
variable's separator its parent's variable p and a random part of S_p, or all of it, so that the pattern
is an elimination's without eliminating anything).
"""

import numpy as np

from autograder.checks import Call, Verdict
from autograder.checks.common import check, failed
from autograder.checks.edges import Edge
from autograder.feedback import call_fields

MODULES = ("bayes_tree",)
TREE = "bayes_tree.bayes_tree"
CLIQUE_OF = "bayes_tree.clique_of"
TARGET = "@autograder.tasks.bayes_tree:bayes_tree_task"
CLIQUE_OF_TARGET = "bayes_tree:clique_of"

#: an exception's likely cause, added to the feedback of a call that raised it
ERROR_HINTS = {"KeyError": "when v is reached, the clique of its separator's first member must exist already: go "
                           "over the conditionals in reverse elimination order (the last eliminated first)"}

# ---------------------------------------------------------------- inputs

#: (what, ordering, separators): separators[v] sorted by elimination position, as an elimination gives them
PUBLIC: tuple[tuple[str, list, list], ...] = (
    ("a single variable", [0], [[]]),
    ("a chain 0-1-2-3-4-5 eliminated 0, 1, ..., 5", [0, 1, 2, 3, 4, 5], [[1], [2], [3], [4], [5], []]),
    ("a complete graph of 5 variables", [2, 0, 4, 1, 3], [[4, 1, 3], [3], [0, 4, 1, 3], [], [1, 3]]),
    ("a star (centre 0, leaves 1-5) eliminated leaves first", [1, 2, 3, 4, 5, 0],
     [[], [0], [0], [0], [0], [0]]),
    ("a star (centre 0, leaves 1-5) eliminated centre first", [0, 3, 1, 5, 2, 4],
     [[3, 1, 5, 2, 4], [5, 2, 4], [4], [1, 5, 2, 4], [], [2, 4]]),
    ("two components (a triangle 0-1-2 and a chain 3-4-5)", [3, 0, 4, 1, 5, 2],
     [[1, 2], [2], [], [4], [5], []]),
    ("a pose graph of 10 poses with loop closures 0-5, 2-8 and 4-9, in a minimum-degree order",
     [0, 1, 3, 6, 7, 9, 2, 4, 5, 8],
     [[1, 5], [2, 5], [4, 5, 8], [2, 4], [5, 8], [8], [7, 5], [5, 8], [], [4, 8]]),
    ("a pattern where S_3 = [0, 1] is a strict subset of the clique {0, 1, 2}", [5, 4, 3, 0, 1, 2],
     [[1, 2], [2], [], [0, 1], [3, 1], [3, 0, 1]]),
)


def _random_pattern(rng, n, roots):
    """An elimination's pattern grown from the last eliminated variable down: ``roots`` variables (the last
    one among them) get no separator; every other v gets a variable p eliminated after it and a part of S_p
    (all of it one time in three), which keeps S_v without p inside S_p."""
    ordering = [int(v) for v in rng.permutation(n)]
    empty = {n - 1} | {int(k) for k in rng.choice(n - 1, size=roots - 1, replace=False)}
    separators = [[] for _ in range(n)]
    for k in range(n - 2, -1, -1):
        if k in empty:
            continue
        p = ordering[int(rng.integers(k + 1, min(n, k + 5)))]  # a near p: deeper trees
        whole = rng.random() < 1.0 / 3.0
        separators[ordering[k]] = [p] + [u for u in separators[p] if whole or rng.random() < 0.5]
    return ordering, separators


def _renamed(rng, ordering, separators):
    """The same pattern with variable v called ``name[v]``."""
    name = rng.permutation(len(ordering))
    renamed = [[] for _ in ordering]
    for v, S in enumerate(separators):
        renamed[int(name[v])] = [int(name[u]) for u in S]
    return [int(name[v]) for v in ordering], renamed


def cases(seed=None):
    """``(what, ordering, separators)`` of the public patterns, or, for a seed, as many hidden ones: the public
    patterns renamed (but the complete graph and the star eliminated leaves first) and two random ones."""
    if seed is None:
        return list(PUBLIC)
    rng = np.random.default_rng([seed, 811])
    kept = [case for case in PUBLIC if not case[0].startswith(("a complete graph", "a star (centre 0, leaves 1-5) "
                                                                "eliminated leaves"))]
    out = [(f"{what}, the variables renamed", *_renamed(rng, ordering, separators))
           for what, ordering, separators in kept]
    for n, roots in ((int(rng.integers(8, 13)), 1), (40, 3)):
        out.append((f"a random elimination pattern of {n} variables ({roots} components)",
                    *_random_pattern(rng, n, roots)))
    return out


def _where(what, ordering, separators):
    if len(ordering) > 16:
        return f"on {what}"
    return f"on {what} (ordering {ordering}, separators {separators})"


def _tree_calls(seed=None):
    return [Call(TARGET, (np.array(ordering, dtype=np.int64), separators), returns="dict", label=TREE,
                 where=_where(what, ordering, separators))
            for what, ordering, separators in cases(seed)]


def _partition(rng, n, size):
    """0..n-1 shuffled and cut into lists of 1 to ``size`` variables."""
    order = [int(v) for v in rng.permutation(n)]
    out = []
    while order:
        k = int(rng.integers(1, size + 1))
        out.append(order[:k])
        order = order[k:]
    return out


def _clique_of_calls(seed=None):
    rng = np.random.default_rng([812] if seed is None else [seed, 812])
    frontals = [[[0]], _partition(rng, 7, 1), _partition(rng, 12, 4), _partition(rng, 30, 6)]
    return [Call(CLIQUE_OF_TARGET, (F, sum(len(f) for f in F)),
                 where=f"on frontals {F}" if len(F) <= 8 else f"on {len(F)} cliques of 30 variables")
            for F in frontals]


# ---------------------------------------------------------------- judging


def _unpack(packed):
    from autograder.tasks.common import decode_lists

    return decode_lists(packed)


def _parents(values):
    return [float(x) for x in np.ravel(values)]


#: how each field of the child's output is read
READ = {"frontals": _unpack, "separators": _unpack, "parents": _parents}


def _cause(got, known, field) -> str:
    """The known mistake whose ``field`` is the student's, preferring one that also gives the student's other
    fields (two slips can build the same cliques and differ in the parents), as ": why"; else ''."""
    matched: dict = {}
    for key, read in READ.items():
        mine = read(got[key])
        for value, why in known.get(key, ()):
            if read(value) == mine:
                matched.setdefault(why, set()).add(key)
    best = max((why for why, keys in matched.items() if field in keys), key=lambda why: len(matched[why]),
               default=None)
    return f": {best}" if best else ""


def _lists_judge(field, what, rule):
    """Each clique's ``field`` list against the reference's, in order of creation."""

    def judge(ctx):
        triples, failure = call_fields(ctx, ERROR_HINTS, failed=failed)
        if failure:
            return failure
        for index, (call, got, want) in enumerate(triples):
            mine, ref = _unpack(got[field]), _unpack(want[field])
            if mine == ref:
                continue
            cause = _cause(got, ctx.known(index), field)
            if len(mine) != len(ref):
                return Verdict(0.0, f"{len(mine)} clique{'s' * (len(mine) != 1)}, expected {len(ref)} {call.where}"
                                    f"{cause or ': ' + rule}")
            c = next(c for c in range(len(ref)) if mine[c] != ref[c])
            text = f"clique {c}'s {what} {mine[c]}, expected {ref[c]} {call.where}"
            if not cause and sorted(mine[c]) == sorted(ref[c]):
                cause = ": the same variables in another order; list them by elimination position, earliest first"
            return Verdict(0.0, text + (cause or f": {rule}"))
        return Verdict(1.0, "ok")

    return judge


def _parents_judge(ctx):
    triples, failure = call_fields(ctx, ERROR_HINTS, failed=failed)
    if failure:
        return failure
    for index, (call, got, want) in enumerate(triples):
        mine, ref = _parents(got["parents"]), _parents(want["parents"])
        if mine == ref:
            continue
        cause = _cause(got, ctx.known(index), "parents")
        if len(mine) != len(ref):
            return Verdict(0.0, f"parents has {len(mine)} entries, expected one per clique ({len(ref)}) "
                                f"{call.where}{cause}")
        c = next(c for c in range(len(ref)) if mine[c] != ref[c])
        return Verdict(0.0, f"parents[{c}] = {mine[c]:g}, expected {ref[c]:g} {call.where}"
                            f"{cause or ': the parent is the clique of the separator first member (-1 for a root)'}")
    return Verdict(1.0, "ok")


def _clique_of_judge(ctx):
    triples, failure = call_fields(ctx, failed=failed)
    if failure:
        return failure
    for call, got, want in triples:
        mine, ref = np.asarray(got["value"], dtype=float), np.asarray(want["value"], dtype=float)
        if mine.shape != ref.shape:
            return Verdict(0.0, f"clique_of returned shape {mine.shape}, expected {ref.shape} {call.where}")
        wrong = np.flatnonzero(mine != ref)
        if wrong.size:
            v = int(wrong[0])
            return Verdict(0.0, f"clique_of[{v}] = {mine[v]:g}, expected {ref[v]:g} (variable {v} is a frontal of "
                                f"clique {ref[v]:g}) {call.where}")
    return Verdict(1.0, "ok")


CHECKS = [
    check(TREE, "the cliques' frontals", 3, _tree_calls,
          _lists_judge("frontals", "frontals are",
                       "v joins the clique of p = S_v[0] exactly when that clique's frontals and separator are "
                       "the set S_v")),
    check(TREE, "the cliques' separators", 2, _tree_calls,
          _lists_judge("separators", "separator is",
                       "a clique's separator is S_v of the variable that created it")),
    check(TREE, "the parents (the tree)", 2, _tree_calls, _parents_judge),
    check(CLIQUE_OF, "each variable's clique", 1, _clique_of_calls, _clique_of_judge),
]

# ---------------------------------------------------------------- the edges


def _pattern(call):
    return [int(v) for v in call.args[0]], [list(S) for S in call.args[1]]


def _chain(call):
    ordering, separators = _pattern(call)
    firsts = [S[0] for S in separators if S]
    return (len(ordering) >= 3 and all(len(S) <= 1 for S in separators) and len(firsts) == len(ordering) - 1
            and len(set(firsts)) == len(firsts))


def _complete(call):
    ordering, separators = _pattern(call)
    return len(ordering) >= 3 and all(separators[v] == ordering[k + 1:] for k, v in enumerate(ordering))


def _strict_subset(call):
    _, separators = _pattern(call)
    return any(S and len(S) < 1 + len(separators[S[0]]) and len(S) > 1 for S in separators)


def _merge_below_root(call):
    _, separators = _pattern(call)
    return any(S and separators[S[0]] and S[1:] == separators[S[0]] for S in separators)


EDGES = (
    Edge("a single variable (n = 1)", TARGET, lambda c: len(c.args[0]) == 1),
    Edge("a chain: every separator holds one variable, each variable the first member of one separator at most",
         TARGET, _chain),
    Edge("a complete graph: every separator holds all the variables eliminated later", TARGET, _complete),
    Edge("two connected components (two empty separators)", TARGET,
         lambda c: sum(1 for S in c.args[1] if not S) == 2),
    Edge("a separator of two or more variables, a strict subset of its first member p together with S_p (a "
         "child clique, not a merge)", TARGET, _strict_subset),
    Edge("a separator that is its first member p together with all of S_p, S_p not empty", TARGET,
         _merge_below_root),
    Edge("clique_of on one clique of one variable", CLIQUE_OF_TARGET, lambda c: c.args[1] == 1),
)
