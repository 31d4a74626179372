"""Checks of ``bundle_adjustment``: the BAL reprojection residuals and their Jacobians, the
block normal equations, and the Schur-complement step, each graded alone on a small
synthetic problem.

Public inputs: 4 cameras (one with a rotation of 1e-9 rad, the small-angle case) and 12
points, each seen by 2 to 4 cameras (observations shuffled), distortion that matters (|k1 p^2| about 0.1), observations
perturbed by pixel noise; for the normal equations and the Schur step, the reference
Jacobians of that problem (so each exercise is graded alone) and LM damping, passed as
arguments or already added to U and V; for the Schur step also a problem of 112 cameras and
224 points (S is 1008 x 1008: the reference solves it sparse). Hidden inputs: other problems
of the same kinds from the hidden seed.

The residual function is also called with every camera's parameter j (and every point's
coordinate i) moved by +h and -h: a wrong Jacobian's feedback then says whether it agrees
with central differences of the student's own r (the derivative is right for the model they
wrote: the model is wrong) or not (the derivative is wrong), and which columns differ. It also
says which factor of the chain rule is wrong: the data hold the reference's d predicted / d P,
d P / d w and d P / d X at call 0, and J_cam's t columns are the student's own d predicted / d P,
so a slip in that shared factor is told apart from one in the factors after it (``which_factor``).
"""

from functools import cache

import numpy as np

from autograder.checks import Call, Verdict
from autograder.checks.common import check, residual_or_jacobian, values
from autograder.checks.edges import Edge
from autograder.expected import FACTOR_PREFIX
from autograder.feedback import fields_of

MODULES = ("bundle_adjustment",)
RESIDUALS = "bundle_adjustment.reprojection_residuals_and_jacobians"
NORMAL = "bundle_adjustment.normal_equations"
SCHUR = "bundle_adjustment.schur_solve"

# ---------------------------------------------------------------- inputs


def _rotate(w, X):
    """Rodrigues: R(w) X for (K, 3) angle-axis vectors and points."""
    theta = np.linalg.norm(w, axis=1, keepdims=True)
    with np.errstate(invalid="ignore", divide="ignore"):
        k = np.where(theta > 0, w / theta, 0.0)
    c, s = np.cos(theta), np.sin(theta)
    return X * c + np.cross(k, X) * s + k * np.sum(k * X, axis=1, keepdims=True) * (1 - c)


@cache
def problem(seed=None, large=False):
    """A small BAL problem: ``cameras`` (C, 9), ``points`` (P, 3), ``camera_index``,
    ``point_index`` (K,), ``observations`` (K, 2); every point seen by 2 to 4 cameras, every
    point in front of every camera that sees it (P_z < 0 in the BAL convention). ``large``: 112
    cameras (9C above the reference's dense limit: its sparse branch) and 224 points, point p seen
    by camera p mod 112 among others (every camera sees 2 points or more)."""
    if large:
        rng = np.random.default_rng(67 if seed is None else [seed, 267])
        num_cameras, num_points = 112, 224
    else:
        rng = np.random.default_rng(61 if seed is None else [seed, 261])
        num_cameras, num_points = 4, 12
    cameras = np.zeros((num_cameras, 9))
    cameras[:, :3] = rng.normal(0, 0.3, (num_cameras, 3))
    cameras[0, :3] = rng.normal(0, 1e-9, 3)  # the small-angle case
    cameras[:, 3:5] = rng.normal(0, 0.5, (num_cameras, 2))
    cameras[:, 5] = -rng.uniform(8.0, 12.0, num_cameras)
    cameras[:, 6] = rng.uniform(400.0, 600.0, num_cameras)
    cameras[:, 7] = rng.uniform(-8.0, 8.0, num_cameras)
    cameras[:, 8] = rng.uniform(-40.0, 40.0, num_cameras)
    points = rng.normal(0, 1.5, (num_points, 3))
    pairs = []
    for p in range(num_points):
        seen = rng.choice(num_cameras, int(rng.integers(2, 5)), replace=False)
        if large and p % num_cameras not in seen:
            seen[0] = p % num_cameras
        pairs += [(int(c), p) for c in sorted(seen)]
    pairs = [pairs[k] for k in rng.permutation(len(pairs))]  # observations in no particular order
    return _observed(cameras, points, pairs, rng)


