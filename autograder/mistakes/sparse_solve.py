# RELEASE: omit
"""Known mistakes in ``sparse_solve`` (see ``autograder.mistakes``)."""

import numpy as np

from autograder.checks.sparse_solve import DENSE, SPARSE, UPPER


def dense_mistakes(call, ref):
    H, b = (np.asarray(v, dtype=float) for v in call.args[:2])
    return {"value": [(-ref["value"], "dx has the opposite sign: solve H dx = -b"),
                      (np.linalg.solve(np.triu(H), -b), "H was treated as upper triangular: solve with the whole "
                                                        "symmetric H"),
                      (np.linalg.solve(np.diag(np.diag(H)), -b), "only the diagonal of H was used")]}


def upper_mistakes(call, ref):
    H = np.asarray(call.args[0], dtype=float)
    return {"M": [(H, "this is the whole of H: keep its upper triangle only, diagonal included "
                      "(scipy.sparse.triu(H, format='csc'))"),
                  (np.tril(H), "this is the lower triangle: the upper triangle has row <= column (scipy.sparse.triu)"),
                  (np.triu(H, 1), "the diagonal is missing: the upper triangle includes it (triu with k=0)")]}


def _upper(shape, indices, indptr, data):
    import scipy.sparse as sp

    return sp.csc_matrix((np.asarray(data, dtype=float), np.asarray(indices), np.asarray(indptr)),
                         shape=tuple(shape)).toarray()


def _solve_mistakes(shape, indices, indptr, values, rhs, name, ref):
    """``{name k: [...]}`` for the successive solves of one solver."""
    known = {}
    uppers = [_upper(shape, indices, indptr, data) for data in values]
    first = uppers[0] + np.triu(uppers[0], 1).T
    for k, (U, b) in enumerate(zip(uppers, rhs)):
        b = np.asarray(b, dtype=float)
        pairs = [(-ref[f"{name}{k}"], "dx has the opposite sign: solve H dx = -b"),
                 (np.linalg.solve(U, -b), "H_upper holds only the upper triangle of H: tell the solver "
                                          "(qdldl.Solver(H_upper, upper=True)), do not solve with H_upper as if "
                                          "it were H")]
        if k > 0 and not np.array_equal(U, uppers[0]):
            pairs.insert(0, (np.linalg.solve(first, -b),
                             "this solve used the first call's matrix: keep the symbolic analysis but "
                             "refactorize with the new values on every later call (qdldl: "
                             "solver.update(H_upper, upper=True)) before solving"))
            pairs.insert(1, (-np.linalg.solve(first, -b), "this solve used the first call's matrix and "
                                                          "has the opposite sign"))
        known[f"{name}{k}"] = pairs
    return known


def sparse_mistakes(call, ref):
    return _solve_mistakes(*call.args, "dx", ref)


def alternating_mistakes(call, ref):
    first, second = call.args
    return {**_solve_mistakes(*first, "a", ref), **_solve_mistakes(*second, "b", ref)}


def _reused(shape, patterns, rhs, same):
    """The steps of a solver that analyses again only when ``same(old, new)`` is False, qdldl's update
    taking another pattern as the analysed one (what it silently does). Only while the other pattern
    has as many entries as the analysed one: with fewer or more, qdldl reads past its arrays and its
    answer is whatever memory holds, no known answer (the steps stop there)."""
    import qdldl
    import scipy.sparse as sp

    steps, solver, analysed = [], None, None
    for (indices, indptr, data), b in zip(patterns, rhs):
        H = sp.csc_matrix((np.asarray(data, dtype=float), np.asarray(indices), np.asarray(indptr)), shape=tuple(shape))
        if solver is None or not same(analysed, H):
            solver, analysed = qdldl.Solver(H, upper=True), H
        elif H.nnz != analysed.nnz:
            break
        else:
            solver.update(H, upper=True)
        steps.append(-solver.solve(np.asarray(b, dtype=float)))
    return steps


def pattern_mistakes(call, ref):
    shape, patterns, rhs = call.args
    known: dict = {name: [] for name in ref if name.startswith("dx")}
    for same, why in ((lambda old, new: True, "the analysis of the first pattern was reused for another pattern: "
                                              "qdldl's update then gives a wrong factorization without a word; "
                                              "make a new qdldl.Solver when the pattern changes"),
                      (lambda old, new: old.nnz == new.nnz, "the pattern changed but not the number of entries: "
                                                            "compare H_upper.indptr and H_upper.indices, not nnz")):
        try:
            steps = _reused(shape, patterns, rhs, same)
        except ValueError:  # qdldl refused the other pattern: nothing to recognise
            continue
        for k, step in enumerate(steps):
            if not np.allclose(step, ref[f"dx{k}"], rtol=1e-6, atol=1e-9):
                known[f"dx{k}"].append((step, why))
    for k in range(len(patterns)):
        known[f"dx{k}"].append((-ref[f"dx{k}"], "dx has the opposite sign: solve H dx = -b"))
    return known


MISTAKES = {
    f"{SPARSE}: a changed pattern is analysed again": pattern_mistakes,
    f"{DENSE}: dx solves H dx = -b": dense_mistakes,
    f"{UPPER}: upper triangle as CSC": upper_mistakes,
    f"{SPARSE}: first solve": sparse_mistakes,
    f"{SPARSE}: later solves with new values, same pattern": sparse_mistakes,
    f"{SPARSE}: two solvers, two patterns, used alternately": alternating_mistakes,
}
