"""A type of factor: the kinds of its variables and one residual, written once for arrays, Jets and JAX.

``residual(z, *points)`` maps the measurements ``z`` (M, *measurement shape) and the values of the
factor's variables (each (M, *shape), arrays, Jets or JAX arrays) to the residuals (M, dim). Written
with ``course.factorgraph.jetmath``'s functions (``jetmath.sqrt``, ``jetmath.stack``, ``jetmath.so3_log``,
...) and arithmetic, the same code gives the values, run on Jets our derivatives, and traced by JAX
the ``jax`` back end's; ``gtsam-custom`` calls it on Jets too. numpy's own functions run on arrays
and Jets (those Jets support are listed in the ``jets`` exercise's docstring: the arithmetic,
``abs``, comparisons and ``np.where``, ``np.sum``, ``np.stack``, ``np.concatenate``,
``np.linalg.norm``, ``np.dot``, ``np.einsum``, ``.T``, ``@``, the elementary functions; any other
fails with one line naming it and what to write instead) but not under JAX, which then says so,
naming the factor type. Nothing else is needed to add a factor to the course: no Jacobian is written
by hand, nothing is registered. Two different factor types of one name in a graph are an error.
"""

from collections.abc import Callable
from dataclasses import dataclass


@dataclass(frozen=True)
class FactorType:
    """``name``; ``kinds`` (one ``VariableKind`` per slot); residual size ``dim``; ``residual``."""

    name: str
    kinds: tuple
    dim: int
    residual: Callable

    def __call__(self, z, *points):
        return self.residual(z, *points)
