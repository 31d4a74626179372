"""The factor library: residuals written once, for numpy arrays, Jets and JAX.

Each residual ``r(z, *values)`` takes the measurements ``z`` (M, *measurement shape) and its
variables' values (M, *shape), and uses ``course.factorgraph.jetmath`` for everything that touches a
value, so that the same source gives our values, our Jets' derivatives and JAX's
(``course.backends.factorgraph.jax_factors`` traces it as it is). Every residual is "predicted minus
measured", in the tangent coordinates of ``course.factorgraph.variables`` (SE(3): translation first).

Priors and betweens on every kind of variable (:func:`prior`, :func:`between`)::

    Vector(n)   prior  x - z                        between  (x_j - x_i) - z
    SE2         prior  between from the origin      between  [R_z^T (R_i^T (t_j - t_i) - t_z);
                                                              wrap(theta_j - theta_i - theta_z)]
    SO3         prior  Log(Z^T R)                   between  Log(Z^T R_i^T R_j)
    SE3         prior  between from the identity    between  [R_z^T (R_i^T (t_j - t_i) - t_z);
                                                              Log(R_z^T R_i^T R_j)]

(``z`` for SO(3) a rotation (3, 3); for SE(3) a stored pose (12,): t, then R row by row.)

Measurements of a landmark ``l`` from a pose ``x`` (``d = t_l - t_x``):

- ``RANGE_2D`` (SE2, Vector2), ``RANGE_3D`` (SE3, Vector3): ``|d| - z``, ``z`` (1,);
- ``BEARING_2D`` (SE2, Vector2): ``wrap(atan2(d_y, d_x) - theta - z)``, ``z`` (1,);
- ``BEARING_3D`` (SE3, Vector3): the direction ``u = R^T d / |d|`` in the pose's frame against the measured
  unit vector ``z`` (3,), in a basis ``(b1, b2)`` of the plane orthogonal to ``z`` (made from ``z`` alone):
  ``r = (b1 . u, b2 . u)`` (2,), 0 where ``u = z`` (GTSAM's ``BearingFactor3D``: a ``Unit3`` error in its own basis);
- ``RANGE_BEARING`` (SE2, Vector2): both, ``z = (range, bearing)``;
- ``POSITION_2D`` (SE2), ``GPS`` (SE3): the pose's position ``t - z``, ``z`` (2,) or (3,) (GTSAM's
  ``GPSFactor``: the body's origin, no lever arm);
- ``PINHOLE`` (SE3 camera pose, Vector3 point): the camera looks along its z axis, ``x`` its pose in the
  world (GTSAM's ``PinholeCamera``); ``P = R^T (X - t)``, ``z = (u, v, fx, fy, cx, cy)`` (6,) the pixel and
  the calibration: ``r = (fx P_x / P_z + cx - u, fy P_y / P_z + cy - v)``;
- ``POINT_TO_PLANE`` (SE3): ICP's error of a point ``p`` of the moving scan against the plane of a
  target point ``q`` with normal ``n``, ``z = (p, q, n)`` (9,): ``r = n . (R p + t - q)`` (1,).

The course's problems: ``BETWEEN_SE2`` (chapter 2's edge), ``BETWEEN_SE3`` (chapter 6's), and
``REPROJECTION_BAL``, chapter 4's observation of a point (Vector3) by a BAL camera (Vector9,
``(w, t, f, k1, k2)``, updated by plain addition), ``z`` the observed pixel (2,)::

    P = R(w) X + t,  p = -P[:2] / P[2],  r = f (1 + k1 |p|^2 + k2 |p|^4) p - z
"""

import functools

import numpy as np

from course.factorgraph import jetmath as jm
from course.factorgraph.factor_type import FactorType
from course.factorgraph.variables import BAL_CAMERA, SE2, SE3, SO3, Vector, se3_parts

# ---------------------------------------------------------------- between and prior residuals


def between_vector(z, xi, xj):
    return xj - xi - z


def prior_vector(z, x):
    return x - z


