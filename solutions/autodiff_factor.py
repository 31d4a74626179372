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
    # BEGIN SOLUTION
    dims = [int(np.shape(P)[-1]) for P in plus_jacobians]
    k = int(sum(dims))
    offsets = np.concatenate([[0], np.cumsum(dims)]).astype(int)
    points = []
    for P, x, offset, d in zip(plus_jacobians, xs, offsets, dims):
        x = np.asarray(x, dtype=float)
        n = int(np.prod(x.shape[1:]))
        grad = np.zeros((len(x), n, k))
        grad[:, :, offset:offset + d] = P
        points.append(jet(x.reshape(len(x), n), grad).reshape(x.shape))
    r = residual(*points)
    grad = np.asarray(r.grad, dtype=float)
    return (np.asarray(r.value, dtype=float),
            [grad[..., offsets[a]:offsets[a + 1]] for a in range(len(dims))])
    # END SOLUTION


#: the derived results, in three levels (``python -m autograder hint NAME LEVEL``; the release
#: prints levels 1..N into the docstrings with ``--hints N``, course.core.hints)
HINTS = {
    "tangent_jacobians": (
        """Give every scalar of every step its own direction: ``k`` directions in all, variable ``a``'s
        step taking ``d_a`` of them. To first order the moved value is ``vec(x_a) + P_a delta_a``: the Jet of
        ``x_a`` carries that as its derivative. Evaluate the residual once, and cut the derivative's last
        axis into the variables' blocks.""",
        """Variable ``a``'s directions start at ``offset_a = d_1 + ... + d_(a-1)``. By the chain rule
        ``dr / d delta_a = (dr / d vec(x_a)) P_a``: seed ``x_a``'s Jet with ``grad[:, :, offset_a:offset_a + d_a]
        = P_a`` (not the identity, and not its transpose; 0 in the other directions), and
        ``r.grad[..., offset_a + j]`` is ``dr / d delta_a[j]`` at ``delta = 0``.""",
        """::

            offsets = [0, d_1, d_1 + d_2, ...]
            grad_a = zeros((M, n_a, k)); grad_a[:, :, offsets[a]:offsets[a + 1]] = P_a
            points = [jet(x_a.reshape(M, n_a), grad_a).reshape(x_a.shape) for each a]
            r = residual(*points)
            return r.value, [r.grad[..., offsets[a]:offsets[a + 1]] for each a]""",
    ),
}
