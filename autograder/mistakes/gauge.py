# RELEASE: omit
"""Known mistakes in ``gauge`` (see ``autograder.mistakes``): the 7 directions written one
camera and one point at a time, with one slip or none."""

import numpy as np

from autograder.checks.gauge import DIRECTIONS
from course.geometry.so3 import skew, so3_exp


def _right_jacobian(w):
    theta = np.linalg.norm(w)
    W = skew(w)
    if theta < 1e-6:
        return np.eye(3) - 0.5 * W + W @ W / 6.0
    return (np.eye(3) - (1 - np.cos(theta)) / theta**2 * W + (theta - np.sin(theta)) / theta**3 * W @ W)


def directions(call, *, rotation="right", rot_sign=-1.0, cross="u x X", translation="R", scale_t=True,
               scale_f=False):
    """N (9C + 3P, 7) with one slip or none."""
    cameras, points = (np.asarray(a, dtype=float) for a in call.args)
    C, P = len(cameras), len(points)
    d_cam, d_point = np.zeros((7, C, 9)), np.zeros((7, P, 3))
    for axis in range(3):
        u = np.eye(3)[axis]
        for c in range(C):
            w = cameras[c, :3]
            J = {"right": _right_jacobian(w), "left": _right_jacobian(w).T, "none": np.eye(3)}[rotation]
            d_cam[axis, c, :3] = rot_sign * np.linalg.solve(J, u)
            R = so3_exp(w)
            d_cam[3 + axis, c, 3:6] = {"R": -R @ u, "none": 0.0, "plain": -u, "plus": R @ u}[translation]
        for p in range(P):
            d_point[axis, p] = np.cross(u, points[p]) if cross == "u x X" else np.cross(points[p], u)
            d_point[3 + axis, p] = u
    if scale_t:
        d_cam[6, :, 3:6] = cameras[:, 3:6]
    if scale_f:
        d_cam[6, :, 6] = cameras[:, 6]
    d_point[6] = points
    return np.concatenate([d_cam.reshape(7, -1), d_point.reshape(7, -1)], axis=1).T


def _known(call, ref):
    slips = [
        ({"rot_sign": 1.0}, "the cameras turn against the scene: dw = -J_r(w)^-1 u_a (R becomes R exp(-e [u_a]_x))"),
        ({"rotation": "none"}, "dw = -u_a holds only at w = 0: multiply by J_r(w)^-1, the inverse right "
                               "Jacobian of the angle axis"),
        ({"rotation": "left"}, "J_l(w)^-1 = J_r(w)^-T is the left Jacobian's inverse: R(w + dw) = R(w) exp([J_r dw]_x) "
                               "needs the right one"),
        ({"cross": "X x u"}, "the point moves by u_a x X (not X x u_a) when the scene turns about u_a"),
        ({"translation": "none"}, "a camera must move with the scene: dt = -R(w) u_a, so that R X + t stays"),
        ({"translation": "plain"}, "t is in the camera's frame: dt = -R(w) u_a, not -u_a"),
        ({"translation": "plus"}, "R (X + u_a) + t' = R X + t needs dt = -R(w) u_a, not +R(w) u_a"),
        ({"scale_t": False}, "scaling the scene scales every translation too: dt = t"),
        ({"scale_f": True}, "the intrinsics (f, k1, k2) do not change with the scene's scale: f d p is "
                            "scale-free"),
    ]
    return {"value": [(directions(call, **slip), why) for slip, why in slips]}


MISTAKES = {f"{DIRECTIONS}: {title}": _known
            for title in ("translation directions", "rotation directions", "scale direction")}