def _cameras(rng, num_cameras):
    """Cameras 8 to 12 units behind the origin (every point of N(0, 1.5) in front), distortion that matters."""
    cameras = np.zeros((num_cameras, 9))
    cameras[:, :3] = rng.normal(0, 0.3, (num_cameras, 3))
    cameras[:, 3:5] = rng.normal(0, 0.5, (num_cameras, 2))
    cameras[:, 5] = -rng.uniform(8.0, 12.0, num_cameras)
    cameras[:, 6] = rng.uniform(400.0, 600.0, num_cameras)
    cameras[:, 7] = rng.uniform(-8.0, 8.0, num_cameras)
    cameras[:, 8] = rng.uniform(-40.0, 40.0, num_cameras)
    return cameras


def _observed(cameras, points, pairs, rng):
    """The problem with observations ``pairs`` (camera, point): projections plus pixel noise."""
    ci, pi = (np.array(v, dtype=np.int64) for v in zip(*pairs))
    P = _rotate(cameras[ci, :3], points[pi]) + cameras[ci, 3:6]
    p = -P[:, :2] / P[:, 2:]
    r2 = np.sum(p * p, axis=1, keepdims=True)
    predicted = cameras[ci, 6:7] * (1 + cameras[ci, 7:8] * r2 + cameras[ci, 8:9] * r2**2) * p
    observations = predicted + rng.normal(0, 2.0, predicted.shape)
    return {"cameras": cameras, "points": points, "camera_index": ci, "point_index": pi,
            "observations": observations}


#: |w| of the edge problem's camera 1: nearly pi
NEAR_PI = np.pi - 1e-3


@cache
def edge_problem(seed=None, one=False):
    """The edges of the contract. ``one``: one camera, one point, one observation (K = 1). Else 4
    cameras and 6 points: camera 0 not rotated at all (w = 0 exactly), camera 1 rotated by pi - 1e-3,
    camera 3 (the last) sees no point; point 0 is seen by camera 0 alone, point 5 (the last) by none,
    points 1 to 4 by 2 or 3 of cameras 0 to 2."""
    rng = np.random.default_rng(63 if seed is None else [seed, 265])
    if one:
        cameras = _cameras(rng, 1)
        return _observed(cameras, rng.normal(0, 1.5, (1, 3)), [(0, 0)], rng)
    cameras = _cameras(rng, 4)
    cameras[0, :3] = 0.0
    axis = rng.normal(size=3)
    cameras[1, :3] = NEAR_PI * axis / np.linalg.norm(axis)
    points = rng.normal(0, 1.5, (6, 3))
    pairs = [(0, 0)]
    for p in range(1, 5):
        pairs += [(int(c), p) for c in sorted(rng.choice(3, int(rng.integers(2, 4)), replace=False))]
    pairs = [pairs[k] for k in rng.permutation(len(pairs))]
    return _observed(cameras, points, pairs, rng)


def _edge_where(g) -> str:
    if len(g["cameras"]) == 1:
        return "on one camera, one point and one observation (K = 1)"
    return ("on a problem of 4 cameras (camera 0 not rotated, w = 0 exactly; camera 1 rotated by pi - 1e-3 rad; "
            "camera 3 sees no point) and 6 points (point 0 seen by camera 0 alone, point 5 by none), "
            f"{len(g['camera_index'])} observations")


def _edge_groups(g) -> dict:
    if len(g["cameras"]) == 1:
        return {}
    ci = g["camera_index"]
    return {"seen by camera 0, whose rotation is exactly 0 (the small-angle branch at 0)":
            tuple(int(k) for k in np.flatnonzero(ci == 0)),
            "seen by camera 1, rotated by pi - 1e-3 rad": tuple(int(k) for k in np.flatnonzero(ci == 1))}


