"""Checks of ``elimination`` (chapter 8): eliminating one variable, a Gaussian conditional on it and a
new factor on its separator.

The split is not unique (the signs of R's rows; any rows A_new with the same information), so each
output is judged by what the contract fixes, computed from the student's outputs and from the
reference's: R upper triangular and ``R^T R`` (= Lambda_xx); ``R^T S`` and ``R^T d`` (= Lambda_xs and
eta_x); ``A_new^T A_new`` and ``A_new^T b_new`` (the separator's information and information vector).
A QR of the stacked rows (signs of R as they come) and the Cholesky route both keep full marks.
Tolerances: ``RTOL`` relative, plus ``RTOL`` times the inputs' scale of the entry (``c_i c_j`` for an
information's entry (i, j), ``c_i |b|`` for an information vector's entry i, with ``c`` the column norms of
``[A_x A_s]``), so that the small entries of ill-scaled blocks are judged at their own scale.

Public inputs: a planar pose with a prior, odometry from the pose before, odometry to the pose after
and a landmark; one odometry factor alone (m = n_x); two priors on a 2-vector (no separator); a
scalar between two others with a prior; the pose with odometry and a landmark only (5 rows for
n_x + n_s = 8 unknowns: the new factor singular but not zero); the first pose with ill-scaled
blocks (a precise prior, entries near 1e3; a landmark in other units, entries near 1e-3).
Hidden: the same kinds from the hidden seed.
"""

import numpy as np

from autograder.checks import Call, Verdict
from autograder.checks.common import check, failed
from autograder.checks.edges import Edge
from autograder.feedback import call_fields, close, fmt

MODULES = ("elimination",)
ELIMINATE = "elimination.eliminate_variable"
TARGET = f"elimination:{ELIMINATE.split('.')[1]}"
RETURNS = ("R", "S", "d", "A_new", "b_new")

#: relative tolerance of every invariant, and of its absolute floor at the inputs' scale
RTOL = 1e-9
#: what a factorisation that fails, or gives numbers that are not finite, has likely met
SINGULAR = ("the new factor's information Lambda_ss - S^T S can be singular (zero when m = n_x, rank m - n_x when "
            "m - n_x < n_s): write it back as rows without a plain Cholesky (skip its zero pivots, or keep the "
            "positive eigenvalues of eigh), or take the rows below R of a QR of [A_x | A_s | b]")

POSE, LANDMARK = 3, 2

# ---------------------------------------------------------------- inputs


def _rng(seed, salt):
    return np.random.default_rng(salt if seed is None else [seed, 800 + salt])


def _stack(rng, blocks, dims, scales=None):
    """The stacked rows of factors: ``blocks`` a list of (rows, variables touched), ``dims`` each
    variable's size (variable 0 is x); each touched block N(0, 1) times its factor's scale (and the
    variable's, ``scales = (factor scales, variable scales)``). Returns A_x, A_s, b."""
    starts = np.concatenate([[0], np.cumsum(dims)]).astype(int)
    factor_scale, unit = scales if scales is not None else ([1.0] * len(blocks), [1.0] * len(dims))
    rows = []
    for (count, touched), scale in zip(blocks, factor_scale):
        block = np.zeros((count, int(starts[-1])))
        for v in touched:
            block[:, starts[v]:starts[v + 1]] = rng.normal(0.0, 1.0, (count, dims[v])) * scale * unit[v]
        rows.append(block)
    A = np.vstack(rows)
    b = rng.normal(0.0, 1.0, len(A))
    return A[:, :dims[0]], A[:, dims[0]:], b


