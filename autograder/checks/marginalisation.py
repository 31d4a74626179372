"""Checks of ``marginalisation`` (chapter 5): the Schur-complement prior of a sliding window,
its residual form and its first-order update.

Public inputs: the three rooms (scalars x1, x2, x3; a prior on x1 and two relative
measurements; x2 removed, leaving a direct x1 - x3 factor); a window of 4 planar poses (3
each) and 4 landmarks (2 each), interleaved in the state, the oldest pose and a landmark it
anchors removed (indices not contiguous, not sorted); the same window with a landmark seen
once by a single bearing (a singular H_mm) and with precise measurements (scale 1e6) and a
direction of H_mm 1e-12 times weaker than the largest (dropped by the relative threshold);
priors ``H = Q diag(s) Q^T`` of full rank, of rank 4 of 6, and of scale 1e4 with an
eigenvalue of 1e-5 (dropped) for the residual form. Hidden: the same kinds from the hidden seed.

The residual form ``(J, e)`` is unique only up to an orthogonal transform of its rows, so
it is judged by ``J^T J``, ``J^T e`` and the number of rows.
"""

from functools import cache

import numpy as np

from autograder.checks import Call, Verdict
from autograder.checks.common import check, failed, values
from autograder.checks.edges import Edge
from autograder.feedback import call_fields, compare

MODULES = ("marginalisation",)
MARGINALISE = "marginalisation.marginalise"
RESIDUAL = "marginalisation.prior_residual"
UPDATE = "marginalisation.prior_update"

#: relative tolerance of every comparison; atol is this times the largest reference entry
RTOL = 1e-8
ATOL = 1e-10

POSE, LANDMARK = 3, 2

# ---------------------------------------------------------------- inputs


def three_rooms(seed=None):
    """The three rooms: scalar positions x1, x2, x3 with a prior x1 ~ z0 (sigma0) and
    relative measurements x2 - x1 ~ z12, x3 - x2 ~ z23 (sigmas s12, s23), linearised at a
    state x. Returns ``(H (3, 3), b (3,), x)`` with ``b = J^T W r`` (r = prediction - z)."""
    rng = np.random.default_rng(71 if seed is None else [seed, 271])
    if seed is None:
        z0, z12, z23, sigmas, x = 0.0, 1.0, 1.0, np.array([0.1, 0.5, 0.5]), np.array([0.05, 1.1, 1.9])
    else:
        z0, z12, z23 = rng.normal(0, 1), rng.uniform(0.5, 2), rng.uniform(0.5, 2)
        sigmas = rng.uniform(0.05, 1.0, 3)
        x = np.array([z0, z0 + z12, z0 + z12 + z23]) + rng.normal(0, 0.2, 3)
    J = np.array([[1.0, 0.0, 0.0], [-1.0, 1.0, 0.0], [0.0, -1.0, 1.0]])
    r = J @ x - np.array([z0, z12, z23])
    W = np.diag(1.0 / sigmas**2)
    return J.T @ W @ J, J.T @ W @ r, x


