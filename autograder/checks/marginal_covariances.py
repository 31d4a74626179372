"""Checks of ``marginal_covariances`` (chapter 8): the marginals of every variable by the recursion on
the square-root information, and the joint marginal of a few by triangular solves.

Inputs: ``R``, the upper Cholesky factor of ``H = A^T A + 0.01 I`` of a random factor graph (a chain of
odometry factors with loop closures, a prior on the first variable), computed densely and stored on
its symbolic pattern (the entries elimination fills are stored, whatever their value). Public: 14
variables of sizes 1, 2, 3 and 6 mixed (R as CSC); the same with a filled-in entry stored with the
value 0 (CSR); 12 scalar variables (CSR); one variable of size 6; a chain of 20,000 scalar variables
(R bidiagonal, CSC: a dense Sigma needs 3.2 GB, over the child's memory). Joint marginals of 3 keys in
increasing order, of 4 keys not in order, of one key, and of 3 keys of the chain. Hidden: the same
kinds from the hidden seed.

Every block is compared with the reference's with ``atol`` 1e-10 times the block's largest entry (the
block's scale) and ``rtol`` 1e-8.
"""

from functools import cache

import numpy as np

from autograder.checks import Call, Verdict
from autograder.checks.common import check, failed
from autograder.checks.edges import Edge
from autograder.feedback import call_fields, compare

MODULES = ("marginal_covariances",)
MARGINALS = "marginal_covariances.marginal_covariances"
JOINT = "marginal_covariances.joint_marginal"
MARGINALS_TASK = "@autograder.tasks.marginal_covariances:marginals"
JOINT_TASK = "@autograder.tasks.marginal_covariances:joint"

RTOL = 1e-8
#: relative to the block's largest reference entry
ATOL = 1e-10
CHAIN = 20_000
PRIOR = 0.01

# ---------------------------------------------------------------- inputs


def symbolic(coupled) -> list:
    """The pattern of R, row by row (sorted column lists), of a Cholesky factor of a matrix whose
    upper-triangular couplings are ``coupled`` (n, n) bool: row i holds H's row i and the rows of its
    children in the elimination tree, from column i on."""
    n = len(coupled)
    rows: list = []
    children: list = [[] for _ in range(n)]
    for i in range(n):
        cols = set((np.flatnonzero(coupled[i, i:]) + i).tolist()) | {i}
        for child in children[i]:
            cols |= {j for j in rows[child] if j >= i}
        rows.append(sorted(cols))
        if len(rows[i]) > 1:
            children[rows[i][1]].append(i)
    return rows


