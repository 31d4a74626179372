"""The geometry a residual needs, written once for numpy arrays and for Jets.

Every function here takes arrays or Jets (any class with ``value`` (...,), ``grad`` (..., k), the
constructor ``type(x)(value, grad)``, indexing and ``reshape``, and the arithmetic and numpy
functions of chapter 7's ``jets`` exercise) and returns the same kind. The branches that a value
decides (the small-angle series, the angle wrap) are chosen on the value alone, and the
derivative follows the branch taken: that is how Ceres' Jets treat ``if``, and why ``Exp`` at
``delta = 0`` uses its series (the closed form divides 0 by 0 there).
"""

import numpy as np

#: below this squared angle (rad^2), Exp and Log use their series (exact to rounding there)
SMALL_ANGLE_SQUARED = 1e-10


def is_jet(x) -> bool:
    return hasattr(x, "grad") and hasattr(x, "value") and not isinstance(x, np.ndarray)


def value_of(x) -> np.ndarray:
    """The value of a Jet, or the array itself."""
    return np.asarray(x.value if is_jet(x) else x, dtype=float)


def where(mask, a, b):
    """``np.where(mask, a, b)`` for arrays and Jets alike (``mask`` a boolean array of the values'
    shape): the derivative of the branch taken."""
    jets = [x for x in (a, b) if is_jet(x)]
    if not jets:
        return np.where(mask, a, b)
    kind, k = type(jets[0]), jets[0].grad.shape[-1]

    def grad(x):
        return x.grad if is_jet(x) else np.zeros(np.shape(x) + (k,))

    mask = np.asarray(mask)
    return kind(np.where(mask, value_of(a), value_of(b)), np.where(mask[..., None], grad(a), grad(b)))


def branches(small, series, closed):
    """``where(small, series(), closed())`` for arrays and Jets, each branch computed only if some entry
    takes it: ``series`` and ``closed`` return a tuple of values each, ``small`` is a boolean array.
    A batch of rotations rarely holds both kinds, and each branch is a dozen Jet operations."""
    small = np.asarray(small)
    if not small.any():
        return closed()
    if small.all():
        return series()
    return tuple(where(small, s, c) for s, c in zip(series(), closed()))


def wrap_angle(theta):
    """``theta`` wrapped to ``[-pi, pi)``: a constant multiple of 2 pi subtracted (derivative 1)."""
    turns = np.floor((value_of(theta) + np.pi) / (2.0 * np.pi))
    return theta - 2.0 * np.pi * turns


def dot3(a, b):
    """``a . b`` over the last axis of two (..., 3) vectors."""
    return a[..., 0] * b[..., 0] + a[..., 1] * b[..., 1] + a[..., 2] * b[..., 2]


def squared_norm3(a):
    """``|a|^2`` (...,) of (..., 3) vectors, by squares (on Jets one product each, not two)."""
    return a[..., 0] ** 2 + a[..., 1] ** 2 + a[..., 2] ** 2


def skew(v):
    """``[v]_x`` (..., 3, 3) of ``v`` (..., 3): ``[v]_x u = v x u``."""
    x, y, z = v[..., 0], v[..., 1], v[..., 2]
    zero = 0.0 * x
    return np.stack([np.stack([zero, -z, y], axis=-1), np.stack([z, zero, -x], axis=-1),
                     np.stack([-y, x, zero], axis=-1)], axis=-2)


def vee(W):
    """The vector (..., 3) of the antisymmetric part of ``W`` (..., 3, 3): ``vee((W - W^T) / 2)``."""
    return 0.5 * np.stack([W[..., 2, 1] - W[..., 1, 2], W[..., 0, 2] - W[..., 2, 0],
                           W[..., 1, 0] - W[..., 0, 1]], axis=-1)


def matvec(A, v):
    """``A v`` (..., n) of matrices (..., n, m) and vectors (..., m)."""
    return (A @ v[..., None])[..., 0]


def transpose(A):
    """The transpose of the last two axes."""
    return A.mT if is_jet(A) else np.swapaxes(A, -1, -2)


def rotation2d(theta):
    """``R(theta)`` (..., 2, 2)."""
    c, s = np.cos(theta), np.sin(theta)
    return np.stack([np.stack([c, -s], axis=-1), np.stack([s, c], axis=-1)], axis=-2)


def cross(a, b):
    """``a x b`` (..., 3) of two (..., 3) vectors."""
    ax, ay, az = a[..., 0], a[..., 1], a[..., 2]
    bx, by, bz = b[..., 0], b[..., 1], b[..., 2]
    return np.stack([ay * bz - az * by, az * bx - ax * bz, ax * by - ay * bx], axis=-1)


