"""Chapter 7 exercise: Jets, forward-mode automatic differentiation in numpy.

A Jet is a number together with its derivative in ``k`` seeded directions: ``value`` (...,) and
``grad`` (..., k), ``grad[..., j] = d value / d seed_j``. It is the first-order truncation of
``value + sum_j grad_j eps_j`` with ``eps_i eps_j = 0`` (a dual number), so every operation obeys
the chain rule: ``f(a + da) = f(a) + f'(a) da``. A residual written for numpy arrays runs on Jets
unchanged: numpy's functions (``np.sin(x)``, ``np.sqrt(x)``, ``x @ y``) call :meth:`Jet.__array_ufunc__`,
which sends them to the rules of this module; an array of Jets is one Jet with ``value`` of
that shape (a batch of M rotation matrices is ``value`` (M, 3, 3), ``grad`` (M, 3, 3, k)).

The container is given, ``course.core.jet_container.JetContainer``, which ``Jet`` extends: the
constructor, ``seed``, ``constant``, indexing, ``reshape``, ``.T``, ``sum``, ``+``, ``-`` and the
like, which need no derivative rule.

Given with the Jet, built from your rules (so they are right when your rules are): ``abs`` and
``np.abs`` (the sign decided by the value: at 0 the derivative is ``+dx``, as Ceres' ``abs``),
comparisons (``x < 0`` compares the values and gives a boolean array), ``np.where``,
``np.minimum`` and ``np.maximum`` (at a tie the first operand's derivative), ``np.sum``,
``np.mean``, ``np.stack``, ``np.concatenate``, ``.T`` and ``np.transpose``, ``np.linalg.norm``
(scaled; at 0 the derivative is 0, as ``np.sqrt(x * x)``'s), ``np.dot``, ``np.einsum``, ``@`` with a
1-D operand on either side, ``np.arctan`` (``arctan2(x, 1)``), ``np.tanh`` (by ``exp(-2|x|)``) and
``np.hypot`` (scaled; at (0, 0) the derivative is 0). Their values are numpy's. Any other numpy
function on a Jet fails with one line naming it and what to write instead.

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
- x ** p with 0 < p < 1 at x = 0: value 0, derivative 0 where x's derivative is 0, else +-inf in its sign
- arctan2 on each axis (y = 0 with x < 0 gives pi)
- arctan2 at magnitudes whose squares overflow or underflow (x, y ~ 1e200 and ~ 1e-200): finite derivatives
- one direction (k = 1) and a scalar Jet (value of shape ())

Allowed imports: numpy, scipy, course.core.jet_container.
"""

import numpy as np

from course.core.jet_container import (
    JetContainer,
    axes_of,
    compare,
    concatenate,
    maximum,
    minimum,
    stack,
    value_of,
    where,
)


def _parts(x):
    """``(value, grad or None)`` of a Jet or a constant."""
    if isinstance(x, Jet):
        return x.value, x.grad
    return np.asarray(x, dtype=float), None


def _times(factor, grad):
    """``factor[..., None] * grad`` (the chain rule's product), broadcast."""
    return np.asarray(factor)[..., None] * grad


class Jet(JetContainer):
    """``value`` (...,) and ``grad`` (..., k): a batch of numbers with their derivatives in k directions.

    Given (``course.core.jet_container.JetContainer``): the constructor ``Jet(value, grad)``, ``constant``,
    ``seed``, ``shape``, ``ndim``, ``k``, ``len``, indexing, ``reshape``, ``swapaxes``, ``.mT``, ``.T``,
    ``transpose``, ``sum``, ``mean``, ``+``, ``-`` and the comparisons."""

    def __abs__(self):
        return _abs(self)

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
        with np.errstate(divide="ignore", invalid="ignore"):
            grad = _times(p * self.value ** (p - 1.0), self.grad)
        if p < 1.0:  # x^(p-1) is infinite at x = 0: 0 * inf = nan where nothing moves
            grad = np.where(self.grad == 0.0, 0.0, grad)
        return Jet(self.value**p, grad)
        # END SOLUTION

    def __matmul__(self, other):
        return _matmul(self, other)

    def __rmatmul__(self, other):
        return _matmul(other, self)

    # --------------------------------------------------------------- given: numpy's functions call the rules

    def __array_ufunc__(self, ufunc, method, *inputs, **kwargs):
        name = f"np.{ufunc.__name__}"
        if method != "__call__":
            raise TypeError(f"{name}.{method} is not supported on Jets: {_ALTERNATIVES.get(name + '.' + method, _ANY)}")
        if kwargs:
            raise TypeError(f"{name}(..., {', '.join(kwargs)}=...) is not supported on Jets: call {name} without "
                            f"keyword arguments")
        rule = _UFUNCS.get(ufunc)
        if rule is None:
            raise TypeError(_unsupported(name))
        return rule(*inputs)

    def __array_function__(self, func, types, args, kwargs):
        rule = _FUNCTIONS.get(func)
        if rule is None:
            raise TypeError(_unsupported("np" + func.__module__[len("numpy"):] + "." + func.__name__))
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
    scale = np.maximum(np.abs(xv), np.abs(yv))  # x^2 + y^2 = scale * r: no overflow, no underflow
    xs, ys = xv / scale, yv / scale
    r = scale * (xs * xs + ys * ys)
    grad = 0.0
    if yg is not None:
        grad = grad + _times(xs / r, yg)
    if xg is not None:
        grad = grad - _times(ys / r, xg)
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


