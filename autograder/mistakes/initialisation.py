# RELEASE: omit
"""Known mistakes in ``initialisation`` (see ``autograder.mistakes``): each initialiser
written plainly (a loop over the edges, dense least squares) with one slip or none."""

from collections import deque

import numpy as np

from autograder.checks.common import wrap
from autograder.checks.initialisation import ROTATIONS, TRANSLATIONS, TREE


def _rotation(a):
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, -s], [s, c]])


def tree(num_poses, ei, ej, z, anchor_pose, anchor=0, *, backward="inverse", compose="se2", root="anchor"):
    """Poses along the breadth-first tree (each vertex by the first edge in edge order from the
    previous depth), with one slip or none."""
    neighbours = [[] for _ in range(num_poses)]
    for k, (i, j) in enumerate(zip(ei, ej)):
        neighbours[i].append((k, j, True))
        neighbours[j].append((k, i, False))
    depth = {anchor: 0}
    queue = deque([anchor])
    while queue:
        u = queue.popleft()
        for _, v, _ in sorted(neighbours[u]):
            if v not in depth:
                depth[v] = depth[u] + 1
                queue.append(v)
    poses = np.zeros((num_poses, 3))
    poses[anchor] = anchor_pose if root == "anchor" else 0.0
    for v in sorted(depth, key=depth.get):
        if v == anchor:
            continue
        options = sorted((k, u, fwd) for k, u, fwd in ((k, u, not f) for k, u, f in neighbours[v])
                         if depth[u] == depth[v] - 1)
        k, u, fwd = options[0]
        dz = np.array(z[k], dtype=float)
        if not fwd:
            if backward == "inverse":
                dz = np.array([*(-_rotation(dz[2]).T @ dz[:2]), -dz[2]])
            elif backward == "negated":
                dz = -dz
            elif backward == "rotated":
                dz = np.array([*(-_rotation(dz[2]) @ dz[:2]), -dz[2]])
        x = poses[u]
        if compose == "se2":
            xy = x[:2] + _rotation(x[2]) @ dz[:2]
        else:  # added in the world frame
            xy = x[:2] + dz[:2]
        theta = x[2] + dz[2]
        poses[v] = [*xy, wrap(theta)]
    return poses


def tree_mistakes(call, ref):
    args, anchor = call.args, call.kwargs.get("anchor", 0)
    if args[0] == 1:  # a single pose: every slip gives the anchor as it is
        return {"value": []}

    def slip(**kwargs):
        return tree(*args, anchor=anchor, **kwargs)

    return {"value": [
        (slip(backward="same"), "an edge walked backwards (from j to i) composes inverse(z_ij), not z_ij: "
                                "x_i = x_j (+) inverse(z_ij)"),
        (slip(backward="negated"), "inverse(z) is not -z: inverse(dx, dy, da) = (-R(da)^T (dx, dy), -da)"),
        (slip(compose="added"), "the measurement's translation is in pose i's frame: x_j = x_i (+) z_ij "
                                "rotates it by R(theta_i) before adding it"),
        (slip(root="origin"), "the tree starts from the origin: the anchor is at anchor_pose"),
        (slip(backward="rotated"), "inverse(dx, dy, da) rotates by R(da)^T: (-R(da)^T (dx, dy), -da), not "
                                   "(-R(da) (dx, dy), -da)"),
    ]}


def rotations(num_poses, ei, ej, z, info, anchor_theta, anchor=0, *, relation="right", weight="rotation",
              anchored=True, project="atan2"):
    """Chordal theta by dense least squares on (c, s), with one slip or none."""
    n = num_poses
    rows, rhs = [], []
    w = {"rotation": info[:, 2, 2], "none": np.ones(len(ei)), "translation": info[:, 0, 0]}[weight]
    for k, (i, j) in enumerate(zip(ei, ej)):
        R = _rotation(z[k, 2])
        if relation == "transposed":
            R = R.T
        a, b = (i, j) if relation != "swapped" else (j, i)
        block = np.zeros((2, 2 * n))
        block[:, 2 * b:2 * b + 2] = np.eye(2)
        block[:, 2 * a:2 * a + 2] = -R
        rows.append(np.sqrt(w[k]) * block)
        rhs.append(np.zeros(2))
    A, y = np.vstack(rows), np.concatenate(rhs)
    held = np.array([np.cos(anchor_theta), np.sin(anchor_theta)]) if anchored else np.array([1.0, 0.0])
    free = np.ones(2 * n, dtype=bool)
    free[2 * anchor:2 * anchor + 2] = False
    v = np.zeros(2 * n)
    v[~free] = held
    v[free] = np.linalg.lstsq(A[:, free], y - A[:, ~free] @ held, rcond=None)[0]
    c, s = v[0::2], v[1::2]
    theta = np.arctan2(s, c) if project == "atan2" else np.arctan(s / c)
    theta[anchor] = anchor_theta  # the anchor as given, whatever the slip
    return theta


