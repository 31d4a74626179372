"""Chapter 7 exercise: Jets, forward-mode automatic differentiation in numpy.

A Jet is a number together with its derivative in ``k`` seeded directions: ``value`` (...,) and
``grad`` (..., k), ``grad[..., j] = d value / d seed_j``. It is the first-order truncation of
``value + sum_j grad_j eps_j`` with ``eps_i eps_j = 0`` (a dual number), so every operation obeys
the chain rule: ``f(a + da) = f(a) + f'(a) da``. A residual written for numpy arrays runs on Jets
unchanged: numpy's functions (``np.sin(x)``, ``np.sqrt(x)``, ``x @ y``) call :meth:`Jet.__array_ufunc__`,
which sends them to the rules of this module; an array of Jets is one Jet with ``value`` of
that shape (a batch of M rotation matrices is ``value`` (M, 3, 3), ``grad`` (M, 3, 3, k)).

What you write: the derivative rules of the arithmetic (``__mul__``, ``__truediv__``, ``__pow__``),
of ``sqrt``, ``sin``, ``cos``, ``exp``, ``log``, ``arctan2`` and of the matrix product ``matmul``. Each
returns a new Jet; the operands broadcast as numpy arrays do, on ``value``'s axes (``grad`` has one
axis more, the last). An operand that is a plain number or array is a constant (derivative 0).
Derive each rule from ``f(a + da) = f(a) + f'(a) da`` with ``da`` the operand's ``grad``.

Inputs at the edges of the contract (each is a check input):
- sqrt at 0 with a zero derivative: value 0, derivative 0
- sqrt at 0 with a nonzero derivative: value 0, derivative +-inf in the sign of the derivative
- x ** 0: value 1, derivative 0 (also at x = 0)
- x ** 1 at x = 0 and x ** 2 at x = 0: derivative 1 * dx and 0
- arctan2 on each axis (y = 0 with x < 0 gives pi)
- one direction (k = 1) and a scalar Jet (value of shape ())

Allowed imports: numpy, scipy.
"""

import numpy as np


def _parts(x):
    """``(value, grad or None)`` of a Jet or a constant."""
    if isinstance(x, Jet):
        return x.value, x.grad
    return np.asarray(x, dtype=float), None


def _times(factor, grad):
    """``factor[..., None] * grad`` (the chain rule's product), broadcast."""
    return np.asarray(factor)[..., None] * grad