def _where(g) -> str:
    return (f"on a problem of {len(g['cameras'])} cameras (camera 0 rotated by 1e-9 rad), {len(g['points'])} "
            f"points and {len(g['camera_index'])} observations")


#: the camera parameters (J_cam's columns) and the point coordinates (J_point's), as feedback names them
CAMERA_COLUMNS = ("w_x", "w_y", "w_z", "t_x", "t_y", "t_z", "f", "k1", "k2")
POINT_COLUMNS = ("X", "Y", "Z")
#: J_cam's blocks of columns, for feedback
CAMERA_BLOCKS = (("the rotation columns (w)", slice(0, 3)), ("the translation columns (t)", slice(3, 6)),
                 ("the focal-length column (f)", slice(6, 7)), ("the distortion columns (k1, k2)", slice(7, 9)))
POINT_BLOCKS = (("the X column", slice(0, 1)), ("the Y column", slice(1, 2)), ("the Z column", slice(2, 3)))
#: the reference's factors of the Jacobians at call 0, which the instructor's data holds under these names
#: (d predicted / d P (K, 2, 3), d P / d w (K, 3, 3), d P / d X = R(w) (K, 3, 3)): feedback says which factor
#: a wrong Jacobian goes wrong through
FACTORS = tuple(FACTOR_PREFIX + name for name in ("d predicted / d P", "d P / d w", "d P / d X"))
#: relative step of the central differences
STEP = 1e-6
#: what the moved calls' ``where`` ends with (their known mistakes are not needed: feedback names call 0's)
DIFFERENCES = "(for central differences of r)"


def steps(values):
    """The step per column of ``values`` (N, n): ``STEP max(1, max |column|)``."""
    return STEP * np.maximum(1.0, np.max(np.abs(values), axis=0))


def _residual_calls(seed=None):
    """The residuals at the problem, then (for central differences) with every camera's
    parameter j moved by +-h_j, then every point's coordinate i by +-h_i: 1 + 2 (9 + 3) calls."""
    g = problem(seed)
    target = f"bundle_adjustment:{RESIDUALS.split('.')[1]}"
    cameras, points = g["cameras"], g["points"]
    rest = (g["camera_index"], g["point_index"], g["observations"])
    small = tuple(int(k) for k in np.flatnonzero(g["camera_index"] == 0))
    groups = {"seen by camera 0, whose rotation is 1e-9 rad (the small-angle case)": small}
    calls = [Call(target, (cameras, points, *rest), returns=("r", "J_cam", "J_point"), where=_where(g),
                  groups=groups)]
    for what, base, names in (("camera", cameras, CAMERA_COLUMNS), ("point", points, POINT_COLUMNS)):
        for column, h in enumerate(steps(base)):
            for sign in (1.0, -1.0):
                moved = base.copy()
                moved[:, column] += sign * h
                args = (moved, points) if what == "camera" else (cameras, moved)
                calls.append(Call(target, (*args, *rest), returns=("r", "J_cam", "J_point"),
                                  where=_where(g) + f", every {what}'s {names[column]} {'+' if sign > 0 else '-'} "
                                                    f"{h:.3g} {DIFFERENCES}"))
    for e in (edge_problem(seed), edge_problem(seed, one=True)):  # the edges, after the differences' calls
        calls.append(Call(target, (e["cameras"], e["points"], e["camera_index"], e["point_index"],
                                   e["observations"]), returns=("r", "J_cam", "J_point"), where=_edge_where(e),
                          groups=_edge_groups(e)))
    return calls


