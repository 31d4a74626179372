"""The numpy a residual is written with, on chapter 7's Jets (the given part of ``solutions/jets.py``, built
from the student's rules): each function's value against numpy's and its derivative against central
differences or the analytic one, at the edges too; a residual written with them solved by the factor
graph with automatic Jacobians as with numeric ones; and one line for what Jets do not support."""

import numpy as np
import pytest

from course.core import impl as impl_loader
from course.factorgraph import SE2, FactorGraph, FactorGraphProblem, FactorType, Vector
from course.solver import minimize

JETS = impl_loader.load("solutions").module("jets")
Jet = JETS.Jet
#: central differences with this step agree with exact derivatives of smooth functions of O(1) to about this
CD_STEP, CD_TOL = 1e-6, 1e-7


def seeded(*xs):
    """Jets of ``xs`` (any shapes) seeded in ``k = sum of their sizes`` directions, in order."""
    xs = [np.asarray(x, dtype=float) for x in xs]
    k, offset, out = sum(x.size for x in xs), 0, []
    for x in xs:
        grad = np.zeros((x.size, k))
        grad[np.arange(x.size), offset + np.arange(x.size)] = 1.0
        out.append(Jet(x, grad.reshape(x.shape + (k,))))
        offset += x.size
    return out


def central(f, *xs, h=CD_STEP):
    """The Jacobian (size of f, sum of the inputs' sizes) of ``f`` by central differences."""
    xs = [np.asarray(x, dtype=float) for x in xs]
    flat = np.concatenate([x.ravel() for x in xs])
    cuts = np.cumsum([x.size for x in xs])[:-1]

    def at(v):
        return np.asarray(f(*[p.reshape(x.shape) for p, x in zip(np.split(v, cuts), xs)]), dtype=float).ravel()

    return np.stack([(at(flat + h * e) - at(flat - h * e)) / (2 * h) for e in np.eye(flat.size)], axis=1)


def agrees(f, *xs, tol=CD_TOL):
    """``f`` on Jets: its value is numpy's on arrays and its derivative central differences'."""
    out = f(*seeded(*xs))
    want = np.asarray(f(*[np.asarray(x, dtype=float) for x in xs]), dtype=float)
    assert isinstance(out, Jet) and out.value.shape == want.shape
    np.testing.assert_allclose(out.value, want, rtol=1e-14, atol=1e-15)
    np.testing.assert_allclose(out.grad.reshape(want.size, -1), central(f, *xs), rtol=tol, atol=tol)


RNG = np.random.default_rng(44)
V3, W3 = np.array([0.4, -1.3, 0.9]), np.array([-0.7, 0.2, 1.1])
A23, B33 = RNG.normal(size=(2, 3)), RNG.normal(size=(3, 3))
STACK = RNG.normal(size=(4, 3, 3))