# --------------------------------------------------------------- given: more of numpy, from your rules


def _abs(x):
    """``|x|`` as ``x`` times its sign, decided by the value; at 0 the sign is + (derivative ``dx``)."""
    signed = x * np.where(x.value < 0.0, -1.0, 1.0)
    return Jet(np.abs(x.value), signed.grad)


def _sum(x, axis=None, keepdims=False):
    return x.sum(axis, keepdims)


def _mean(x, axis=None, keepdims=False):
    return x.mean(axis, keepdims)


def _transpose(x, axes=None):
    return x.transpose() if axes is None else x.transpose(axes)


def _matmul(a, b):
    """``a @ b`` by your ``matmul``, a 1-D ``a`` (n,) taken as a row (1, n) and the axis dropped after."""
    if np.ndim(value_of(a)) != 1:
        return matmul(a, b)
    out = matmul(a[None, :], b)
    return out[0] if np.ndim(value_of(b)) == 1 else out[..., 0, :]


def _dot(a, b):
    """``np.dot(a, b)`` of 0-, 1- and 2-D operands: a product, ``a @ b`` or the scalar ``sum(a * b)``."""
    na, nb = np.ndim(value_of(a)), np.ndim(value_of(b))
    if na == 0 or nb == 0:
        return a * b if isinstance(a, Jet) else b * a
    if na > 2 or nb > 2:
        raise TypeError("np.dot of arrays beyond 2-D is not supported on Jets: use @ (a stack of matrices) or "
                        "np.einsum")
    return _matmul(a, b)


def _einsum(subscripts, *operands, **kwargs):
    """``np.einsum`` of Jets and constants (explicit or implicit output, ``...`` broadcast): each operand
    laid out on all the subscripts' letters, multiplied by your ``*`` and summed over the letters the
    output drops. A letter repeated in one operand takes its diagonal first."""
    if kwargs or not isinstance(subscripts, str):
        raise TypeError("np.einsum on Jets takes the subscripts as a string and no keyword arguments")
    spec = subscripts.replace(" ", "")
    inputs, _, output = spec.partition("->")
    terms = inputs.split(",")
    if len(terms) != len(operands):
        raise ValueError(f"np.einsum: {len(terms)} operands in {subscripts!r}, {len(operands)} given")
    ranks = [np.ndim(value_of(x)) - len(s.replace("...", "")) for s, x in zip(terms, operands)]
    spare = [c for c in "ABCDEFGHIJKLMNOPQRSTUVWXYZ" if c not in spec]
    wide = max(ranks) if any("..." in s for s in terms) else 0
    ellipsis = "".join(spare[:wide])
    terms = [s.replace("...", ellipsis[wide - n:] if n else "") for s, n in zip(terms, ranks)]
    if "->" not in spec:
        letters = "".join(terms)
        output = ellipsis + "".join(sorted(c for c in set(letters) if letters.count(c) == 1 and c not in ellipsis))
    else:
        output = output.replace("...", ellipsis)
    k_letter = spare[wide]
    order = "".join(dict.fromkeys("".join(terms) + output))  # every letter once, output's last
    laid = []
    for s, x in zip(terms, operands):
        unique = "".join(dict.fromkeys(s))
        if unique != s:  # a repeated letter: its diagonal (a linear selection, no derivative rule)
            if isinstance(x, Jet):
                x = Jet(np.einsum(f"{s}->{unique}", x.value),
                        np.einsum(f"{s}{k_letter}->{unique}{k_letter}", x.grad))
            else:
                x = np.einsum(f"{s}->{unique}", value_of(x))
        present = [c for c in order if c in unique]
        x = x.transpose([unique.index(c) for c in present]) if isinstance(x, Jet) else \
            np.transpose(value_of(x), [unique.index(c) for c in present])
        shape = tuple(x.shape[present.index(c)] if c in present else 1 for c in order)
        laid.append(x.reshape(shape))
    product = laid[0]
    for x in laid[1:]:
        product = product * x if isinstance(product, Jet) else x * product
    dropped = tuple(i for i, c in enumerate(order) if c not in output)
    total = product.sum(axis=dropped) if dropped else product
    kept = [c for c in order if c in output]
    return total.transpose([kept.index(c) for c in output]) if output else total


