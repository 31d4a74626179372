"""Checks of ``sparse_solve``: the dense solve, the upper triangle as CSC, and the sparse
Cholesky solver (first solve, later solves on the same pattern, one symbolic analysis, a
pattern that changes between calls, two solvers on two patterns used alternately).

Public inputs: H and b of the 6-pose graph of the assembly checks (first pose fixed) at
two sets of poses, a damped H with another b, and a small dense system; the second
solver's pattern is the same graph with its poses numbered in reverse. Hidden inputs:
the same kinds from the hidden graph, another damping and b, and a random renumbering.
"""

from functools import cache

import numpy as np

from autograder.checks import Call, Verdict
from autograder.checks.common import check, failed, values
from autograder.checks.edges import Edge
from autograder.checks.pose_graph_assembly import small_graph
from autograder.feedback import call_fields, compare

MODULES = ("sparse_solve",)
DENSE = "sparse_solve.dense_solve"
UPPER = "sparse_solve.upper_triangle_csc"
SPARSE = "sparse_solve.SparseCholeskySolver"
QDLDL = ("qdldl",)  # no wheel for every Python: where it is missing these checks are not run

# ---------------------------------------------------------------- inputs


@cache
def systems(seed=None):
    """Reference H (fixed [0]) and b of the small graph at two sets of poses, plus a damped H
    (instructor side: inside a calls builder)."""
    from autograder import reference

    asm = reference.solutions_module("pose_graph_assembly").assemble_normal_equations
    g = small_graph(seed)
    H1, b1, _ = asm(g["poses"], g["edges_i"], g["edges_j"], g["measurements"], g["information"], [0])
    H2, b2, _ = asm(g["poses_b"], g["edges_i"], g["edges_j"], g["measurements"], g["information"], [0])
    rng = np.random.default_rng(11 if seed is None else [seed, 221])
    damping = 0.3 if seed is None else float(np.round(rng.uniform(0.05, 1.0), 3))
    H3 = H2 + np.diag(damping * np.diag(H2))
    b3 = rng.normal(size=len(b2)) * np.abs(b2).max()
    return (H1, b1), (H2, b2), (H3, b3)


def _dense_calls(seed=None):
    (H1, b1), _, (H3, b3) = systems(seed)
    rng = np.random.default_rng(5 if seed is None else [seed, 222])
    M = rng.normal(size=(12, 4))
    H4, b4 = M.T @ M + 0.1 * np.eye(4), rng.normal(size=4)
    H5, b5 = np.array([[float(np.round(rng.uniform(0.5, 4.0), 3))]]), np.round(rng.normal(size=1), 3)
    return [Call("sparse_solve:dense_solve", (H, b), where=where) for H, b, where in (
        (H1, b1, "for H and b of the 6-pose graph (18 x 18)"),
        (H3, b3, "for a damped H of the 6-pose graph"),
        (H4, b4, "for a 4 x 4 symmetric positive definite H"),
        (H5, b5, f"for a 1 x 1 H = [[{H5[0, 0]:g}]]"))]


def _upper_calls(seed=None):
    (H1, _), _, _ = systems(seed)
    return [Call("@autograder.tasks.sparse_solve:upper_triangle", (H1, sparse), returns="dict",
                 label="sparse_solve.upper_triangle_csc",
                 where=f"for H of the 6-pose graph given as {'a scipy CSR matrix' if sparse else 'a dense array'}")
            for sparse in (False, True)]


def _on_pattern(matrices):
    """CSC pattern (shape, indices, indptr) of the union of the upper triangles of
    ``matrices``, and each one's values on it (explicit zeros included); the upper
    triangle is the reference's (instructor side: inside a calls builder)."""
    from autograder import reference

    union = sum(np.abs(H) for H in matrices) > 0
    pattern = reference.solutions_module("sparse_solve").upper_triangle_csc(union.astype(float)).tocsc()
    pattern.eliminate_zeros()
    pattern.sort_indices()
    rows = pattern.indices
    cols = np.repeat(np.arange(pattern.shape[1]), np.diff(pattern.indptr))
    values = [np.asarray(H[rows, cols], dtype=float) for H in matrices]
    return pattern.shape, pattern.indices.copy(), pattern.indptr.copy(), values


@cache
def _pattern(seed=None):
    return _on_pattern([H for H, _ in systems(seed)])


@cache
def _renumbered(seed=None):
    """The systems with the poses renumbered (reversed; hidden: a random order): another pattern
    of the same size and number of entries."""
    poses = len(systems(seed)[0][1]) // 3
    if seed is None:
        order = np.arange(poses)[::-1]
    else:
        rng = np.random.default_rng([seed, 225])
        order = rng.permutation(poses)
        while np.array_equal(order, np.arange(poses)):
            order = rng.permutation(poses)
    dofs = (3 * order[:, None] + np.arange(3)).ravel()
    renumbered = [(H[np.ix_(dofs, dofs)], b[dofs]) for H, b in systems(seed)]
    return _on_pattern([H for H, _ in renumbered]), [b for _, b in renumbered]