@cache
def linearized(seed=None, large=False, edge=None):
    """The reference residuals and Jacobians of ``problem(seed, large)`` (``edge``: of ``edge_problem(seed,
    one=edge)``) (instructor side: inside a calls builder)."""
    from autograder import reference

    g = problem(seed, large) if edge is None else edge_problem(seed, one=edge)
    f = reference.solutions_module("bundle_adjustment").reprojection_residuals_and_jacobians
    return f(g["cameras"], g["points"], g["camera_index"], g["point_index"], g["observations"])


def _normal_calls(seed=None):
    g = problem(seed)
    r, J_cam, J_point = linearized(seed)
    args = (r, J_cam, J_point, g["camera_index"], g["point_index"], len(g["cameras"]), len(g["points"]))
    calls = [Call(f"bundle_adjustment:{NORMAL.split('.')[1]}", args, returns=("U", "V", "W", "g_cam", "g_point",
                                                                             "chi2"),
                  where=_where(g) + ", at the reference r and Jacobians")]
    for one in (False, True):
        e = edge_problem(seed, one=one)
        args = (*linearized(seed, edge=one), e["camera_index"], e["point_index"], len(e["cameras"]), len(e["points"]))
        calls.append(Call(f"bundle_adjustment:{NORMAL.split('.')[1]}", args,
                          returns=("U", "V", "W", "g_cam", "g_point", "chi2"),
                          where=_edge_where(e) + ", at the reference r and Jacobians"))
    return calls


def _schur_calls(seed=None):
    """The Schur step of the small problem at two LM dampings, then at the second with the damping already
    added to U and V (no damping arguments), then of the large problem (112 cameras)."""
    from autograder import reference

    normal = reference.solutions_module("bundle_adjustment").normal_equations
    target = f"bundle_adjustment:{SCHUR.split('.')[1]}"
    rng = np.random.default_rng(5 if seed is None else [seed, 263])
    # without damping, S is singular: bundle adjustment has a 7-dimensional gauge freedom
    lams = (1e-2, 1.0) if seed is None else (10.0 ** float(rng.uniform(-3, -1)), float(rng.uniform(0.5, 2)))
    small, large = ((g, normal(*linearized(seed, big), g["camera_index"], g["point_index"], len(g["cameras"]),
                               len(g["points"])))
                    for big, g in ((False, problem(seed)), (True, problem(seed, True))))
    calls = []
    for (g, (U, V, W, g_cam, g_point, _)), lam, folded in (
            (small, lams[0], False), (small, lams[1], False), (small, lams[1], True), (large, lams[1], False)):
        dc, dp = lam * np.einsum("cii->ci", U), lam * np.einsum("pii->pi", V)
        rest = (W, g_cam, g_point, g["camera_index"], g["point_index"])
        if folded:  # the damping added by the caller
            U, V = U.copy(), V.copy()
            U[:, np.arange(9), np.arange(9)] += dc
            V[:, np.arange(3), np.arange(3)] += dp
            calls.append(Call(target, (U, V, *rest), returns=("dx_cam", "dx_point"),
                              where=_where(g) + f", U and V with lambda diag(H) added (lambda = {lam:.3g}), "
                                                "no damping arguments"))
        else:
            calls.append(Call(target, (U, V, *rest), {"damping_cam": dc, "damping_point": dp},
                              returns=("dx_cam", "dx_point"),
                              where=_where(g) + f", reference U, V, W, g; LM damping lambda diag(H), "
                                                f"lambda = {lam:.3g}"))
    # the edges: a point seen once (V_p of rank 2, definite through the damping alone), a camera that sees no
    # point and a point seen by none (their blocks are the damping alone: lambda max(diag(H), 1e-6))
    e = edge_problem(seed)
    U, V, W, g_cam, g_point, _ = normal(*linearized(seed, edge=False), e["camera_index"], e["point_index"],
                                        len(e["cameras"]), len(e["points"]))
    dc = EDGE_LAMBDA * np.maximum(np.einsum("cii->ci", U), 1e-6)
    dp = EDGE_LAMBDA * np.maximum(np.einsum("pii->pi", V), 1e-6)
    calls.append(Call(target, (U, V, W, g_cam, g_point, e["camera_index"], e["point_index"]),
                      {"damping_cam": dc, "damping_point": dp}, returns=("dx_cam", "dx_point"),
                      where=_edge_where(e) + f", reference U, V, W, g; damping lambda max(diag(H), 1e-6), "
                                             f"lambda = {EDGE_LAMBDA:g}"))
    return calls


