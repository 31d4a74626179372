# RELEASE: omit
"""Known mistakes in ``bundle_adjustment`` (see ``autograder.mistakes``): the BAL model, its
Jacobians and the block normal equations written plainly (one observation at a time), the
Schur step over all observation pairs at once with a dense S, each with one slip or none."""

import warnings

import numpy as np
import scipy.linalg

from autograder.checks.bundle_adjustment import DIFFERENCES, FACTORS, NORMAL, RESIDUALS, SCHUR
from course.geometry.so3 import right_jacobian, skew, so3_exp


def _predict(camera, X, *, sign=-1.0, distortion="right", rotation="R"):
    R = so3_exp(camera[:3]) if rotation == "R" else so3_exp(camera[:3]).T
    P = R @ X + camera[3:6]
    p = sign * P[:2] / P[2]
    r2 = p @ p
    k1, k2 = camera[7], camera[8]
    d = {"right": 1 + k1 * r2 + k2 * r2**2, "none": 1.0, "norm": 1 + k1 * np.sqrt(r2) + k2 * r2}[distortion]
    return camera[6] * d * p, P, p, d


def residuals(call, flip=False, **slip):
    cameras, points, ci, pi, observed = call.args
    out = np.array([_predict(cameras[c], points[p], **slip)[0] - o for c, p, o in zip(ci, pi, observed)])
    return -out if flip else out


def _dpred_dP(cam, X, dd=True):
    """``(d predicted / d P (2, 3), p (2,), d)`` of one observation (``dd=False``: without d's own
    derivative)."""
    _, P, pp, d = _predict(cam, X)
    k1, k2, r2 = cam[7], cam[8], pp @ pp
    dp_dP = np.array([[-1 / P[2], 0, P[0] / P[2] ** 2], [0, -1 / P[2], P[1] / P[2] ** 2]])
    dd_dp = (2 * k1 + 4 * k2 * r2) * pp if dd else np.zeros(2)
    return cam[6] * (d * np.eye(2) + np.outer(pp, dd_dp)) @ dp_dP, pp, d


def jacobians(call, *, point="R", rotation="exact", dd=True, df="dp", sign=1.0):
    """(J_cam (K, 2, 9), J_point (K, 2, 3)) of the right model, with one slip or none."""
    cameras, points, ci, pi, _ = call.args
    Jc, Jp = [], []
    for c, p in zip(ci, pi):
        cam, X = cameras[c], points[p]
        dpred_dP, pp, d = _dpred_dP(cam, X, dd)
        f, r2 = cam[6], pp @ pp
        R = so3_exp(cam[:3])
        if rotation == "exact":
            dRX = np.empty((3, 3))
            for a in range(3):  # central differences of R(w) X, exact to rounding for this smooth map
                e = np.zeros(3)
                e[a] = 1e-6
                dRX[:, a] = (so3_exp(cam[:3] + e) @ X - so3_exp(cam[:3] - e) @ X) / 2e-6
        else:  # the small-angle (perturbation) form, exact only at w = 0
            dRX = -skew(R @ X)
        J = np.zeros((2, 9))
        J[:, :3] = dpred_dP @ dRX
        J[:, 3:6] = dpred_dP
        J[:, 6] = d * pp if df == "dp" else pp
        J[:, 7] = f * r2 * pp
        J[:, 8] = f * r2**2 * pp
        Jc.append(sign * J)
        Jp.append(sign * (dpred_dP @ R if point == "R" else dpred_dP))
    return np.array(Jc), np.array(Jp)


def factors(call) -> dict:
    """The reference's factors of the Jacobians at every observation, under the names of
    ``checks.bundle_adjustment.FACTORS``: d predicted / d P (K, 2, 3), d P / d w (K, 3, 3) and
    d P / d X = R(w) (K, 3, 3); J_cam's (w, t) columns are d predicted / d P times (d P / d w, I),
    J_point is d predicted / d P times R(w)."""
    cameras, points, ci, pi, _ = call.args
    out: dict[str, list] = {name: [] for name in FACTORS}
    for c, p in zip(ci, pi):
        cam, X = cameras[c], points[p]
        dpred_dP = _dpred_dP(cam, X)[0]
        R = so3_exp(cam[:3])
        for name, value in zip(FACTORS, (dpred_dP, -R @ skew(X) @ right_jacobian(cam[:3]), R)):
            out[name].append(value)
    return {name: [(np.array(values), "the reference's factor")] for name, values in out.items()}


