"""Chapter 2 exercise: the error of one 2D pose-graph edge and its Jacobians.

Inputs at the edges of the contract (each is a check input):
- raw angle error theta_j - theta_i - theta_ij exactly pi: e_theta = -pi
- raw angle error exactly -pi: e_theta = -pi
"""

import numpy as np


def edge_error_and_jacobians(x_i, x_j, z_ij):
    """Error ``e_ij`` (3,) and Jacobians ``A_ij = de/dx_i``, ``B_ij = de/dx_j`` (3, 3).

    Poses and the measurement are ``(x, y, theta)``; the measurement is pose j seen
    from pose i. With ``t = (x, y)`` and ``R(theta)`` the 2D rotation::

        e_t     = R_ij^T (R_i^T (t_j - t_i) - t_ij)
        e_theta = wrap(theta_j - theta_i - theta_ij)      wrapped to [-pi, pi): pi wraps to -pi

        A_ij = [[-R_ij^T R_i^T,  R_ij^T dR_i^T/dtheta_i (t_j - t_i)],
                [ 0    0,        -1                               ]]
        B_ij = [[ R_ij^T R_i^T,  0],
                [ 0    0,        1]]

    Hint: ``dR^T/dtheta = [[-sin, cos], [-cos, -sin]]``; ``course.geometry.se2.wrap_angle``
    wraps angles.
    """
    # BEGIN SOLUTION
    x_i, x_j, z_ij = (np.asarray(v, dtype=float) for v in (x_i, x_j, z_ij))
    ci, si = np.cos(x_i[2]), np.sin(x_i[2])
    cz, sz = np.cos(z_ij[2]), np.sin(z_ij[2])
    Ri_T = np.array([[ci, si], [-si, ci]])
    Rz_T = np.array([[cz, sz], [-sz, cz]])
    dRi_T = np.array([[-si, ci], [-ci, -si]])
    dt = x_j[:2] - x_i[:2]
    e = np.empty(3)
    e[:2] = Rz_T @ (Ri_T @ dt - z_ij[:2])
    e[2] = (x_j[2] - x_i[2] - z_ij[2] + np.pi) % (2.0 * np.pi) - np.pi
    A = np.zeros((3, 3))
    A[:2, :2] = -Rz_T @ Ri_T
    A[:2, 2] = Rz_T @ dRi_T @ dt
    A[2, 2] = -1.0
    B = np.zeros((3, 3))
    B[:2, :2] = Rz_T @ Ri_T
    B[2, 2] = 1.0
    return e, A, B
    # END SOLUTION
