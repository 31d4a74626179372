"""Tangent conventions beside GTSAM's and Ceres', and the converters a port needs.

A covariance or an information matrix is only meaningful in the coordinates of the residual (or
tangent) it belongs to. Where the libraries order or perturb differently, a matrix copied as it is
weighs the wrong components: a GTSAM ``BetweenFactorPose3`` noise model given to our ``BETWEEN_SE3``
puts the rotation's sigmas on the translation.

- **SE(3) pose.** Ours: tangent ``(rho, phi)``, translation first; ``(t + R rho, R Exp(phi))`` (on
  the right). GTSAM ``Pose3``: ``(omega, v)``, rotation first; ``x Exp(xi)`` (on the right; to first
  order ``(R Exp(omega), t + R v)``, the same motion as ours in the other order). Ceres: no pose
  type; a ``ProductManifold`` in the order its user builds it.
- **SO(3).** Ours and GTSAM's ``Rot3``: ``R Exp(phi)`` (right). Ceres' ``QuaternionManifold``:
  ``Exp(d) R`` (left; before Ceres 2.2, ``Exp(2 d) R``).
- **SE(2) pose.** Ours: ``(x, y, theta) + delta`` (global, as chapter 2). GTSAM ``Pose2``: the same
  order in the body frame (``t + R v``). Ceres' pose-graph example: plain addition, angle wrapped.
- **Between residuals.** Ours (SE(3)): ``[R_z^T (R_i^T (t_j - t_i) - t_z); Log(R_z^T R_i^T R_j)]``,
  translation first. GTSAM: ``Logmap(z^-1 x_i^-1 x_j)``, ``(omega, v)``, rotation first. 2D: the
  same order in both.

Near a minimum GTSAM's ``Pose3`` between error and ours agree to first order up to the order of
their two halves, so an information matrix ports by swapping its 3x3 blocks
(:func:`from_gtsam_pose3`); a 2D ``Pose2`` between error is ours in the same order (no change).
"""

import numpy as np

#: ours -> GTSAM's order of an SE(3) tangent or between residual: (rho, phi) -> (omega, v)
POSE3_ORDER = np.array([3, 4, 5, 0, 1, 2])


def _swap_pose3(matrix) -> np.ndarray:
    M = np.asarray(matrix, dtype=float)
    if M.shape[-2:] != (6, 6):
        raise ValueError(f"an SE(3) covariance or information matrix is (..., 6, 6), got shape {M.shape}")
    return M[..., POSE3_ORDER, :][..., :, POSE3_ORDER]


def from_gtsam_pose3(matrix) -> np.ndarray:
    """A GTSAM ``Pose3`` covariance or information matrix (..., 6, 6), rotation first, in our order
    (translation first): ``P M P^T`` with the permutation that swaps the two 3x3 halves."""
    return _swap_pose3(matrix)


def to_gtsam_pose3(matrix) -> np.ndarray:
    """Ours (..., 6, 6), translation first, in GTSAM's ``Pose3`` order (rotation first)."""
    return _swap_pose3(matrix)


def from_ceres_quaternion_covariance(covariance, R, before_2_2: bool = False) -> np.ndarray:
    """A rotation's tangent covariance (3, 3) from Ceres' ``QuaternionManifold`` (left: ``Exp(d) R``;
    ``Exp(2 d) R`` before Ceres 2.2) in ours (``R Exp(phi)``, right): ``Exp(d) R = R Exp(R^T d)``, so
    ``phi = s R^T d`` with ``s`` 1 (2 before 2.2) and ``C = (s R^T) C_d (s R^T)^T``."""
    A = (2.0 if before_2_2 else 1.0) * np.asarray(R, dtype=float).T
    return A @ np.asarray(covariance, dtype=float) @ A.T
