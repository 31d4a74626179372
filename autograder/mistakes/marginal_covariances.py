# RELEASE: omit
"""Known mistakes in ``marginal_covariances`` (see ``autograder.mistakes``): the marginals and joint marginals
a slip gives, computed densely on the checks' small inputs (none on the 20,000-variable chain but those read
off the reference's output)."""

import numpy as np

from autograder.checks.marginal_covariances import CHECKS, JOINT, MARGINALS
from autograder.tasks.marginal_covariances import matrix

#: above this size no slip is computed densely
DENSE = 2000


def _dense(call):
    n, fmt, indptr, indices, data = call.args[:5]
    if n > DENSE:
        return None, None
    R = matrix(n, fmt, indptr, indices, data).tocsr()
    stored = np.zeros((n, n), dtype=bool)
    rows = np.repeat(np.arange(n), np.diff(R.indptr))
    stored[rows, R.indices] = True
    return R.toarray(), stored


def recursion(R, pattern, sign=-1.0, own=True, rest=True):
    """Sigma on ``pattern`` (entries off it taken 0) by the recursion with a slip: ``sign`` of Sigma_ij,
    ``own``: the 1 / R_ii^2 term of Sigma_ii (kept in a row with no later entry, the last row's formula written
    apart), ``rest``: the sum in Sigma_ii."""
    n = len(R)
    S = np.zeros((n, n))
    for i in range(n - 1, -1, -1):
        K = [k for k in range(i + 1, n) if pattern[i, k]]
        r = R[i, K]
        for j in K:
            S[i, j] = S[j, i] = sign * (r @ S[K, j]) / R[i, i]
        S[i, i] = ((1.0 / R[i, i] if own or not K else 0.0) - (r @ S[K, i] if rest else 0.0)) / R[i, i]
    return S


def _blocks(S, sizes):
    starts = np.concatenate([[0], np.cumsum(sizes)])
    return np.concatenate([S[a:b, a:b].ravel() for a, b in zip(starts[:-1], starts[1:])])


def _marginals(call, ref):
    R, stored = _dense(call)
    if R is None:
        return {}
    sizes = [int(d) for d in call.args[5]]
    starts = np.concatenate([[0], np.cumsum(sizes)])
    H = R.T @ R
    conditional = np.concatenate([np.linalg.inv(H[a:b, a:b]).ravel() for a, b in zip(starts[:-1], starts[1:])])
    separator = np.concatenate([np.linalg.inv(R[a:b, a:b].T @ R[a:b, a:b]).ravel()
                                for a, b in zip(starts[:-1], starts[1:])])
    slips = [
        (conditional, "that is (H_vv)^-1, the covariance of v given all the other variables (its conditional), "
                      "not its marginal: the marginal is the block of (R^T R)^-1"),
        (separator, "that is (R_vv^T R_vv)^-1, v's covariance given its separator (the conditional of the Bayes "
                    "tree's clique), not its marginal: the marginal takes the rows R_vk, k > v, through Sigma_kv"),
        (_blocks(np.linalg.inv(R @ R.T), sizes),
         "that is (R R^T)^-1, not (R^T R)^-1: run the recursion from the last row up, on R's rows (R_ik, k > i)"),
        (_blocks(recursion(R, stored, own=False), sizes),
         "Sigma_ii needs its own term: Sigma_ii = (1 / R_ii) (1 / R_ii - sum_k R_ik Sigma_ki)"),
        (_blocks(recursion(R, stored, rest=False), sizes),
         "Sigma_ii = 1 / R_ii^2 holds only for the last row: Sigma_ii = (1 / R_ii) (1 / R_ii - sum_k R_ik Sigma_ki)"),
        (_blocks(recursion(R, stored, sign=1.0), sizes),
         "the off-diagonal entries have the wrong sign: Sigma_ij = -(1 / R_ii) sum_k R_ik Sigma_kj"),
        (_blocks(recursion(R, R != 0.0), sizes),
         "a stored entry of R with the value 0 is still part of the pattern: the recursion needs Sigma there "
         "(read R.indices, do not drop zeros)"),
    ]
    return {"blocks": slips}


def _joint(call, ref):
    sizes, keys = [int(d) for d in call.args[5]], [int(k) for k in call.args[6]]
    starts = np.concatenate([[0], np.cumsum(sizes)])
    spans = [np.arange(starts[k], starts[k + 1]) for k in keys]
    local = np.concatenate([[0], np.cumsum([len(s) for s in spans])])
    S = np.asarray(ref["Sigma"], dtype=float)
    order = np.argsort(keys, kind="stable")
    sorted_local = np.concatenate([np.arange(local[k], local[k + 1]) for k in order])
    diagonal = np.zeros_like(S)
    for a, b in zip(local[:-1], local[1:]):
        diagonal[a:b, a:b] = S[a:b, a:b]
    slips = [(diagonal, "the joint marginal keeps the cross-covariances between the keys: Sigma[cols][:, cols], "
                        "not its diagonal blocks alone")]
    if list(order) != list(range(len(keys))):
        slips.append((S[np.ix_(sorted_local, sorted_local)],
                      "the blocks are in increasing key order: keep the order of keys as given"))
    R, _ = _dense(call)
    if R is not None:
        cols = np.concatenate(spans)
        slips.append((np.linalg.inv(R @ R.T)[np.ix_(cols, cols)],
                      "that is (R R^T)^-1: solve R^T Y = E (lower) first, then R X = Y (upper)"))
        slips.append((np.linalg.inv((R.T @ R)[np.ix_(cols, cols)]),
                      "that is the inverse of H's block (the covariance given all the other variables), not the "
                      "block of H^-1"))
    return {"Sigma": slips}


MISTAKES = {check.name: (_marginals if check.exercise == MARGINALS else _joint) for check in CHECKS}
assert all(check.exercise in (MARGINALS, JOINT) for check in CHECKS)

