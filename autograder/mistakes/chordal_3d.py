# RELEASE: omit
"""Known mistakes in ``chordal_3d`` (see ``autograder.mistakes``): the two least squares
written densely with one slip, and the projections students write instead of the nearest
rotation."""

import numpy as np

from autograder.checks.chordal_3d import PROJECT, RELAXED, TRANSLATIONS


def _solve_with_anchor(H, g, anchor, known):
    """``x`` (3N, c) of ``H x = g`` with the anchor's block held at ``known`` (3, c)."""
    n = H.shape[0] // 3
    free = np.flatnonzero(np.repeat(np.arange(n) != anchor, 3))
    fixed = np.arange(3 * anchor, 3 * anchor + 3)
    x = np.zeros((3 * n,) + np.shape(known)[1:])
    x[fixed] = known
    x[free] = np.linalg.solve(H[np.ix_(free, free)], g[free] - H[np.ix_(free, fixed)] @ known)
    return x


def relaxed(call, *, transpose_z=True, weighted=True, rows=True, sign=1.0):
    n, ei, ej, R_z, w, R_anchor = call.args
    anchor = call.kwargs["anchor"]
    w = np.asarray(w, float) if weighted else np.ones(len(ei))
    H = np.zeros((3 * n, 3 * n))
    for i, j, Z, wk in zip(ei, ej, np.asarray(R_z), w):
        A = Z.T if transpose_z else Z  # r_j - A r_i = 0
        si, sj = slice(3 * i, 3 * i + 3), slice(3 * j, 3 * j + 3)
        H[si, si] += wk * A.T @ A
        H[sj, sj] += wk * np.eye(3)
        H[si, sj] -= wk * A.T
        H[sj, si] -= wk * A
    X = _solve_with_anchor(H, np.zeros((3 * n, 3)), anchor, sign * np.asarray(R_anchor).T)
    out = X.reshape(n, 3, 3)
    out = out.transpose(0, 2, 1) if rows else out
    out[anchor] = R_anchor
    return out


def relaxed_mistakes(call, ref):
    return {"value": [
        (relaxed(call, transpose_z=False), "row a of R_j = R_i R_z reads r_j^a = R_z^T r_i^a (R_z transposed)"),
        (relaxed(call, weighted=False), "weigh each edge by its weight w_k"),
        (relaxed(call, rows=False), "X's column a is row a of the R's: R_k[a, :] = X[3k:3k+3, a] (you returned R^T)"),
        (relaxed(call, sign=-1.0), "the anchor's columns move to the right-hand side with a minus: "
                                   "H_FF X_F = -H_FA X_A"),
    ]}


def project_mistakes(call, ref):
    M = np.asarray(call.args[0], float)
    U, S, Vt = np.linalg.svd(M)
    d = np.linalg.det(np.matmul(U, Vt))
    if np.any((d < 0) & (S[:, 1] - S[:, 2] <= 1e-6 * S[:, 0])):  # a reflection whose nearest rotation is not unique
        return {"value": []}
    first = U.copy()
    first[:, :, 0] *= d[:, None]
    Q = np.linalg.qr(M)[0]
    return {"value": [
        (np.matmul(U, Vt), "U V^T is a reflection when det(U V^T) = -1: multiply U's last column by that "
                           "determinant"),
        (np.matmul(first, Vt), "flip the column of U for the smallest singular value (the last), not the first"),
        (np.matmul(Vt.transpose(0, 2, 1), U.transpose(0, 2, 1)), "the nearest rotation is U ... V^T, not V ... U^T"),
        (Q, "Gram-Schmidt (QR) orthonormalises but is not the nearest rotation: use the SVD"),
        (M / np.linalg.norm(M, axis=2, keepdims=True), "normalising the rows does not make them orthogonal"),
    ]}


def translations(call, *, rotate_c=True, weight="right", sign=1.0, left=False):
    n, ei, ej, t_z, R_z, info, R, t_anchor = call.args
    anchor = call.kwargs["anchor"]
    R, R_z, t_z, info = (np.asarray(v, float) for v in (R, R_z, t_z, info))
    H, g = np.zeros((3 * n, 3 * n)), np.zeros(3 * n)
    for k, (i, j) in enumerate(zip(ei, ej)):
        Q = R[i] @ R_z[k]
        W = {"right": Q @ info[k, :3, :3] @ Q.T, "plain": info[k, :3, :3], "none": np.eye(3)}[weight]
        c = (R[i].T if left else R[i]) @ t_z[k] if rotate_c else t_z[k]
        si, sj = slice(3 * i, 3 * i + 3), slice(3 * j, 3 * j + 3)
        H[si, si] += W
        H[sj, sj] += W
        H[si, sj] -= W
        H[sj, si] -= W
        g[si] -= sign * W @ c
        g[sj] += sign * W @ c
    return _solve_with_anchor(H, g, anchor, np.asarray(t_anchor, float)).reshape(n, 3)


def translation_mistakes(call, ref):
    return {"value": [
        (translations(call, rotate_c=False), "t_z is in pose i's frame: t_j - t_i = R_i t_z"),
        (translations(call, left=True), "t_j - t_i = R_i t_z, not R_i^T t_z"),
        (translations(call, weight="plain"), "Omega_tt weighs e_t = (R_i R_z)^T r: in the world frame the weight is "
                                             "W = (R_i R_z) Omega_tt (R_i R_z)^T"),
        (translations(call, weight="none"), "weigh each edge by W = (R_i R_z) Omega_tt (R_i R_z)^T"),
        (translations(call, sign=-1.0), "g has the opposite sign: g_i -= W c, g_j += W c"),
    ]}


MISTAKES = {
    f"{RELAXED}: the relaxation's 3x3 matrices": relaxed_mistakes,
    f"{PROJECT}: the nearest rotation (SVD, determinant fixed)": project_mistakes,
    f"{TRANSLATIONS}: positions given the rotations": translation_mistakes,
}
