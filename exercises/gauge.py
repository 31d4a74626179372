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
    raise NotImplementedError("TODO gauge.gauge_directions: not implemented yet")
