"""Chapter 4, going further: the gauge freedom of bundle adjustment.

Move the whole scene by a similarity (rotate it by Q, shift it by s, scale it by k) and
move every camera with it: every reprojection stays the same, so the cost cannot tell
the two apart. These 7 directions span the null space of the Jacobian J (K 2, 9C + 3P),
so ``H = J^T J`` has 7 zero eigenvalues (up to rounding) and undamped Gauss-Newton meets
a singular system. Fixing 7 of the unknowns (``BundleAdjustmentProblem(fix_gauge=True)``)
or damping removes them.

The state is ``x = concat(cameras.ravel(), points.ravel())`` (9C + 3P,) as in
``bundle_adjustment`` (camera = angle-axis w, t, f, k1, k2; the unknowns are updated by
addition); a direction is a tangent vector of x.

Inputs at the edges of the contract (each is a check input):
- a camera not rotated at all (w = 0 exactly)
- a camera rotated by nearly pi (|w| = pi - 1e-3)
- one camera and one point (C = P = 1)

Allowed imports: numpy, scipy, course.geometry.so3.
"""

import numpy as np

from course.geometry.so3 import skew

#: below this |w| the coefficient of J_r(w)^-1 uses its Taylor series
SMALL_ANGLE = 1e-4


def gauge_directions(cameras, points):
    """The 7 infinitesimal similarities of the scene as columns of ``N`` (9C + 3P, 7).

    Args: cameras (C, 9), points (P, 3). Column ``m`` is the derivative at ``e = 0`` of the state
    ``x(e)`` of the scene moved by the m-th one-parameter similarity below, ``dx/de`` (9C + 3P,),
    each camera moving with the scene so that every reprojection stays the same:

    - 0, 1, 2: rotation of the scene about the world origin by the angle ``e`` about axis a (the
      unit vector ``u_a``): ``X -> Exp(e u_a) X``; every camera keeps each point's camera-frame
      coordinates ``R(w) X + t``;
    - 3, 4, 5: translation of the scene by ``e u_a``: ``X -> X + e u_a``; every camera keeps
      ``R(w) X + t``;
    - 6: scaling about the origin: ``X -> (1 + e) X``; every camera keeps its rotation and scales
      ``R(w) X + t`` by ``1 + e`` (the projection divides it out).

    f, k1, k2 never move. Derive the change of each camera's ``w`` and ``t`` and of each point
    (``python -m autograder hint gauge_directions 1``, then 2 and 3). The right Jacobian ``J_r`` of the
    angle axis is defined by ``R(w + dw) = R(w) Exp(J_r(w) dw)`` to first order; with ``theta = |w|``,
    ``W = [w]_x``, its inverse is::

        J_r(w)^-1 = I + W / 2 + (1 / theta^2 - (1 + cos theta) / (2 theta sin theta)) W^2

    where the last coefficient is ``1/12 + theta^2 / 720`` near theta = 0 (below
    ``SMALL_ANGLE``). ``R(w) u`` is Rodrigues' formula (``bundle_adjustment``'s docstring).
    """
    # BEGIN SOLUTION
    cameras = np.asarray(cameras, dtype=float)
    points = np.asarray(points, dtype=float)
    C, P = len(cameras), len(points)
    w = cameras[:, :3]
    t2 = np.sum(w * w, axis=1)
    theta = np.sqrt(t2)
    small = theta < SMALL_ANGLE
    safe = np.where(small, 1.0, theta)
    a = np.where(small, 1.0 - t2 / 6.0, np.sin(safe) / safe)
    b = np.where(small, 0.5 - t2 / 24.0, (1.0 - np.cos(safe)) / safe**2)
    c = np.where(small, 1.0 / 12.0 + t2 / 720.0,
                 1.0 / safe**2 - (1.0 + np.cos(safe)) / (2.0 * safe * np.sin(safe)))
    W = skew(w)
    W2 = np.matmul(W, W)
    eye = np.eye(3)
    R = eye + a[:, None, None] * W + b[:, None, None] * W2
    Jr_inv = eye + 0.5 * W + c[:, None, None] * W2
    d_cam = np.zeros((7, C, 9))
    d_point = np.zeros((7, P, 3))
    for axis in range(3):
        u = eye[axis]
        d_cam[axis, :, :3] = -Jr_inv[:, :, axis]
        d_point[axis] = np.cross(u, points)
        d_cam[3 + axis, :, 3:6] = -R[:, :, axis]
        d_point[3 + axis] = u
    d_cam[6, :, 3:6] = cameras[:, 3:6]
    d_point[6] = points
    return np.concatenate([d_cam.reshape(7, -1), d_point.reshape(7, -1)], axis=1).T
    # END SOLUTION


#: the derived results, in three levels (``python -m autograder hint NAME LEVEL``; the release
#: prints levels 1..N into the docstrings with ``--hints N``, course.core.hints)
HINTS = {
    "gauge_directions": (
        """For each similarity, write the moved point ``X(e)`` and the moved camera ``(w(e), t(e))``,
        impose the invariance for every X (``R(w(e)) X(e) + t(e)`` equal to ``R(w) X + t``, or to ``(1 + e)``
        times it), solve for the camera's new rotation and translation, and differentiate at ``e = 0``.
        Entries that do not move are 0.""",
        """Rotation: ``R' Exp(e u_a) X + t' = R X + t`` for every X gives ``t' = t`` and ``R' = R Exp(-e u_a)``;
        with ``R(w + dw) = R(w) Exp(J_r(w) dw)`` that is ``J_r(w) dw = -e u_a``. Also
        ``d/de Exp(e u) X = [u]_x X = u x X`` at ``e = 0``. Translation: ``R (X + e u_a) + t' = R X + t``
        gives ``t' = t - e R u_a``. Scaling: ``R (1 + e) X + t' = (1 + e) (R X + t)`` gives ``t' = (1 + e) t``.""",
        """Per camera (w, t) and point X::

            columns 0, 1, 2 (axis a):  dw = -J_r(w)^-1 u_a   dt = 0           dX = u_a x X
            columns 3, 4, 5 (axis a):  dw = 0                dt = -R(w) u_a   dX = u_a
            column  6:                 dw = 0                dt = t           dX = X

        ``-J_r(w)^-1 u_a`` is minus column a of ``J_r(w)^-1`` and ``R(w) u_a`` column a of ``R(w)``; f, k1,
        k2 rows are 0.""",
    ),
}