CASES = {
    "abs": (lambda x: abs(x), [V3]),
    "np.abs": (lambda x: np.abs(x), [V3]),
    "np.where by a comparison": (lambda x: np.where(x < 0, -2.0 * x, x * x), [V3]),
    "np.where with a constant": (lambda x: np.where(x > 0.5, x, 0.25), [V3]),
    "np.minimum": (lambda x, y: np.minimum(x, y), [V3, W3]),
    "np.maximum with a constant": (lambda x: np.maximum(x, 0.1), [V3]),
    "np.sum": (lambda X: np.sum(X * X), [A23]),
    "np.sum over an axis": (lambda X: np.sum(X, axis=0), [A23]),
    "sum over two axes, kept": (lambda X: (X * X).sum(axis=(0, 1), keepdims=True), [A23]),
    "np.mean": (lambda X: np.mean(X * X, axis=-1), [A23]),
    "np.stack with a constant": (lambda x: np.stack([x, np.ones(3), x * x], axis=-1), [V3]),
    "np.concatenate": (lambda x, y: np.concatenate([x, 2.0 * y, np.zeros(2)]), [V3, W3]),
    "np.concatenate on axis 1": (lambda X: np.concatenate([X, X * X], axis=1), [A23]),
    "np.linalg.norm": (lambda x: np.linalg.norm(x), [V3]),
    "np.linalg.norm over an axis": (lambda X: np.linalg.norm(X, axis=-1), [A23]),
    "np.linalg.norm kept": (lambda X: np.linalg.norm(X, axis=0, keepdims=True), [A23]),
    "np.linalg.norm of a matrix (Frobenius)": (lambda X: np.linalg.norm(X), [A23]),
    "np.dot of vectors": (lambda x, y: np.dot(x, y), [V3, W3]),
    "np.dot of a matrix and a vector": (lambda X, y: np.dot(X, y), [A23, W3]),
    "np.dot of a vector and a matrix": (lambda x, B: np.dot(x, B), [V3, B33]),
    "np.dot of matrices": (lambda X, B: np.dot(X, B), [A23, B33]),
    "np.dot by a number": (lambda x: np.dot(x, 2.5), [V3]),
    "np.einsum matrix-vector": (lambda X, y: np.einsum("ij,j->i", X, y), [A23, W3]),
    "np.einsum matrix-matrix": (lambda X, B: np.einsum("ij,jk->ik", X, B), [A23, B33]),
    "np.einsum implicit": (lambda X, B: np.einsum("ij,jk", X, B), [A23, B33]),
    "np.einsum batched": (lambda S, y: np.einsum("mab,b->ma", S, y), [STACK, W3]),
    "np.einsum with ellipsis": (lambda S, T: np.einsum("...ij,...jk->...ik", S, T), [STACK, B33]),
    "np.einsum dot": (lambda x, y: np.einsum("i,i", x, y), [V3, W3]),
    "np.einsum outer": (lambda x, y: np.einsum("i,j->ij", x, y), [V3, W3]),
    "np.einsum trace": (lambda B: np.einsum("ii->", B), [B33]),
    "np.einsum transpose": (lambda X: np.einsum("ij->ji", X), [A23]),
    "np.einsum a constant": (lambda x: np.einsum("ij,j->i", A23, x), [W3]),
    "np.einsum output reordered": (lambda X, B: np.einsum("ij,jk->ki", X, B), [A23, B33]),
    "np.einsum batched products": (lambda S, T: np.einsum("mij,mjk->mik", S, T), [STACK, STACK]),
    "np.einsum batched trace": (lambda S: np.einsum("mii->m", S), [STACK]),
    "np.einsum three operands": (lambda x, B, y: np.einsum("i,ij,j->", x, B, y), [V3, B33, W3]),
    ".T": (lambda X: X.T @ X, [A23]),
    "np.transpose": (lambda S: np.transpose(S, (1, 0, 2)), [STACK]),
    "1-D @ 1-D": (lambda x, y: x @ y, [V3, W3]),
    "1-D @ matrix": (lambda x, B: x @ B, [V3, B33]),
    "1-D @ a stack": (lambda x, S: x @ S, [V3, STACK]),
    "constant 1-D @ matrix": (lambda B: W3 @ B, [B33]),
    "matrix @ 1-D": (lambda B, x: B @ x, [B33, V3]),
    "np.arctan": (lambda x: np.arctan(x), [V3]),
    "np.tanh": (lambda x: np.tanh(x), [V3]),
    "np.hypot": (lambda x, y: np.hypot(x, y), [V3, W3]),
    "np.hypot with a constant": (lambda x: np.hypot(x, 2.0), [V3]),
    "(x * x) ** 0.5 away from 0": (lambda x: (x * x) ** 0.5, [V3]),
}


@pytest.mark.parametrize("name", sorted(CASES))
def test_each_function_gives_numpys_value_and_the_central_differences_derivative(name):
    f, xs = CASES[name]
    agrees(f, *xs)


def one(value, dx=1.0):
    """A scalar Jet in one direction."""
    return Jet(np.asarray(value, dtype=float), np.array([dx]))


def test_comparisons_compare_values_and_return_boolean_arrays():
    (x,) = seeded(V3)
    for got, want in ((x < 0, V3 < 0), (x <= 0.4, V3 <= 0.4), (x > W3, V3 > W3), (x >= 0.9, V3 >= 0.9),
                      (0 > x, V3 < 0), (W3 < x, W3 < V3), (np.less(x, W3), V3 < W3), (x == 0.4, V3 == 0.4),
                      (x != x, np.zeros(3, dtype=bool))):
        assert isinstance(got, np.ndarray) and got.dtype == bool
        np.testing.assert_array_equal(got, want)


def test_abs_at_0_takes_the_right_side_and_minimum_at_a_tie_the_first_operand():
    assert abs(one(0.0, -2.0)).grad.tolist() == [-2.0]  # |x| at 0: d|x| = dx (the sign at 0 is +)
    assert abs(one(-0.0, 3.0)).value == 0.0 and np.signbit(abs(one(-0.0, 3.0)).value) == np.False_
    assert np.minimum(one(1.0, 2.0), one(1.0, 5.0)).grad.tolist() == [2.0]
    assert np.maximum(one(1.0, 2.0), one(1.0, 5.0)).grad.tolist() == [2.0]
    assert np.minimum(one(1.0, 2.0), 3.0).grad.tolist() == [2.0] and np.minimum(one(4.0, 2.0), 3.0).grad.tolist() == [0]