def between_se2(z, xi, xj):
    ci, si = jm.cos(xi[..., 2]), jm.sin(xi[..., 2])
    cz, sz = jm.cos(z[..., 2]), jm.sin(z[..., 2])
    dx, dy = xj[..., 0] - xi[..., 0], xj[..., 1] - xi[..., 1]
    u = ci * dx + si * dy - z[..., 0]  # R_i^T (t_j - t_i) - t_z
    v = -si * dx + ci * dy - z[..., 1]
    return jm.stack([cz * u + sz * v, -sz * u + cz * v,
                     jm.wrap_angle(xj[..., 2] - xi[..., 2] - z[..., 2])], axis=-1)


def prior_se2(z, x):
    return between_se2(z, np.zeros(z.shape[:-1] + (3,)), x)


def between_so3(z, Ri, Rj):
    return jm.so3_log(jm.transpose(z) @ (jm.transpose(Ri) @ Rj))


def prior_so3(z, R):
    return jm.so3_log(jm.transpose(z) @ R)


def between_se3(z, xi, xj):
    t_z, R_z = se3_parts(z)
    t_i, R_i = se3_parts(xi)
    t_j, R_j = se3_parts(xj)
    # R_z^T R_i^T = (R_i R_z)^T: one product fewer on Jets, none when x_i is a constant
    A_T = jm.transpose(R_i @ R_z)
    e_t = jm.matvec(A_T, t_j - t_i) - jm.matvec(jm.transpose(R_z), t_z)
    e_phi = jm.so3_log(A_T @ R_j)
    return jm.concatenate([e_t, e_phi])


def prior_se3(z, x):
    origin = np.zeros(z.shape[:-1] + (12,))
    origin[..., 3:] = np.eye(3).ravel()
    return between_se3(z, origin, x)


# ---------------------------------------------------------------- landmarks, positions, cameras, planes


def range_2d(z, x, landmark):
    dx, dy = landmark[..., 0] - x[..., 0], landmark[..., 1] - x[..., 1]
    return jm.stack([jm.sqrt(dx * dx + dy * dy) - z[..., 0]], axis=-1)


def range_3d(z, x, landmark):
    t, _ = se3_parts(x)
    return jm.stack([jm.sqrt(jm.squared_norm3(landmark - t)) - z[..., 0]], axis=-1)


def bearing_2d(z, x, landmark):
    dx, dy = landmark[..., 0] - x[..., 0], landmark[..., 1] - x[..., 1]
    return jm.stack([jm.wrap_angle(jm.arctan2(dy, dx) - x[..., 2] - z[..., 0])], axis=-1)


def bearing_3d(z, x, landmark):
    t, R = se3_parts(x)
    P = jm.matvec(jm.transpose(R), landmark - t)
    u = P / jm.sqrt(jm.squared_norm3(P))[..., None]
    # a basis (b1, b2) of the plane orthogonal to the measured direction z, from z alone
    helper = jm.where((jm.value_of(z[..., 0]) ** 2 < 0.5)[..., None], np.array([1.0, 0.0, 0.0]),
                      np.array([0.0, 1.0, 0.0]))
    b1 = jm.cross(z, helper)
    b1 = b1 / jm.sqrt(jm.squared_norm3(b1))[..., None]
    b2 = jm.cross(z, b1)
    return jm.stack([jm.dot3(b1, u), jm.dot3(b2, u)], axis=-1)


def range_bearing(z, x, landmark):
    dx, dy = landmark[..., 0] - x[..., 0], landmark[..., 1] - x[..., 1]
    return jm.stack([jm.sqrt(dx * dx + dy * dy) - z[..., 0],
                     jm.wrap_angle(jm.arctan2(dy, dx) - x[..., 2] - z[..., 1])], axis=-1)


def position_2d(z, x):
    return x[..., :2] - z


def gps(z, x):
    return x[..., :3] - z


def pinhole(z, x, point):
    t, R = se3_parts(x)
    P = jm.matvec(jm.transpose(R), point - t)
    inverse_depth = 1.0 / P[..., 2]
    return jm.stack([z[..., 2] * P[..., 0] * inverse_depth + z[..., 4] - z[..., 0],
                     z[..., 3] * P[..., 1] * inverse_depth + z[..., 5] - z[..., 1]], axis=-1)