#: the damping of the Schur step's edge problem: V_p of its point seen once is definite through it alone
EDGE_LAMBDA = 1e-2  # large enough that the step is fixed to 1e-12 (at 1e-4, rounding moved it by 2e-9)


# ---------------------------------------------------------------- judges


def _values(names, rtol, atol, labels, cause):
    return values(names, rtol, atol, cause, labels, atol_scaled=True)


def own_differences(ctx, name: str):
    """The central differences of the student's own r (K, 2, n) for the Jacobian ``name``, from
    the calls that move the cameras (J_cam) or the points (J_point); None when a call failed."""
    first, count = (1, len(CAMERA_COLUMNS)) if name == "J_cam" else (1 + 2 * len(CAMERA_COLUMNS), len(POINT_COLUMNS))
    h = steps(ctx.calls[0].args[0 if name == "J_cam" else 1])  # as the calls moved them
    columns = []
    for column in range(count):
        k = first + 2 * column
        (plus, bad_plus), (minus, bad_minus) = (fields_of(ctx.student[k], ctx.calls[k]),
                                                fields_of(ctx.student[k + 1], ctx.calls[k + 1]))
        if bad_plus or bad_minus or "r" not in plus or "r" not in minus:
            return None
        r_plus, r_minus = np.asarray(plus["r"], float), np.asarray(minus["r"], float)
        if r_plus.shape != r_minus.shape or r_plus.ndim != 2:
            return None
        columns.append((r_plus - r_minus) / (2.0 * h[column]))
    return np.stack(columns, axis=-1)


def _residual_or_jacobian(name, blocks, judge):
    """``common.residual_or_jacobian`` for BA: blocks of columns, differences of the student's r."""
    return residual_or_jacobian(name, [(text, (Ellipsis, cols)) for text, cols in blocks], judge, own_differences,
                                "r", "the residuals check", "model")


def which_factor(ctx) -> str:
    """Which factor of the chain rule the student's J_cam and J_point go wrong through, or "".

    J_cam's t columns are the student's d predicted / d P itself (d P / d t = I). When it is wrong
    and, times the reference's d P / d w and d P / d X, it gives the student's rotation columns and
    J_point, both Jacobians go wrong through that one shared factor; when it is right, the factors
    after it are named instead.
    """
    known = ctx.known(0)
    if any(len(known.get(name, ())) != 1 for name in FACTORS) or ctx.student[0].error is not None:
        return ""
    A, dP_dw, R = (np.asarray(known[name][0][0], float) for name in FACTORS)
    (student, bad), (reference, _) = fields_of(ctx.student[0], ctx.calls[0]), fields_of(ctx.reference[0], ctx.calls[0])
    if bad or "J_cam" not in student or "J_point" not in student:
        return ""
    J_cam, J_point = np.asarray(student["J_cam"], float), np.asarray(student["J_point"], float)
    K = len(A)
    if J_cam.shape != (K, 2, 9) or J_point.shape != (K, 2, 3) or not (np.isfinite(J_cam).all() and np.isfinite(
            J_point).all()):
        return ""

    def same(got, want):
        return np.allclose(got, want, rtol=1e-6, atol=1e-8 * max(1.0, float(np.max(np.abs(want)))))

    mine = J_cam[:, :, 3:6]  # the student's d predicted / d P
    rotation_follows, point_follows = same(J_cam[:, :, :3], mine @ dP_dw), same(J_point, mine @ R)
    if not same(mine, A):
        if not (rotation_follows and point_follows):
            return ""
        columns = [f"d predicted / d P_{axis}" for a, axis in enumerate("xyz") if not same(mine[:, :, a], A[:, :, a])]
        k, i, j = (int(v) for v in np.unravel_index(int(np.argmax(np.abs(mine - A))), A.shape))
        return ("\nWhich factor: J_cam and J_point both go wrong through the factor they share, d predicted / d P "
                "(projection and distortion): your J_cam's t columns are that factor (d P / d t = I), and times the "
                "reference's d P / d w and d P / d X = R(w) it gives your rotation columns and your J_point. In it, "
                f"{' and '.join(columns)} {'differs' if len(columns) == 1 else 'differ'} (observation {k}: "
                f"[{i}, {j}] = {mine[k, i, j]:.6g}, expected {A[k, i, j]:.6g}).")
    wrong = []
    if not rotation_follows:
        wrong.append("d P / d w (J_cam's rotation columns are d predicted / d P times d(R(w) X)/dw)")
    if not point_follows:
        wrong.append("d P / d X = R(w) (J_point is d predicted / d P times R(w))")
    if not same(J_cam[:, :, 6:], np.asarray(reference["J_cam"], float)[:, :, 6:]):
        wrong.append("d predicted / d (f, k1, k2) (J_cam's last three columns, which do not go through P)")
    if not wrong:
        return ""
    return "\nWhich factor: your d predicted / d P (J_cam's t columns) is right; " + "; and ".join(wrong) + " is not."