def window(seed=None, kind="definite"):
    """A sliding window ``(H, b, remove, where)``: 4 planar poses and 4 landmarks
    interleaved in the state (P0 L0 P1 L1 P2 L2 P3 L3, then L4 in the other kinds); a prior
    on P0, odometry between consecutive poses, every landmark seen by 2 or 3 poses (2 rows
    each), random Jacobian blocks, ``H = J^T J``, ``b = J^T r``. ``remove`` = P0 and L0 (which
    P0 anchors), unsorted. ``kind``: ``"definite"``; ``"seen once"``: L4 seen by P0 alone, one
    bearing row (H_mm singular); ``"weak"``: the same with L4's second row 1e-6 times the
    first and every block scaled by 1e3."""
    rng = np.random.default_rng({"definite": 73, "seen once": 79, "weak": 83}[kind] if seed is None
                                else [seed, 273, len(kind)])
    dims = [POSE, LANDMARK] * 4 + ([LANDMARK] if kind != "definite" else [])
    start = np.concatenate([[0], np.cumsum(dims)])
    n = int(start[-1])
    pose = [0, 2, 4, 6]
    land = [1, 3, 5, 7, 8][: len(dims) - 4]
    rows = []

    def factor(variables, count):
        block = np.zeros((count, n))
        for v in variables:
            block[:, start[v]:start[v + 1]] = rng.normal(0, 1, (count, dims[v]))
        rows.append(block)

    factor([pose[0]], POSE)
    for k in range(3):
        factor([pose[k], pose[k + 1]], POSE)
    for j in range(4):
        seen = [0] + sorted(rng.choice([1, 2, 3], int(rng.integers(1, 3)), replace=False).tolist()) if j == 0 \
            else sorted(rng.choice(4, int(rng.integers(2, 4)), replace=False).tolist())
        for p in seen:
            factor([pose[p], land[j]], 2)
    if kind != "definite":
        factor([pose[0], land[4]], 1)
        if kind == "weak":
            factor([pose[0], land[4]], 1)
            rows[-1] *= 1e-6
    J = np.vstack(rows) * (1e3 if kind == "weak" else 1.0)
    r = rng.normal(0, 1, len(J))
    removed = [pose[0], land[0]] + ([land[4]] if kind != "definite" else [])
    remove = np.concatenate([np.arange(start[v], start[v + 1]) for v in removed])
    remove = remove[rng.permutation(len(remove))]
    where = {"definite": "on a window of 4 poses and 4 landmarks, P0 and L0 removed",
             "seen once": "on a window of 4 poses and 5 landmarks, P0, L0 and L4 removed; L4 is seen once, by one "
                          "bearing, so H_mm is singular",
             "weak": "on a window of 4 poses and 5 landmarks (scale 1e6), P0, L0 and L4 removed; H_mm has an "
                     "eigenvalue 1e-12 times its largest"}[kind]
    return J.T @ J, J.T @ r, remove.astype(np.int64), f"{where} (remove = {remove.tolist()})"


def _marginalise_call(H, b, remove, where):
    return Call(f"marginalisation:{MARGINALISE.split('.')[1]}", (H, b, remove), returns=("H_prior", "b_prior"),
                where=where)


def _rooms_calls(seed=None):
    H, b, x = three_rooms(seed)
    return [_marginalise_call(H, b, np.array([1]), f"on the three rooms at x = {np.round(x, 3).tolist()}, x2 "
                                                   "removed")]


def _window_calls(seed=None):
    return [_marginalise_call(*window(seed, "definite"))]


def _singular_calls(seed=None):
    return [_marginalise_call(*window(seed, kind)) for kind in ("seen once", "weak")]


@cache
def priors(seed=None):
    """``(H_prior, b_prior, where)`` triples: ``Q diag(s) Q^T`` of 6 variables with
    ``b = H y``: full rank; rank 4; scale 1e4 with an eigenvalue 1e-5 and one 0."""
    rng = np.random.default_rng(89 if seed is None else [seed, 289])
    out = []
    for s, where in ((10.0 ** rng.uniform(0, 2, 6), "on a prior of full rank (6 variables)"),
                     (np.concatenate([10.0 ** rng.uniform(0, 2, 4), [0.0, 0.0]]),
                      "on a prior of rank 4 (6 variables)"),
                     # the zero eigenvalue comes out of eigh as rounding noise of about 1e-11 here, a hundred
                     # times below the absolute 1e-8 a slip compares with, and 1e-5 sits ten times below
                     # the relative threshold (1e-4 to 1e-3): no decision here turns on rounding
                     (np.concatenate([1e4 * rng.uniform(1, 10, 4), [1e-5, 0.0]]),
                      "on a prior of scale 1e4 with eigenvalues 1e-5 and 0 (6 variables)")):
        Q, _ = np.linalg.qr(rng.normal(0, 1, (6, 6)))
        H = (Q * s) @ Q.T
        H = 0.5 * (H + H.T)
        out.append((H, H @ rng.normal(0, 1, 6), where))
    return out


