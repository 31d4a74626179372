# RELEASE: omit
"""Known mistakes in ``pose_graph_3d`` (see ``autograder.mistakes``): the SE(3) edge written
with one slip, and the retraction in the wrong frame or off the manifold."""

import numpy as np

from autograder.checks.pose_graph_3d import DIFFERENCES, EDGE_ERRORS, RETRACT
from course.geometry.so3 import exp_many, log_many, right_jacobian, right_jacobian_inverse_many, skew


def _vee_of_skew_part(M):
    """``vee((M - M^T) / 2)`` (K, 3): ``sin(theta) u``, Log's small-angle stand-in."""
    return np.stack([M[:, 2, 1] - M[:, 1, 2], M[:, 0, 2] - M[:, 2, 0], M[:, 1, 0] - M[:, 0, 1]], axis=1) / 2.0


def edge(args, *, translation="right", rotation="right", log="exact", jr="inverse", a_phi="right",
         d_sign=1.0, a_rho="local", b_rho="right"):
    """``(e, A, B)`` of the edges with one slip or none (keyword = the part written wrong)."""
    t, R, ei, ej, t_z, R_z = (np.asarray(a) for a in args)
    Ri, Rj = R[ei], R[ej]
    RiT, RzT = Ri.transpose(0, 2, 1), R_z.transpose(0, 2, 1)
    d = np.einsum("mab,mb->ma", RiT, t[ej] - t[ei])
    D_R = RzT @ RiT @ Rj
    e = np.empty((len(ei), 6))
    e[:, :3] = {"right": lambda: np.einsum("mab,mb->ma", RzT, d - t_z),
                "unrotated": lambda: d - t_z,
                "world": lambda: t[ej] - t[ei] - t_z}[translation]()
    rot = {"right": D_R, "measurement_last": RiT @ Rj @ RzT, "reversed": Rj.transpose(0, 2, 1) @ Ri @ R_z}[rotation]
    e[:, 3:] = log_many(rot) if log == "exact" else _vee_of_skew_part(rot)
    phi = e[:, 3:]
    if jr == "inverse":
        J = right_jacobian_inverse_many(phi)
    elif jr == "none":
        J = np.tile(np.eye(3), (len(ei), 1, 1))
    else:  # the Jacobian itself, not its inverse
        J = np.array([right_jacobian(p) for p in phi])
    A, B = np.zeros((len(ei), 6, 6)), np.zeros((len(ei), 6, 6))
    A[:, :3, :3] = -RzT if a_rho == "local" else -RzT @ RiT
    A[:, :3, 3:] = d_sign * RzT @ skew(d)
    A[:, 3:, 3:] = -J @ Rj.transpose(0, 2, 1) @ Ri if a_phi == "right" else -J
    B[:, :3, :3] = D_R if b_rho == "right" else np.tile(np.eye(3), (len(ei), 1, 1))
    B[:, 3:, 3:] = J
    return e, A, B


def edge_mistakes(call, ref):
    if call.where.endswith(DIFFERENCES):  # the moved inputs: feedback names the first call's mistakes
        return {}
    known = {"e": [], "A": [], "B": []}
    slips = (
        ({"translation": "unrotated"}, {"e": "the translation error is rotated into the measurement's frame: "
                                              "e_t = R_z^T (R_i^T (t_j - t_i) - t_z)"}),
        ({"translation": "world"}, {"e": "t_j - t_i is in the world frame: bring it into pose i's frame with "
                                         "R_i^T before comparing it with t_z"}),
        ({"rotation": "measurement_last"}, {"e": "the measurement's inverse comes first: "
                                                 "D_R = R_z^T (R_i^T R_j), not (R_i^T R_j) R_z^T"}),
        ({"rotation": "reversed"}, {"e": "e_phi has the opposite sign: Log(R_z^T R_i^T R_j), not its inverse"}),
        ({"log": "skew"}, {"e": "vee((D - D^T)/2) is sin(theta) u, equal to Log(D) only for small angles: "
                                "use the full Log (so3.log_many)"}),
        ({"jr": "none"}, {"A": "the inverse right Jacobian J_r^-1(e_phi) is missing (exact only when e_phi = 0)",
                          "B": "the inverse right Jacobian J_r^-1(e_phi) is missing (exact only when e_phi = 0)"}),
        ({"jr": "forward"}, {"A": "J_r(e_phi) where J_r^-1(e_phi) belongs: Log(D Exp(d)) = Log(D) + J_r^-1 d",
                             "B": "J_r(e_phi) where J_r^-1(e_phi) belongs: Log(D Exp(d)) = Log(D) + J_r^-1 d"}),
        ({"a_phi": "plain"}, {"A": "moving pose i by Exp(phi) turns D_R by Exp(-R_j^T R_i phi): "
                                   "d e_phi / d phi_i = -J_r^-1 R_j^T R_i"}),
        ({"d_sign": -1.0}, {"A": "d e_t / d phi_i = +R_z^T [d]x (from Exp(-phi) d = d - phi x d = d + d x phi)"}),
        ({"a_rho": "world"}, {"A": "the step moves t by R rho (in the pose's frame): d e_t / d rho_i = -R_z^T"}),
        ({"b_rho": "identity"}, {"B": "the step moves t_j by R_j rho: d e_t / d rho_j = R_z^T R_i^T R_j"}),
    )
    for slip, texts in slips:
        outputs = dict(zip(("e", "A", "B"), edge(call.args, **slip)))
        for name, text in texts.items():
            known[name].append((outputs[name], text))
    known["e"].append((-np.asarray(ref["e"]), "e has the opposite sign: the error of D = Z^-1 T_i^-1 T_j"))
    for name in ("A", "B"):
        known[name].append((-np.asarray(ref[name]), f"{name} has the opposite sign"))
    return known


def retract_mistakes(call, ref):
    t, R, delta = (np.asarray(a, dtype=float) for a in call.args)
    rho, phi = delta[:, :3], delta[:, 3:]
    R_right, R_left = np.matmul(R, exp_many(phi)), np.matmul(exp_many(phi), R)
    t_local = t + np.einsum("nab,nb->na", R, rho)
    return {
        "t": [(t + rho, "the step is in the pose's frame: t + R rho, not t + rho"),
              (t + np.einsum("nab,nb->na", R_right, rho), "rotate rho by the pose's rotation before the step "
                                                          "(R, not R Exp(phi))")],
        "R": [(R_left, "the step multiplies on the right: R Exp(phi), not Exp(phi) R"),
              (np.matmul(R, exp_many(-phi)), "R Exp(phi), not R Exp(-phi)"),
              (R + np.matmul(R, skew(phi)), "R (I + [phi]x) is not a rotation: use R Exp(phi)")],
    } if t_local.shape == np.shape(ref["t"]) else {}


MISTAKES = {
    f"{EDGE_ERRORS}: error e": edge_mistakes,
    f"{EDGE_ERRORS}: Jacobian A = de/d delta_i": edge_mistakes,
    f"{EDGE_ERRORS}: Jacobian B = de/d delta_j": edge_mistakes,
    f"{RETRACT}: the retraction T (+) delta": retract_mistakes,
}
