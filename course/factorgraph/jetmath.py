"""The geometry a residual needs, written once for numpy arrays, Jets and JAX.

Every function here takes numpy arrays, Jets (any class with ``value`` (...,), ``grad`` (..., k), the
constructor ``type(x)(value, grad)``, indexing and ``reshape``, and the arithmetic and numpy
functions of chapter 7's ``jets`` exercise) or JAX arrays (traced by ``jax.jit``, ``jax.vmap`` and
``jax.jacfwd``), and returns the same kind: each function picks its array namespace from its
inputs (:func:`namespace`: ``jax.numpy`` for a JAX array, numpy otherwise, whose functions reach a
Jet's rules). A residual written with these functions (``jetmath.cos``, ``jetmath.stack``, ...) for
everything that touches a variable's value is one source for the three: our values, our Jets'
derivatives and JAX's (``course.backends.factorgraph.jax_factors``).

The branches that a value decides (the small-angle series, the angle wrap) are chosen on the value
alone, and the derivative follows the branch taken: that is how Ceres' Jets treat ``if``, and why
``Exp`` at ``delta = 0`` uses its series (the closed form divides 0 by 0 there). On arrays and Jets
a branch that no entry takes is not computed; under JAX, which cannot look at a traced value, both
are, each at safe values where it is not taken (``where``), so that neither divides by 0.
"""

import sys

import numpy as np

#: below this squared angle (rad^2), Exp and Log use their series (exact to rounding there)
SMALL_ANGLE_SQUARED = 1e-10


def is_jet(x) -> bool:
    return hasattr(x, "grad") and hasattr(x, "value") and not isinstance(x, np.ndarray)


def is_jax(x) -> bool:
    """Whether ``x`` is a JAX array or tracer (without importing JAX: it is loaded if ``x`` is one)."""
    jax = sys.modules.get("jax")
    return jax is not None and isinstance(x, jax.Array)


def namespace(*xs):
    """The array namespace of ``xs``: ``jax.numpy`` if one is a JAX array, else ``numpy`` (whose
    functions send a Jet to its rules)."""
    return sys.modules["jax.numpy"] if any(is_jax(x) for x in xs) else np


def value_of(x):
    """The value of a Jet, the array itself, or a JAX array without its derivative."""
    if is_jax(x):
        return sys.modules["jax"].lax.stop_gradient(x)
    return np.asarray(x.value if is_jet(x) else x, dtype=float)


def some(mask) -> bool:
    """Whether some entry of the boolean ``mask`` is set; always True under JAX (it cannot look)."""
    return True if is_jax(mask) else bool(np.any(mask))


def every(mask) -> bool:
    """Whether every entry of ``mask`` is set; always False under JAX (it cannot look)."""
    return False if is_jax(mask) else bool(np.all(mask))


# ---------------------------------------------------------------- numpy's functions, for the three


def sin(x):
    return namespace(x).sin(x)


def cos(x):
    return namespace(x).cos(x)


def sqrt(x):
    return namespace(x).sqrt(x)


def exp(x):
    return namespace(x).exp(x)


def log(x):
    return namespace(x).log(x)


def arctan2(y, x):
    return namespace(y, x).arctan2(y, x)


def stack(arrays, axis=-1):
    """``np.stack(arrays, axis)`` of arrays, Jets (and constants) or JAX arrays."""
    return namespace(*arrays).stack(arrays, axis=axis)


def concatenate(arrays):
    """``np.concatenate(arrays, axis=-1)`` of arrays, Jets (and constants) or JAX arrays."""
    return namespace(*arrays).concatenate(arrays, axis=-1)