def _residual_calls(seed=None):
    return [Call(f"marginalisation:{RESIDUAL.split('.')[1]}", (H, b), returns=("J", "e"), where=where)
            for H, b, where in priors(seed)]


def _update_calls(seed=None):
    rng = np.random.default_rng(97 if seed is None else [seed, 297])
    calls = []
    for rows, where in ((6, "J square (6, 6)"), (4, "J (4, 6), a prior of rank 4")):
        J, e0 = rng.normal(0, 2, (rows, 6)), rng.normal(0, 1, rows)
        x_lin = rng.normal(0, 1, 6)
        x = x_lin + rng.normal(0, 0.3, 6)
        calls.append(Call(f"marginalisation:{UPDATE.split('.')[1]}", (J, e0, x_lin, x), where=f"with {where}"))
    return calls


# ---------------------------------------------------------------- judges


def invariants(J, e) -> dict:
    """What the residual form determines: ``J^T J``, ``J^T e`` and the number of rows."""
    J, e = np.asarray(J, dtype=float), np.asarray(e, dtype=float)
    return {"JtJ": J.T @ J, "Jte": J.T @ e, "rows": np.array(float(len(J)))}


_LABELS = {"JtJ": "J^T J", "Jte": "J^T e", "rows": "the number of rows of J"}
_CAUSES = {"JtJ": "J = diag(sqrt(s)) V^T over the eigenpairs of H_prior with s > eps max(s), so that J^T J = H_prior",
           "Jte": "e = diag(1 / sqrt(s)) V^T b_prior, so that J^T e = b_prior",
           "rows": "one row per eigenvalue s > eps max(s) of H_prior (eps is relative, to the largest)"}


def _judge_residual(names):
    def judge(ctx):
        triples, failure = call_fields(ctx, failed=failed)
        if failure:
            return failure
        for index, (call, got, want) in enumerate(triples):
            J, e = np.asarray(got["J"], dtype=float), np.asarray(got["e"], dtype=float)
            n = len(call.args[0])
            if J.ndim != 2 or J.shape[1] != n or e.shape != (J.shape[0],):
                return Verdict(0.0, f"J has shape {J.shape} and e {e.shape}, expected (r, {n}) and (r,) {call.where}")
            mine, ref = invariants(J, e), invariants(want["J"], want["e"])
            known = ctx.known(index)
            for name in names:
                atol = ATOL * max(float(np.max(np.abs(ref[name]))), np.finfo(float).tiny)
                text = compare(mine[name], ref[name], _LABELS[name], RTOL, 0.5 if name == "rows" else atol,
                               call.where, known.get(name, ()), _CAUSES[name])
                if text:
                    return Verdict(0.0, text)
        return Verdict(1.0, "ok")

    return judge


_M_LABELS = {"H_prior": "H_prior[{}]", "b_prior": "b_prior[{}]"}
_M_CAUSE = {"H_prior": "H_prior = H_rr - H_rm H_mm^-1 H_mr over the kept indices in their original order",
            "b_prior": "b_prior = b_r - H_rm H_mm^-1 b_m over the kept indices in their original order"}
_SINGULAR = ("H_mm can be singular (a landmark seen once): invert it by its eigen-decomposition "
             "(np.linalg.eigh), dropping the eigenvalues s <= eps max(s) (eps is relative, to the largest)")


def _m_values(names, cause):
    return values(names, RTOL, ATOL, cause, _M_LABELS, atol_scaled=True, errors={"LinAlgError": _SINGULAR})


