"""One Jet operation on given values and derivatives, with the student's Jet class
(``checks/jets.py``), and a factor's tangent Jacobians with a Jet that carries derivatives
it is told (``checks/autodiff_factor.py``).

An operand is ``("jet", value, grad)`` (a Jet of the implementation's class), ``("array", value)``
(a constant array) or ``("number", p)`` (a Python float).
"""

import numpy as np

from autograder.tasks.common import OutputError

#: how each operation is called on the operands (the rules through their methods and functions)
OPERATIONS = {
    "mul": lambda m, a, b: a * b,
    "truediv": lambda m, a, b: a / b,
    "pow": lambda m, a, p: a**p,
    "sqrt": lambda m, a: m.sqrt(a),
    "sin": lambda m, a: m.sin(a),
    "cos": lambda m, a: m.cos(a),
    "exp": lambda m, a: m.exp(a),
    "log": lambda m, a: m.log(a),
    "arctan2": lambda m, y, x: m.arctan2(y, x),
    "matmul": lambda m, a, b: m.matmul(a, b),
}


def _operand(module, spec):
    kind = spec[0]
    if kind == "jet":
        return module.Jet(np.asarray(spec[1], dtype=float), np.asarray(spec[2], dtype=float))
    if kind == "array":
        return np.asarray(spec[1], dtype=float)
    return float(spec[1])


def apply(operation, operands, impl):
    """``{"value", "grad"}`` of ``operation`` (a key of :data:`OPERATIONS`) on ``operands``."""
    module = impl.module("jets")
    out = OPERATIONS[operation](module, *(_operand(module, spec) for spec in operands))
    if not (hasattr(out, "value") and hasattr(out, "grad")):
        raise OutputError(f"returned {type(out).__name__}, expected a Jet (with value and grad)")
    return {"value": np.asarray(out.value, dtype=float), "grad": np.asarray(out.grad, dtype=float)}


def residual_on_jets(factor, z, xs, impl):
    """``{"value", "grad"}`` of the framework's factor ``factor`` (a name of
    ``course.factorgraph.factors``) on Jets of the implementation's class seeded at ``xs`` in their
    stored coordinates (k = the sum of their sizes, in slot order): the residual written once for
    arrays, run on Jets."""
    from course.factorgraph import factors

    module = impl.module("jets")
    ftype = getattr(factors, factor)
    xs = [np.asarray(x, dtype=float) for x in xs]
    sizes = [int(np.prod(x.shape[1:])) for x in xs]
    k, offset, points = int(sum(sizes)), 0, []
    for x, size in zip(xs, sizes):
        seeded = module.Jet.seed(x.reshape(len(x), size), offset, k)
        points.append(seeded.reshape(x.shape) if x.ndim > 2 else seeded)
        offset += size
    out = ftype.residual(np.asarray(z, dtype=float), *points)
    if not (hasattr(out, "value") and hasattr(out, "grad")):
        raise OutputError(f"the residual returned {type(out).__name__}, expected a Jet")
    return {"value": np.asarray(out.value, dtype=float), "grad": np.asarray(out.grad, dtype=float)}


