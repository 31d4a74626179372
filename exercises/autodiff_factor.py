"""Chapter 7 exercise: a factor's Jacobians on the tangent spaces of its variables, by Jets.

A factor with s variables has a residual ``r(x_1, ..., x_s)`` (M, m), vectorised over its M factors.
Its Jacobian with respect to variable ``a`` is taken in that variable's tangent space: the derivative
of ``r(x_1, ..., x_a (+) delta_a, ..., x_s)`` with respect to ``delta_a`` (size ``d_a``) at
``delta_a = 0``, where ``(+)`` is the variable's retraction (``x + delta`` for a vector; ``(t + R rho,
R Exp(phi))`` for an SE(3) pose, as in chapter 6). Forward-mode automatic differentiation gives all
of them in one evaluation: seed every step as Jets at zero, in ``k = d_1 + ... + d_s`` directions,
move each variable by its step through its retraction, evaluate the residual once on the moved
Jets, and read the blocks off its derivative. Derive how the seeds must be laid out so that each
block comes out where it belongs (``python -m autograder hint tangent_jacobians 1``).

Inputs at the edges of the contract (each is a check input):
- one factor (M = 1)
- one variable (s = 1)
- a variable stored in another shape than its tangent size (SO(3): 3x3 stored, 3 tangent)
- the same kind in two slots

Allowed imports: numpy, scipy.
"""

import numpy as np


def tangent_jacobians(residual, retractions, dims, xs, jet):
    """``r`` (M, m) and ``[J_1, ..., J_s]``, ``J_a = dr/d delta_a`` (M, m, d_a), at ``delta = 0``.

    Args:
        residual: ``residual(p_1, ..., p_s)`` -> (M, m): the residual of the moved values (Jets).
        retractions: s functions ``retract(x, delta)`` -> the moved value, ``x`` (M, *shape_a) an
            array, ``delta`` (M, d_a) a Jet; the result is a Jet of ``x``'s shape.
        dims: the tangent sizes ``(d_1, ..., d_s)``.
        xs: the variables' values ``(x_1, ..., x_s)``, each (M, *shape_a).
        jet: the Jet class: ``jet.seed(value, offset, k)`` (value (M, n): its entry ``[..., i]`` has
            the unit derivative in direction ``offset + i`` of ``k``) and ``jet.constant(value, k)``
            (a zero derivative); a Jet has ``value`` and ``grad`` (value's shape + (k,)) and an array's
            container: indexing and slicing (``jet_M_k[:, 2:5]``), ``reshape``, ``+``, ``-`` and scaling
            by a number.
    """
    raise NotImplementedError("TODO autodiff_factor.tangent_jacobians: not implemented yet")