def problems(seed=None) -> list:
    """``(A_x, A_s, b, where)`` of every check input (see the module docstring)."""
    out = []
    # a pose x with a prior, odometry from p0 and to p1, and a landmark l; s = (p0, p1, l)
    rng = _rng(seed, 81)
    dims = [POSE, POSE, POSE, LANDMARK]
    out.append((*_stack(rng, [(3, [0]), (3, [1, 0]), (3, [0, 2]), (2, [0, 3])], dims),
                "on a planar pose (n_x = 3) with a prior, odometry from the pose before, odometry to the pose "
                "after and a landmark (m = 11, n_s = 8)"))
    rng = _rng(seed, 83)
    out.append((*_stack(rng, [(3, [0, 1])], [POSE, POSE]),
                "on one odometry factor alone (m = n_x = 3, n_s = 3): the new factor is empty"))
    rng = _rng(seed, 85)
    out.append((*_stack(rng, [(2, [0]), (3, [0])], [2]), "on two priors on a 2-vector (m = 5, no separator, n_s = 0)"))
    rng = _rng(seed, 87)
    out.append((*_stack(rng, [(1, [0]), (1, [1, 0]), (1, [0, 2])], [1, 1, 1]),
                "on a scalar (n_x = 1) with a prior and a relative measurement to each of two others (m = 3, n_s = 2)"))
    rng = _rng(seed, 89)
    out.append((*_stack(rng, [(3, [0, 1]), (2, [0, 2])], [POSE, POSE, LANDMARK]),
                "on a pose with odometry and a landmark only (m = 5, n_x = 3, n_s = 5): the new factor's information "
                "is singular but not zero"))
    rng = _rng(seed, 91)
    out.append((*_stack(rng, [(3, [0]), (3, [0, 1]), (2, [0, 2])], [POSE, POSE, LANDMARK],
                        ([1e3, 1.0, 1.0], [1.0, 1.0, 1e-3])),
                "on a pose with ill-scaled whitened blocks: a precise prior (entries near 1e3), odometry and a "
                "landmark in other units (entries near 1e-3) (m = 8, n_s = 5)"))
    rng = _rng(seed, 93)
    out.append((*_stack(rng, [(3, [0]), (3, [0]), (3, [0, 1]), (1, [0, 2])], [POSE, POSE, LANDMARK]),
                "on a pose with two priors, odometry and a landmark seen by one bearing (one row) (m = 10 >= n_x + n_s "
                "= 8): enough rows, but no row measures one direction of the landmark, so the new factor's "
                "information is singular"))
    return out


def _calls(seed=None):
    return [Call(TARGET, (A_x, A_s, b), returns=RETURNS, where=where) for A_x, A_s, b, where in problems(seed)]


# ---------------------------------------------------------------- judges


def _factor(A_new, b_new, n_s):
    """A_new (k, n_s) and b_new (k,) as arrays; an empty A_new of any shape is (0, n_s)."""
    A_new, b_new = np.asarray(A_new, dtype=float), np.asarray(b_new, dtype=float)
    if A_new.size == 0 and b_new.size == 0:
        return np.zeros((0, n_s)), np.zeros(0)
    return A_new, b_new


def shape_problem(got, n_x, n_s) -> str:
    """What is wrong with the shapes of the outputs, or ''."""
    R, S, d = (np.asarray(got[k], dtype=float) for k in ("R", "S", "d"))
    A_new, b_new = _factor(got["A_new"], got["b_new"], n_s)
    if R.shape != (n_x, n_x):
        return f"R has shape {R.shape}, expected ({n_x}, {n_x})"
    if S.shape != (n_x, n_s) and not (S.size == 0 and n_x * n_s == 0):
        transposed = ": S is transposed" if S.shape == (n_s, n_x) else ""
        return f"S has shape {S.shape}, expected ({n_x}, {n_s}){transposed}"
    if d.shape != (n_x,):
        return f"d has shape {d.shape}, expected ({n_x},)"
    if A_new.ndim != 2 or A_new.shape[1] != n_s:
        return f"A_new has shape {A_new.shape}, expected (k, {n_s}) for some k >= 0"
    if b_new.shape != (len(A_new),):
        return f"b_new has shape {b_new.shape}, expected ({len(A_new)},) (one entry per row of A_new)"
    return ""


def invariants(outputs, n_x, n_s) -> dict:
    """What the contract fixes, from ``outputs`` (R, S, d, A_new, b_new): the largest entry of R below
    its diagonal, R^T R, R^T S, R^T d, A_new^T A_new, A_new^T b_new."""
    R = np.asarray(outputs["R"], dtype=float)
    S = np.asarray(outputs["S"], dtype=float).reshape(n_x, n_s)
    d = np.asarray(outputs["d"], dtype=float)
    A_new, b_new = _factor(outputs["A_new"], outputs["b_new"], n_s)
    lower = np.tril(R, -1)
    return {"below": np.array(float(np.max(np.abs(lower))) if lower.size else 0.0),
            "RtR": R.T @ R, "RtS": R.T @ S, "Rtd": R.T @ d,
            "AtA": A_new.T @ A_new, "Atb": A_new.T @ b_new}