def test_norm_and_powers_below_1_at_0_are_guarded_like_sqrt():
    x = Jet(np.zeros(3), np.eye(3))
    for out in (np.linalg.norm(x), np.sqrt(x[0] * x[0] + x[1] * x[1] + x[2] * x[2]), np.sum(x * x) ** 0.5,
                np.hypot(x[0], x[1])):
        assert out.value == 0.0 and out.grad.tolist() == [0.0, 0.0, 0.0]
    assert ((x[0] * x[0]) ** 0.5).grad.tolist() == np.sqrt(x[0] * x[0]).grad.tolist() == [0.0, 0.0, 0.0]
    with np.errstate(divide="ignore", invalid="ignore"):
        assert (x[0] ** 0.25).grad.tolist() == [np.inf, 0.0, 0.0]  # d(x^p) infinite where x moves
        assert (Jet(0.0, [-1.0, 0.0]) ** 0.5).grad.tolist() == [-np.inf, 0.0]


def test_large_and_tiny_magnitudes_keep_finite_derivatives():
    for scale in (1e200, 1e-200):
        y, x = Jet(3.0 * scale, [scale, 0.0]), Jet(-4.0 * scale, [0.0, scale])
        # d atan2 = (x dy - y dx) / (x^2 + y^2): (-4 * 1 - 3 * 1) / 25 per unit of the seeds' scale
        np.testing.assert_allclose(np.arctan2(y, x).grad, [-4.0 / 25.0, -3.0 / 25.0], rtol=1e-15)
        np.testing.assert_allclose(np.hypot(y, x).grad, [3.0 / 5.0 * scale, -4.0 / 5.0 * scale], rtol=1e-15)
        with np.errstate(over="ignore"):  # the value is numpy's: inf at 1e200 (as on arrays)
            norm = np.linalg.norm(np.stack([y, x]))
        np.testing.assert_allclose(norm.grad, [3.0 / 5.0 * scale, -4.0 / 5.0 * scale], rtol=1e-15)
    for t in (400.0, -400.0, 0.0, 1e-12):
        out = np.tanh(one(t))
        assert out.value == np.tanh(t) and out.grad[0] == pytest.approx(1.0 - np.tanh(t) ** 2, rel=1e-15, abs=0)


@pytest.mark.parametrize("call, names", [
    (lambda x: np.tan(x), ("np.tan", "np.sin(x) / np.cos(x)")),
    (lambda x: np.arcsin(x), ("np.arcsin", "np.arctan2(x, np.sqrt(1 - x * x))")),
    (lambda x: np.linalg.inv(x[:1].reshape(1, 1)), ("np.linalg.inv", "cofactors")),
    (lambda x: np.cross(x[None], W3), ("np.cross", "np.stack")),
    (lambda x: np.sinc(x), ("np.sinc", "np.tanh")),  # no alternative of its own: the list of what Jets support
    (lambda x: np.sin(x, out=np.zeros(3)), ("np.sin(..., out=...)", "without keyword arguments")),
    (lambda x: np.maximum.reduce(x), ("np.maximum.reduce", "np.maximum")),
])
def test_what_jets_do_not_support_fails_with_one_line_naming_it_and_the_alternative(call, names):
    (x,) = seeded(V3)
    with pytest.raises(TypeError) as error:
        call(x)
    text = str(error.value)
    assert "\n" not in text and all(n in text for n in names), text


def test_the_students_jet_gains_them_from_the_given_part():
    """The stubs' Jet holds the same given code: ``abs`` on it runs the student's ``__mul__`` (a TODO)."""
    stub = impl_loader.load("exercises").module("jets").Jet
    x = stub(np.array([1.0]), np.array([[1.0]]))
    assert (x < 0).tolist() == [False] and np.concatenate([x, x]).value.tolist() == [1.0, 1.0]
    with pytest.raises(NotImplementedError):
        abs(x)


def _range_only(z, x, landmark):
    """The distance from an SE(2) pose's position to a 2D landmark, by ``np.linalg.norm``."""
    return (np.linalg.norm(landmark - x[..., :2], axis=-1) - z[..., 0])[..., None]


def _prior_tanh(z, x):
    """A bounded (tanh) pull of a 2D point towards ``z``: ``2 tanh((x - z) / 2)``, abs'd, with a maximum."""
    d = x - z
    return np.concatenate([2.0 * np.tanh(0.5 * d[..., :1]), np.maximum(np.abs(d[..., 1:]), 0.0) * 1.0], axis=-1)