class Jet:
    """``value`` (...,) and ``grad`` (..., k): a batch of numbers with their derivatives in k directions."""

    __array_priority__ = 1000  # numpy defers ``array * jet`` to ``jet.__rmul__``

    def __init__(self, value, grad):
        self.value = np.asarray(value, dtype=float)
        grad = np.asarray(grad, dtype=float)
        if grad.shape[:-1] != self.value.shape:
            grad = np.broadcast_to(grad, self.value.shape + grad.shape[-1:])
        self.grad = grad

    # --------------------------------------------------------------- given: the container

    @classmethod
    def constant(cls, value, k: int) -> "Jet":
        """``value`` with a zero derivative in ``k`` directions."""
        value = np.asarray(value, dtype=float)
        return cls(value, np.zeros(value.shape + (k,)))

    @classmethod
    def seed(cls, value, offset: int, k: int) -> "Jet":
        """``value`` (..., n) as the variables ``offset .. offset + n - 1`` of ``k``: the derivative of
        its entry ``[..., i]`` is the unit vector ``offset + i``."""
        value = np.asarray(value, dtype=float)
        n = value.shape[-1]
        grad = np.zeros(value.shape + (k,))
        grad[..., np.arange(n), offset + np.arange(n)] = 1.0
        return cls(value, grad)

    @property
    def shape(self):
        return self.value.shape

    @property
    def ndim(self):
        return self.value.ndim

    @property
    def k(self) -> int:
        return self.grad.shape[-1]

    def __len__(self):
        return len(self.value)

    def __getitem__(self, index):
        index = index if isinstance(index, tuple) else (index,)
        if any(i is Ellipsis for i in index):
            return Jet(self.value[index], self.grad[index + (slice(None),)])
        return Jet(self.value[index], self.grad[index + (Ellipsis,)] if index else self.grad)

    def reshape(self, *shape) -> "Jet":
        """``value`` reshaped (as ``ndarray.reshape``); each entry keeps its derivative."""
        value = self.value.reshape(*shape)
        return Jet(value, self.grad.reshape(value.shape + (self.k,)))

    def swapaxes(self, a: int, b: int) -> "Jet":
        """Axes ``a`` and ``b`` of ``value`` swapped (negative axes count from ``value``'s last)."""
        a, b = (axis % self.ndim for axis in (a, b))
        return Jet(np.swapaxes(self.value, a, b), np.swapaxes(self.grad, a, b))

    @property
    def mT(self) -> "Jet":
        """The matrix transpose of the last two axes (as ``ndarray.mT``)."""
        return self.swapaxes(-1, -2)

    def sum(self, axis=None) -> "Jet":
        """The sum over ``value``'s ``axis`` (an int, or all of them)."""
        axes = tuple(range(self.ndim)) if axis is None else (axis % self.ndim,)
        return Jet(self.value.sum(axis=axes), self.grad.sum(axis=axes))

    def __repr__(self):
        return f"Jet(value={self.value!r}, grad={self.grad!r})"

    def __neg__(self):
        return Jet(-self.value, -self.grad)

    def __pos__(self):
        return self

    def __add__(self, other):
        v, g = _parts(other)
        return Jet(self.value + v, self.grad if g is None else self.grad + g)

    __radd__ = __add__

    def __sub__(self, other):
        v, g = _parts(other)
        return Jet(self.value - v, self.grad if g is None else self.grad - g)

    def __rsub__(self, other):
        return (-self) + other

    # --------------------------------------------------------------- yours: the derivative rules

    def __mul__(self, other):
        """``self * other``."""
        # BEGIN SOLUTION
        v, g = _parts(other)
        grad = _times(v, self.grad)
        if g is not None:
            grad += _times(self.value, g)  # both terms have the broadcast shape: add in place
        return Jet(self.value * v, grad)
        # END SOLUTION

    __rmul__ = __mul__

    def __truediv__(self, other):
        """``self / other``."""
        # BEGIN SOLUTION
        v, g = _parts(other)
        quotient = self.value / v
        grad = _times(1.0 / v, self.grad)
        if g is not None:
            grad -= _times(quotient / v, g)
        return Jet(quotient, grad)
        # END SOLUTION

    def __rtruediv__(self, other):
        """``other / self`` for a constant ``other``."""
        # BEGIN SOLUTION
        v = np.asarray(other, dtype=float)
        quotient = v / self.value
        return Jet(quotient, _times(-quotient / self.value, self.grad))
        # END SOLUTION

    def __pow__(self, p):
        """``self ** p`` for a constant real ``p`` (a number, not a Jet)."""
        # BEGIN SOLUTION
        p = float(p)
        if p == 0.0:
            return Jet(np.ones_like(self.value), np.zeros_like(self.grad))
        if p == 1.0:
            return Jet(self.value.copy(), self.grad.copy())
        return Jet(self.value**p, _times(p * self.value ** (p - 1.0), self.grad))
        # END SOLUTION

    def __matmul__(self, other):
        return matmul(self, other)

    def __rmatmul__(self, other):
        return matmul(other, self)

    # --------------------------------------------------------------- given: numpy's functions call the rules

    def __array_ufunc__(self, ufunc, method, *inputs, **kwargs):
        rule = _UFUNCS.get(ufunc)
        if method != "__call__" or rule is None or kwargs:
            return NotImplemented
        return rule(*inputs)

    def __array_function__(self, func, types, args, kwargs):
        rule = _FUNCTIONS.get(func)
        if rule is None:
            return NotImplemented
        return rule(*args, **kwargs)


def sqrt(x: Jet) -> Jet:
    """``sqrt(x)``; at ``x = 0`` the derivative is 0 where ``x``'s is 0, else +-inf in its sign."""
    # BEGIN SOLUTION
    root = np.sqrt(x.value)
    with np.errstate(divide="ignore", invalid="ignore"):
        grad = _times(0.5 / root, x.grad)
    grad = np.where(x.grad == 0.0, 0.0, grad)
    return Jet(root, grad)
    # END SOLUTION