def _norm(x, ord=None, axis=None, keepdims=False):
    """``np.linalg.norm`` (the 2-norm, or Frobenius over two axes): ``s sqrt(sum((x / s)^2))`` with ``s``
    the largest ``|x|`` (no overflow); at 0 the derivative is 0, as ``np.sqrt(x * x)``'s."""
    if ord not in (None, 2, "fro"):
        raise TypeError(f"np.linalg.norm(..., ord={ord!r}) is not supported on Jets: the 2-norm only; write "
                        f"other norms with abs, np.sum and np.maximum")
    axes = axes_of(axis, x.ndim)
    scale = np.max(np.abs(x.value), axis=axes, keepdims=True) if x.value.size else np.ones(())
    scale = np.where(scale == 0.0, 1.0, scale)
    scaled = x * (1.0 / scale)
    root = sqrt((scaled * scaled).sum(axes, keepdims)) * (scale if keepdims else np.squeeze(scale, axes))
    return Jet(np.linalg.norm(x.value, axis=axis, keepdims=keepdims), root.grad)


def _hypot(a, b):
    """``np.hypot(a, b)`` as ``s sqrt((a / s)^2 + (b / s)^2)``, ``s = max(|a|, |b|)``: no overflow; at (0, 0)
    the derivative is 0."""
    value = np.hypot(value_of(a), value_of(b))
    scale = np.maximum(np.abs(value_of(a)), np.abs(value_of(b)))
    scale = np.where(scale == 0.0, 1.0, scale)
    a, b = a * (1.0 / scale), b * (1.0 / scale)
    return Jet(value, (sqrt(a * a + b * b) * scale).grad)


def _arctan(x):
    """``arctan(x) = arctan2(x, 1)``."""
    return Jet(np.arctan(x.value), arctan2(x, 1.0).grad)


def _tanh(x):
    """``tanh(x) = s (1 - e) / (1 + e)`` with ``e = exp(-2 |x|)`` (in (0, 1]: no overflow) and ``s`` the sign."""
    sign = np.where(x.value < 0.0, -1.0, 1.0)
    e = exp(x * (-2.0 * sign))
    return Jet(np.tanh(x.value), ((1.0 - e) / (1.0 + e) * sign).grad)


#: what to write for a numpy function Jets do not have (the rest: :data:`_ANY`)
_ALTERNATIVES = {
    "np.tan": "write np.sin(x) / np.cos(x)",
    "np.arcsin": "write np.arctan2(x, np.sqrt(1 - x * x))",
    "np.arccos": "write np.arctan2(np.sqrt(1 - x * x), x)",
    "np.sinh": "write (np.exp(x) - np.exp(-x)) / 2",
    "np.cosh": "write (np.exp(x) + np.exp(-x)) / 2",
    "np.square": "write x * x (or x ** 2)",
    "np.log1p": "write np.log(1 + x)",
    "np.expm1": "write np.exp(x) - 1",
    "np.log10": "write np.log(x) / np.log(10)",
    "np.log2": "write np.log(x) / np.log(2)",
    "np.cbrt": "write np.where(x < 0, -1.0, 1.0) * abs(x) ** (1 / 3)",
    "np.sign": "write np.where(x < 0, -1.0, 1.0) (a constant)",
    "np.fmin": "write np.minimum(a, b)",
    "np.fmax": "write np.maximum(a, b)",
    "np.floor": "a step has no derivative: decide it on the value, np.floor(x.value)",
    "np.round": "a step has no derivative: decide it on the value, np.round(x.value)",
    "np.clip": "write np.minimum(np.maximum(x, low), high)",
    "np.max": "write np.maximum of the entries, or pick with np.where",
    "np.min": "write np.minimum of the entries, or pick with np.where",
    "np.prod": "write the product of the entries with *",
    "np.cross": "write the components with * and -, then np.stack",
    "np.outer": "write a[:, None] * b[None, :]",
    "np.inner": "write np.sum(a * b, axis=-1)",
    "np.vdot": "write np.sum(a * b)",
    "np.trace": "write np.einsum('...ii->...', A)",
    "np.zeros_like": "write np.zeros(x.shape) (a constant)",
    "np.ones_like": "write np.ones(x.shape) (a constant)",
    "np.linalg.inv": "write the inverse of a small matrix by its cofactors over its determinant",
    "np.linalg.det": "write the determinant of a small matrix by its cofactors",
    "np.linalg.solve": "write the inverse of a small matrix by its cofactors, then @",
    "np.add.reduce": "write np.sum(x, axis)",
}