class TracingJet:
    """A Jet that carries the derivatives it is given and has no rules of its own: the residual of
    ``tangent_jacobians_task`` computes its own in closed form, so that the student's
    ``autodiff_factor`` is graded without their ``jets``. It has what the real Jet's given part has that
    needs no derivative rule of the exercise (``course.factorgraph``'s and the exercise's ``jets.Jet``:
    the constructor ``TracingJet(value, grad)``, ``seed``, ``constant``, ``shape``, ``ndim``, ``k``,
    ``len``, indexing and slicing, ``reshape``, ``swapaxes``, ``mT``, ``T``, ``transpose``, ``sum``,
    ``mean``, ``+``, ``-``, scaling by a number, ``abs``, comparisons, and numpy's ``stack``,
    ``concatenate``, ``where``, ``sum``, ``mean``, ``transpose``, ``minimum``, ``maximum``, ``abs``),
    so that any use of it the contract allows is graded alike; the rest fails with one line."""

    def __init__(self, value, grad):
        self.value = np.asarray(value, dtype=float)
        grad = np.asarray(grad, dtype=float)
        if grad.shape[:-1] != self.value.shape:
            grad = np.broadcast_to(grad, self.value.shape + grad.shape[-1:])
        self.grad = grad

    @classmethod
    def constant(cls, value, k):
        """``value`` with a zero derivative in ``k`` directions."""
        value = np.asarray(value, dtype=float)
        return cls(value, np.zeros(value.shape + (int(k),)))

    @classmethod
    def seed(cls, value, offset, k):
        value = np.asarray(value, dtype=float)
        n = value.shape[-1]
        grad = np.zeros(value.shape + (int(k),))
        grad[..., np.arange(n), int(offset) + np.arange(n)] = 1.0
        return cls(value, grad)

    @property
    def shape(self):
        return self.value.shape

    @property
    def ndim(self):
        return self.value.ndim

    @property
    def k(self):
        return self.grad.shape[-1]

    def __len__(self):
        return len(self.value)

    def __getitem__(self, index):
        index = index if isinstance(index, tuple) else (index,)
        if any(i is Ellipsis for i in index):
            return TracingJet(self.value[index], self.grad[index + (slice(None),)])
        return TracingJet(self.value[index], self.grad[index + (Ellipsis,)] if index else self.grad)

    def reshape(self, *shape):
        value = self.value.reshape(*shape)
        return TracingJet(value, self.grad.reshape(value.shape + (self.k,)))

    def swapaxes(self, a, b):
        a, b = (axis % self.ndim for axis in (a, b))
        return TracingJet(np.swapaxes(self.value, a, b), np.swapaxes(self.grad, a, b))

    @property
    def mT(self):  # noqa: N802 (numpy's name)
        return self.swapaxes(-1, -2)

    @property
    def T(self):  # noqa: N802 (numpy's name)
        return self.transpose()

    def transpose(self, *axes):
        axes = tuple(axes[0]) if len(axes) == 1 and isinstance(axes[0], (tuple, list)) else axes
        axes = tuple(range(self.ndim))[::-1] if not axes else tuple(a % self.ndim for a in axes)
        return TracingJet(np.transpose(self.value, axes), np.transpose(self.grad, axes + (self.ndim,)))

    def sum(self, axis=None, keepdims=False):
        axes = _axes(axis, self.ndim)
        return TracingJet(self.value.sum(axis=axes, keepdims=keepdims), self.grad.sum(axis=axes, keepdims=keepdims))

    def mean(self, axis=None, keepdims=False):
        total = self.sum(axis, keepdims)
        return total * (float(total.value.size) / float(max(self.value.size, 1)))

    def __abs__(self):
        sign = np.where(self.value < 0.0, -1.0, 1.0)
        return TracingJet(np.abs(self.value), sign[..., None] * self.grad)

    def __lt__(self, other):
        return self.value < _value(other)

    def __le__(self, other):
        return self.value <= _value(other)

    def __gt__(self, other):
        return self.value > _value(other)

    def __ge__(self, other):
        return self.value >= _value(other)

    def __eq__(self, other):  # type: ignore[override]
        return self.value == _value(other)

    def __ne__(self, other):  # type: ignore[override]
        return self.value != _value(other)

    __hash__ = None  # type: ignore[assignment]

    def __array_ufunc__(self, ufunc, method, *inputs, **kwargs):
        rule = _TRACING_UFUNCS.get(ufunc)
        if method != "__call__" or kwargs or rule is None:
            raise TypeError(f"np.{ufunc.__name__} is not supported on the stand-in Jet of the autodiff_factor "
                            f"checks (it has no derivative rules): the seeds are moved by the retractions only")
        return rule(*inputs)

    def __array_function__(self, func, types, args, kwargs):
        rule = _TRACING_FUNCTIONS.get(func)
        if rule is None:
            raise TypeError(f"np.{func.__name__} is not supported on the stand-in Jet of the autodiff_factor "
                            f"checks (it has no derivative rules): the seeds are moved by the retractions only")
        return rule(*args, **kwargs)

    def __neg__(self):
        return TracingJet(-self.value, -self.grad)

    def __pos__(self):
        return self

    def __add__(self, other):
        if isinstance(other, TracingJet):
            return TracingJet(self.value + other.value, self.grad + other.grad)
        return TracingJet(self.value + np.asarray(other, dtype=float), self.grad)

    __radd__ = __add__

    def __sub__(self, other):
        return self + (-other)

    def __rsub__(self, other):
        return (-self) + other

    def __mul__(self, number):
        """Scaling by a number (a seed may be scaled; numpy's scalars and 0-d arrays too); nothing else."""
        if isinstance(number, TracingJet) or np.ndim(number) != 0:
            raise TypeError("the stand-in Jet of the autodiff_factor checks is scaled by numbers only (it has no "
                            "derivative rules): the seeds are moved by the retractions only")
        number = float(number)
        return TracingJet(number * self.value, number * self.grad)

    __rmul__ = __mul__


def _value(x):
    return x.value if isinstance(x, TracingJet) else np.asarray(x, dtype=float)


def _axes(axis, ndim):
    if axis is None:
        return tuple(range(ndim))
    return tuple(a % ndim for a in (axis if isinstance(axis, (tuple, list)) else (axis,)))