def sin(x: Jet) -> Jet:
    """``sin(x)``."""
    # BEGIN SOLUTION
    return Jet(np.sin(x.value), _times(np.cos(x.value), x.grad))
    # END SOLUTION


def cos(x: Jet) -> Jet:
    """``cos(x)``."""
    # BEGIN SOLUTION
    return Jet(np.cos(x.value), _times(-np.sin(x.value), x.grad))
    # END SOLUTION


def exp(x: Jet) -> Jet:
    """``exp(x)``."""
    # BEGIN SOLUTION
    value = np.exp(x.value)
    return Jet(value, _times(value, x.grad))
    # END SOLUTION


def log(x: Jet) -> Jet:
    """``log(x)`` for ``x > 0``."""
    # BEGIN SOLUTION
    return Jet(np.log(x.value), _times(1.0 / x.value, x.grad))
    # END SOLUTION


def arctan2(y, x) -> Jet:
    """``arctan2(y, x)`` (the angle of the point (x, y)); either may be a constant."""
    # BEGIN SOLUTION
    yv, yg = _parts(y)
    xv, xg = _parts(x)
    r2 = xv * xv + yv * yv
    grad = 0.0
    if yg is not None:
        grad = grad + _times(xv / r2, yg)
    if xg is not None:
        grad = grad - _times(yv / r2, xg)
    return Jet(np.arctan2(yv, xv), grad)
    # END SOLUTION


def matmul(a, b) -> Jet:
    """The matrix product ``a @ b`` of stacks of matrices (..., n, m) and (..., m, p), each a Jet or a
    constant array, broadcast as numpy's ``matmul``; a vector ``b`` (m,) is a column, as there."""
    # BEGIN SOLUTION
    av, ag = _parts(a)
    bv, bg = _parts(b)
    column = bv.ndim == 1
    if column:
        bv = bv[..., None]
        bg = None if bg is None else bg[..., None, :]
    value = av @ bv
    grad = None
    if ag is not None:  # (dA B)[..., i, :, :] = B^T dA[..., i, :, :]: one batched matmul
        grad = np.swapaxes(bv, -1, -2)[..., None, :, :] @ ag
    if bg is not None:  # A dB with dB's (p, k) flattened: one batched matmul
        flat = av @ bg.reshape(bg.shape[:-2] + (-1,))
        dB = flat.reshape(flat.shape[:-1] + bg.shape[-2:])
        grad = dB if grad is None else grad + dB
    if column:
        return Jet(value[..., 0], grad[..., 0, :])
    return Jet(value, grad)
    # END SOLUTION


def _stack(arrays, axis=0):
    """``np.stack`` of Jets and constants: the derivatives stacked alike."""
    ks = {a.k for a in arrays if isinstance(a, Jet)}
    (k,) = ks
    jets = [a if isinstance(a, Jet) else Jet.constant(a, k) for a in arrays]
    ndim = jets[0].ndim + 1
    axis = axis % ndim
    return Jet(np.stack([j.value for j in jets], axis=axis), np.stack([j.grad for j in jets], axis=axis))


#: numpy's functions, sent to the rules (``np.sin(jet)`` is ``sin(jet)``)
_UFUNCS = {
    np.add: lambda a, b: a + b if isinstance(a, Jet) else b + a,
    np.subtract: lambda a, b: a - b if isinstance(a, Jet) else -(b - a),
    np.multiply: lambda a, b: a * b if isinstance(a, Jet) else b * a,
    np.true_divide: lambda a, b: a / b if isinstance(a, Jet) else b.__rtruediv__(a),
    np.negative: lambda a: -a,
    np.power: lambda a, p: a**p,
    np.sqrt: sqrt,
    np.sin: sin,
    np.cos: cos,
    np.exp: exp,
    np.log: log,
    np.arctan2: arctan2,
    np.matmul: matmul,
}
_FUNCTIONS = {np.stack: _stack}