def _sparse_calls(count):
    def build(seed=None):
        shape, indices, indptr, values = _pattern(seed)
        rhs = [b for _, b in systems(seed)][:count]
        where = ("for the upper triangle of H of the 6-pose graph (one call)" if count == 1 else
                 f"for {count} successive calls on one solver with the same pattern and new values "
                 "(other poses, then a damped H)")
        return [Call("@autograder.tasks.sparse_solve:sparse_solves", (shape, indices, indptr, values[:count], rhs),
                     returns="dict", label="sparse_solve.SparseCholeskySolver.solve", where=where)]

    return build


def _alternating_calls(seed=None):
    shape, indices, indptr, values = _pattern(seed)
    rhs = [b for _, b in systems(seed)]
    (shape2, indices2, indptr2, values2), rhs2 = _renumbered(seed)
    # each solver keeps its matrix and gets a new b (refactorizing is graded by the checks above)
    first = (shape, indices, indptr, [values[0], values[0]], [rhs[0], rhs[2]])
    second = (shape2, indices2, indptr2, [values2[0], values2[0]], [rhs2[0], rhs2[2]])
    return [Call("@autograder.tasks.sparse_solve:alternating_solves", (first, second), returns="dict",
                 label="sparse_solve.SparseCholeskySolver.solve",
                 where="with two solvers, one per pattern (the 6-pose graph, and the same graph with its poses "
                       "numbered differently), called alternately: first solver, second solver, first, second "
                       "(each with its own H and a new b)")]


def _csc(H, extra=None):
    """``(indices, indptr, data)`` of the upper triangle of ``H`` with its zeros left out, plus an
    explicit zero at ``extra`` (row, column) when given."""
    import scipy.sparse as sp

    upper = sp.triu(sp.csc_matrix(H), format="csc")
    upper.eliminate_zeros()
    if extra is not None:
        upper = upper.tolil()
        upper[extra] = 1.0
        upper = upper.tocsc()
        upper[extra] = 0.0  # an explicit zero: stored, so part of the pattern
    upper.sort_indices()
    return upper.indices.copy(), upper.indptr.copy(), upper.data.copy()


@cache
def _pattern_changes(seed=None):
    """Four upper triangles for one solver: H1; H2 with an off-diagonal entry cancelled to exactly zero
    (left out, as ``upper_triangle_csc`` of a dense H leaves it); the damped H3 with another entry left
    out and an explicit zero stored elsewhere (the same number of entries as H1, other positions); H1
    again. (shape, patterns, rhs, where)."""
    (H1, b1), (H2, b2), (H3, b3) = systems(seed)
    rows, cols = np.nonzero(np.triu(H1, 1))
    rng = np.random.default_rng(17 if seed is None else [seed, 227])
    first, second = rng.choice(len(rows), 2, replace=False)
    H2 = H2.copy()
    H2[rows[first], cols[first]] = H2[cols[first], rows[first]] = 0.0
    H3 = H3.copy()
    H3[rows[second], cols[second]] = H3[cols[second], rows[second]] = 0.0
    empty = np.argwhere(np.triu(H1 == 0, 1))
    extra = tuple(int(v) for v in empty[rng.integers(len(empty))])
    patterns = [_csc(H1), _csc(H2), _csc(H3, extra), _csc(H1)]
    where = (f"for 4 successive calls on one solver whose pattern changes: H; another H with entry "
             f"({rows[first]}, {cols[first]}) cancelled to exactly 0 and left out; a damped H with entry "
             f"({rows[second]}, {cols[second]}) left out and an explicit zero stored at {extra} (as many entries "
             "as the first, other positions); the first H again")
    return H1.shape, patterns, [b1, b2, b3, -b1], where


def _pattern_calls(seed=None):
    shape, patterns, rhs, where = _pattern_changes(seed)
    return [Call("@autograder.tasks.sparse_solve:pattern_solves", (shape, patterns, rhs), returns="dict",
                 label="sparse_solve.SparseCholeskySolver.solve", where=where)]


# ---------------------------------------------------------------- judges


def _judge_upper(ctx):
    triples, failure = call_fields(ctx, failed=failed)
    if failure:
        return failure
    from autograder.tasks.common import decode_text

    partial = None
    for index, (call, got, want) in enumerate(triples):
        text = compare(got["M"], want["M"], "upper[{}]", 1e-12, 0.0, call.where, ctx.known(index).get("M", ()),
                       "the upper triangle of H")
        if text:
            return Verdict(0.0, text)
        if not got["sparse"]:
            partial = (f"the values are right but you returned a dense {decode_text(got['format'])} {call.where}: "
                       "return a scipy.sparse CSC matrix (scipy.sparse.triu(H, format='csc'))")
        elif not got["csc"]:
            partial = (f"the values are right but the matrix is in {decode_text(got['format']).upper()} format "
                       f"{call.where}: the sparse solver expects CSC (format='csc' or .tocsc())")
    return Verdict(0.5, partial) if partial else Verdict(1.0, "ok")


SHARED_STATE = ("two SparseCholeskySolver objects must not share a factorization: keep the qdldl.Solver on "
                "the instance (self._solver, made in __init__ as None), not on the class or in a module-level "
                "variable")