def scales(call) -> dict:
    """The inputs' scale of each entry of each invariant, from the column norms ``c`` of ``[A_x A_s]``
    (``c_x``, ``c_s``): ``c_i c_j`` for an information's entry (i, j), ``c_i |b|`` for an information
    vector's entry i (the rounding of ``A^T A`` and ``A^T b`` entry by entry); ``max c_x`` for R's
    entries below the diagonal."""
    A_x, A_s, b = (np.asarray(a, dtype=float) for a in call.args)
    c = np.linalg.norm(np.hstack([A_x, A_s]), axis=0)
    c_x, c_s = c[:A_x.shape[1]], c[A_x.shape[1]:]
    rhs = float(np.linalg.norm(b))
    return {"below": float(np.max(c_x)), "RtR": np.outer(c_x, c_x), "RtS": np.outer(c_x, c_s), "Rtd": c_x * rhs,
            "AtA": np.outer(c_s, c_s), "Atb": c_s * rhs}


LABELS = {"RtR": "R^T R", "RtS": "R^T S", "Rtd": "R^T d", "AtA": "A_new^T A_new", "Atb": "A_new^T b_new"}
MEANING = {"RtR": "Lambda_xx = A_x^T A_x", "RtS": "Lambda_xs = A_x^T A_s", "Rtd": "eta_x = A_x^T b",
           "AtA": "the separator's information Lambda_ss - S^T S", "Atb": "the separator's information vector "
           "eta_s - S^T d"}
CAUSES = {"RtR": "R is the upper Cholesky factor of Lambda_xx (R^T R = Lambda_xx), or the R of a QR of A_x",
          "RtS": "S = R^-T Lambda_xs, so that R^T S = Lambda_xs",
          "Rtd": "d = R^-T eta_x with eta = A^T b, so that R^T d = eta_x",
          "AtA": "the new factor's information is the Schur complement Lambda_ss - S^T S",
          "Atb": "the new factor's information vector is eta_s - S^T d"}


def _excess(mine, ref, atol):
    return np.abs(mine - ref) - (atol + RTOL * np.abs(ref))


def _matches(mine, known, atol) -> list:
    """The texts of the known mistakes whose value ``mine`` is, in order."""
    return [why for value, why in known if np.shape(value) == np.shape(mine) and close(mine, value, RTOL, atol)]


def _difference(mine, ref, name, atol, where, causes):
    """The feedback line where ``mine`` differs from ``ref`` beyond ``RTOL |ref| + atol``, or ''; ``causes``:
    the texts of the known mistakes it matches (the first is named), else the usual cause."""
    excess = _excess(mine, ref, atol)
    if not np.any(excess > 0):
        return ""
    index = tuple(int(k) for k in np.unravel_index(int(np.argmax(excess)), excess.shape))
    entry = f"{LABELS[name]}[{', '.join(map(str, index))}]"
    text = (f"{entry} = {fmt(mine[index])}, expected {fmt(ref[index])} {where} ({int(np.sum(excess > 0))} of "
            f"{excess.size} entries differ; {LABELS[name]} must be {MEANING[name]}; tolerance {RTOL:g} relative "
            f"and {RTOL:g} of the inputs' scale, here {fmt(atol[index])})")
    return f"{text}: {causes[0] if causes else CAUSES[name]}"


