"""SO(2)/SE(2) helpers, vectorized over leading axes.

A pose is ``(x, y, theta)``; arrays of poses have shape ``(..., 3)``.
Angles are wrapped to ``[-pi, pi)``.
"""

import numpy as np


def wrap_angle(theta):
    """Wrap angles (any shape) to ``[-pi, pi)``."""
    return (np.asarray(theta) + np.pi) % (2.0 * np.pi) - np.pi


def rotation(theta):
    """Rotation matrices ``R(theta)``, shape ``theta.shape + (2, 2)``."""
    theta = np.asarray(theta, dtype=float)
    c, s = np.cos(theta), np.sin(theta)
    return np.stack([np.stack([c, -s], -1), np.stack([s, c], -1)], -2)


def between(pose_i, pose_j):
    """Relative pose ``x_i^-1 o x_j`` (pose j in the frame of pose i), shape ``(..., 3)``."""
    pose_i, pose_j = np.asarray(pose_i, float), np.asarray(pose_j, float)
    c, s = np.cos(pose_i[..., 2]), np.sin(pose_i[..., 2])
    dx = pose_j[..., 0] - pose_i[..., 0]
    dy = pose_j[..., 1] - pose_i[..., 1]
    return np.stack(
        [c * dx + s * dy, -s * dx + c * dy, wrap_angle(pose_j[..., 2] - pose_i[..., 2])], -1
    )


def compose(pose_a, pose_b):
    """Composition ``x_a o x_b``, shape ``(..., 3)``."""
    pose_a, pose_b = np.asarray(pose_a, float), np.asarray(pose_b, float)
    c, s = np.cos(pose_a[..., 2]), np.sin(pose_a[..., 2])
    return np.stack(
        [
            pose_a[..., 0] + c * pose_b[..., 0] - s * pose_b[..., 1],
            pose_a[..., 1] + s * pose_b[..., 0] + c * pose_b[..., 1],
            wrap_angle(pose_a[..., 2] + pose_b[..., 2]),
        ],
        -1,
    )


def edge_errors(poses, i, j, z):
    """Pose-graph edge errors ``e_ij`` for all edges, shape ``(M, 3)``.

    ``e_ij = [R_ij^T (R_i^T (t_j - t_i) - t_ij); wrap(theta_j - theta_i - theta_ij)]``
    with ``poses (N, 3)``, ``i, j (M,)`` vertex indices and ``z (M, 3)`` measurements.
    This is the framework's trusted error, used to score every back end alike.
    """
    rel = between(poses[i], poses[j])
    c, s = np.cos(z[:, 2]), np.sin(z[:, 2])
    dx = rel[:, 0] - z[:, 0]
    dy = rel[:, 1] - z[:, 1]
    return np.stack([c * dx + s * dy, -s * dx + c * dy, wrap_angle(rel[:, 2] - z[:, 2])], -1)


def weighted_chi2(errors, info):
    """``sum_k e_k^T Omega_k e_k`` for ``errors (M, 3)`` and ``info (M, 3, 3)``."""
    return float(np.einsum("mi,mij,mj->", errors, info, errors))