def residual_mistakes(call, ref):
    if call.where.endswith(DIFFERENCES):  # the moved inputs: feedback names the first call's mistakes
        return {}

    def jac(**slip):
        return dict(zip(("J_cam", "J_point"), jacobians(call, **slip)))

    known = {"r": [
        (residuals(call, sign=1.0), "the BAL projection is p = -P[:2] / P[2] (the camera looks down -z)"),
        (residuals(call, flip=True), "r = predicted - observed, not observed - predicted"),
        (residuals(call, distortion="none"), "the radial distortion d = 1 + k1 |p|^2 + k2 |p|^4 is missing"),
        (residuals(call, distortion="norm"), "the distortion is in |p|^2 and |p|^4: d = 1 + k1 |p|^2 + k2 |p|^4"),
        (residuals(call, rotation="RT"), "the rotation is R(w), not its transpose (P = R(w) X + t)"),
    ], "J_cam": [], "J_point": []}
    for slip, text in (({"sign": -1.0}, "the Jacobians have the opposite sign (of observed - predicted)"),
                       ({"dd": False}, "the derivative of the distortion d with respect to p is missing: "
                                       "d(f d p)/dp = f (d I + p (dd/dp)^T), dd/dp = (2 k1 + 4 k2 |p|^2) p"),
                       ({"rotation": "small"}, "d(R(w) X)/dw = -[R X]x holds only at w = 0: with the camera "
                                               "updated by w + dw, differentiate R(w) X in w itself"),
                       ({"df": "p"}, "d predicted / d f = d p (the distortion included)"),
                       ({"point": "I"}, "the point enters through P = R X + t: J_point = (d predicted / d P) R")):
        for name, value in jac(**slip).items():
            if not np.allclose(value, ref[name], rtol=1e-9, atol=1e-12):
                known[name].append((value, text))
    return known | factors(call)


def normal(call, *, accumulate="add", gradient=1.0, chi2_scale=1.0, coupling="cam_point", minlength=True):
    r, J_cam, J_point, ci, pi, num_cameras, num_points = call.args
    U, V = np.zeros((num_cameras, 9, 9)), np.zeros((num_points, 3, 3))
    g_cam, g_point = np.zeros((num_cameras, 9)), np.zeros((num_points, 3))
    for k, (c, p) in enumerate(zip(ci, pi)):
        if accumulate == "add":
            U[c] += J_cam[k].T @ J_cam[k]
            V[p] += J_point[k].T @ J_point[k]
            g_cam[c] += gradient * J_cam[k].T @ r[k]
            g_point[p] += gradient * J_point[k].T @ r[k]
        else:  # numpy's U[ci] += blocks: a repeated index keeps the last block only
            U[c] = J_cam[k].T @ J_cam[k]
            V[p] = J_point[k].T @ J_point[k]
            g_cam[c] = gradient * J_cam[k].T @ r[k]
            g_point[p] = gradient * J_point[k].T @ r[k]
    W = np.einsum("kai,kaj->kij", J_cam, J_point)
    if coupling == "per_camera":
        summed = np.zeros((num_cameras, 9, 3))
        np.add.at(summed, ci, W)
        W = summed[ci]
    if not minlength:  # np.bincount without minlength: the arrays end at the last camera and point seen
        U, g_cam = U[:int(np.max(ci)) + 1], g_cam[:int(np.max(ci)) + 1]
        V, g_point = V[:int(np.max(pi)) + 1], g_point[:int(np.max(pi)) + 1]
    return {"U": U, "V": V, "W": W, "g_cam": g_cam, "g_point": g_point,
            "chi2": chi2_scale * float(np.sum(r * r))}


def normal_mistakes(call, ref):
    known = {name: [] for name in ref}
    for slip, text in (({"accumulate": "last"}, "U[camera_index] += blocks keeps one block per repeated index "
                                                "(numpy's fancy-index +=): accumulate with np.add.at"),
                       ({"gradient": -1.0}, "the gradient has the opposite sign: g = J^T r (the step solves "
                                            "H dx = -g)"),
                       ({"chi2_scale": 0.5}, "chi2 = sum r^T r, without a factor 1/2 (the BAL cost is half of it)"),
                       ({"coupling": "per_camera"}, "W_k = J_cam_k^T J_point_k is one block per observation, not "
                                                    "summed over the camera's observations"),
                       ({"minlength": False}, "a camera that sees no point (or a point seen by none) keeps its zero "
                                              "block: np.bincount(..., minlength=...) of num_cameras (num_points) "
                                              "blocks, not up to the last index seen")):
        for name, value in normal(call, **slip).items():
            if np.shape(value) != np.shape(ref[name]) or not np.allclose(value, ref[name], rtol=1e-12, atol=1e-14):
                known[name].append((value, text))
    return known