def _with_factor(judge):
    """``judge``, with what ``which_factor`` says added to a wrong Jacobian's feedback."""

    def judged(ctx):
        verdict = judge(ctx)
        if verdict.fraction >= 1.0 or verdict.not_implemented:
            return verdict
        said = which_factor(ctx)
        return Verdict(verdict.fraction, verdict.message + said, verdict.not_implemented) if said else verdict

    return judged


_RES_LABELS = {"r": "r[{}]", "J_cam": "J_cam[{}]", "J_point": "J_point[{}]"}
_NORMAL_LABELS = {"U": "U[{}]", "V": "V[{}]", "W": "W[{}]", "g_cam": "g_cam[{}]", "g_point": "g_point[{}]",
                  "chi2": "chi2"}
_SCHUR_LABELS = {"dx_cam": "dx_cam[{}]", "dx_point": "dx_point[{}]"}

CHECKS = [
    check(RESIDUALS, "residuals r", 2, _residual_calls, _values(("r",), 1e-8, 1e-10, _RES_LABELS,
          "r = f d p - observed with P = R(w) X + t, p = -P[:2] / P[2], d = 1 + k1 |p|^2 + k2 |p|^4")),
    check(RESIDUALS, "camera Jacobian J_cam", 3, _residual_calls, _with_factor(_residual_or_jacobian(
        "J_cam", CAMERA_BLOCKS, _values(("J_cam",), 1e-6, 1e-8, _RES_LABELS,
                                                 "J_cam[k] = d r_k / d (w, t, f, k1, k2), the exact derivative of "
                                                 "R(w) X in w")))),
    check(RESIDUALS, "point Jacobian J_point", 2, _residual_calls, _with_factor(_residual_or_jacobian(
        "J_point", POINT_BLOCKS, _values(("J_point",), 1e-6, 1e-8, _RES_LABELS,
                                                    "J_point[k] = d r_k / d X = (d predicted / d P) R(w)")))),
    check(NORMAL, "camera blocks U, point blocks V, coupling W", 3, _normal_calls,
          _values(("U", "V", "W"), 1e-10, 1e-12, _NORMAL_LABELS,
                 "U_c = sum J_cam^T J_cam over camera c's observations, V_p likewise, W_k = J_cam_k^T J_point_k")),
    check(NORMAL, "gradients and chi2", 2, _normal_calls,
          _values(("g_cam", "g_point", "chi2"), 1e-10, 1e-12, _NORMAL_LABELS,
                 "g_cam_c = sum J_cam^T r, g_point_p = sum J_point^T r, chi2 = sum r^T r")),
    check(SCHUR, "camera step from the reduced system", 3, _schur_calls,
          _values(("dx_cam",), 1e-7, 1e-10, _SCHUR_LABELS,
                 "S = U + D_c - sum W (V + D_p)^-1 W^T, S dx_cam = -g_cam + sum W (V + D_p)^-1 g_point")),
    check(SCHUR, "point step by back-substitution", 2, _schur_calls,
          _values(("dx_point",), 1e-7, 1e-10, _SCHUR_LABELS,
                 "dx_point_p = (V_p + D_p)^-1 (-g_point_p - sum W_k^T dx_cam)")),
]


