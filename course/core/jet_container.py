"""The container of a Jet (chapter 7): a batch of numbers ``value`` (...,) with their derivatives in ``k``
directions ``grad`` (..., k), and everything about it that needs no derivative rule.

``JetContainer`` holds the constructor (a ``grad`` broadcast to ``value``'s shape plus its last axis),
``constant``, ``seed``, ``shape``, ``ndim``, ``k``, ``len``, indexing and slicing, ``reshape``,
``swapaxes``, ``.mT``, ``.T``, ``transpose``, ``sum``, ``mean`` (by a product with a number), ``+`` and
``-`` (with another Jet or a constant, whose derivative is 0) and the comparisons (they compare the
values: a boolean array, no derivative). Each returns its own class (``type(self)``): the exercise's
``jets.Jet`` extends it with the derivative rules, and the autograder's stand-in Jet
(``autograder/tasks/jets.py``) with a product by numbers alone. The functions below are numpy's
``stack``, ``concatenate``, ``where``, ``minimum`` and ``maximum`` on Jets and constants, with the
helpers they share.
"""

import numpy as np


class JetContainer:
    """``value`` (...,) and ``grad`` (..., k); a subclass gives the derivative rules (``*``, ``/``, ...)."""

    __array_priority__ = 1000  # numpy defers ``array * jet`` to ``jet.__rmul__``

    def __init__(self, value, grad):
        self.value = np.asarray(value, dtype=float)
        grad = np.asarray(grad, dtype=float)
        if grad.shape[:-1] != self.value.shape:
            grad = np.broadcast_to(grad, self.value.shape + grad.shape[-1:])
        self.grad = grad

    @classmethod
    def constant(cls, value, k: int):
        """``value`` with a zero derivative in ``k`` directions."""
        value = np.asarray(value, dtype=float)
        return cls(value, np.zeros(value.shape + (int(k),)))

    @classmethod
    def seed(cls, value, offset: int, k: int):
        """``value`` (..., n) as the variables ``offset .. offset + n - 1`` of ``k``: the derivative of
        its entry ``[..., i]`` is the unit vector ``offset + i``."""
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
    def k(self) -> int:
        return self.grad.shape[-1]

    def __len__(self):
        return len(self.value)

    def __getitem__(self, index):
        index = index if isinstance(index, tuple) else (index,)
        if any(i is Ellipsis for i in index):
            return type(self)(self.value[index], self.grad[index + (slice(None),)])
        return type(self)(self.value[index], self.grad[index + (Ellipsis,)] if index else self.grad)

    def reshape(self, *shape):
        """``value`` reshaped (as ``ndarray.reshape``); each entry keeps its derivative."""
        value = self.value.reshape(*shape)
        return type(self)(value, self.grad.reshape(value.shape + (self.k,)))

    def swapaxes(self, a: int, b: int):
        """Axes ``a`` and ``b`` of ``value`` swapped (negative axes count from ``value``'s last)."""
        a, b = (axis % self.ndim for axis in (a, b))
        return type(self)(np.swapaxes(self.value, a, b), np.swapaxes(self.grad, a, b))

    @property
    def mT(self):  # noqa: N802 (numpy's name)
        """The matrix transpose of the last two axes (as ``ndarray.mT``)."""
        return self.swapaxes(-1, -2)

    @property
    def T(self):  # noqa: N802 (numpy's name)
        """All of ``value``'s axes reversed (as ``ndarray.T``)."""
        return self.transpose()

    def transpose(self, *axes):
        """``value``'s axes permuted (as ``ndarray.transpose``; none given: reversed)."""
        axes = tuple(axes[0]) if len(axes) == 1 and isinstance(axes[0], (tuple, list)) else axes
        axes = tuple(range(self.ndim))[::-1] if not axes else tuple(a % self.ndim for a in axes)
        return type(self)(np.transpose(self.value, axes), np.transpose(self.grad, axes + (self.ndim,)))

    def sum(self, axis=None, keepdims=False):
        """The sum over ``value``'s ``axis`` (an int, a tuple of them, or all of them)."""
        axes = axes_of(axis, self.ndim)
        return type(self)(self.value.sum(axis=axes, keepdims=keepdims), self.grad.sum(axis=axes, keepdims=keepdims))

    def mean(self, axis=None, keepdims=False):
        """The mean over ``value``'s ``axis`` (an int, a tuple of them, or all of them)."""
        total = self.sum(axis, keepdims)
        return total * (float(total.value.size) / float(max(self.value.size, 1)))

    def __repr__(self):
        return f"{type(self).__name__}(value={self.value!r}, grad={self.grad!r})"

    def __neg__(self):
        return type(self)(-self.value, -self.grad)

    def __pos__(self):
        return self

    def __add__(self, other):
        if isinstance(other, JetContainer):
            return type(self)(self.value + other.value, self.grad + other.grad)
        return type(self)(self.value + np.asarray(other, dtype=float), self.grad)

    __radd__ = __add__

    def __sub__(self, other):
        if isinstance(other, JetContainer):
            return type(self)(self.value - other.value, self.grad - other.grad)
        return type(self)(self.value - np.asarray(other, dtype=float), self.grad)

    def __rsub__(self, other):
        return (-self) + other

    # comparisons compare the values: a boolean array, as numpy's (no derivative)
    def __lt__(self, other):
        return self.value < value_of(other)

    def __le__(self, other):
        return self.value <= value_of(other)

    def __gt__(self, other):
        return self.value > value_of(other)

    def __ge__(self, other):
        return self.value >= value_of(other)

    def __eq__(self, other):  # type: ignore[override]
        return self.value == value_of(other)

    def __ne__(self, other):  # type: ignore[override]
        return self.value != value_of(other)

    __hash__ = None  # type: ignore[assignment]  # comparisons give arrays, as numpy's: no hash