def rodrigues_coefficients(phi):
    """``(a, b) = (sin t / t, (1 - cos t) / t^2)`` with ``t = |phi|`` (...,), and their series below
    ``SMALL_ANGLE_SQUARED`` (where the closed forms divide 0 by 0)."""
    t2 = squared_norm3(phi)
    small = value_of(t2) < SMALL_ANGLE_SQUARED

    def closed():
        safe = where(small, 1.0, t2) if small.any() else t2
        t = np.sqrt(safe)
        return np.sin(t) / t, (1.0 - np.cos(t)) / safe

    return branches(small, lambda: (1.0 - t2 / 6.0, 0.5 - t2 / 24.0), closed)


def so3_rotate(phi, v):
    """``Exp(phi) v`` (..., 3) without the matrix: ``v + a (phi x v) + b phi x (phi x v)`` (Rodrigues)."""
    a, b = rodrigues_coefficients(phi)
    w_v = cross(phi, v)
    return v + a[..., None] * w_v + b[..., None] * cross(phi, w_v)


def so3_exp(phi):
    """``Exp(phi)`` (..., 3, 3) of rotation vectors (..., 3): ``I + a [phi]_x + b [phi]_x^2`` with
    ``a = sin t / t``, ``b = (1 - cos t) / t^2``, ``t = |phi|``; their series below
    ``SMALL_ANGLE_SQUARED``, where the closed forms divide 0 by 0."""
    a, b = rodrigues_coefficients(phi)
    W = skew(phi)
    return np.eye(3) + a[..., None, None] * W + b[..., None, None] * (W @ W)


def so3_log(R):
    """``Log(R)`` (..., 3) of rotations (..., 3, 3), the angle ``t`` in [0, pi], right at every angle:

    - ``w (1 + |w|^2 / 6)`` for small angles (``w = vee(R) = sin t u``, ``cos t > 0``);
    - ``w t / sin t`` with ``t = atan2(|w|, cos t)``, ``cos t = (tr R - 1) / 2``, up to a right angle;
    - beyond it (:func:`so3_log_wide`) the axis from the symmetric part, where ``w`` has lost the
      direction: near pi ``sin t`` is rounding noise, and ``w / sin t`` with it (its derivative ~ 1/sin^2 t).
    """
    w = vee(R)
    s2 = squared_norm3(w)
    cos_v = 0.5 * (value_of(R[..., 0, 0]) + value_of(R[..., 1, 1]) + value_of(R[..., 2, 2]) - 1.0)
    wide = cos_v < 0.0
    small = (value_of(s2) < SMALL_ANGLE_SQUARED) & ~wide

    def closed():
        sin_t = np.sqrt(where(small, 1.0, s2) if small.any() else s2)
        cos_t = 0.5 * (R[..., 0, 0] + R[..., 1, 1] + R[..., 2, 2] - 1.0)
        return (np.arctan2(sin_t, cos_t) / sin_t,)

    if wide.all():
        return so3_log_wide(R, w)
    scale, = branches(small, lambda: (1.0 + s2 / 6.0,), closed)
    narrow = w * scale[..., None]
    if not wide.any():
        return narrow
    return where(wide[..., None], so3_log_wide(R, w, wide), narrow)


def so3_log_wide(R, w, wide=None):
    """``Log(R)`` (..., 3) for angles beyond a right angle (``cos t < 0``), exact at pi.

    ``B = (R + R^T) / 2 - cos t I = (1 - cos t) u u^T``: the axis is the column ``k`` of B with the
    largest diagonal, ``u = B[:, k] / sqrt((1 - cos t) B_kk)`` (``B_kk >= (1 - cos t) / 3 > 0``), its
    sign that of ``u . w``; then ``sin t = u . w`` (smooth through pi, unlike ``|w|``) and
    ``t = atan2(sin t, cos t)``. ``wide`` (...,) marks the entries that take this branch: the others
    get a harmless value (they are discarded by the caller)."""
    cos_t = 0.5 * (R[..., 0, 0] + R[..., 1, 1] + R[..., 2, 2] - 1.0)
    one_minus = 1.0 - cos_t
    diag = np.stack([value_of(R[..., i, i]) for i in range(3)], axis=-1) - value_of(cos_t)[..., None]
    k = np.argmax(diag, axis=-1)
    if wide is not None:
        k = np.where(wide, k, 0)
    u = None
    for col in range(3):
        chosen = k == col
        if not chosen.any():
            continue
        B_col = np.stack([0.5 * (R[..., i, col] + R[..., col, i]) - (cos_t if i == col else 0.0)
                          for i in range(3)], axis=-1)
        norm2 = one_minus * B_col[..., col]
        if wide is not None or not chosen.all():
            usable = chosen & (wide if wide is not None else True)
            norm2 = where(usable, norm2, 1.0)
        candidate = B_col / np.sqrt(norm2)[..., None]
        u = candidate if u is None else where(chosen[..., None], candidate, u)
    flip = np.where(value_of(dot3(u, w)) < 0.0, -1.0, 1.0)
    u = u * flip[..., None]
    return u * np.arctan2(dot3(u, w), cos_t)[..., None]
