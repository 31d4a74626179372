"""The factor graph's Jacobians by JAX: the ``jax`` back end (chapter 7's other automatic differentiation).

The residuals of ``course.factorgraph.factors`` transcribed in ``jax.numpy`` (one factor at a time,
the same formulas and the same small-angle branches), the retractions of
``course.factorgraph.variables`` likewise, and a factor's tangent Jacobians as
``jax.jacfwd`` of ``delta -> r(x (+) delta)`` at ``delta = 0``, under ``jax.vmap`` over a group's
factors and ``jax.jit`` (float64: ``jax_enable_x64`` is set when this module is imported). Each
group's function is compiled once per shape, ahead of time (``jit(...).lower(...).compile()``), so
that the compile time is measured alone (``JaxJacobians.compile_seconds``) and kept out of the
per-iteration time. :func:`problem` plugs them into :class:`course.factorgraph.FactorGraphProblem`
(its ``jacobians`` hook): our minimizer, our assembly and sparse solve, our error; only the
factors' residuals and Jacobians in the linearisation come from JAX.

``jax`` is optional (the ``peers`` extra, Python 3.11 to 3.14): import this module only where
``course.core.peers.installed("jax")``.
"""

import time

import jax
import jax.numpy as jnp
import numpy as np

jax.config.update("jax_enable_x64", True)

#: below this squared angle (rad^2), Exp and Log use their series (as ``course.factorgraph.jetmath``)
SMALL_ANGLE_SQUARED = 1e-10


# ---------------------------------------------------------------- geometry, one value at a time


def wrap_angle(theta):
    """``theta`` wrapped to ``[-pi, pi)`` (``floor`` has derivative 0: the wrap's is 1)."""
    return theta - 2.0 * jnp.pi * jnp.floor((theta + jnp.pi) / (2.0 * jnp.pi))


def skew(v):
    return jnp.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])


def rodrigues_coefficients(phi):
    """``(sin t / t, (1 - cos t) / t^2)``, ``t = |phi|``, their series below ``SMALL_ANGLE_SQUARED``; the
    branch not taken is evaluated at a safe angle, so that its derivative is finite."""
    t2 = phi @ phi
    small = t2 < SMALL_ANGLE_SQUARED
    safe = jnp.where(small, 1.0, t2)
    t = jnp.sqrt(safe)
    return (jnp.where(small, 1.0 - t2 / 6.0, jnp.sin(t) / t),
            jnp.where(small, 0.5 - t2 / 24.0, (1.0 - jnp.cos(t)) / safe))


def so3_exp(phi):
    """``Exp(phi) = I + a [phi]_x + b [phi]_x^2`` (3, 3)."""
    a, b = rodrigues_coefficients(phi)
    K = skew(phi)
    return jnp.eye(3) + a * K + b * (K @ K)


def so3_rotate(phi, v):
    """``Exp(phi) v`` without the matrix (Rodrigues)."""
    a, b = rodrigues_coefficients(phi)
    w_v = jnp.cross(phi, v)
    return v + a * w_v + b * jnp.cross(phi, w_v)


def so3_log(R):
    """``Log(R)``, the angle in [0, pi], with the branches of ``jetmath.so3_log``: the series for small
    angles, ``w t / sin t`` up to a right angle, beyond it the axis from the symmetric part
    ``(R + R^T) / 2 - cos t I = (1 - cos t) u u^T`` and ``t = atan2(u . w, cos t)`` (exact at pi).
    Every branch is evaluated at safe values where it is not taken, so that its derivative is finite."""
    w = 0.5 * jnp.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]])
    s2 = w @ w
    cos_t = 0.5 * (jnp.trace(R) - 1.0)
    wide = cos_t < 0.0
    small = (s2 < SMALL_ANGLE_SQUARED) & ~wide
    safe = jnp.where(small | wide, 1.0, s2)
    sin_t = jnp.sqrt(safe)
    narrow = w * jnp.where(small, 1.0 + s2 / 6.0, jnp.arctan2(sin_t, cos_t) / sin_t)
    B = 0.5 * (R + R.T) - cos_t * jnp.eye(3)
    k = jnp.argmax(jnp.diag(B))
    safe_cos = jnp.where(wide, cos_t, -1.0)
    column = jnp.where(wide, B[:, k], jnp.eye(3)[k])
    u = column / jnp.sqrt((1.0 - safe_cos) * jnp.where(wide, B[k, k], 0.5))
    u = jnp.where(u @ w < 0.0, -u, u)
    return jnp.where(wide, u * jnp.arctan2(u @ w, safe_cos), narrow)


def se3_parts(x):
    """``(t (3,), R (3, 3))`` of an SE(3) value (12,) (t, then R row by row)."""
    return x[:3], x[3:].reshape(3, 3)


# ---------------------------------------------------------------- the retractions, by kind name


def retract_vector(x, delta):
    return x + delta


def retract_se2(x, delta):
    moved = x + delta
    return jnp.stack([moved[0], moved[1], wrap_angle(moved[2])])


def retract_so3(x, delta):
    return x @ so3_exp(delta)


def retract_se3(x, delta):
    t, R = se3_parts(x)
    return jnp.concatenate([t + R @ delta[:3], (R @ so3_exp(delta[3:])).ravel()])