def rotation_mistakes(call, ref):
    args, anchor = call.args, call.kwargs.get("anchor", 0)
    if args[0] == 1:  # a single pose: every slip gives the anchor as it is
        return {"value": []}

    def slip(**kwargs):
        return rotations(*args, anchor=anchor, **kwargs)

    return {"value": [
        (slip(relation="transposed"), "the relative rotation is transposed, or R_j is where R_i belongs (the same "
                                      "thing): an edge says R_j = R_i R_ij, so v_j - R(theta_ij) v_i = 0 "
                                      "(v = (cos, sin))"),
        (slip(weight="none"), "the edges are not weighted: w_k = information[k, 2, 2] multiplies edge k's terms"),
        (slip(weight="translation"), "the rotation weight is information[k, 2, 2], not information[k, 0, 0]"),
        (slip(anchored=False), "the anchor's (c, s) is (cos anchor_theta, sin anchor_theta): here the anchor is at "
                               "angle 0"),
        (slip(project="arctan"), "theta = arctan(s / c) loses the quadrant (c < 0): use atan2(s, c)"),
    ]}


def translations(num_poses, ei, ej, z, info, theta, anchor_xy, anchor=0, *, weight="rotated", lever="R_i",
                 sign=1.0, anchored=True):
    """Positions by dense weighted least squares given theta, with one slip or none."""
    n = num_poses
    H, g = np.zeros((2 * n, 2 * n)), np.zeros(2 * n)
    for k, (i, j) in enumerate(zip(ei, ej)):
        om = info[k, :2, :2]
        R = {"rotated": _rotation(theta[i] + z[k, 2]), "R_i only": _rotation(theta[i])}.get(weight, np.eye(2))
        W = np.eye(2) if weight == "none" else R @ om @ R.T
        c = {"R_i": _rotation(theta[i]), "R_j": _rotation(theta[j]), "none": np.eye(2)}[lever] @ z[k, :2] * sign
        si, sj = slice(2 * i, 2 * i + 2), slice(2 * j, 2 * j + 2)
        H[si, si] += W
        H[sj, sj] += W
        H[si, sj] -= W
        H[sj, si] -= W
        g[si] -= W @ c
        g[sj] += W @ c
    free = np.ones(2 * n, dtype=bool)
    free[2 * anchor:2 * anchor + 2] = False
    held = np.asarray(anchor_xy, dtype=float) if anchored else np.zeros(2)
    t = np.zeros(2 * n)
    t[~free] = held
    t[free] = np.linalg.solve(H[np.ix_(free, free)], g[free] - H[np.ix_(free, ~free)] @ held)
    return t.reshape(-1, 2)


def translation_mistakes(call, ref):
    args, anchor = call.args, call.kwargs.get("anchor", 0)
    if args[0] == 1:  # a single pose: every slip gives the anchor as it is
        return {"value": []}

    def slip(**kwargs):
        return translations(*args, anchor=anchor, **kwargs)

    return {"value": [
        (slip(weight="unrotated"), "Omega_tt weighs the error in the measurement's frame: in the world frame it is "
                                   "W = R Omega_tt R^T with R = R(theta_i + theta_ij)"),
        (slip(weight="R_i only"), "W rotates Omega_tt by R(theta_i + theta_ij) (the error is R_ij^T R_i^T r), "
                                  "not by R(theta_i) alone"),
        (slip(weight="none"), "the edges are not weighted: each residual's weight is W = R Omega_tt R^T"),
        (slip(lever="none"), "t_ij is in pose i's frame: the residual is t_j - t_i - R(theta_i) t_ij"),
        (slip(lever="R_j"), "R_j where R_i belongs: the residual is t_j - t_i - R(theta_i) t_ij"),
        (slip(sign=-1.0), "the residual's sign: r = t_j - t_i - R(theta_i) t_ij (t_j is where t_i plus the "
                          "rotated measurement lands)"),
        (slip(anchored=False), "the anchor is at anchor_xy, not at the origin"),
    ]}


MISTAKES = {
    f"{TREE}: poses along the breadth-first tree": tree_mistakes,
    f"{ROTATIONS}: theta by the chordal relaxation": rotation_mistakes,
    f"{TRANSLATIONS}: positions given the rotations": translation_mistakes,
}