def point_to_plane(z, x):
    t, R = se3_parts(x)
    p, q, n = z[..., 0:3], z[..., 3:6], z[..., 6:9]
    return jm.stack([jm.dot3(n, jm.matvec(R, p) + t - q)], axis=-1)


def reprojection_bal(z, camera, point):
    P = jm.so3_rotate(camera[..., :3], point) + camera[..., 3:6]
    minus_inverse_depth = -1.0 / P[..., 2]  # one division, two products: fewer Jet operations
    px, py = P[..., 0] * minus_inverse_depth, P[..., 1] * minus_inverse_depth
    n2 = px**2 + py**2
    scale = camera[..., 6] * (1.0 + camera[..., 7] * n2 + camera[..., 8] * n2**2)
    return jm.stack([scale * px - z[..., 0], scale * py - z[..., 1]], axis=-1)


# ---------------------------------------------------------------- the factor types

BETWEEN_SE2 = FactorType("between_se2", (SE2, SE2), 3, between_se2)
BETWEEN_SO3 = FactorType("between_so3", (SO3, SO3), 3, between_so3)
BETWEEN_SE3 = FactorType("between_se3", (SE3, SE3), 6, between_se3)
PRIOR_SE2 = FactorType("prior_se2", (SE2,), 3, prior_se2)
PRIOR_SO3 = FactorType("prior_so3", (SO3,), 3, prior_so3)
PRIOR_SE3 = FactorType("prior_se3", (SE3,), 6, prior_se3)
RANGE_2D = FactorType("range_2d", (SE2, Vector(2)), 1, range_2d)
RANGE_3D = FactorType("range_3d", (SE3, Vector(3)), 1, range_3d)
BEARING_2D = FactorType("bearing_2d", (SE2, Vector(2)), 1, bearing_2d)
BEARING_3D = FactorType("bearing_3d", (SE3, Vector(3)), 2, bearing_3d)
RANGE_BEARING = FactorType("range_bearing", (SE2, Vector(2)), 2, range_bearing)
POSITION_2D = FactorType("position_2d", (SE2,), 2, position_2d)
GPS = FactorType("gps", (SE3,), 3, gps)
PINHOLE = FactorType("pinhole", (SE3, Vector(3)), 2, pinhole)
POINT_TO_PLANE = FactorType("point_to_plane", (SE3,), 1, point_to_plane)
REPROJECTION_BAL = FactorType("reprojection_bal", (BAL_CAMERA, Vector(3)), 2, reprojection_bal)

_BY_KIND = {SE2: (PRIOR_SE2, BETWEEN_SE2), SO3: (PRIOR_SO3, BETWEEN_SO3), SE3: (PRIOR_SE3, BETWEEN_SE3)}


@functools.cache
def _vector_factors(kind) -> tuple:
    """The prior and the between of a vector kind, made once (a factor type is known by identity)."""
    return (FactorType(f"prior_{kind.name.lower()}", (kind,), kind.dim, prior_vector),
            FactorType(f"between_{kind.name.lower()}", (kind, kind), kind.dim, between_vector))


def _factors_of(kind) -> tuple:
    if kind in _BY_KIND:
        return _BY_KIND[kind]
    if isinstance(kind, Vector):
        return _vector_factors(kind)
    raise ValueError(f"no prior or between factor for variables of kind {getattr(kind, 'name', kind)!r}: "
                     "the library has them for Vector(n), SE2, SO3 and SE3")


def prior(kind) -> FactorType:
    """The prior factor type of a variable kind (``prior(SE3) is PRIOR_SE3``; ``prior(Vector(3))`` the
    same object at every call): the variable against a measured value ``z`` of its kind's shape."""
    return _factors_of(kind)[0]


def between(kind) -> FactorType:
    """The between factor type of a variable kind: variable ``j`` seen from variable ``i``, ``z`` a value
    of the kind's shape (a rotation (3, 3) for SO3, a stored pose (12,) for SE3)."""
    return _factors_of(kind)[1]
