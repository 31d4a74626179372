# RELEASE: omit
"""Known mistakes in ``elimination`` (see ``autograder.mistakes``): the Cholesky route written plainly,
with one slip or none, given as the invariants the checks compare (R^T R, R^T S, R^T d, A_new^T A_new,
A_new^T b_new) and, for a lower-triangular R, R itself."""

import numpy as np

from autograder.checks.elimination import ELIMINATE, invariants


def eliminated(call, *, lower=False, S_of="R^-T", d_of="R^-T", schur=-1.0, schur_d=True, b_sign=1.0,
               rows_as_given=False):
    """The invariants of the Cholesky route with one slip or none, and R (key ``R``)."""
    A_x, A_s, b = (np.asarray(a, dtype=float) for a in call.args)
    n_x, n_s = A_x.shape[1], A_s.shape[1]
    A = np.hstack([A_x, A_s])
    Lam, eta = A.T @ A, b_sign * (A.T @ b)
    L = np.linalg.cholesky(Lam[:n_x, :n_x])
    R = L.T
    S = {"R^-T": np.linalg.solve(R.T, Lam[:n_x, n_x:]), "none": Lam[:n_x, n_x:],
         "R^-1": np.linalg.solve(R, Lam[:n_x, n_x:])}[S_of]
    d = {"R^-T": np.linalg.solve(R.T, eta[:n_x]), "none": eta[:n_x], "R^-1": np.linalg.solve(R, eta[:n_x])}[d_of]
    out = invariants({"R": L if lower else R, "S": S, "d": d, "A_new": np.zeros((0, n_s)), "b_new": np.zeros(0)},
                     n_x, n_s)
    if rows_as_given:
        out["AtA"], out["Atb"] = A_s.T @ A_s, b_sign * (A_s.T @ b)
    else:
        out["AtA"] = Lam[n_x:, n_x:] + schur * S.T @ S
        out["Atb"] = eta[n_x:] - S.T @ d if schur_d else eta[n_x:].copy()
    out["R"] = L if lower else R
    return out


SLIPS = (
    ({"lower": True}, "R is lower triangular: np.linalg.cholesky gives L with Lambda_xx = L L^T; the conditional's R "
                      "is its transpose L^T (upper)"),
    ({"S_of": "none"}, "S = R^-T Lambda_xs (solve R^T S = Lambda_xs), not Lambda_xs itself"),
    ({"S_of": "R^-1"}, "S solves R^T S = Lambda_xs (R^-T, the transpose: L S = Lambda_xs with L = R^T), not R S = "
                       "Lambda_xs"),
    ({"d_of": "none"}, "d = R^-T eta_x (solve R^T d = eta_x), not eta_x itself"),
    ({"d_of": "R^-1"}, "d solves R^T d = eta_x (R^-T, the transpose), not R d = eta_x"),
    ({"schur": 0.0}, "the new factor's information is the Schur complement Lambda_ss - S^T S: what x explained "
                     "leaves the separator"),
    ({"schur": 1.0}, "the Schur complement subtracts: Lambda_ss - S^T S, not Lambda_ss + S^T S"),
    ({"b_sign": -1.0}, "eta = A^T b (the error is ||A x - b||^2, so its gradient at 0 is -2 A^T b); eta = -A^T b is "
                       "the Gauss-Newton convention r = -b, which flips d and b_new"),
    ({"schur_d": False}, "the new factor's information vector is eta_s - S^T d, not eta_s = A_s^T b: x's part of "
                         "b leaves with it"),
    ({"rows_as_given": True}, "the new factor is not the rows of A_s (and b) as given: after the orthogonal "
                              "transform Q^T [A_x | A_s | b] it is the rows below R, i.e. information Lambda_ss - "
                              "S^T S and eta_s - S^T d"),
)


def elimination_mistakes(call, ref):
    want = invariants(ref, np.shape(call.args[0])[1], np.shape(call.args[1])[1])
    want["R"] = np.asarray(ref["R"], dtype=float)
    known: dict = {name: [] for name in want}
    for slip, why in SLIPS:
        try:
            got = eliminated(call, **slip)
        except (np.linalg.LinAlgError, ValueError):
            continue
        for name, value in got.items():
            if name == "below":
                continue
            if name == "R" and not slip.get("lower"):
                continue
            if np.shape(value) != np.shape(want[name]) or not np.allclose(value, want[name], rtol=1e-6, atol=1e-9):
                known[name].append((value, why))
    known.pop("below", None)
    return known


MISTAKES = {f"{ELIMINATE}: {title}": elimination_mistakes
            for title in ("the conditional's R: upper triangular, R^T R = Lambda_xx",
                          "the conditional's S and d: R^T S = Lambda_xs, R^T d = eta_x",
                          "the new factor on the separator: A_new^T A_new and A_new^T b_new")}