def where(mask, a, b):
    """``np.where(mask, a, b)`` for arrays, Jets and JAX alike (``mask`` a boolean array of the values'
    shape): the derivative of the branch taken."""
    if is_jax(mask) or is_jax(a) or is_jax(b):
        return namespace(mask, a, b).where(mask, a, b)
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
    takes it (under JAX both, always): ``series`` and ``closed`` return a tuple of values each, ``small``
    is a boolean array. A batch of rotations rarely holds both kinds, and each branch is a dozen Jet
    operations."""
    if not some(small):
        return closed()
    if every(small):
        return series()
    return tuple(where(small, s, c) for s, c in zip(series(), closed()))


def wrap_angle(theta):
    """``theta`` wrapped to ``[-pi, pi)``: a constant multiple of 2 pi subtracted (derivative 1)."""
    turns = namespace(theta).floor((value_of(theta) + np.pi) / (2.0 * np.pi))
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
    return stack([stack([zero, -z, y], axis=-1), stack([z, zero, -x], axis=-1),
                  stack([-y, x, zero], axis=-1)], axis=-2)


def vee(W):
    """The vector (..., 3) of the antisymmetric part of ``W`` (..., 3, 3): ``vee((W - W^T) / 2)``. The
    entries are picked from ``W`` flattened to (..., 9): one index on one axis (on a Jet, a third less
    time than a pair of indices on two axes)."""
    flat = W.reshape(W.shape[:-2] + (9,))
    return 0.5 * (flat[..., _VEE_PLUS] - flat[..., _VEE_MINUS])


#: the entries ``(2, 1), (0, 2), (1, 0)`` of ``[w]_x`` that hold ``w``'s components, and their mirrors
#: ``(1, 2), (2, 0), (0, 1)``, as indices of the matrix flattened row by row (:func:`vee`)
_VEE_PLUS, _VEE_MINUS = np.array([7, 2, 3]), np.array([5, 6, 1])


def matvec(A, v):
    """``A v`` (..., n) of matrices (..., n, m) and vectors (..., m)."""
    return (A @ v[..., None])[..., 0]


def transpose(A):
    """The transpose of the last two axes."""
    return A.mT if is_jet(A) else namespace(A).swapaxes(A, -1, -2)


def rotation2d(theta):
    """``R(theta)`` (..., 2, 2)."""
    c, s = cos(theta), sin(theta)
    return stack([stack([c, -s], axis=-1), stack([s, c], axis=-1)], axis=-2)


def cross(a, b):
    """``a x b`` (..., 3) of two (..., 3) vectors."""
    ax, ay, az = a[..., 0], a[..., 1], a[..., 2]
    bx, by, bz = b[..., 0], b[..., 1], b[..., 2]
    return stack([ay * bz - az * by, az * bx - ax * bz, ax * by - ay * bx], axis=-1)


def rodrigues_coefficients(phi):
    """``(a, b) = (sin t / t, (1 - cos t) / t^2)`` with ``t = |phi|`` (...,), and their series below
    ``SMALL_ANGLE_SQUARED`` (where the closed forms divide 0 by 0)."""
    t2 = squared_norm3(phi)
    small = value_of(t2) < SMALL_ANGLE_SQUARED

    def closed():
        safe = where(small, 1.0, t2) if some(small) else t2
        t = sqrt(safe)
        return sin(t) / t, (1.0 - cos(t)) / safe

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
    return a[..., None, None] * W + b[..., None, None] * (W @ W) + np.eye(3)


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
        unsafe = small | wide  # 0 / 0 in the series' entries, and at pi in the wide ones
        sin_t = sqrt(where(unsafe, 1.0, s2) if some(unsafe) else s2)
        cos_t = 0.5 * (R[..., 0, 0] + R[..., 1, 1] + R[..., 2, 2] - 1.0)
        return (arctan2(sin_t, cos_t) / sin_t,)

    if every(wide):
        return so3_log_wide(R, w)
    scale, = branches(small, lambda: (1.0 + s2 / 6.0,), closed)
    narrow = w * scale[..., None]
    if not some(wide):
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
    xp = namespace(R)
    diag = stack([value_of(R[..., i, i]) for i in range(3)], axis=-1) - value_of(cos_t)[..., None]
    k = xp.argmax(diag, axis=-1)
    if wide is not None:
        k = xp.where(wide, k, 0)
    u = None
    for col in range(3):
        chosen = k == col
        if not some(chosen):
            continue
        B_col = stack([0.5 * (R[..., i, col] + R[..., col, i]) - (cos_t if i == col else 0.0)
                       for i in range(3)], axis=-1)
        norm2 = one_minus * B_col[..., col]
        if wide is not None or not every(chosen):
            usable = chosen & (wide if wide is not None else True)
            norm2 = where(usable, norm2, 1.0)
        candidate = B_col / sqrt(norm2)[..., None]
        u = candidate if u is None else where(chosen[..., None], candidate, u)
    flip = xp.where(value_of(dot3(u, w)) < 0.0, -1.0, 1.0)
    u = u * flip[..., None]
    return u * arctan2(dot3(u, w), cos_t)[..., None]
