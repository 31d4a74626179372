"""Chapter 7 exercise: a factor's Jacobians on the tangent spaces of its variables, by Jets.

A factor with s variables has a residual ``r(x_1, ..., x_s)`` (M, m), vectorised over its M factors.
Its Jacobian with respect to variable ``a`` is taken in that variable's tangent space: the derivative
of ``r(x_1, ..., x_a (+) delta_a, ..., x_s)`` with respect to ``delta_a`` (size ``d_a``) at
``delta_a = 0``, where ``(+)`` is the variable's retraction (``x + delta`` for a vector; ``(t + R rho,
R Exp(phi))`` for an SE(3) pose, as in chapter 6). You are given each retraction's derivative at
``delta = 0``, its plus-Jacobian ``P_a = d vec(x_a (+) delta_a) / d delta_a`` (M, n_a, d_a), with ``n_a``
the number of stored values of ``x_a`` (``vec`` row by row, as numpy's ``reshape``): Ceres'
``Manifold::PlusJacobian``. Forward-mode automatic differentiation gives all the Jacobians in one
evaluation: make every variable's stored value a Jet in ``k = d_1 + ... + d_s`` directions, whose
derivative says how it moves with the steps, evaluate the residual once on them, and read the blocks
off its derivative. Derive what each Jet's derivative must be, and where, so that each block comes
out where it belongs (``python -m autograder hint tangent_jacobians 1``). No retraction runs on Jets.

Inputs at the edges of the contract (each is a check input):
- one factor (M = 1)
- one variable (s = 1)
- a variable stored in another shape than its tangent size (SO(3): 3x3 stored, 3 tangent)
- the same kind in two slots
- a plus-Jacobian that is neither the identity nor symmetric (a square one)
- a variable held fixed in some factors: its plus-Jacobian is 0 there

Allowed imports: numpy, scipy.
"""

import numpy as np


def tangent_jacobians(residual, plus_jacobians, xs, jet):
    """``r`` (M, m) and ``[J_1, ..., J_s]``, ``J_a = dr/d delta_a`` (M, m, d_a), at ``delta = 0``.

    Args:
        residual: ``residual(p_1, ..., p_s)`` -> (M, m): the residual of the values ``p_a``, each a Jet
            of ``x_a``'s shape (M, *shape_a).
        plus_jacobians: ``[P_1, ..., P_s]``, ``P_a = d vec(x_a (+) delta_a) / d delta_a`` at ``delta_a = 0``
            (M, n_a, d_a), ``n_a = prod(shape_a)``; ``d_a`` is its last size. Where a variable is held
            fixed, its rows are 0: it does not move, and its block comes out 0.
        xs: the variables' values ``(x_1, ..., x_s)``, each (M, *shape_a).
        jet: the Jet class: ``jet(value, grad)`` (``grad`` of value's shape + (k,): ``grad[..., j]`` is the
            derivative of ``value`` in direction ``j``), ``jet.seed(value, offset, k)`` (value (M, n): its
            entry ``[..., i]`` has the unit derivative in direction ``offset + i`` of ``k``) and
            ``jet.constant(value, k)`` (a zero derivative); a Jet has ``value`` and ``grad`` and an array's
            container: indexing and slicing (``jet_M_k[:, 2:5]``), ``reshape``, ``+``, ``-`` and scaling by
            a number.
    """
    raise NotImplementedError("TODO autodiff_factor.tangent_jacobians: not implemented yet")
