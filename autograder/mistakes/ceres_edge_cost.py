# RELEASE: omit
"""Known mistakes in ``ceres_edge_cost.SE2EdgeCost`` (see ``autograder.mistakes``)."""

import numpy as np

from autograder.checks.ceres_edge_cost import CERES


def ceres_mistakes(call, ref):
    from autograder.reference import solutions_module

    z, U, x_i, x_j = (np.asarray(v, dtype=float) for v in call.args)
    e, A, B = solutions_module("pose_graph_edge").edge_error_and_jacobians(x_i, x_j, z)
    omega = U.T @ U
    raw = np.array(e, dtype=float)
    raw[2] = x_j[2] - x_i[2] - z[2]
    upper = np.triu(U)
    return {
        "r": [(upper @ e, "only U's upper triangle is used: U is any square root of Omega (U^T U = Omega), not "
                          "always triangular; r = U e with every entry of U"),
              (e, "r is the unwhitened error e: r = U e (sqrt_information times e), so that r^T r = e^T Omega e"),
              (omega @ e, "multiply e by the square root U, not by Omega = U^T U"),
              (U.T @ e, "r = U e, not U^T e"),
              (-U @ e, "r has the opposite sign: r = U e with e = (pose j seen from pose i) - z_ij"),
              (U @ raw, "the angle error is not wrapped to [-pi, pi)")],
        "J_i": [(A, "the Jacobian is not whitened: jacobians[0] = U A (row-major), A = de/dx_i"),
                (omega @ A, "whiten with U, not Omega: jacobians[0] = U A"),
                (U.T @ A, "jacobians[0] = U A, not U^T A"),
                ((U @ A).T, "jacobians[0] is filled column-major: Ceres reads it row-major, "
                            "jacobians[0][:] = (U @ A).ravel()"),
                (-U @ A, "jacobians[0] has the opposite sign: U de/dx_i")],
        "J_j": [(B, "the Jacobian is not whitened: jacobians[1] = U B (row-major), B = de/dx_j"),
                (omega @ B, "whiten with U, not Omega: jacobians[1] = U B"),
                (U.T @ B, "jacobians[1] = U B, not U^T B"),
                ((U @ B).T, "jacobians[1] is filled column-major: Ceres reads it row-major, "
                            "jacobians[1][:] = (U @ B).ravel()"),
                (-U @ B, "jacobians[1] has the opposite sign: U de/dx_j")],
    }


MISTAKES = {
    f"{CERES}: residuals r = U e": ceres_mistakes,
    f"{CERES}: jacobians U A, U B": ceres_mistakes,
}