RANGE_ONLY = FactorType("range_only", (SE2, Vector(2)), 1, _range_only)
PRIOR_TANH = FactorType("prior_tanh", (Vector(2),), 2, _prior_tanh)


def _range_only_graph():
    rng = np.random.default_rng(7)
    poses = np.array([[0.0, 0.0, 0.0], [2.0, 0.5, 0.4], [4.0, -0.5, -0.3], [1.0, 3.0, 1.0]])
    marks = np.array([[1.0, 2.0], [3.0, -1.5], [5.0, 2.5], [-1.0, 1.0]])
    graph = FactorGraph("range only")
    for k, pose in enumerate(poses):
        graph.add_variable(f"x{k}", SE2, pose)
        graph.fix(f"x{k}")  # known poses: the landmarks are found by their ranges
    for j, mark in enumerate(marks):
        graph.add_variable(f"l{j}", Vector(2), mark + rng.normal(0, 0.2, 2))
    for k, pose in enumerate(poses):
        for j, mark in enumerate(marks):
            graph.add(RANGE_ONLY, [f"x{k}", f"l{j}"], [np.hypot(*(mark - pose[:2])) + rng.normal(0, 0.01)])
    graph.add(PRIOR_TANH, ["l0"], marks[0] + 0.05, np.eye(2))
    return graph


def test_a_residual_written_with_them_is_solved_alike_with_automatic_and_numeric_jacobians():
    graph = _range_only_graph()
    auto, numeric = FactorGraphProblem(graph), FactorGraphProblem(graph, jacobians="numeric")
    for group in range(2):
        r_a, J_a = auto.factor_jacobians(auto.x0, group)
        r_n, J_n = numeric.factor_jacobians(numeric.x0, group)
        np.testing.assert_array_equal(r_a, r_n)
        for a, n in zip(J_a, J_n):
            np.testing.assert_allclose(a, n, rtol=0, atol=1e-7)
    a, n = minimize(auto, "lm-type3"), minimize(numeric, "lm-type3")
    assert a.final_chi2 == pytest.approx(n.final_chi2, rel=1e-6) and a.final_chi2 < 1e-2
    np.testing.assert_allclose(a.params, n.params, atol=1e-6)


def test_the_graders_stand_in_jet_has_what_the_given_part_has_without_a_rule():
    """``TracingJet`` (the autodiff_factor checks' Jet) gives what the real Jet gives for each operation
    of the given part that needs no derivative rule of the exercise."""
    from autograder.tasks.jets import TracingJet

    X, Y = RNG.normal(size=(2, 3)), RNG.normal(size=(2, 3))
    operations = [
        lambda a, b: a.T, lambda a, b: a.transpose(1, 0), lambda a, b: np.transpose(a), lambda a, b: a.sum(axis=(0, 1)),
        lambda a, b: np.sum(a, axis=0, keepdims=True), lambda a, b: np.mean(b, axis=-1), lambda a, b: a.mean(),
        lambda a, b: abs(a), lambda a, b: np.abs(b), lambda a, b: np.where(a < b, a, b), lambda a, b: np.where(
            a > 0, a, 0.5), lambda a, b: np.minimum(a, b), lambda a, b: np.maximum(a, 0.0),
        lambda a, b: np.stack([a, b, np.ones((2, 3))], axis=1), lambda a, b: np.concatenate([a, X], axis=-1),
        lambda a, b: np.concatenate([a, b], axis=None), lambda a, b: a - 2.0 * b + X, lambda a, b: X - a,
        lambda a, b: np.float64(3.0) * a, lambda a, b: a[:, 1:] + b[..., :2], lambda a, b: a.reshape(3, 2).mT,
        lambda a, b: -a,
    ]
    real, stand_in = seeded(X, Y), [TracingJet(j.value, j.grad) for j in seeded(X, Y)]
    for index, f in enumerate(operations):
        want, got = f(*real), f(*stand_in)
        assert isinstance(got, TracingJet), index
        np.testing.assert_array_equal(got.value, want.value, err_msg=str(index))
        np.testing.assert_allclose(got.grad, want.grad, rtol=1e-15, atol=0, err_msg=str(index))
    for f in (lambda a, b: (a < b, a >= 0.1, X > a, a == b, a != b), lambda a, b: (np.shape(a), np.ndim(a))):
        for g, w in zip(f(*stand_in), f(*real)):
            np.testing.assert_array_equal(g, w)
    for rule in (lambda a, b: a * b, lambda a, b: a * X, lambda a, b: np.sin(a), lambda a, b: np.einsum("ij->i", a)):
        with pytest.raises(TypeError, match="stand-in Jet"):
            rule(*stand_in)
