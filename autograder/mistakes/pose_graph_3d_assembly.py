# RELEASE: omit
"""Known mistakes in ``pose_graph_3d_assembly`` (see ``autograder.mistakes``)."""

import numpy as np

from autograder.checks.pose_graph_3d_assembly import ASSEMBLER


def _dense(call, blocks, *, weight=True, fixed=True):
    """The upper triangle of H, b and chi2 assembled densely, with one slip or none."""
    data = call.args[0]
    n = 6 * data["num_poses"]
    e, A, B = (np.asarray(v, dtype=float) for v in blocks)
    info = np.asarray(data["information"]) if weight else np.tile(np.eye(6), (len(e), 1, 1))
    H, b = np.zeros((n, n)), np.zeros(n)
    for k, (i, j) in enumerate(zip(data["edges_i"], data["edges_j"])):
        J = np.zeros((6, n))
        J[:, 6 * i:6 * i + 6], J[:, 6 * j:6 * j + 6] = A[k], B[k]
        H += J.T @ info[k] @ J
        b += J.T @ info[k] @ e[k]
    if fixed:
        for p in data["fixed"]:
            s = slice(6 * p, 6 * p + 6)
            H[s, :], H[:, s], b[s] = 0.0, 0.0, 0.0
            H[s, s] = np.eye(6)
    chi2 = float(np.einsum("mi,mij,mj->", e, info, e))
    return np.triu(H), b, chi2


def assembler_mistakes(call, ref):
    _, blocks = call.args
    known = {}
    for k in range(2):
        H_ref = np.asarray(ref[f"H{k}"], dtype=float)
        full = H_ref + np.triu(H_ref, 1).T
        unweighted = _dense(call, blocks[k], weight=False)
        free = _dense(call, blocks[k], fixed=False)
        known[f"H{k}"] = [
            (full, "H holds the whole matrix: store the upper triangle only (diagonal included)"),
            (np.tril(full), "H holds the lower triangle: store the upper triangle (row <= column)"),
            (unweighted[0], "H = J^T J: weigh every edge by its information, J^T Omega J"),
            (free[0], "a fixed pose keeps an identity diagonal block and zero rows and columns"),
        ]
        if k == 1:
            known["H1"].append((H_ref + ref["H0"], "the second call added onto the first call's values: "
                                                   "start every assemble from zero"))
        known[f"b{k}"] = [(-np.asarray(ref[f"b{k}"]), "b has the opposite sign: b = J^T Omega e"),
                          (unweighted[1], "b = J^T e: weigh every edge by its information, J^T Omega e"),
                          (free[1], "a fixed pose's entries of b are zero")]
        known[f"chi2{k}"] = [(unweighted[2], "chi2 = sum e^T Omega e, weighted by the information")]
    return known


MISTAKES = {f"{ASSEMBLER}: H (upper, CSC), b, chi2 in 6x6 blocks": assembler_mistakes}