def _tracing(operands):
    """Each operand as a TracingJet (a constant with a zero derivative)."""
    ks = {a.k for a in operands if isinstance(a, TracingJet)}
    if len(ks) != 1:
        raise ValueError(f"Jets with different numbers of directions combined: k = {sorted(ks)}")
    k = ks.pop()
    return [a if isinstance(a, TracingJet) else TracingJet.constant(a, k) for a in operands]


def _stack(arrays, axis=0):
    jets = _tracing(arrays)
    axis = axis % (jets[0].ndim + 1)
    return TracingJet(np.stack([j.value for j in jets], axis=axis), np.stack([j.grad for j in jets], axis=axis))


def _concatenate(arrays, axis=0):
    jets = _tracing(arrays)
    if axis is None:
        jets, axis = [j.reshape(-1) for j in jets], 0
    axis = axis % jets[0].ndim
    return TracingJet(np.concatenate([j.value for j in jets], axis=axis),
                      np.concatenate([j.grad for j in jets], axis=axis))


def _where(mask, a, b):
    a, b = _tracing((a, b))
    mask = np.asarray(mask, dtype=bool)
    return TracingJet(np.where(mask, a.value, b.value), np.where(mask[..., None], a.grad, b.grad))


def _multiply(a, b):
    """Scaling by a number (``TracingJet.__mul__``)."""
    return a * b if isinstance(a, TracingJet) else b * a


def _compare(ufunc):
    return lambda a, b: ufunc(_value(a), _value(b))


_TRACING_UFUNCS: dict = {
    np.add: lambda a, b: a + b if isinstance(a, TracingJet) else b + a,
    np.subtract: lambda a, b: a - b if isinstance(a, TracingJet) else -(b - a),
    np.multiply: _multiply,
    np.negative: lambda a: -a,
    np.positive: lambda a: a,
    np.absolute: abs,
    np.minimum: lambda a, b: _where(~(_value(b) < _value(a)), a, b),
    np.maximum: lambda a, b: _where(~(_value(a) < _value(b)), a, b),
    **{f: _compare(f) for f in (np.less, np.less_equal, np.greater, np.greater_equal, np.equal, np.not_equal)},
}
_TRACING_FUNCTIONS: dict = {
    np.stack: _stack, np.concatenate: _concatenate, np.where: _where,
    np.sum: lambda x, axis=None, keepdims=False: x.sum(axis, keepdims),
    np.mean: lambda x, axis=None, keepdims=False: x.mean(axis, keepdims),
    np.transpose: lambda x, axes=None: x.transpose() if axes is None else x.transpose(axes),
    np.shape: lambda x: np.shape(_value(x)), np.ndim: lambda x: np.ndim(_value(x)),
}


def _flat(point, M, size, k):
    """``(value (M, size), grad (M, size, k) or None)`` of a TracingJet or an array."""
    if isinstance(point, TracingJet):
        return point.value.reshape(M, size), point.grad.reshape(M, size, -1)
    return np.asarray(point, dtype=float).reshape(M, size), None


def tangent_jacobians_task(kinds, xs, plus, C, D, impl):
    """``autodiff_factor.tangent_jacobians`` of ``r = sum_a C_a vec(p_a) + (sum_a D_a vec(p_a))^2``
    (entrywise square; ``C_a``, ``D_a`` (M, m, size_a)) on variables of ``kinds`` at ``xs``, with the
    plus-Jacobians ``plus`` (M, size_a, d_a).

    Fields: ``r`` (M, m), ``count`` (how many blocks came back), ``J0``, ``J1``, ... the blocks."""
    sizes = [int(np.prod(np.shape(x)[1:])) for x in xs]
    M = len(xs[0])

    def residual(*points):
        flats = [_flat(p, M, s, None) for p, s in zip(points, sizes)]
        s_lin = sum(np.einsum("mij,mj->mi", Ca, v) for Ca, (v, _) in zip(C, flats))
        s_sq = sum(np.einsum("mij,mj->mi", Da, v) for Da, (v, _) in zip(D, flats))
        value = s_lin + s_sq**2
        grads = [(np.asarray(Ca) + 2.0 * s_sq[:, :, None] * np.asarray(Da), g)
                 for Ca, Da, (_, g) in zip(C, D, flats) if g is not None]
        if not grads:
            return value
        return TracingJet(value, sum(np.matmul(A, g) for A, g in grads))

    module = impl.module("autodiff_factor")
    out = module.tangent_jacobians(residual, [np.array(P, dtype=float) for P in plus],
                                   [np.array(x, dtype=float) for x in xs], TracingJet)
    if not isinstance(out, tuple) or len(out) != 2:
        raise OutputError(f"returned {type(out).__name__}, expected a tuple (r, [J_1, ..., J_s])")
    r, J = out
    fields = {"r": np.asarray(r, dtype=float), "count": float(len(J))}
    for a, block in enumerate(J):
        fields[f"J{a}"] = np.asarray(block, dtype=float)
    return fields