# ---------------------------------------------------------------- the edges of the contract


def _rotation_norms(call):
    cameras, ci = np.asarray(call.args[0], float), np.asarray(call.args[2])
    return np.linalg.norm(cameras[np.unique(ci), :3], axis=1)


def _counts(call, which):
    """How many observations each camera (``which = "camera"``) or point has, in a normal_equations or
    schur_solve call."""
    if call.target.endswith("normal_equations"):
        index, count = (call.args[3], call.args[5]) if which == "camera" else (call.args[4], call.args[6])
    else:
        index, count = (call.args[5], len(call.args[0])) if which == "camera" else (call.args[6], len(call.args[1]))
    return np.bincount(np.asarray(index), minlength=count)


_R_TARGET = f"bundle_adjustment:{RESIDUALS.split('.')[1]}"
_N_TARGET = f"bundle_adjustment:{NORMAL.split('.')[1]}"
_S_TARGET = f"bundle_adjustment:{SCHUR.split('.')[1]}"


def _damped_once(call) -> bool:
    """A point seen once whose V_p (rank 2) is definite through the damping alone."""
    once = _counts(call, "point") == 1
    return bool(np.any(once)) and "damping_point" in call.kwargs and bool(np.all(call.kwargs["damping_point"] > 0))


EDGES = (
    Edge("reprojection_residuals_and_jacobians: a camera not rotated at all (w = 0 exactly)", _R_TARGET,
         lambda c: bool(np.any(_rotation_norms(c) == 0.0))),
    Edge("reprojection_residuals_and_jacobians: a camera rotated by nearly pi (|w| = pi - 1e-3)", _R_TARGET,
         lambda c: bool(np.any(np.abs(_rotation_norms(c) - np.pi) <= 1e-2))),
    Edge("reprojection_residuals_and_jacobians: one observation (K = 1: one camera, one point)", _R_TARGET,
         lambda c: len(c.args[2]) == 1),
    Edge("normal_equations: one observation (K = 1)", _N_TARGET, lambda c: len(c.args[0]) == 1),
    Edge("normal_equations: a camera that sees no point, the last (U_c = 0, g_cam_c = 0)", _N_TARGET,
         lambda c: _counts(c, "camera")[-1] == 0),
    Edge("normal_equations: a point seen by no camera, the last (V_p = 0, g_point_p = 0)", _N_TARGET,
         lambda c: _counts(c, "point")[-1] == 0),
    Edge("normal_equations: a point seen by one camera (V_p of rank 2)", _N_TARGET,
         lambda c: bool(np.any(_counts(c, "point") == 1))),
    Edge("schur_solve: a point seen once, V_p of rank 2 made definite by the damping alone (lambda = 1e-2)",
         _S_TARGET, _damped_once),
    Edge("schur_solve: a camera that sees no point and a point seen by none (their blocks: the damping alone)",
         _S_TARGET, lambda c: bool(np.any(_counts(c, "camera") == 0) and np.any(_counts(c, "point") == 0))),
    Edge("schur_solve: the damping already in U and V (no damping arguments)", _S_TARGET,
         lambda c: "damping_cam" not in c.kwargs),
    Edge("schur_solve: 9C above DENSE_LIMIT (112 cameras: the sparse branch)", _S_TARGET,
         lambda c: 9 * len(c.args[0]) > 1000),
)