def retraction(kind):
    """The JAX retraction of a ``course.factorgraph.variables`` kind (by its name)."""
    if kind.name == "SE2":
        return retract_se2
    if kind.name == "SE3":
        return retract_se3
    if kind.name == "SO3":
        return retract_so3
    if kind.name.startswith("Vector") or kind.name == "BALCamera":
        return retract_vector
    raise ValueError(f"no JAX retraction for variables of kind {kind.name}")


# ---------------------------------------------------------------- the residuals, by factor type name


def between_se2(z, xi, xj):
    ci, si = jnp.cos(xi[2]), jnp.sin(xi[2])
    cz, sz = jnp.cos(z[2]), jnp.sin(z[2])
    dx, dy = xj[0] - xi[0], xj[1] - xi[1]
    u = ci * dx + si * dy - z[0]
    v = -si * dx + ci * dy - z[1]
    return jnp.stack([cz * u + sz * v, -sz * u + cz * v, wrap_angle(xj[2] - xi[2] - z[2])])


def prior_se2(z, x):
    return between_se2(z, jnp.zeros(3), x)


def between_se3(z, xi, xj):
    t_z, R_z = se3_parts(z)
    t_i, R_i = se3_parts(xi)
    t_j, R_j = se3_parts(xj)
    e_t = R_z.T @ (R_i.T @ (t_j - t_i) - t_z)
    return jnp.concatenate([e_t, so3_log(R_z.T @ (R_i.T @ R_j))])


def prior_se3(z, x):
    origin = jnp.concatenate([jnp.zeros(3), jnp.eye(3).ravel()])
    return between_se3(z, origin, x)


def range_bearing(z, x, landmark):
    dx, dy = landmark[0] - x[0], landmark[1] - x[1]
    return jnp.stack([jnp.sqrt(dx * dx + dy * dy) - z[0], wrap_angle(jnp.arctan2(dy, dx) - x[2] - z[1])])


def reprojection_bal(z, camera, point):
    P = so3_rotate(camera[:3], point) + camera[3:6]
    p = -P[:2] / P[2]
    n2 = p @ p
    return camera[6] * (1.0 + camera[7] * n2 + camera[8] * n2 * n2) * p - z


#: factor type name -> its residual in ``jax.numpy``, one factor: ``r(z, *values)`` (m,)
RESIDUALS = {"between_se2": between_se2, "prior_se2": prior_se2, "between_se3": between_se3,
             "prior_se3": prior_se3, "range_bearing": range_bearing, "reprojection_bal": reprojection_bal}


def linearisation(factor_type):
    """``f(z (M, ...), *xs (M, *shape_a)) -> (r (M, m), (J_a (M, m, d_a), ...))`` for ``factor_type``:
    ``jax.jacfwd`` through the retractions at ``delta = 0``, under ``jax.vmap`` (not yet jitted)."""
    try:
        residual = RESIDUALS[factor_type.name]
    except KeyError:
        raise ValueError(f"no JAX residual for factor type {factor_type.name!r}: add one to "
                         "course.backends.factorgraph.jax_factors.RESIDUALS") from None
    retractions = [retraction(kind) for kind in factor_type.kinds]
    dims = [kind.dim for kind in factor_type.kinds]
    slots = tuple(range(len(dims)))

    def one(z, *xs):
        def moved(*deltas):
            r = residual(z, *[retract(x, d) for retract, x, d in zip(retractions, xs, deltas)])
            return r, r

        J, r = jax.jacfwd(moved, argnums=slots, has_aux=True)(*[jnp.zeros(d) for d in dims])
        return r, J

    return jax.vmap(one)


class JaxJacobians:
    """The ``jacobians`` hook of ``FactorGraphProblem``: ``(ftype, z, xs) -> (r, [J_a])`` by JAX.

    One compiled function per factor type and shapes, compiled on first use; ``compile_seconds`` is
    the time spent compiling (tracing, lowering and XLA's compilation), ``compilations`` how many."""

    def __init__(self):
        self._compiled: dict = {}
        self.compile_seconds = 0.0
        self.compilations = 0

    def __call__(self, factor_type, z, xs):
        z = np.ascontiguousarray(z, dtype=float)
        xs = [np.ascontiguousarray(x, dtype=float) for x in xs]
        key = (factor_type.name, z.shape, tuple(x.shape for x in xs))
        compiled = self._compiled.get(key)
        if compiled is None:
            start = time.perf_counter()
            compiled = jax.jit(linearisation(factor_type)).lower(z, *xs).compile()
            self.compile_seconds += time.perf_counter() - start
            self.compilations += 1
            self._compiled[key] = compiled
        r, J = compiled(z, *xs)
        return np.asarray(r), [np.asarray(block) for block in J]


def problem(graph, impl="solutions", solver=None):
    """``FactorGraphProblem(graph, impl, jacobians=JaxJacobians(), solver=solver)``, compiled at its start
    (one linearisation): its ``jacobians.compile_seconds`` says how long compiling took."""
    from course.factorgraph import FactorGraphProblem

    out = FactorGraphProblem(graph, impl, jacobians=JaxJacobians(), solver=solver)
    out.linearize(out.x0)
    return out
