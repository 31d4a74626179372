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
    raise NotImplementedError("TODO pose_graph_edge.edge_error_and_jacobians: not implemented yet")