def _judge_sparse(names, cause="dx solves H dx = -b", hints=None):
    """Compares the fields ``names(call)`` ((field, where) pairs) of every call."""

    def judge(ctx):
        triples, failure = call_fields(ctx, hints, failed=failed)
        if failure:
            return failure
        for index, (call, got, want) in enumerate(triples):
            known = ctx.known(index)
            for name, what in names(call):
                text = compare(got.get(name, np.array(np.nan)), want[name], "dx[{}]", 1e-8, 1e-10, what,
                               known.get(name, ()), cause)
                if text:
                    return Verdict(0.0, text)
        return Verdict(1.0, "ok")

    return judge


def _successive(call):
    count = len(call.args[3])
    return [(f"dx{k}", f"{call.where}, call {k + 1}" if count > 1 else call.where) for k in range(count)]


def _changing(call):
    return [(f"dx{k}", f"{call.where}, call {k + 1}") for k in range(len(call.args[1]))]


NEW_PATTERN = ("a call whose pattern (H_upper.indptr, H_upper.indices) differs from the one analysed must be "
               "analysed again (a new qdldl.Solver): qdldl's update assumes the analysed pattern and silently "
               "gives a wrong factorization otherwise; compare the pattern itself, not only the number of entries")


def _alternating(call):
    out = []
    for k in range(len(call.args[0][3])):
        out.append((f"a{k}", f"{call.where}; the first solver's call {k + 1}"))
        out.append((f"b{k}", f"{call.where}; the second solver's call {k + 1}"))
    return out


def _judge_reuse(ctx):
    triples, failure = call_fields(ctx, failed=failed)
    if failure:
        return failure
    _, got, _ = triples[0]
    created = float(got.get("solvers_created", np.nan))
    calls = len(ctx.calls[0].args[3])
    if not np.isfinite(created):
        return Verdict(0.0, "the grader could not count the qdldl.Solver objects your solver made")
    if created == 1:
        return Verdict(1.0, f"ok (one qdldl.Solver for {calls} solves)")
    if created == 0:
        return Verdict(0.0, f"no qdldl.Solver was made in {calls} solves: make one on the first call "
                            "(ordering and symbolic analysis) and update it on later calls")
    return Verdict(0.0, f"{int(created)} qdldl.Solver objects were made for {calls} solves with the same pattern: "
                        "make one on the first call and refactorize it with solver.update(H_upper, upper=True) "
                        "later, so that the ordering and symbolic analysis are done once")


CHECKS = [
    check(DENSE, "dx solves H dx = -b", 2, _dense_calls,
          values(("value",), 1e-8, 1e-10, "dx solves H dx = -b", labels={"value": "dx"},
                 errors={"LinAlgError": "H is symmetric positive definite here"})),
    check(UPPER, "upper triangle as CSC", 1, _upper_calls, _judge_upper),
    check(SPARSE, "first solve", 2, _sparse_calls(1), _judge_sparse(_successive), needs=QDLDL),
    check(SPARSE, "later solves with new values, same pattern", 2, _sparse_calls(3), _judge_sparse(_successive),
          needs=QDLDL),
    check(SPARSE, "one symbolic analysis for the pattern", 1, _sparse_calls(3), _judge_reuse, needs=QDLDL),
    check(SPARSE, "a changed pattern is analysed again", 2, _pattern_calls,
          _judge_sparse(_changing, NEW_PATTERN, {"ValueError": NEW_PATTERN}), needs=QDLDL),
    check(SPARSE, "two solvers, two patterns, used alternately", 1, _alternating_calls,
          _judge_sparse(_alternating, SHARED_STATE, {"ValueError": SHARED_STATE}), needs=QDLDL),
]


def _pattern_steps(call):
    """Every (earlier, later) pair of the patterns of a ``pattern_solves`` call."""
    patterns = call.args[1]
    return [(patterns[i], patterns[j]) for j in range(len(patterns)) for i in range(j)]


EDGES = (
    Edge("dense_solve: n = 1 (a 1 x 1 H)", "sparse_solve:dense_solve", lambda c: np.shape(c.args[0]) == (1, 1)),
    Edge("upper_triangle_csc: H given as a scipy sparse matrix", "@autograder.tasks.sparse_solve:upper_triangle",
         lambda c: bool(c.args[1])),
    Edge("SparseCholeskySolver: an entry of H cancelled to exactly zero and left out (fewer entries)",
         "@autograder.tasks.sparse_solve:pattern_solves",
         lambda c: any(len(b[0]) < len(a[0]) for a, b in _pattern_steps(c))),
    Edge("SparseCholeskySolver: as many entries as an earlier pattern, at other positions (an explicit zero "
         "stored)", "@autograder.tasks.sparse_solve:pattern_solves",
         lambda c: any(len(b[0]) == len(a[0]) and not np.array_equal(a[0], b[0]) and np.any(b[2] == 0.0)
                       for a, b in _pattern_steps(c))),
    Edge("SparseCholeskySolver: two solvers, each with its own pattern, used alternately",
         "@autograder.tasks.sparse_solve:alternating_solves",
         lambda c: not np.array_equal(c.args[0][1], c.args[1][1])),
)
