# RELEASE: omit
"""Known mistakes in ``marginalisation`` (see ``autograder.mistakes``): the Schur complement,
the residual form and its update written plainly, with one slip or none."""

import numpy as np

from autograder.checks.marginalisation import MARGINALISE, RESIDUAL, UPDATE, invariants


def _inverse(A, eps, how):
    A = 0.5 * (A + A.T)
    if how == "inv":
        return np.linalg.inv(A)
    s, V = np.linalg.eigh(A)
    keep = s > (eps if how == "absolute" else eps * max(float(s.max()), 0.0))
    if how == "rows":  # eigenvectors read as the rows of V
        return V[keep, :].T @ np.diag(1.0 / s[keep]) @ V[keep, :]
    if how == "no inverse":
        return V[:, keep] @ np.diag(s[keep]) @ V[:, keep].T
    return V[:, keep] @ np.diag(1.0 / s[keep]) @ V[:, keep].T


def _stable(slip_outputs, call):
    """The outputs of a slip (``slip_outputs(call)``, a dict of arrays), or None where it raises (a
    singular matrix inverted). The oracle keeps only the outputs that rounding does not move
    (:func:`autograder.rounding.stable`): a slip that reads eigenvectors of a repeated eigenvalue or
    keeps an eigenvalue that is zero to rounding is dropped there."""
    try:
        with np.errstate(all="ignore"):
            return slip_outputs(call)
    except (np.linalg.LinAlgError, ValueError):
        return None


def marginal(call, *, inverse="eigh", sign=-1.0, b_sign=-1.0, b_term=True, keep="in order"):
    H, b, remove = (np.asarray(a) for a in call.args)
    H, b = H.astype(float), b.astype(float)
    eps = float(call.kwargs.get("eps", 1e-8))
    n = len(H)
    if keep == "contiguous":  # everything outside [min(remove), max(remove)]
        kept = [i for i in range(n) if i < remove.min() or i > remove.max()]
    elif keep == "removed order":
        kept = [i for i in range(n) if i not in remove]
        kept = kept[::-1]
    else:
        kept = [i for i in range(n) if i not in remove]
    Hmm_inv = _inverse(H[np.ix_(remove, remove)], eps, inverse)
    H_rm, H_mr = H[np.ix_(kept, remove)], H[np.ix_(remove, kept)]
    term = H_rm @ Hmm_inv @ H_mr
    H_prior = H[np.ix_(kept, kept)] + sign * term
    b_prior = b[kept] + (b_sign * H_rm @ Hmm_inv @ b[remove] if b_term else 0.0)
    return {"H_prior": H_prior, "b_prior": b_prior}


_MARGINAL_SLIPS = (
    ({"sign": 1.0}, "the Schur complement subtracts: H_prior = H_rr - H_rm H_mm^-1 H_mr"),
    ({"inverse": "no inverse"}, "H_rm H_mm^-1 H_mr needs the inverse of H_mm (1 / s on the eigenvalues), not H_mm"),
    ({"inverse": "rows"}, "np.linalg.eigh returns the eigenvectors as the columns of V: H_mm^-1 = V diag(1/s) V^T"),
    ({"b_sign": 1.0}, "b_prior = b_r - H_rm H_mm^-1 b_m (the same elimination as H_prior, so the same sign)"),
    ({"b_term": False}, "b_prior = b_r - H_rm H_mm^-1 b_m: the removed variables' gradient moves to the kept ones"),
    ({"inverse": "inv"}, "np.linalg.inv of a singular H_mm is meaningless: use the eigen-decomposition and drop "
                         "the eigenvalues s <= eps max(s)"),
    ({"inverse": "absolute"}, "eps is relative: drop the eigenvalues s <= eps max(s), not s <= eps"),
    ({"keep": "contiguous"}, "the removed indices need not be contiguous: keep every index not in remove"),
    ({"keep": "removed order"}, "keep the kept variables in their original (increasing) order"),
)


