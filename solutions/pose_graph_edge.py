"""Chapter 2 exercise: the error of one 2D pose-graph edge and its Jacobians.

Inputs at the edges of the contract (each is a check input):
- raw angle error theta_j - theta_i - theta_ij exactly pi: e_theta = -pi
- raw angle error exactly -pi: e_theta = -pi

Allowed imports: numpy, scipy.
"""

import numpy as np


def edge_error_and_jacobians(x_i, x_j, z_ij):
    """Error ``e_ij`` (3,) and Jacobians ``A_ij = de/dx_i``, ``B_ij = de/dx_j`` (3, 3).

    Poses and the measurement are ``(x, y, theta)``; the measurement is pose j seen
    from pose i. With ``t = (x, y)`` and ``R(theta)`` the 2D rotation::

        e_t     = R_ij^T (R_i^T (t_j - t_i) - t_ij)
        e_theta = wrap(theta_j - theta_i - theta_ij)      wrapped to [-pi, pi): pi wraps to -pi

    Derive ``A_ij`` and ``B_ij`` yourself: the derivatives of ``e`` in the ordinary coordinates
    ``(x, y, theta)`` of each pose (the poses are updated by plain addition), rows ``(e_t, e_theta)``,
    columns ``(x, y, theta)``. The grader compares values, so any correct way of writing them
    scores. ``course.geometry.se2.wrap_angle`` wraps angles.
    ``python -m autograder hint edge_error_and_jacobians 1`` (then 2, 3) if you are stuck.
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


#: the derived results, in three levels (``python -m autograder hint NAME LEVEL``; the release
#: prints levels 1..N into the docstrings with ``--hints N``, course.core.hints)
HINTS = {
    "edge_error_and_jacobians": (
        """Differentiate ``e_t`` and ``e_theta`` by each of the six coordinates in turn. ``e_t`` is
        linear in ``t_i`` and ``t_j`` (a constant matrix times ``t_j - t_i``) and depends on
        ``theta_i`` only through ``R_i^T``; it does not depend on ``theta_j`` at all. ``e_theta`` is
        a difference of angles (the wrap is constant almost everywhere). Write A and B as 2x2,
        2x1, 1x2 and 1x1 blocks.""",
        """The derivative of a 2D rotation's transpose is again a rotation-like matrix::

            R(theta)^T = [[cos, sin], [-sin, cos]]    d R^T / d theta = [[-sin, cos], [-cos, -sin]]

        so ``d e_t / d theta_i = R_ij^T (dR_i^T/dtheta_i) (t_j - t_i)``, and ``d e_t / d t_j =
        R_ij^T R_i^T`` = ``-d e_t / d t_i``.""",
        """::

            A_ij = [[-R_ij^T R_i^T,  R_ij^T dR_i^T/dtheta_i (t_j - t_i)],
                    [ 0    0,        -1                               ]]
            B_ij = [[ R_ij^T R_i^T,  0],
                    [ 0    0,        1]]

        with ``dR^T/dtheta = [[-sin, cos], [-cos, -sin]]``.""",
    ),
}