def schur(call, *, damp_u=True, damp_v=True, s_sign=-1.0, rhs_sign=1.0, back_sign=-1.0):
    U, V, W, g_cam, g_point, ci, pi = call.args
    damping_cam, damping_point = call.kwargs.get("damping_cam"), call.kwargs.get("damping_point")
    C = len(U)
    U, V = U.copy(), V.copy()
    if damping_cam is not None and damping_point is not None:
        if damp_u:
            U[:, range(9), range(9)] += damping_cam
        if damp_v:
            V[:, range(3), range(3)] += damping_point
    Vinv = np.linalg.inv(V)
    # S = U + s_sign * sum over the observation pairs (k, m) of one point of W_k V_p^-1 W_m^T, in (C, C, 9, 9)
    # blocks; dense, as random points couple most cameras
    Y = W @ Vinv[pi]
    k, m = np.nonzero(pi[:, None] == pi[None, :])
    blocks = np.zeros((C, C, 9, 9))
    blocks[np.arange(C), np.arange(C)] = U
    np.add.at(blocks, (ci[k], ci[m]), s_sign * Y[k] @ W[m].transpose(0, 2, 1))
    rhs = -g_cam.copy()
    np.add.at(rhs, ci, rhs_sign * (Y @ g_point[pi][:, :, None])[:, :, 0])
    S = blocks.transpose(0, 2, 1, 3).reshape(9 * C, 9 * C)
    dx_cam = scipy.linalg.solve(S, rhs.ravel(), assume_a="sym").reshape(C, 9)
    back = -g_point.copy()
    np.add.at(back, pi, back_sign * (W.transpose(0, 2, 1) @ dx_cam[ci][:, :, None])[:, :, 0])
    dx_point = (Vinv @ back[:, :, None])[:, :, 0]
    return {"dx_cam": dx_cam, "dx_point": dx_point}


#: the largest reduced system (9C unknowns) whose slips are worked out: a slip shows on the small problem's
#: calls already, and the five dense solves of the 112-camera call were most of a grading run's oracle time
SLIP_UNKNOWNS = 500


def schur_mistakes(call, ref):
    known = {name: [] for name in ref}
    if 9 * len(call.args[0]) > SLIP_UNKNOWNS:
        return known
    for slip, text in (({"damp_v": False}, "the damping is added to V as well as U, before the elimination: "
                                           "S = U + D_c - W (V + D_p)^-1 W^T"),
                       ({"damp_u": False}, "the damping D_c is missing from the camera blocks U"),
                       ({"s_sign": 1.0}, "S = U - W V^-1 W^T: the coupling term is subtracted"),
                       ({"rhs_sign": -1.0}, "the reduced right-hand side is -g_cam + W V^-1 g_point"),
                       ({"back_sign": 1.0}, "back-substitution: dx_point = V^-1 (-g_point - W^T dx_cam)")):
        try:
            # a slip may leave S singular to rounding (no D_c: the gauge): its step is rounding noise, which
            # no student reproduces and which differs from run to run; such a slip is no known answer
            with warnings.catch_warnings():
                warnings.simplefilter("error", scipy.linalg.LinAlgWarning)
                outputs = schur(call, **slip)
        except (np.linalg.LinAlgError, scipy.linalg.LinAlgWarning):
            continue
        for name, value in outputs.items():
            if not np.allclose(value, ref[name], rtol=1e-9, atol=1e-14):
                known[name].append((value, text))
    return known


MISTAKES = {
    f"{RESIDUALS}: residuals r": residual_mistakes,
    f"{RESIDUALS}: camera Jacobian J_cam": residual_mistakes,
    f"{RESIDUALS}: point Jacobian J_point": residual_mistakes,
    f"{NORMAL}: camera blocks U, point blocks V, coupling W": normal_mistakes,
    f"{NORMAL}: gradients and chi2": normal_mistakes,
    f"{SCHUR}: camera step from the reduced system": schur_mistakes,
    f"{SCHUR}: point step by back-substitution": schur_mistakes,
}
