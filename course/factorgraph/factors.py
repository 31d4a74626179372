"""The factor types of the course's problems, as residuals written once for arrays and Jets.

- ``BETWEEN_SE2``: chapter 2's edge, ``z = (x, y, theta)`` pose j seen from pose i::

      e = [R_z^T (R_i^T (t_j - t_i) - t_z);  wrap(theta_j - theta_i - theta_z)]

- ``BETWEEN_SE3``: chapter 6's edge, ``z`` an SE(3) value (12,)::

      e = [R_z^T (R_i^T (t_j - t_i) - t_z);  Log(R_z^T R_i^T R_j)]

- ``PRIOR_SE2``, ``PRIOR_SE3``: a pose against a measured one (the between error from the measured pose).
- ``RANGE_BEARING``: a 2D pose and a landmark (Vector2), ``z = (range, bearing)``.
- ``REPROJECTION_BAL``: chapter 4's observation of a point (Vector3) by a BAL camera (Vector9,
  ``(w, t, f, k1, k2)``, updated by plain addition), ``z`` the observed pixel (2,)::

      P = R(w) X + t,  p = -P[:2] / P[2],  r = f (1 + k1 |p|^2 + k2 |p|^4) p - z
"""

import numpy as np

from course.factorgraph import jetmath
from course.factorgraph.factor_type import FactorType
from course.factorgraph.variables import BAL_CAMERA, SE2, SE3, Vector, se3_parts


def between_se2(z, xi, xj):
    ci, si = np.cos(xi[..., 2]), np.sin(xi[..., 2])
    cz, sz = np.cos(z[..., 2]), np.sin(z[..., 2])
    dx, dy = xj[..., 0] - xi[..., 0], xj[..., 1] - xi[..., 1]
    u = ci * dx + si * dy - z[..., 0]  # R_i^T (t_j - t_i) - t_z
    v = -si * dx + ci * dy - z[..., 1]
    return np.stack([cz * u + sz * v, -sz * u + cz * v,
                     jetmath.wrap_angle(xj[..., 2] - xi[..., 2] - z[..., 2])], axis=-1)


def between_se3(z, xi, xj):
    t_z, R_z = se3_parts(z)
    t_i, R_i = se3_parts(xi)
    t_j, R_j = se3_parts(xj)
    # R_z^T R_i^T = (R_i R_z)^T: one product fewer on Jets, none when x_i is a constant
    A_T = jetmath.transpose(R_i @ R_z)
    e_t = jetmath.matvec(A_T, t_j - t_i) - jetmath.matvec(np.swapaxes(R_z, -1, -2), t_z)
    e_phi = jetmath.so3_log(A_T @ R_j)
    return _concatenate(e_t, e_phi)


def prior_se2(z, x):
    return between_se2(z, _origin_like(z, 3), x)


def prior_se3(z, x):
    origin = np.zeros(z.shape[:-1] + (12,))
    origin[..., 3:] = np.eye(3).ravel()
    return between_se3(z, origin, x)


def range_bearing(z, x, landmark):
    dx, dy = landmark[..., 0] - x[..., 0], landmark[..., 1] - x[..., 1]
    return np.stack([np.sqrt(dx * dx + dy * dy) - z[..., 0],
                     jetmath.wrap_angle(np.arctan2(dy, dx) - x[..., 2] - z[..., 1])], axis=-1)


def reprojection_bal(z, camera, point):
    P = jetmath.so3_rotate(camera[..., :3], point) + camera[..., 3:6]
    minus_inverse_depth = -1.0 / P[..., 2]  # one division, two products: fewer Jet operations
    px, py = P[..., 0] * minus_inverse_depth, P[..., 1] * minus_inverse_depth
    n2 = px**2 + py**2
    scale = camera[..., 6] * (1.0 + camera[..., 7] * n2 + camera[..., 8] * n2**2)
    return np.stack([scale * px - z[..., 0], scale * py - z[..., 1]], axis=-1)


def _origin_like(z, n):
    return np.zeros(z.shape[:-1] + (n,))


def _concatenate(a, b):
    return np.stack([a[..., i] for i in range(a.shape[-1])] + [b[..., i] for i in range(b.shape[-1])], axis=-1)


BETWEEN_SE2 = FactorType("between_se2", (SE2, SE2), 3, between_se2)
BETWEEN_SE3 = FactorType("between_se3", (SE3, SE3), 6, between_se3)
PRIOR_SE2 = FactorType("prior_se2", (SE2,), 3, prior_se2)
PRIOR_SE3 = FactorType("prior_se3", (SE3,), 6, prior_se3)
RANGE_BEARING = FactorType("range_bearing", (SE2, Vector(2)), 2, range_bearing)
REPROJECTION_BAL = FactorType("reprojection_bal", (BAL_CAMERA, Vector(3)), 2, reprojection_bal)