def factor_graph(rng, sizes, loops, tree=False):
    """``(R dense (n, n), pattern rows, coupled)`` of a chain of variables of ``sizes`` with ``loops``
    closures (pairs of variables at least 2 apart), a prior on the first and ``PRIOR`` I. ``tree``: each
    variable but the last tied to a later one drawn at random instead of the next (the first two to the
    last), so that the elimination tree branches."""
    sizes = list(sizes)
    m = len(sizes)
    starts = np.concatenate([[0], np.cumsum(sizes)]).astype(int)
    n = int(starts[-1])
    blocks = []

    def factor(pairs):
        count = sizes[pairs[-1]]
        rows = np.zeros((count, n))
        for v in pairs:
            d = sizes[v]
            block = rng.normal(0.0, 1.0, (count, d)) * 0.5
            if v == pairs[-1]:
                block[: min(count, d), : min(count, d)] += np.eye(min(count, d))
            rows[:, starts[v]:starts[v + 1]] = block
        blocks.append(rows * 10.0 ** rng.uniform(-0.5, 0.5))

    factor([0])
    for v in range(1, m):
        if tree:
            u = v - 1
            factor([u, m - 1 if u < 2 else int(rng.integers(u + 1, m))])
        else:
            factor([v - 1, v])
    pairs = set()
    while len(pairs) < min(loops, max(0, (m - 1) * (m - 2) // 2)):
        i, j = sorted(rng.choice(m, 2, replace=False).tolist())
        if j - i >= 2:
            pairs.add((i, j))
    for i, j in sorted(pairs):
        factor([i, j])
    A = np.vstack(blocks)
    H = A.T @ A + PRIOR * np.eye(n)
    owner = np.repeat(np.arange(m), sizes)
    linked = np.eye(m, dtype=bool)
    for rows in blocks:
        touched = np.unique(owner[np.flatnonzero(np.any(rows != 0.0, axis=0))])
        linked[np.ix_(touched, touched)] = True
    coupled = np.triu(linked[np.ix_(owner, owner)])
    return np.linalg.cholesky(H).T, symbolic(coupled), coupled


def stored(R, rows, fmt):
    """``(indptr, indices, data)`` of ``R`` on the pattern ``rows`` (values 0 kept), as ``fmt``."""
    n = len(rows)
    r = np.repeat(np.arange(n), [len(cols) for cols in rows])
    c = np.concatenate([np.asarray(cols, dtype=np.int64) for cols in rows])
    if fmt == "csc":
        order = np.lexsort((r, c))
        r, c = c[order], r[order]  # walk columns: the "rows" of the compressed form are R's columns
        data = R[c, r]
    else:
        data = R[r, c]
    indptr = np.concatenate([[0], np.cumsum(np.bincount(r, minlength=n))]).astype(np.int64)
    return indptr, c.astype(np.int64), np.asarray(data, dtype=float)


def _sizes(rng, count, last):
    sizes = rng.choice([1, 2, 3, 6], count).tolist()
    sizes[-1] = last
    return [int(d) for d in sizes]


@cache
def problem(kind, seed=None):
    """``{n, fmt, indptr, indices, data, sizes, where}`` of one kind of input: ``graph``, ``zero``,
    ``scalar``, ``one``, ``tree`` or ``chain``."""
    code = {"graph": 801, "zero": 801, "scalar": 803, "one": 805, "chain": 807, "tree": 809}[kind]
    rng = np.random.default_rng(code if seed is None else [seed, code])
    if kind == "chain":
        d = rng.uniform(1.0, 2.0, CHAIN)
        e = d[:-1] * rng.uniform(-0.9, 0.9, CHAIN - 1)
        indptr = np.concatenate([[0, 1], np.arange(3, 2 * CHAIN, 2)]).astype(np.int64)
        indices = np.empty(2 * CHAIN - 1, dtype=np.int64)
        data = np.empty(2 * CHAIN - 1)
        indices[0], data[0] = 0, d[0]
        indices[1::2], indices[2::2] = np.arange(CHAIN - 1), np.arange(1, CHAIN)
        data[1::2], data[2::2] = e, d[1:]
        return {"n": CHAIN, "fmt": "csc", "indptr": indptr, "indices": indices, "data": data,
                "sizes": [1] * CHAIN, "where": f"on a chain of {CHAIN} scalar variables (R bidiagonal, CSC)"}
    if kind == "one":
        d = 6 if seed is None else int(rng.integers(2, 7))
        sizes, loops = [d], 0
    elif kind == "scalar":
        sizes, loops = [1] * (12 if seed is None else int(rng.integers(8, 16))), 3
    elif kind == "tree":
        count = 10 if seed is None else int(rng.integers(8, 14))
        sizes, loops = _sizes(rng, count, 3), 1
    else:
        count = 14 if seed is None else int(rng.integers(10, 18))
        sizes, loops = _sizes(rng, count, 6 if seed is None else int(rng.choice([2, 3, 6]))), 3
    R, rows, coupled = factor_graph(rng, sizes, loops, tree=kind == "tree")
    fmt = {"graph": "csc", "zero": "csr", "scalar": "csr", "one": "csc", "tree": "csr"}[kind]
    where = {"graph": f"on a factor graph of {len(sizes)} variables of sizes {sizes} with loop closures "
                      f"(R as CSC, {sum(len(c) for c in rows)} stored entries)",
             "scalar": f"on a factor graph of {len(sizes)} scalar variables with loop closures (R as CSR)",
             "one": f"on one variable of size {sizes[0]} (R (n, n) upper triangular, CSC)",
             "tree": f"on a factor graph of {len(sizes)} variables of sizes {sizes} whose elimination tree "
                     "branches (a variable with two or more children; R as CSR)",
             "zero": ""}[kind]
    if kind == "zero":
        fill = [(i, j) for i, cols in enumerate(rows) for j in cols if j > i and not coupled[i, j]]
        i, j = fill[int(rng.integers(len(fill)))]
        R = R.copy()
        R[i, j] = 0.0
        where = (f"on a factor graph of {len(sizes)} variables of sizes {sizes} (R as CSR) whose filled-in entry "
                 f"R[{i}, {j}] is stored with the value 0")
    indptr, indices, data = stored(R, rows, fmt)
    return {"n": len(R), "fmt": fmt, "indptr": indptr, "indices": indices, "data": data, "sizes": sizes,
            "where": where}


def _args(p):
    return (p["n"], p["fmt"], p["indptr"], p["indices"], p["data"], p["sizes"])


def _marginals_call(p):
    return Call(MARGINALS_TASK, _args(p), returns="dict", label=MARGINALS, where=p["where"])


def _root_calls(seed=None):
    return [_marginals_call(problem(kind, seed)) for kind in ("graph", "one")]


def _every_calls(seed=None):
    return [_marginals_call(problem(kind, seed)) for kind in ("graph", "scalar", "zero", "one", "tree")]


def _chain_calls(seed=None):
    return [_marginals_call(problem("chain", seed))]


def _keys(p, count, rng, ordered):
    keys = rng.choice(len(p["sizes"]), count, replace=False)
    keys = np.sort(keys) if ordered else keys
    while not ordered and count > 1 and np.all(np.diff(keys) > 0):
        keys = rng.permutation(keys)
    return [int(k) for k in keys]


def _joint_call(p, keys, what):
    return Call(JOINT_TASK, _args(p) + (keys,), returns="dict", label=JOINT,
                where=f"{p['where']}, keys = {keys} ({what})")


def _joint_calls(seed=None):
    rng = np.random.default_rng(811 if seed is None else [seed, 811])
    graph, scalar, one = problem("graph", seed), problem("scalar", seed), problem("one", seed)
    return [_joint_call(graph, _keys(graph, 3, rng, True), "in increasing order"),
            _joint_call(scalar, _keys(scalar, 3, rng, True), "in increasing order"),
            _joint_call(graph, [int(rng.integers(len(graph["sizes"])))], "one key"),
            _joint_call(one, [0], "one key")]


def _order_calls(seed=None):
    rng = np.random.default_rng(813 if seed is None else [seed, 813])
    graph, scalar = problem("graph", seed), problem("scalar", seed)
    return [_joint_call(graph, _keys(graph, 4, rng, False), "not in increasing order"),
            _joint_call(scalar, _keys(scalar, 3, rng, False), "not in increasing order")]


def _joint_chain_calls(seed=None):
    rng = np.random.default_rng(815 if seed is None else [seed, 815])
    chain = problem("chain", seed)
    k = int(rng.integers(CHAIN - 2))
    return [_joint_call(chain, [k, k + 1, CHAIN - 1], "two neighbours and the root")]


# ---------------------------------------------------------------- judges

_CAUSE = ("Sigma = (R^T R)^-1: from the last row of R up, Sigma_ij = -(1 / R_ii) sum_k R_ik Sigma_kj "
          "(j > i, R_ij stored), then Sigma_ii = (1 / R_ii) (1 / R_ii - sum_k R_ik Sigma_ki)")
_ERRORS = {"KeyError": "an entry of Sigma the recursion needs was not computed: every stored entry of R is part of "
                       "the pattern, a stored 0 included (read R.indices, do not drop zeros)",
           "MemoryError": "a dense (n, n) matrix does not fit: compute Sigma only on R's pattern",
           "Memory": "a dense (n, n) matrix does not fit: compute Sigma only on R's pattern",
           "Timeout": "compute Sigma only on R's pattern, one row of R at a time"}


def _blocks(flat, sizes):
    out, at = [], 0
    for d in sizes:
        out.append(np.asarray(flat[at:at + d * d], dtype=float).reshape(d, d))
        at += d * d
    return out


def _block_text(got, want, v, d, where, mistakes):
    """The feedback line for variable v's block, or None when it matches. ``mistakes``: (blocks, why)."""
    atol = ATOL * max(float(np.max(np.abs(want))), np.finfo(float).tiny)
    text = compare(got, want, f"Sigma_vv[{{}}] of variable {v} (size {d})", RTOL, atol, where)
    if text is None:
        return None
    for blocks, why in mistakes:
        if all(np.shape(b) == np.shape(w) and np.allclose(g, b, rtol=RTOL, atol=ATOL * max(
                float(np.max(np.abs(w))), np.finfo(float).tiny)) for g, b, w in blocks):
            return f"{text}: {why}"
    return f"{text}: {_CAUSE}"


def _judge_marginals(last_only):
    def judge(ctx):
        triples, failure = call_fields(ctx, _ERRORS, failed=failed)
        if failure:
            return failure
        for index, (call, got, want) in enumerate(triples):
            sizes = [int(d) for d in call.args[5]]
            mine, ref = _blocks(got["blocks"], sizes), _blocks(want["blocks"], sizes)
            chosen = [len(sizes) - 1] if last_only else range(len(sizes))
            slips = [(_blocks(value, sizes), why) for value, why in ctx.known(index).get("blocks", ())]
            for v in chosen:
                others = [([(mine[u], s[u], ref[u]) for u in chosen], why) for s, why in slips]
                text = _block_text(mine[v], ref[v], v, sizes[v], call.where, others)
                if text:
                    if last_only:
                        text = f"the root's (the last variable's) marginal: {text}"
                    return Verdict(0.0, text)
        return Verdict(1.0, "ok")

    return judge


def _judge_joint(ctx):
    triples, failure = call_fields(ctx, _ERRORS, failed=failed)
    if failure:
        return failure
    for index, (call, got, want) in enumerate(triples):
        sizes, keys = [int(d) for d in call.args[5]], list(call.args[6])
        total = sum(sizes[k] for k in keys)
        S, ref = np.asarray(got["Sigma"], dtype=float), np.asarray(want["Sigma"], dtype=float)
        if S.shape != ref.shape:
            return Verdict(0.0, f"the joint marginal has shape {S.shape}, expected ({total}, {total}) (the sizes of "
                                f"keys {keys} summed) {call.where}")
        atol = ATOL * float(np.max(np.abs(ref)))
        text = compare(S, ref, "Sigma_joint[{}]", RTOL, atol, call.where, ctx.known(index).get("Sigma", ()),
                       "Sigma_joint = Sigma[cols][:, cols], cols the rows of keys[0], keys[1], ... in the order given: "
                       "solve R^T Y = E, then R X = Y, and keep X[cols]")
        if text:
            if not np.all(np.isfinite(S)):
                return Verdict(0.0, text)
            excess = np.abs(S - ref) - (atol + RTOL * np.abs(ref))  # the entry compare names: the worst
            a, b = np.unravel_index(int(np.argmax(excess)), excess.shape)
            at = np.concatenate([[0], np.cumsum([sizes[k] for k in keys])])
            va, vb = (int(np.searchsorted(at, x, side="right") - 1) for x in (a, b))
            return Verdict(0.0, f"{text} (entry [{a}, {b}] is in the block of keys[{va}] = {keys[va]} and "
                                f"keys[{vb}] = {keys[vb]})")
    return Verdict(1.0, "ok")


CHECKS = [
    check(MARGINALS, "the root's marginal (the last variable)", 2, _root_calls, _judge_marginals(True)),
    check(MARGINALS, "every variable's marginal", 3, _every_calls, _judge_marginals(False)),
    check(MARGINALS, "a chain of 20,000 variables (no dense Sigma)", 2, _chain_calls, _judge_marginals(False)),
    check(JOINT, "the joint marginal with its cross-covariances", 3, _joint_calls, _judge_joint),
    check(JOINT, "keys in the order given", 2, _order_calls, _judge_joint),
    check(JOINT, "a chain of 20,000 variables (triangular solves)", 1, _joint_chain_calls, _judge_joint),
]


def _sizes_of(call):
    return [int(d) for d in call.args[5]]


def _stored_zero(call):
    return bool(np.any(np.asarray(call.args[4]) == 0.0))


def _mixed(call):
    return {1, 2, 3, 6} <= set(_sizes_of(call))


def _fill(call):
    """Some stored entry of R off the diagonal blocks that couples variables 2 or more apart."""
    sizes = _sizes_of(call)
    owner = np.repeat(np.arange(len(sizes)), sizes)
    indptr, indices = np.asarray(call.args[2]), np.asarray(call.args[3])
    outer = np.repeat(np.arange(call.args[0]), np.diff(indptr))
    return bool(np.any(np.abs(owner[outer] - owner[indices]) >= 2))


def _branching(call):
    """Some variable is the parent of two or more in R's elimination tree (first column right of its rows)."""
    sizes = _sizes_of(call)
    owner = np.repeat(np.arange(len(sizes)), sizes)
    indptr, indices = np.asarray(call.args[2]), np.asarray(call.args[3])
    outer = np.repeat(np.arange(call.args[0]), np.diff(indptr))
    if call.args[1] == "csc":
        outer, indices = indices, outer
    later = owner[indices] > owner[outer]
    parent = np.full(len(sizes), len(sizes))
    np.minimum.at(parent, owner[outer][later], owner[indices][later])
    children = np.bincount(parent[parent < len(sizes)], minlength=len(sizes))
    return bool(np.any(children >= 2))


EDGES = (
    Edge("one variable (the root is the whole of R)", MARGINALS_TASK, lambda c: len(_sizes_of(c)) == 1),
    Edge("scalar variables only (every size 1)", MARGINALS_TASK,
         lambda c: 1 < len(_sizes_of(c)) < CHAIN and set(_sizes_of(c)) == {1}),
    Edge("variables of sizes 1, 2, 3 and 6 mixed, with loop closures (fill-in in R)", MARGINALS_TASK,
         lambda c: _mixed(c) and _fill(c)),
    Edge("a filled-in entry of R stored with the value 0", MARGINALS_TASK, _stored_zero),
    Edge("a variable with two or more children in the elimination tree (R's rows branch)", MARGINALS_TASK,
         _branching),
    Edge("R given as CSR", MARGINALS_TASK, lambda c: c.args[1] == "csr"),
    Edge("R given as CSC", MARGINALS_TASK, lambda c: c.args[1] == "csc"),
    Edge("a chain of 20,000 scalar variables (a dense Sigma needs 3.2 GB)", MARGINALS_TASK,
         lambda c: len(_sizes_of(c)) == CHAIN),
    Edge("joint_marginal: one key", JOINT_TASK, lambda c: len(c.args[6]) == 1),
    Edge("joint_marginal: keys not in increasing order", JOINT_TASK, lambda c: bool(np.any(np.diff(c.args[6]) < 0))),
)