def value_of(x):
    """The value of a Jet, or the constant as an array."""
    return x.value if isinstance(x, JetContainer) else np.asarray(x, dtype=float)


def axes_of(axis, ndim: int) -> tuple:
    """``axis`` (None, an int or a tuple) as a tuple of non-negative axes of ``ndim``."""
    if axis is None:
        return tuple(range(ndim))
    return tuple(a % ndim for a in (axis if isinstance(axis, (tuple, list)) else (axis,)))


def directions(operands) -> int:
    """The number of directions of the Jets among ``operands`` (all alike)."""
    ks = {a.k for a in operands if isinstance(a, JetContainer)}
    if len(ks) != 1:
        raise ValueError(f"Jets with different numbers of directions combined: k = {sorted(ks)}")
    return ks.pop()


def as_jets(operands) -> list:
    """Each operand as a Jet of the first Jet's class (a constant with a zero derivative)."""
    k = directions(operands)
    cls = type(next(a for a in operands if isinstance(a, JetContainer)))
    return [a if isinstance(a, JetContainer) else cls.constant(a, k) for a in operands]


def stack(arrays, axis=0):
    """``np.stack`` of Jets and constants: the derivatives stacked alike."""
    jets = as_jets(arrays)
    axis = axis % (jets[0].ndim + 1)
    return type(jets[0])(np.stack([j.value for j in jets], axis=axis), np.stack([j.grad for j in jets], axis=axis))


def concatenate(arrays, axis=0):
    """``np.concatenate`` of Jets and constants along ``axis`` (None: flattened)."""
    jets = as_jets(arrays)
    if axis is None:
        jets, axis = [j.reshape(-1) for j in jets], 0
    axis = axis % jets[0].ndim
    return type(jets[0])(np.concatenate([j.value for j in jets], axis=axis),
                         np.concatenate([j.grad for j in jets], axis=axis))


def where(mask, a, b):
    """``np.where(mask, a, b)``: the value and the derivative of the operand the mask picks."""
    a, b = as_jets((a, b))
    mask = np.asarray(mask, dtype=bool)
    return type(a)(np.where(mask, a.value, b.value), np.where(mask[..., None], a.grad, b.grad))


def minimum(a, b):
    """``np.minimum(a, b)``: the smaller operand; at a tie the first."""
    return where(~(value_of(b) < value_of(a)), a, b)


def maximum(a, b):
    """``np.maximum(a, b)``: the larger operand; at a tie the first."""
    return where(~(value_of(a) < value_of(b)), a, b)


def compare(ufunc):
    """A numpy comparison on Jets and constants: it compares the values."""
    return lambda a, b: ufunc(value_of(a), value_of(b))