#: the derived results, in three levels (``python -m autograder hint NAME LEVEL``; the release
#: prints levels 1..N into the docstrings with ``--hints N``, course.core.hints)
HINTS = {
    "Jet.__mul__": (
        """Write both operands as ``a + da eps`` and ``b + db eps`` with ``eps^2 = 0`` and multiply out;
        a constant operand has ``db = 0``. ``_parts`` splits an operand into value and grad (None for a
        constant).""",
        """``(a + da eps)(b + db eps) = ab + (b da + a db) eps``. ``da`` has one axis more than ``a``
        (the k directions), so the value that multiplies it needs a trailing axis: ``_times(b, da)``.""",
        """``Jet(a * b, _times(b, da) + _times(a, db))``, the second term only when ``other`` is a Jet.""",
    ),
    "Jet.__truediv__": (
        """Divide ``a + da eps`` by ``b + db eps``: multiply above and below by ``b - db eps``.""",
        """``1 / (b + db eps) = 1/b - db / b^2 eps``.""",
        """``Jet(a / b, _times(1 / b, da) - _times(a / b^2, db))``; for a constant numerator
        (``__rtruediv__``): ``Jet(c / b, _times(-c / b^2, db))``.""",
    ),
    "Jet.__pow__": (
        """Expand ``(x + dx eps)^p`` to first order; then look at ``p = 0`` and ``p = 1`` at ``x = 0``,
        where the general formula meets ``0 * inf``.""",
        """``(x + dx eps)^p = x^p + p x^(p-1) dx eps``; ``x^0`` is the constant 1 and ``x^1`` is ``x``.""",
        """``p == 0``: value 1, grad 0; ``p == 1``: a copy; else ``Jet(x**p, _times(p * x**(p - 1), dx))``.""",
    ),
    "sqrt": (
        """The chain rule with ``f = sqrt``; then decide the value at ``x = 0``, where ``f'`` is infinite.""",
        """``d sqrt(x) = dx / (2 sqrt(x))``: at ``x = 0`` it is ``dx * inf``: infinite in the sign of ``dx``,
        and ``0 * inf = nan`` where ``dx = 0`` (set those to 0: nothing depends on the seeds).""",
        """``root = sqrt(x)``; ``grad = _times(0.5 / root, dx)`` (with numpy's divide warnings off), then
        ``np.where(dx == 0, 0, grad)``.""",
    ),
    "sin": ("""The chain rule: ``f(x + dx eps) = f(x) + f'(x) dx eps``.""", """``sin' = cos``.""",
            """``Jet(np.sin(x), _times(np.cos(x), dx))``."""),
    "cos": ("""The chain rule: ``f(x + dx eps) = f(x) + f'(x) dx eps``.""", """``cos' = -sin``.""",
            """``Jet(np.cos(x), _times(-np.sin(x), dx))``."""),
    "exp": ("""The chain rule: ``f(x + dx eps) = f(x) + f'(x) dx eps``.""", """``exp' = exp``.""",
            """``Jet(e, _times(e, dx))`` with ``e = np.exp(x)``."""),
    "log": ("""The chain rule: ``f(x + dx eps) = f(x) + f'(x) dx eps``.""", """``log' = 1 / x``.""",
            """``Jet(np.log(x), _times(1 / x, dx))``."""),
    "arctan2": (
        """``arctan2(y, x)`` is the angle of (x, y); differentiate it by y and by x (either may be a
        constant) and add the two terms.""",
        """``d atan2(y, x) / dy = x / (x^2 + y^2)``, ``d / dx = -y / (x^2 + y^2)``; the value is numpy's
        ``arctan2`` (the quadrant matters).""",
        """``Jet(np.arctan2(y, x), _times(x / r2, dy) - _times(y / r2, dx))`` with ``r2 = x^2 + y^2``.""",
    ),
    "matmul": (
        """The product rule for matrices, with the k directions as a last axis of the derivative;
        handle a vector ``b`` (m,) as a column.""",
        """``d(A B) = dA B + A dB``; with ``dA`` (..., n, m, k): ``einsum("...ijk,...jl->...ilk", dA, B)``.""",
        """``value = A @ B``; ``grad = einsum("...ijk,...jl->...ilk", dA, B) + einsum("...ij,...jlk->...ilk", A,
        dB)`` (each term only for a Jet operand); for a vector ``b`` add a trailing axis and drop it after.""",
    ),
}