def _judge(names, upper=False):
    def judge(ctx):
        triples, failure = call_fields(ctx, {"LinAlgError": SINGULAR}, failed=failed)
        if failure:
            return failure
        for index, (call, got, want) in enumerate(triples):
            n_x, n_s = np.shape(call.args[0])[1], np.shape(call.args[1])[1]
            problem = shape_problem(got, n_x, n_s)
            if problem:
                return Verdict(0.0, f"{problem} {call.where}")
            mine, ref, scale = invariants(got, n_x, n_s), invariants(want, n_x, n_s), scales(call)
            known = ctx.known(index)
            for name in names:
                if not np.all(np.isfinite(mine[name])):
                    return Verdict(0.0, f"{LABELS[name]} has entries that are not finite {call.where}"
                                        + (f": {SINGULAR}" if name in ("AtA", "Atb") else ""))
            if upper and mine["below"] > RTOL * scale["below"]:
                R = np.asarray(got["R"], dtype=float)
                i, j = (int(k) for k in np.unravel_index(int(np.argmax(np.abs(np.tril(R, -1)))), R.shape))
                text = (f"R[{i}, {j}] = {fmt(R[i, j])} below the diagonal {call.where}: R must be upper triangular")
                for value, why in known.get("R", ()):
                    if close(R, value, RTOL, RTOL * scale["below"]):
                        return Verdict(0.0, f"{text}: {why}")
                return Verdict(0.0, text)
            wrong = [name for name in names if np.any(_excess(mine[name], ref[name], RTOL * scale[name]) > 0)]
            if wrong:
                # a mistake that explains every wrong invariant of the check is named before one that explains one
                each = [_matches(mine[name], known.get(name, ()), RTOL * scale[name]) for name in wrong]
                both = [why for why in each[0] if all(why in other for other in each[1:])]
                name = wrong[0]
                return Verdict(0.0, _difference(mine[name], ref[name], name, RTOL * scale[name], call.where,
                                                both or each[0]))
        return Verdict(1.0, "ok")

    return judge


CHECKS = [
    check(ELIMINATE, "the conditional's R: upper triangular, R^T R = Lambda_xx", 2, _calls,
          _judge(("RtR",), upper=True)),
    check(ELIMINATE, "the conditional's S and d: R^T S = Lambda_xs, R^T d = eta_x", 2, _calls,
          _judge(("RtS", "Rtd"))),
    check(ELIMINATE, "the new factor on the separator: A_new^T A_new and A_new^T b_new", 3, _calls,
          _judge(("AtA", "Atb"))),
]


def _sizes(call):
    return (len(call.args[2]),) + tuple(int(np.shape(a)[1]) for a in call.args[:2])


def _spread(call) -> float:
    A = np.abs(np.hstack([np.asarray(a, dtype=float) for a in call.args[:2]]))
    return float(A.max() / A[A > 0].min())


def _row_kinds(call) -> int:
    """How many different sets of separator columns the rows touch (a prior touches none)."""
    A_s = np.asarray(call.args[1], dtype=float)
    return len({tuple(np.flatnonzero(row)) for row in A_s})


def _unmeasured(call) -> bool:
    """The stacked rows ``[A_x A_s]`` have rank below n_x + n_s: some direction of the separator no row measures."""
    A = np.hstack([np.asarray(a, dtype=float) for a in call.args[:2]])
    return int(np.linalg.matrix_rank(A)) < A.shape[1]


EDGES = (
    Edge("one factor of n_x rows (m = n_x): the new factor is empty", TARGET, lambda c: _sizes(c)[0] == _sizes(c)[1]),
    Edge("no separator (n_s = 0)", TARGET, lambda c: _sizes(c)[2] == 0),
    Edge("a scalar variable (n_x = 1)", TARGET, lambda c: _sizes(c)[1] == 1),
    Edge("a planar pose (n_x = 3) with factors of different sizes: a prior, odometry and a landmark", TARGET,
         lambda c: _sizes(c)[1] == POSE and _row_kinds(c) >= 3),
    Edge("ill-scaled whitened blocks (entries from 1e-3 to 1e3)", TARGET, lambda c: _spread(c) >= 1e5),
    Edge("fewer rows than n_x + n_s: the new factor's information is singular but not zero", TARGET,
         lambda c: _sizes(c)[1] < _sizes(c)[0] < _sizes(c)[1] + _sizes(c)[2]),
    Edge("as many rows as n_x + n_s or more, with a separator direction no row measures (a singular new factor)",
         TARGET, lambda c: _sizes(c)[0] >= _sizes(c)[1] + _sizes(c)[2] and _unmeasured(c)),
)
