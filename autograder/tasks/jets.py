"""One Jet operation on given values and derivatives, with the student's Jet class
(``checks/jets.py``), and a factor's tangent Jacobians with a Jet that carries derivatives
it is told (``checks/autodiff_factor.py``).

An operand is ``("jet", value, grad)`` (a Jet of the implementation's class), ``("array", value)``
(a constant array) or ``("number", p)`` (a Python float).
"""

import numpy as np

from autograder.tasks.common import OutputError
from course.core import jet_container
from course.core.jet_container import JetContainer

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


class TracingJet(JetContainer):
    """A Jet that carries the derivatives it is given and has no rules of its own: the residual of
    ``tangent_jacobians_task`` computes its own in closed form, so that the student's
    ``autodiff_factor`` is graded without their ``jets``. It is the container the exercise's ``jets.Jet``
    extends (``course.core.jet_container.JetContainer``: the constructor ``TracingJet(value, grad)``,
    ``seed``, ``constant``, ``shape``, ``ndim``, ``k``, ``len``, indexing and slicing, ``reshape``,
    ``swapaxes``, ``mT``, ``T``, ``transpose``, ``sum``, ``mean``, ``+``, ``-``, comparisons), with scaling
    by a number, ``abs`` and numpy's ``stack``, ``concatenate``, ``where``, ``sum``, ``mean``,
    ``transpose``, ``minimum``, ``maximum``, ``abs``, so that any use of it the contract allows is graded
    alike; the rest fails with one line."""

    def __abs__(self):
        sign = np.where(self.value < 0.0, -1.0, 1.0)
        return TracingJet(np.abs(self.value), sign[..., None] * self.grad)

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

    def __mul__(self, number):
        """Scaling by a number (a seed may be scaled; numpy's scalars and 0-d arrays too); nothing else."""
        if isinstance(number, TracingJet) or np.ndim(number) != 0:
            raise TypeError("the stand-in Jet of the autodiff_factor checks is scaled by numbers only (it has no "
                            "derivative rules): the seeds are moved by the retractions only")
        number = float(number)
        return TracingJet(number * self.value, number * self.grad)

    __rmul__ = __mul__


def _multiply(a, b):
    """Scaling by a number (``TracingJet.__mul__``)."""
    return a * b if isinstance(a, TracingJet) else b * a


_TRACING_UFUNCS: dict = {
    np.add: lambda a, b: a + b if isinstance(a, TracingJet) else b + a,
    np.subtract: lambda a, b: a - b if isinstance(a, TracingJet) else -(b - a),
    np.multiply: _multiply,
    np.negative: lambda a: -a,
    np.positive: lambda a: a,
    np.absolute: abs,
    np.minimum: jet_container.minimum,
    np.maximum: jet_container.maximum,
    **{f: jet_container.compare(f) for f in (np.less, np.less_equal, np.greater, np.greater_equal, np.equal,
                                             np.not_equal)},
}
_TRACING_FUNCTIONS: dict = {
    np.stack: jet_container.stack, np.concatenate: jet_container.concatenate, np.where: jet_container.where,
    np.sum: lambda x, axis=None, keepdims=False: x.sum(axis, keepdims),
    np.mean: lambda x, axis=None, keepdims=False: x.mean(axis, keepdims),
    np.transpose: lambda x, axes=None: x.transpose() if axes is None else x.transpose(axes),
    np.shape: lambda x: np.shape(jet_container.value_of(x)), np.ndim: lambda x: np.ndim(jet_container.value_of(x)),
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