def _unsupported(name: str) -> str:
    """One line: ``name`` is not supported on Jets, and what to write instead."""
    return f"{name} is not supported on Jets: {_ALTERNATIVES.get(name, _ANY)}"


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
    np.matmul: _matmul,
    np.absolute: _abs,
    np.positive: lambda a: a,
    np.arctan: _arctan,
    np.tanh: _tanh,
    np.hypot: _hypot,
    np.minimum: minimum,
    np.maximum: maximum,
    np.less: compare(np.less),
    np.less_equal: compare(np.less_equal),
    np.greater: compare(np.greater),
    np.greater_equal: compare(np.greater_equal),
    np.equal: compare(np.equal),
    np.not_equal: compare(np.not_equal),
}
_FUNCTIONS = {np.stack: stack, np.concatenate: concatenate, np.where: where, np.sum: _sum, np.mean: _mean,
              np.transpose: _transpose, np.dot: _dot, np.einsum: _einsum, np.linalg.norm: _norm,
              np.shape: lambda x: np.shape(value_of(x)), np.ndim: lambda x: np.ndim(value_of(x))}
#: what Jets support, for the message of the rest
_ANY = "write it with what Jets support: +, -, *, /, **, @, abs, comparisons, .T, " + ", ".join(sorted(
    {f"np.{f.__name__}" for f in _UFUNCS if f not in (np.add, np.subtract, np.multiply, np.true_divide, np.negative,
                                                       np.positive, np.power, np.matmul, np.absolute, np.less,
                                                       np.less_equal, np.greater, np.greater_equal, np.equal,
                                                       np.not_equal)}
    | {"np.sum", "np.mean", "np.stack", "np.concatenate", "np.where", "np.transpose", "np.dot", "np.einsum",
       "np.linalg.norm"}))


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
        """Expand ``(x + dx eps)^p`` to first order; then look at ``p = 0``, ``p = 1`` and ``0 < p < 1`` at
        ``x = 0``, where the general formula meets ``0 * inf``.""",
        """``(x + dx eps)^p = x^p + p x^(p-1) dx eps``; ``x^0`` is the constant 1 and ``x^1`` is ``x``; for
        ``0 < p < 1`` at 0, as for sqrt, set the derivative to 0 where ``dx = 0``.""",
        """``p == 0``: value 1, grad 0; ``p == 1``: a copy; else ``grad = _times(p * x**(p - 1), dx)`` (numpy's
        divide warnings off), then ``Jet(x**p, np.where(dx == 0, 0, grad))``.""",
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
        ``arctan2`` (the quadrant matters). ``x^2 + y^2`` overflows beyond 1e154: scale x and y by
        ``s = max(|x|, |y|)`` first.""",
        """``Jet(np.arctan2(y, x), _times(xs / r, dy) - _times(ys / r, dx))`` with ``xs, ys = x / s, y / s``
        and ``r = s (xs^2 + ys^2)`` (``= (x^2 + y^2) / s``), ``s = max(|x|, |y|)``.""",
    ),
    "matmul": (
        """The product rule for matrices, with the k directions as a last axis of the derivative;
        handle a vector ``b`` (m,) as a column.""",
        """``d(A B) = dA B + A dB``; with ``dA`` (..., n, m, k): ``einsum("...ijk,...jl->...ilk", dA, B)``.""",
        """``value = A @ B``; ``grad = einsum("...ijk,...jl->...ilk", dA, B) + einsum("...ij,...jlk->...ilk", A,
        dB)`` (each term only for a Jet operand); for a vector ``b`` add a trailing axis and drop it after.""",
    ),
}
