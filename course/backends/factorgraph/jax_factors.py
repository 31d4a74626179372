"""The factor graph's Jacobians by JAX: the ``jax`` back end (chapter 7's other automatic differentiation).

A factor type's own residual (``FactorType.residual``, written with ``course.factorgraph.jetmath``,
which runs on JAX arrays as on numpy arrays and Jets) traced by JAX, and a factor's tangent Jacobians
as ``jax.jacfwd`` of ``delta -> r(x (+) delta)`` at ``delta = 0``, under ``jax.vmap`` over a group's
factors (each call sees one factor, as a batch of 1: the residual's contract) and ``jax.jit``
(float64: ``jax_enable_x64`` is set when this module is imported). Nothing is registered: a user's
factor type reaches JAX by itself; a residual that JAX cannot trace (it calls numpy on a value, or
branches on one in Python) is a ``ValueError`` naming the factor type and why. The retractions are
the kinds' own (``VariableKind.retract``), the course's kinds' in ``jax.numpy`` here.

Each group's function is compiled once per shape, ahead of time (``jit(...).lower(...).compile()``), so
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

from course.factorgraph import jetmath
from course.factorgraph.variables import SE2, SE3, SO3, Vector

jax.config.update("jax_enable_x64", True)


def so3_exp(phi):
    """``Exp(phi)`` (3, 3) of one rotation vector (3,) (``jetmath.so3_exp`` on JAX arrays)."""
    return jetmath.so3_exp(phi)


def so3_log(R):
    """``Log(R)`` (3,) of one rotation (3, 3) (``jetmath.so3_log`` on JAX arrays: right at every angle)."""
    return jetmath.so3_log(R)


# ---------------------------------------------------------------- the course's retractions, one value at a time


def retract_vector(x, delta):
    return x + delta


def retract_se2(x, delta):
    moved = x + delta
    return jnp.stack([moved[0], moved[1], jetmath.wrap_angle(moved[2])])


def retract_so3(x, delta):
    return x @ so3_exp(delta)


def retract_se3(x, delta):
    t, R = x[:3], x[3:].reshape(3, 3)
    return jnp.concatenate([t + R @ delta[:3], (R @ so3_exp(delta[3:])).ravel()])


def retraction(kind):
    """The retraction of a variable kind on one value: the course's kinds' in ``jax.numpy``, any other
    kind's own ``retract`` (on a batch of 1)."""
    if kind == SE2:
        return retract_se2
    if kind == SE3:
        return retract_se3
    if kind == SO3:
        return retract_so3
    if isinstance(kind, Vector):
        return retract_vector

    def retract(x, delta):
        return kind.retract(x[None], delta[None])[0]

    return retract


def linearisation(factor_type):
    """``f(z (M, ...), *xs (M, *shape_a)) -> (r (M, m), (J_a (M, m, d_a), ...))`` for ``factor_type``:
    ``jax.jacfwd`` through the retractions at ``delta = 0``, under ``jax.vmap`` (not yet jitted)."""
    residual = factor_type.residual
    retractions = [retraction(kind) for kind in factor_type.kinds]
    dims = [kind.dim for kind in factor_type.kinds]
    slots = tuple(range(len(dims)))

    def one(z, *xs):
        def moved(*deltas):
            points = [retract(x, d)[None] for retract, x, d in zip(retractions, xs, deltas)]
            r = jnp.reshape(residual(z[None], *points), (factor_type.dim,))
            return r, r

        J, r = jax.jacfwd(moved, argnums=slots, has_aux=True)(*[jnp.zeros(d) for d in dims])
        return r, J

    return jax.vmap(one)


def untraceable(factor_type, exc: Exception) -> ValueError:
    """The one-line error of a factor type whose residual JAX cannot trace."""
    first = " ".join(str(exc).split())[:200]
    return ValueError(
        f"jax: the residual of factor type {factor_type.name!r} cannot be traced by JAX "
        f"({type(exc).__name__}: {first}): write it with course.factorgraph.jetmath's functions "
        "(jetmath.sqrt, jetmath.stack, jetmath.where, ...), not numpy's, and without Python branches on values")


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
        key = (factor_type, z.shape, tuple(x.shape for x in xs))
        compiled = self._compiled.get(key)
        if compiled is None:
            start = time.perf_counter()
            try:
                lowered = jax.jit(linearisation(factor_type)).lower(z, *xs)
            except NotImplementedError:  # a TODO of the course's code: not the residual's fault
                raise
            except Exception as exc:  # noqa: BLE001 - whatever the tracing met, named by its factor type
                raise untraceable(factor_type, exc) from exc
            compiled = lowered.compile()
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
