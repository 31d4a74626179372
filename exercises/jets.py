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
        raise NotImplementedError("TODO jets.Jet.__mul__: not implemented yet")

    __rmul__ = __mul__

    def __truediv__(self, other):
        """``self / other``."""
        raise NotImplementedError("TODO jets.Jet.__truediv__: not implemented yet")

    def __rtruediv__(self, other):
        """``other / self`` for a constant ``other``."""
        raise NotImplementedError("TODO jets.Jet.__rtruediv__: not implemented yet")

    def __pow__(self, p):
        """``self ** p`` for a constant real ``p`` (a number, not a Jet)."""
        raise NotImplementedError("TODO jets.Jet.__pow__: not implemented yet")

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
    raise NotImplementedError("TODO jets.sqrt: not implemented yet")


def sin(x: Jet) -> Jet:
    """``sin(x)``."""
    raise NotImplementedError("TODO jets.sin: not implemented yet")


def cos(x: Jet) -> Jet:
    """``cos(x)``."""
    raise NotImplementedError("TODO jets.cos: not implemented yet")


def exp(x: Jet) -> Jet:
    """``exp(x)``."""
    raise NotImplementedError("TODO jets.exp: not implemented yet")


def log(x: Jet) -> Jet:
    """``log(x)`` for ``x > 0``."""
    raise NotImplementedError("TODO jets.log: not implemented yet")


def arctan2(y, x) -> Jet:
    """``arctan2(y, x)`` (the angle of the point (x, y)); either may be a constant."""
    raise NotImplementedError("TODO jets.arctan2: not implemented yet")


def matmul(a, b) -> Jet:
    """The matrix product ``a @ b`` of stacks of matrices (..., n, m) and (..., m, p), each a Jet or a
    constant array, broadcast as numpy's ``matmul``; a vector ``b`` (m,) is a column, as there."""
    raise NotImplementedError("TODO jets.matmul: not implemented yet")


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