def marginal_mistakes(call, ref):
    known: dict = {name: [] for name in ref}
    for slip, text in _MARGINAL_SLIPS:
        outputs = _stable(lambda c, slip=slip: marginal(c, **slip), call)
        if outputs is None:
            continue
        for name, value in outputs.items():
            if np.shape(value) != np.shape(ref[name]) or not np.allclose(value, ref[name], rtol=1e-6, atol=1e-9):
                known[name].append((value, text))
    return known


def residual(call, *, root=True, scale="sqrt", rows=False, threshold="relative", e_sign=1.0):
    H, b = (np.asarray(a, dtype=float) for a in call.args)
    eps = float(call.kwargs.get("eps", 1e-8))
    s, V = np.linalg.eigh(0.5 * (H + H.T))
    if threshold == "none":
        keep = np.ones(len(s), dtype=bool)
    else:
        keep = s > (eps if threshold == "absolute" else eps * float(s.max()))
    s, V = s[keep], V[keep, :].T if rows else V[:, keep]
    J = (np.sqrt(s) if root else s)[:, None] * V.T
    e = V.T @ b * {"sqrt": 1.0 / np.sqrt(s), "none": 1.0, "s": 1.0 / s}[scale]
    return J, e_sign * e


_RESIDUAL_SLIPS = (
    ({"scale": "none"}, "e = diag(1 / sqrt(s)) V^T b_prior, so that J^T e = V V^T b_prior = b_prior"),
    ({"root": False}, "J = diag(sqrt(s)) V^T: with J = diag(s) V^T, J^T J = V diag(s^2) V^T"),
    ({"scale": "s"}, "e = diag(1 / sqrt(s)) V^T b_prior, not diag(1 / s) V^T b_prior"),
    ({"rows": True}, "np.linalg.eigh returns the eigenvectors as the columns of V"),
    ({"threshold": "absolute"}, "eps is relative: keep the eigenvalues s > eps max(s), not s > eps"),
    ({"threshold": "none"}, "drop the eigenvalues s <= eps max(s) (zero up to rounding, maybe negative) before "
                            "taking 1 / sqrt(s)"),
    ({"e_sign": -1.0}, "J^T e = +b_prior: the prior's cost 1/2 |e + J dx|^2 has gradient J^T e at dx = 0"),
)


def residual_mistakes(call, ref):
    want = invariants(ref["J"], ref["e"])
    known: dict = {name: [] for name in want}
    for slip, text in _RESIDUAL_SLIPS:
        got = _stable(lambda c, slip=slip: invariants(*residual(c, **slip)), call)
        if got is None:
            continue
        for name, value in got.items():
            if value.shape != want[name].shape or not np.allclose(value, want[name], rtol=1e-6, atol=1e-9):
                known[name].append((value, text))
    return known


def update_mistakes(call, ref):
    J, e0, x_lin, x = (np.asarray(a, dtype=float) for a in call.args)
    slips = [
        (lambda: e0 + J @ (x_lin - x), "the step is x - x_lin (from where the prior was made to now)"),
        (lambda: e0 + J @ x, "J multiplies the change since the linearisation point: e0 + J (x - x_lin)"),
        (lambda: J @ (x - x_lin), "the prior's residual at x_lin is e0: e = e0 + J (x - x_lin)"),
        (lambda: e0 + J.T @ (x - x_lin), "J is (r, n): e = e0 + J (x - x_lin), not J^T"),
        (lambda: e0.copy(), "the prior's residual changes as the state moves: e = e0 + J (x - x_lin)"),
    ]
    known = []
    for f, text in slips:
        try:
            known.append((f(), text))
        except ValueError:
            continue
    return {"value": known}


MISTAKES = {
    **{f"{MARGINALISE}: {title}": marginal_mistakes
       for title in ("the three rooms (x2 removed)", "window prior H_prior", "window prior b_prior",
                     "singular and nearly singular H_mm")},
    f"{RESIDUAL}: J^T J = H_prior, one row per kept eigenvalue": residual_mistakes,
    f"{RESIDUAL}: J^T e = b_prior": residual_mistakes,
    f"{UPDATE}: e = e0 + J (x - x_lin)": update_mistakes,
}
