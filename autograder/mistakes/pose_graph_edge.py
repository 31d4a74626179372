# RELEASE: omit
"""Known mistakes in ``pose_graph_edge.edge_error_and_jacobians`` (see ``autograder.mistakes``)."""

import numpy as np

from autograder.checks.common import wrap
from autograder.checks.pose_graph_edge import EDGE


def rot(theta):
    c, s = np.cos(theta), np.sin(theta)
    return np.array([[c, -s], [s, c]])


def drot_t(theta):
    """d R(theta)^T / d theta."""
    c, s = np.cos(theta), np.sin(theta)
    return np.array([[-s, c], [-c, -s]])


def drot(theta):
    """d R(theta) / d theta (the derivative of the wrong matrix)."""
    c, s = np.cos(theta), np.sin(theta)
    return np.array([[-s, -c], [c, -s]])


def block(top_left, column, corner):
    M = np.zeros((3, 3))
    M[:2, :2] = top_left
    M[:2, 2] = column
    M[2, 2] = corner
    return M


def edge_parts(call):
    x_i, x_j, z = (np.asarray(v, dtype=float) for v in call.args[:3])
    dt = x_j[:2] - x_i[:2]
    return x_i, x_j, z, dt, rot(x_i[2]), rot(z[2])


def e_mistakes(call, ref):
    """Keys ``e_t`` (the first two entries of e) and ``e_theta`` (its angle)."""
    x_i, x_j, z, dt, Ri, Rz = edge_parts(call)
    raw = x_j[2] - x_i[2] - z[2]
    tz = z[:2]
    return {
        "e_t": [
            (Rz.T @ (Ri @ dt - tz), "R_i is used where R_i^T belongs (transposed rotation): "
                                    "e_t = R_ij^T (R_i^T (t_j - t_i) - t_ij)"),
            (Rz @ (Ri.T @ dt - tz), "R_ij is used where R_ij^T belongs (transposed rotation): "
                                    "e_t = R_ij^T (R_i^T (t_j - t_i) - t_ij)"),
            (Rz @ (Ri @ dt - tz), "both rotations are transposed: e_t = R_ij^T (R_i^T (t_j - t_i) - t_ij)"),
            (Ri.T @ dt - tz, "the outer R_ij^T is missing: e_t = R_ij^T (R_i^T (t_j - t_i) - t_ij)"),
            (-ref["e"][:2], "e_t has the opposite sign: e = (pose j seen from pose i) - z_ij"),
            (rot(x_j[2]).T @ dt - tz, "rotate t_j - t_i by pose i's angle: R_i^T, not R_j^T"),
            (Rz.T @ (Ri.T @ (x_i[:2] - x_j[:2]) - tz), "t_j - t_i, not t_i - t_j"),
        ],
        "e_theta": [
            (np.array(raw), "e_theta is not wrapped: wrap(theta_j - theta_i - theta_ij) to [-pi, pi), "
                            "e.g. with course.geometry.se2.wrap_angle"),
            (np.array(raw % (2 * np.pi)), "e_theta is wrapped to [0, 2 pi); wrap to [-pi, pi): "
                                          "(angle + pi) % (2 pi) - pi"),
            (-ref["e"][2], "e_theta has the opposite sign: wrap(theta_j - theta_i - theta_ij)"),
            (np.array(wrap(x_j[2] - x_i[2]) - z[2]), "wrap the whole difference theta_j - theta_i - "
                                                      "theta_ij, not only theta_j - theta_i"),
        ],
    }


def a_mistakes(call, ref):
    x_i, x_j, z, dt, Ri, Rz = edge_parts(call)
    A = ref["A"]
    column = Rz.T @ drot_t(x_i[2]) @ dt
    return {"A": [
        (-A, "A has the opposite sign: A = de/dx_i, with top-left block -R_ij^T R_i^T and A[2, 2] = -1"),
        (block(-Rz.T @ Ri, column, -1.0), "A's top-left block uses R_i instead of R_i^T (transposed "
                                          "rotation): it is -R_ij^T R_i^T"),
        (block(-Rz @ Ri.T, column, -1.0), "A's top-left block uses R_ij instead of R_ij^T: it is -R_ij^T R_i^T"),
        (block(-Rz @ Ri, Rz @ drot(x_i[2]) @ dt, -1.0),
         "the rotations in A are transposed: e uses R_ij^T and R_i^T, so A = [[-R_ij^T R_i^T, "
         "R_ij^T dR_i^T/dtheta (t_j - t_i)], [0, 0, -1]]"),
        (block(-Rz.T @ Ri.T, Rz.T @ drot(x_i[2]) @ dt, -1.0),
         "A[0:2, 2] uses dR_i/dtheta; e has R_i^T, so use dR_i^T/dtheta = [[-sin, cos], [-cos, -sin]]"),
        (block(-Rz.T @ Ri.T, -column, -1.0), "A[0:2, 2] has the opposite sign: "
                                             "dR^T/dtheta = [[-sin, cos], [-cos, -sin]]"),
        (block(-Rz.T @ Ri.T, drot_t(x_i[2]) @ dt, -1.0), "A[0:2, 2] lacks the factor R_ij^T: "
                                                         "R_ij^T dR_i^T/dtheta_i (t_j - t_i)"),
        (block(-Rz.T @ Ri.T, np.zeros(2), -1.0), "A[0:2, 2] is zero: e_t depends on theta_i through R_i^T, "
                                                 "its derivative is R_ij^T dR_i^T/dtheta_i (t_j - t_i)"),
        (block(-Ri.T, column, -1.0), "A's top-left block lacks R_ij^T: it is -R_ij^T R_i^T"),
        (block(-Rz.T @ Ri.T, column, 1.0), "A[2, 2] = d e_theta / d theta_i = -1"),
    ]}


def b_mistakes(call, ref):
    x_i, x_j, z, dt, Ri, Rz = edge_parts(call)
    B = ref["B"]
    return {"B": [
        (-B, "B has the opposite sign: B = de/dx_j = [[R_ij^T R_i^T, 0], [0, 0, 1]]"),
        (block(Rz.T @ Ri, np.zeros(2), 1.0), "B uses R_i instead of R_i^T (transposed rotation)"),
        (block(Rz @ Ri.T, np.zeros(2), 1.0), "B uses R_ij instead of R_ij^T (transposed rotation)"),
        (block(Rz @ Ri, np.zeros(2), 1.0), "the rotations in B are transposed: B's top-left block is R_ij^T R_i^T"),
        (block(Ri.T, np.zeros(2), 1.0), "B's top-left block lacks R_ij^T: it is R_ij^T R_i^T"),
        (block(Rz.T @ rot(x_j[2]).T, np.zeros(2), 1.0), "B rotates by pose j's angle: the error rotates "
                                                        "t_j - t_i by R_i^T, so B's block is R_ij^T R_i^T"),
    ]}


MISTAKES = {
    f"{EDGE}: e_t (translation error)": e_mistakes,
    f"{EDGE}: e_theta wrapped to [-pi, pi)": e_mistakes,
    f"{EDGE}: A values": a_mistakes,
    f"{EDGE}: B values": b_mistakes,
}
