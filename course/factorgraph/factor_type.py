"""A type of factor: the kinds of its variables and one residual, written once for arrays and Jets.

``residual(z, *points)`` maps the measurements ``z`` (M, *measurement shape) and the values of the
factor's variables (each (M, *shape), arrays or Jets) to the residuals (M, dim). It uses numpy's
functions and ``course.factorgraph.jetmath`` only, so that the same code gives the values and,
run on Jets, the derivatives (the functions Jets support are listed in the ``jets`` exercise's
docstring: the arithmetic, ``abs``, comparisons and ``np.where``, ``np.sum``, ``np.stack``,
``np.concatenate``, ``np.linalg.norm``, ``np.dot``, ``np.einsum``, ``.T``, ``@``, the elementary
functions; any other fails with one line naming it and what to write instead). Nothing else is
needed to add a factor to the course: no Jacobian is written by hand.
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