CHECKS = [
    check(MARGINALISE, "the three rooms (x2 removed)", 2, _rooms_calls,
          _m_values(("H_prior", "b_prior"), _M_CAUSE)),
    check(MARGINALISE, "window prior H_prior", 2, _window_calls, _m_values(("H_prior",), _M_CAUSE)),
    check(MARGINALISE, "window prior b_prior", 2, _window_calls, _m_values(("b_prior",), _M_CAUSE)),
    check(MARGINALISE, "singular and nearly singular H_mm", 2, _singular_calls,
          _m_values(("H_prior", "b_prior"), _SINGULAR)),
    check(RESIDUAL, "J^T J = H_prior, one row per kept eigenvalue", 2, _residual_calls,
          _judge_residual(("rows", "JtJ"))),
    check(RESIDUAL, "J^T e = b_prior", 2, _residual_calls, _judge_residual(("Jte",))),
    check(UPDATE, "e = e0 + J (x - x_lin)", 1, _update_calls,
          values(("value",), RTOL, ATOL, "e = e0 + J (x - x_lin): the Jacobian stays the one of the "
                 "linearisation point", {"value": "e"}, atol_scaled=True,
                 errors={"ValueError": "J is (r, n) and x - x_lin (n,): e = e0 + J (x - x_lin), not J^T"})),
]


def _spectrum(A) -> np.ndarray:
    A = np.asarray(A, dtype=float)
    return np.linalg.eigvalsh(0.5 * (A + A.T))


def _removed_spectrum(call) -> np.ndarray:
    H, remove = np.asarray(call.args[0], dtype=float), np.asarray(call.args[2])
    return _spectrum(H[np.ix_(remove, remove)])


_M_TARGET = f"marginalisation:{MARGINALISE.split('.')[1]}"
_R_TARGET = f"marginalisation:{RESIDUAL.split('.')[1]}"
_U_TARGET = f"marginalisation:{UPDATE.split('.')[1]}"

EDGES = (
    Edge("marginalise: one variable removed (m = 1)", _M_TARGET, lambda c: len(c.args[2]) == 1),
    Edge("marginalise: removed indices neither contiguous nor sorted", _M_TARGET,
         lambda c: bool(np.any(np.diff(np.asarray(c.args[2])) < 0) and np.ptp(c.args[2]) + 1 > len(c.args[2]))),
    Edge("marginalise: H_mm singular (a landmark seen once, by one bearing)", _M_TARGET,
         lambda c: _removed_spectrum(c)[0] <= 1e-14 * _removed_spectrum(c)[-1]),
    Edge("marginalise: an eigenvalue of H_mm 1e-12 times its largest (below eps max(s), dropped)", _M_TARGET,
         lambda c: bool(np.any((_removed_spectrum(c) > 1e-14 * _removed_spectrum(c)[-1])
                               & (_removed_spectrum(c) < 1e-10 * _removed_spectrum(c)[-1])))),
    Edge("prior_residual: H_prior of full rank", _R_TARGET,
         lambda c: _spectrum(c.args[0])[0] > 1e-6 * _spectrum(c.args[0])[-1]),
    Edge("prior_residual: H_prior of rank 4 of 6 (exact zero eigenvalues)", _R_TARGET,
         lambda c: int(np.sum(_spectrum(c.args[0]) > 1e-10 * _spectrum(c.args[0])[-1])) == 4),
    Edge("prior_residual: an eigenvalue above an absolute 1e-8 but below eps max(s) (dropped)", _R_TARGET,
         lambda c: bool(np.any((_spectrum(c.args[0]) > 1e-7)
                               & (_spectrum(c.args[0]) < 1e-9 * _spectrum(c.args[0])[-1])))),
    Edge("prior_update: J square", _U_TARGET, lambda c: np.shape(c.args[0])[0] == np.shape(c.args[0])[1]),
    Edge("prior_update: J with fewer rows than columns (a prior of lower rank)", _U_TARGET,
         lambda c: np.shape(c.args[0])[0] < np.shape(c.args[0])[1]),
)
