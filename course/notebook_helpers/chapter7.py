"""Chapter 7's lesson (``notebooks/chapter7_factor_graphs.py``): the figures of the theory, the checker
cells' inputs, and the experiments' tables.

Conventions (``course.factorgraph``): a variable is stored as an array of its kind's shape and moved by
its kind's retraction ``x (+) delta`` (SE(2) by addition, the angle wrapped; SE(3) on the right, ``(t + R
rho, R Exp(phi))``, translation first); a factor's residual is written once for arrays and Jets.

* ``todo_as_one_line``, ``exercise``: a context in which an unwritten exercise prints one line; a module of
  an implementation.
* ``Dual``, ``cubic``, ``tangent_figure``: the lesson's dual number (sums and products only), and the
  tangents it gives.
* ``small_function``, ``RULES``, ``jets_check``: every derivative rule of the ``jets`` exercise on one
  function of two numbers, checked against central differences.
* ``se2_edge``, ``edge_jacobian_by_jets``, ``edge_jacobian_by_complex_step``, ``finite_differences``,
  ``step_study``, ``step_figure``, ``step_table``: forward and central differences against the Jet
  derivative of chapter 2's edge, against the step size; the complex step as an independent reference.
* ``b_coefficient``, ``SWITCH``, ``series_figure``, ``zero_angle_table``: Rodrigues' coefficient ``(1 -
  cos t) / t^2`` and its derivative in floating point, closed form against series; ``Exp`` on Jets at 0.
* ``se3_edge``, ``chain_rule``, ``chain_rule_text``: the tangent Jacobians of chapter 6's edge as the
  ambient derivative times the retraction's.
* ``mixed_graph``, ``h_pattern``, ``pattern_figure``, ``solve``, ``run_line``: a graph of SE(2) poses and
  2D landmarks, the pattern of its H, and a solve by the implementation's three chapter-7 pieces alone.
* ``jacobian_agreement``, ``agreement_table``, ``BACKENDS``, ``solve_runs``, ``minimum_line``: the
  experiments' automatic against analytic Jacobians, and the minima.
* ``GpsDrive``, ``gps_drive``, ``odometry_graph``, ``dead_reckoning``, ``position_error``,
  ``drive_figure``: a drive with drifting odometry and a position fix every few poses.
* ``RangeOnly``, ``range_only``, ``range_only_graph``, ``range_only_runs``, ``range_only_table``: range-only
  SLAM (odometry and ranges to beacons at unknown places) from the factor library, ours against GTSAM's
  own factors.
* ``plus_jacobian_study``, ``plus_jacobian_text``: each pose kind's retraction derivative at 0, the Jets' seed.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np

from course.app import plot
from course.core.errors import DatasetError
from course.core.impl import not_implemented_reason
from course.factorgraph import (
    BETWEEN_SE2,
    RANGE_2D,
    RANGE_BEARING,
    SE2,
    SE3,
    FactorGraph,
    FactorGraphProblem,
    Vector,
    between,
    jetmath,
    noise,
    prior,
)
from course.factorgraph.factors import between_se2, between_se3
from course.factorgraph.variables import se3_value
from course.geometry.jacobian_check import JacobianCheck, check_jacobian
from course.geometry.so3 import exp_many, skew
from course.notebook_helpers.lesson import exercise, todo_as_one_line  # noqa: F401 (the cells call them here)
from course.solver import SolverOptions, minimize
from course.solver.superlu import SuperLUSolver

EPS = float(np.finfo(float).eps)

# ---------------------------------------------------------------- every cell that runs your code


# ---------------------------------------------------------------- section 1: dual numbers


class Dual:
    """``a + b eps`` with ``eps^2 = 0``, for sums, differences and products (enough for polynomials)."""

    def __init__(self, a, b=0.0):
        self.a, self.b = float(a), float(b)

    @staticmethod
    def of(x) -> Dual:
        return x if isinstance(x, Dual) else Dual(x)

    def __add__(self, other):
        o = Dual.of(other)
        return Dual(self.a + o.a, self.b + o.b)

    __radd__ = __add__

    def __neg__(self):
        return Dual(-self.a, -self.b)

    def __sub__(self, other):
        return self + (-Dual.of(other))

    def __rsub__(self, other):
        return Dual.of(other) - self

    def __mul__(self, other):
        o = Dual.of(other)
        return Dual(self.a * o.a, self.a * o.b + self.b * o.a)  # the eps^2 term b * o.b is dropped

    __rmul__ = __mul__

    def __repr__(self):
        return f"{self.a:g} + {self.b:g} eps"


def cubic(x):
    """``x^3 - 3 x + 1``, written once for numbers, arrays and :class:`Dual`."""
    return x * x * x - 3 * x + 1


def tangent_figure(points=(-1.6, 0.4, 1.7)):
    """Two panels: (left) the cubic and, at each of ``points``, the tangent whose value and slope one
    evaluation on ``Dual(a, 1)`` gives; (right) how far the cubic is from that tangent, ``|f(a + h) - f(a)
    - f'(a) h|``, against ``h``: the dropped ``eps^2`` terms, of order ``h^2``."""
    fig = plot.figure(10.5, 4.2)
    left, right = fig.subplots(1, 2)
    x = np.linspace(-2.3, 2.3, 200)
    left.plot(x, cubic(x), "k", lw=1.5, label="f(x) = x^3 - 3x + 1")
    h = np.logspace(-6, 0, 40)
    for a in points:
        d = cubic(Dual(a, 1.0))
        span = np.linspace(a - 0.6, a + 0.6, 2)
        left.plot(span, d.a + d.b * (span - a), lw=1.2, label=f"f({a:g} + eps) = {d!r}")
        left.plot([a], [d.a], "o", color="k", ms=4)
        right.loglog(h, np.abs(cubic(a + h) - d.a - d.b * h), label=f"a = {a:g}")
    right.loglog(h, h**2, "k--", lw=0.8, label="h^2")
    left.set_ylim(-4, 6)
    left.grid(True, alpha=0.3)
    left.set_xlabel("x")
    left.set_title("one evaluation on a + eps gives the value and the slope", fontsize=9)
    left.legend(fontsize=7, loc="upper left")
    right.grid(True, alpha=0.3, which="both")
    right.set_xlabel("h")
    right.set_ylabel("|f(a + h) - (f(a) + f'(a) h)|")
    right.set_title("the tangent is off by the dropped eps^2 terms: O(h^2);\nthe slope itself is exact",
                    fontsize=9)
    right.legend(fontsize=7)
    return fig


#: what each row of :func:`small_function` tests (its rule)
RULES = ("x * y", "x / y", "2 / y", "y ** 3", "sqrt(x * x + y * y)", "sin(x)", "cos(y)", "exp(x * y)", "log(y)",
         "arctan2(y, x)", "(R(x) @ v)[0], v = (y, y * y)", "(R(x) @ v)[1], v = (y, y * y)")


def small_function(x, y):
    """The rows :data:`RULES` names, (12,), of two numbers ``x``, ``y`` (floats or scalar Jets); ``R(x)``
    is the 2D rotation by ``x``."""
    Rv = jetmath.rotation2d(x) @ np.stack([y, y * y])
    return np.stack([x * y, x / y, 2.0 / y, y**3, np.sqrt(x * x + y * y), np.sin(x), np.cos(y), np.exp(x * y),
                     np.log(y), np.arctan2(y, x), Rv[0], Rv[1]])


def jets_check(Jet, point=(0.7, 1.3), out=print) -> JacobianCheck:
    """``small_function`` at ``point`` on ``Jet`` (two seeded directions) against central differences:
    a line on the values, then ``check_jacobian``'s report (each row named by its rule)."""
    p = np.asarray(point, dtype=float)
    seeded = Jet.seed(p, 0, 2)
    jet = small_function(seeded[0], seeded[1])
    want = small_function(p[0], p[1])
    value = np.asarray(jet.value, dtype=float)
    if value.shape != want.shape or not np.allclose(value, want, rtol=1e-12, atol=1e-14):
        wrong = [RULES[k] for k in range(len(RULES)) if value.shape != want.shape
                 or not np.isclose(value[k], want[k], rtol=1e-12, atol=1e-14)]
        out(f"values WRONG in {len(wrong)} row(s): {', '.join(wrong)}")
    elif out is not None:
        out(f"values: the {len(want)} rows equal numpy's on floats")
    grad = np.asarray(jet.grad, dtype=float)
    return check_jacobian(lambda x, y: small_function(float(x), float(y)), [p[0], p[1]],
                          J=[grad[:, :1], grad[:, 1:]], names=["x", "y"],
                          rows=[(rule, slice(k, k + 1)) for k, rule in enumerate(RULES)], out=out)


# ---------------------------------------------------------------- section 2: exact against finite differences


def se2_edge(shift=0.0):
    """One edge of chapter 2, ``(z, x_i, x_j)``, each (1, 3): poses about 13 m from the origin (plus
    ``shift`` m along x and y), the residual's angle well inside (-pi, pi)."""
    z = np.array([[0.8, 0.5, -0.35]])
    x_i = np.array([[12.3 + shift, -4.1 + shift, 2.6]])
    x_j = np.array([[13.2 + shift, -3.4 + shift, 2.2]])
    return z, x_i, x_j


def _edge_of_step(delta, shift=0.0):
    """The SE(2) edge's residual (3,) with both poses moved by ``delta`` (6,) through their retraction."""
    z, x_i, x_j = se2_edge(shift)
    delta = np.asarray(delta)
    return between_se2(z, SE2.retract(x_i, delta[None, :3]), SE2.retract(x_j, delta[None, 3:]))[0]


def edge_jacobian_by_jets(Jet, shift=0.0) -> np.ndarray:
    """The SE(2) edge's Jacobian (3, 6) in both poses' steps, by ``Jet`` seeded through the retraction."""
    z, x_i, x_j = se2_edge(shift)
    r = between_se2(z, SE2.retract(x_i, Jet.seed(np.zeros((1, 3)), 0, 6)),
                    SE2.retract(x_j, Jet.seed(np.zeros((1, 3)), 3, 6)))
    return np.asarray(r.grad, dtype=float)[0]


def edge_jacobian_by_complex_step(shift=0.0, h=1e-100) -> np.ndarray:
    """The same Jacobian by the complex step ``Im r(x + i h e_c) / h``: no difference is taken, so it is
    exact to rounding (the residual is analytic; the angle's wrap only subtracts a constant)."""
    columns = []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the wrap reads the real part alone
        for c in range(6):
            delta = np.zeros(6, dtype=complex)
            delta[c] = 1j * h
            columns.append(np.imag(_edge_of_step(delta, shift)) / h)
    return np.stack(columns, axis=1)


def finite_differences(h: float, central: bool, shift=0.0) -> np.ndarray:
    """The SE(2) edge's Jacobian (3, 6) by forward or central differences of step ``h``."""
    columns = []
    for c in range(6):
        e = np.zeros(6)
        e[c] = h
        if central:
            columns.append((_edge_of_step(e, shift) - _edge_of_step(-e, shift)) / (2.0 * h))
        else:
            columns.append((_edge_of_step(e, shift) - _edge_of_step(np.zeros(6), shift)) / h)
    return np.stack(columns, axis=1)


@dataclass
class StepStudy:
    """``forward``, ``central`` (K,): the largest error of each Jacobian against ``reference`` (relative to
    its largest entry) for ``steps`` (K,); ``jets_vs_complex``: the Jets' largest difference from the complex
    step (None without Jets); ``note``: why the Jets are not the reference (a TODO), else empty; ``shift``:
    how far the edge was moved from its place (m along x and y)."""

    steps: np.ndarray
    forward: np.ndarray
    central: np.ndarray
    reference: str
    jets_vs_complex: float | None
    note: str = ""
    shift: float = 0.0

    def best(self, which: str) -> tuple[float, float]:
        """``(smallest error, its step)`` of ``"forward"`` or ``"central"``."""
        errors = getattr(self, which)
        k = int(np.argmin(errors))
        return float(errors[k]), float(self.steps[k])


def step_study(impl="solutions", steps=None, shift=0.0) -> StepStudy:
    """Forward and central differences of the SE(2) edge (its poses moved ``shift`` m along x and y)
    against the Jacobian of ``impl``'s Jets; against the complex step while the Jets are not written
    (``note`` names the TODO)."""
    steps = np.logspace(-15, -1, 57) if steps is None else np.asarray(steps, dtype=float)
    complex_step = edge_jacobian_by_complex_step(shift)
    note, jets_vs_complex = "", None
    try:
        reference = edge_jacobian_by_jets(exercise("jets", impl).Jet, shift)
        name = "the Jets"
        scale = float(np.abs(complex_step).max())
        jets_vs_complex = float(np.abs(reference - complex_step).max()) / scale
    except NotImplementedError as exc:
        note, reference, name = not_implemented_reason(exc), complex_step, "the complex step"
    scale = float(np.abs(reference).max())
    forward = np.array([np.abs(finite_differences(h, False, shift) - reference).max() for h in steps]) / scale
    central = np.array([np.abs(finite_differences(h, True, shift) - reference).max() for h in steps]) / scale
    return StepStudy(steps, forward, central, name, jets_vs_complex, note, shift)


def step_figure(study: StepStudy):
    """The errors of forward and central differences against the step, log-log, each minimum marked, and
    the two error models (truncation ``h``, ``h^2``; rounding ``eps / h``)."""
    fig = plot.figure(7.5, 4.6)
    ax = fig.subplots()
    h = study.steps
    ax.loglog(h, np.maximum(study.forward, 1e-18), "o-", ms=3, label="forward differences")
    ax.loglog(h, np.maximum(study.central, 1e-18), "s-", ms=3, label="central differences")
    for which, colour in (("forward", "tab:blue"), ("central", "tab:orange")):
        error, step = study.best(which)
        ax.loglog([step], [error], "*", ms=14, color=colour)
        ax.annotate(f"{error:.1e} at h = {step:.0e}", (step, error), textcoords="offset points", xytext=(6, -14),
                    fontsize=8, color=colour)
    ax.loglog(h, EPS / h, "k:", lw=0.8, label="rounding, eps / h")
    ax.loglog(h, h, "k--", lw=0.6, label="truncation, h")
    ax.loglog(h, h**2, "k-.", lw=0.6, label="truncation, h^2")
    if study.jets_vs_complex is not None:
        level = max(study.jets_vs_complex, 1e-17)
        ax.axhline(level, color="tab:green", lw=1.2,
                   label=f"Jets against the complex step: {study.jets_vs_complex:.1e}")
    ax.set_ylim(1e-17, 10.0)
    ax.set_xlabel("step h")
    ax.set_ylabel("largest error / largest entry")
    ax.grid(True, alpha=0.3, which="both")
    ax.legend(fontsize=7, loc="lower left")
    where = f", its poses moved {study.shift:g} m" if study.shift else ""
    title = f"chapter 2's edge{where}, its 3 x 6 Jacobian: differences against {study.reference}"
    if study.note:
        title += f"\n(your Jets: {study.note})"
    ax.set_title(title, fontsize=9)
    return fig


def step_table(study: StepStudy) -> str:
    """The smallest error of each difference and where, beside the models' optimal steps and errors."""
    where = f" (its poses moved {study.shift:g} m)" if study.shift else ""
    lines = [f"the SE(2) edge's Jacobian (3 x 6){where}: differences against {study.reference}"
             + (f" (your Jets: {study.note})" if study.note else "")]
    for which, model_step, model_error in (("forward", EPS ** 0.5, EPS ** 0.5), ("central", EPS ** (1 / 3),
                                                                                  EPS ** (2 / 3))):
        error, step = study.best(which)
        lines.append(f"{which + ' differences:':22} smallest error {error:.1e} at h = {step:.1e}"
                     f"   (model: h ~ {model_step:.1e}, error ~ {model_error:.1e})")
    if study.jets_vs_complex is not None:
        lines.append(f"{'the Jets:':22} largest difference from the complex step {study.jets_vs_complex:.1e}")
    return "\n".join(lines)


# ---------------------------------------------------------------- section 3: the retraction, Exp at 0


def b_coefficient(t) -> tuple[np.ndarray, np.ndarray]:
    """Accurate ``b(t) = (1 - cos t) / t^2`` and ``db/dt`` (each (K,) for ``t`` (K,) >= 0): by their
    series below t = 0.5 (ten terms), else by the closed forms (no cancellation there)."""
    t = np.asarray(t, dtype=float)
    k = np.arange(10)
    factorial = np.array([float(np.prod(np.arange(1, 2 * j + 3))) for j in k])  # (2k + 2)!
    signs = (-1.0) ** k
    small = t < 0.5
    ts = np.where(small, t, 0.0)[:, None]
    b_series = (signs * ts ** (2 * k) / factorial).sum(axis=1)
    db_series = (signs[1:] * 2 * k[1:] * ts ** (2 * k[1:] - 1) / factorial[1:]).sum(axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        b_closed = (1.0 - np.cos(t)) / t**2
        db_closed = np.sin(t) / t**2 - 2.0 * (1.0 - np.cos(t)) / t**3
    return np.where(small, b_series, b_closed), np.where(small, db_series, db_closed)


#: the angle below which ``jetmath`` uses the series of Rodrigues' coefficients
SWITCH = float(np.sqrt(jetmath.SMALL_ANGLE_SQUARED))


def series_figure(switch=SWITCH):
    """Two panels against the angle t: the relative error, in floating point, of ``b = (1 - cos t) / t^2``
    (left) and of its derivative as the chain rule gives it, ``sin t / t^2 - 2 (1 - cos t) / t^3`` (right),
    by the closed form and by the series ``1/2 - t^2/24`` (derivative ``-t/12``); ``switch`` marked."""
    t = np.logspace(-9, 0, 300)
    b, db = b_coefficient(t)
    with np.errstate(divide="ignore", invalid="ignore"):
        closed = [(1.0 - np.cos(t)) / t**2, np.sin(t) / t**2 - 2.0 * (1.0 - np.cos(t)) / t**3]
    series = [0.5 - t**2 / 24.0, -t / 12.0]
    fig = plot.figure(10.5, 4.2)
    panels = fig.subplots(1, 2)
    for ax, exact, c, s, what in zip(panels, (b, db), closed, series, ("b(t) = (1 - cos t) / t^2", "db/dt")):
        floor = 1e-17
        ax.loglog(t, np.clip(np.abs(c - exact) / np.abs(exact), floor, 10.0), label="closed form")
        ax.loglog(t, np.clip(np.abs(s - exact) / np.abs(exact), floor, 10.0), label="series, two terms")
        ax.axvline(switch, color="k", ls=":", lw=0.8, label=f"the switch, t = {switch:.0e}")
        ax.set_xlabel("angle t (rad)")
        ax.set_ylabel("relative error")
        ax.set_title(what, fontsize=9)
        ax.grid(True, alpha=0.3, which="both")
        ax.legend(fontsize=7)
    panels[0].set_title("b(t) = (1 - cos t) / t^2: the closed form cancels (eps / t^2), 0/0 at t = 0",
                        fontsize=9)
    panels[1].set_title("its derivative as a Jet carries it: the closed form loses\nall its digits near "
                        "t = 1e-4 (eps / t^4)", fontsize=9)
    return fig


def _closed_form_exp(phi):
    """``Exp(phi)`` by Rodrigues' closed form alone (no series): what the lesson shows failing at 0."""
    t = np.sqrt(jetmath.dot3(phi, phi))
    W = jetmath.skew(phi)
    return np.eye(3) + (np.sin(t) / t)[..., None, None] * W + ((1.0 - np.cos(t)) / (t * t))[..., None, None] * (W @ W)


def zero_angle_table(Jet) -> str:
    """``Exp`` on ``Jet`` seeded at ``phi = 0`` (3 directions): by the closed form alone, and by
    ``jetmath.so3_exp`` (the series below the switch); each one's value and derivative against ``I`` and
    the generators ``[e_k]_x``."""
    generators = jetmath.skew(np.eye(3))  # (3, 3, 3): [e_k]_x
    lines = []
    for label, exp in (("closed form alone", _closed_form_exp), ("with the series", jetmath.so3_exp)):
        with np.errstate(all="ignore"):
            R = exp(Jet.seed(np.zeros((1, 3)), 0, 3))
        value = np.asarray(R.value, dtype=float)[0]
        grad = np.moveaxis(np.asarray(R.grad, dtype=float)[0], -1, 0)  # (3, 3, 3): d Exp / d phi_k
        nans = int(np.isnan(value).sum() + np.isnan(grad).sum())
        if nans:
            lines.append(f"{label:18}: {nans} of {value.size + grad.size} numbers are nan (0/0 at t = 0)")
        else:
            lines.append(f"{label:18}: value - I {np.abs(value - np.eye(3)).max():.1e}, "
                         f"d Exp / d phi_k - [e_k]x {np.abs(grad - generators).max():.1e}")
    return "\n".join(lines)


@dataclass
class SE3Edge:
    """One edge of chapter 6: ``z``, ``x_i``, ``x_j`` stored SE(3) values (1, 12); ``T_i``, ``T_j`` the
    poses as ``(t (3,), R (3, 3))`` for ``check_jacobian(plus="se3")``."""

    z: np.ndarray
    x_i: np.ndarray
    x_j: np.ndarray

    @property
    def T_i(self):
        return self.x_i[0, :3], self.x_i[0, 3:].reshape(3, 3)

    @property
    def T_j(self):
        return self.x_j[0, :3], self.x_j[0, 3:].reshape(3, 3)

    def residual(self, p_i, p_j):
        """``between_se3`` of the stored values (arrays or Jets), (1, 6)."""
        return between_se3(self.z, p_i, p_j)

    def error(self, T_i, T_j) -> np.ndarray:
        """The residual (6,) of poses ``(t, R)``."""
        return np.asarray(self.residual(se3_value(*T_i)[None], se3_value(*T_j)[None]), dtype=float)[0]


def se3_edge(seed=0, residual_angle=0.4) -> SE3Edge:
    """A generic SE(3) edge: random poses, and a measurement that leaves a residual rotation of
    ``residual_angle`` rad (about a random axis) and a translation residual of a few tenths."""
    rng = np.random.default_rng(seed)
    R = exp_many(rng.normal(0.0, 0.8, (2, 3)))
    t = rng.normal(0.0, 2.0, (2, 3))
    axis = rng.normal(size=3)
    w = residual_angle * axis / np.linalg.norm(axis)
    R_z = R[0].T @ R[1] @ exp_many(-w[None])[0]  # then R_z^T R_i^T R_j = Exp(w)
    t_z = R[0].T @ (t[1] - t[0]) + rng.normal(0.0, 0.2, 3)
    return SE3Edge(se3_value(t_z, R_z)[None], se3_value(t[0], R[0])[None], se3_value(t[1], R[1])[None])


def chain_rule(edge: SE3Edge, Jet) -> dict:
    """The edge's Jacobians four ways, by ``Jet``: ``ambient`` (6, 24), the derivative in the 24 stored
    numbers of both poses; ``retraction`` (24, 12), the derivative of ``x (+) delta`` in ``delta`` at 0 by
    Jets through ``SE3.retract``, block-diagonal; ``seeded`` (6, 12), the steps seeded through the
    retraction; ``plus`` (24, 12), the same derivative in closed form (``SE3.plus_jacobian``);
    ``by_plus`` (6, 12), the stored values seeded with it (no retraction on Jets). ``difference``, the
    largest ``|ambient @ retraction - seeded|``; ``plus_difference``, ``|plus - retraction|``;
    ``seed_difference``, ``|by_plus - seeded|``."""
    r = edge.residual(Jet.seed(edge.x_i, 0, 24), Jet.seed(edge.x_j, 12, 24))
    ambient = np.asarray(r.grad, dtype=float)[0]
    retraction, plus = np.zeros((24, 12)), np.zeros((24, 12))
    points = []
    for slot, x in enumerate((edge.x_i, edge.x_j)):
        moved = SE3.retract(x, Jet.seed(np.zeros((1, 6)), 0, 6))
        retraction[12 * slot:12 * slot + 12, 6 * slot:6 * slot + 6] = np.asarray(moved.grad, dtype=float)[0]
        P = SE3.plus_jacobian(x)  # (1, 12, 6)
        plus[12 * slot:12 * slot + 12, 6 * slot:6 * slot + 6] = P[0]
        grad = np.zeros((1, 12, 12))
        grad[:, :, 6 * slot:6 * slot + 6] = P
        points.append(Jet(x, grad))
    seeded = edge.residual(SE3.retract(edge.x_i, Jet.seed(np.zeros((1, 6)), 0, 12)),
                           SE3.retract(edge.x_j, Jet.seed(np.zeros((1, 6)), 6, 12)))
    seeded = np.asarray(seeded.grad, dtype=float)[0]
    by_plus = np.asarray(edge.residual(*points).grad, dtype=float)[0]
    return {"ambient": ambient, "retraction": retraction, "seeded": seeded, "plus": plus, "by_plus": by_plus,
            "difference": float(np.abs(ambient @ retraction - seeded).max()),
            "plus_difference": float(np.abs(plus - retraction).max()),
            "seed_difference": float(np.abs(by_plus - seeded).max())}


def chain_rule_text(parts: dict, edge: SE3Edge) -> str:
    """What :func:`chain_rule` found, the retraction's derivative of ``T_i`` against ``R_i``, and the
    closed-form plus-Jacobian as the Jets' seed."""
    M = parts["retraction"][:12, :6]
    _, R = edge.T_i
    rotation_columns = M[3:, 3:].reshape(3, 3, 3)  # d R / d phi_k as rows of R Exp(phi), per k
    lines = [f"dr/dx (6 x 24) @ d(x (+) delta)/d delta (24 x 12) against the steps seeded through the "
             f"retraction: largest difference {parts['difference']:.1e}",
             f"d t / d rho of T_i (rows 0-2, columns 0-2) is R_i: largest difference "
             f"{np.abs(M[:3, :3] - R).max():.1e}; d t / d phi is {np.abs(M[:3, 3:]).max():.0f}",
             f"d R / d phi_k of T_i is R_i [e_k]x: largest difference "
             f"{max(np.abs(rotation_columns[:, :, k] - R @ skew(np.eye(3)[k])).max() for k in range(3)):.1e}; "
             f"d R / d rho is {np.abs(M[3:, :3]).max():.0f}",
             f"SE3.plus_jacobian (closed form) against the Jets' derivative of the retraction: largest difference "
             f"{parts['plus_difference']:.1e}",
             f"the stored values seeded with it (no retraction on Jets) against the steps seeded through the "
             f"retraction: largest difference {parts['seed_difference']:.1e}"]
    return "\n".join(lines)


# ---------------------------------------------------------------- section 4: the generic linearisation


def mixed_graph(poses=6, landmarks=3, seed=0) -> FactorGraph:
    """A robot's path of ``poses`` SE(2) poses (odometry between neighbours) that sees ``landmarks`` 2D
    landmarks by range and bearing, each pose the two nearest; the first pose fixed. Variables: the poses
    ``x0..``, then the landmarks ``l0..``."""
    rng = np.random.default_rng(seed)
    path = np.stack([np.arange(poses) * 1.0, 0.3 * np.sin(np.arange(poses)), 0.2 * np.arange(poses)], axis=1)
    marks = np.stack([np.linspace(0.5, poses - 1.5, landmarks), 2.0 * (-1.0) ** np.arange(landmarks)], axis=1)
    graph = FactorGraph("a path and its landmarks")
    for k, pose in enumerate(path):
        graph.add_variable(f"x{k}", SE2, pose + (rng.normal(0.0, 0.05, 3) if k else 0.0))
    for k, mark in enumerate(marks):
        graph.add_variable(f"l{k}", Vector(2), mark + rng.normal(0.0, 0.1, 2))
    graph.fix("x0")
    for k in range(poses - 1):
        z = _relative_pose(path[k], path[k + 1])
        graph.add(BETWEEN_SE2, [f"x{k}", f"x{k + 1}"], z, np.diag([100.0, 100.0, 400.0]))
    for k, pose in enumerate(path):
        for j in np.argsort(np.linalg.norm(marks - pose[:2], axis=1))[:2]:
            d = marks[j] - pose[:2]
            graph.add(RANGE_BEARING, [f"x{k}", f"l{j}"], [np.hypot(*d), np.arctan2(d[1], d[0]) - pose[2]],
                      np.diag([25.0, 400.0]))
    return graph


def _relative_pose(a, b) -> np.ndarray:
    """Pose ``b`` (x, y, theta) seen from pose ``a``: chapter 2's measurement."""
    c, s = np.cos(a[2]), np.sin(a[2])
    d = np.asarray(b[:2]) - np.asarray(a[:2])
    return np.array([c * d[0] + s * d[1], -s * d[0] + c * d[1], jetmath.wrap_angle(b[2] - a[2])])


def h_pattern(graph: FactorGraph) -> np.ndarray:
    """Which entries of the graph's H = J^T J can be nonzero (n, n) bool: J's blocks filled with ones, one
    block row per factor, one block column per variable (its tangent size wide)."""
    dims = np.array([kind.dim for kind in graph.kinds])
    offsets = np.concatenate([[0], np.cumsum(dims)])
    rows = []
    for group in graph.groups.values():
        keys, _, _ = group.arrays()
        for key in keys:
            row = np.zeros(offsets[-1], dtype=bool)
            for v in key:
                row[offsets[v]:offsets[v + 1]] = True
            rows.append(row)
    J = np.array(rows, dtype=float)
    return (J.T @ J) > 0


def pattern_figure(graph: FactorGraph):
    """The pattern of the graph's H, its variables' blocks outlined and named: the upper triangle (what
    the assembly stores) dark, the lower one light."""
    pattern = h_pattern(graph)
    n = len(pattern)
    dims = np.array([kind.dim for kind in graph.kinds])
    offsets = np.concatenate([[0], np.cumsum(dims)])
    picture = np.where(pattern, np.where(np.triu(np.ones((n, n), dtype=bool)), 2.0, 1.0), 0.0)
    fig = plot.figure(6.4, 6.0)
    ax = fig.subplots()
    ax.imshow(picture, cmap="Blues", vmin=0.0, vmax=2.0, interpolation="nearest")
    for edge in offsets[1:-1] - 0.5:
        ax.axhline(edge, color="grey", lw=0.5)
        ax.axvline(edge, color="grey", lw=0.5)
    centres = (offsets[:-1] + offsets[1:]) / 2.0 - 0.5
    ax.set_xticks(centres, graph.keys, fontsize=7)
    ax.set_yticks(centres, graph.keys, fontsize=7)
    upper = int(np.triu(pattern).sum())
    sizes = ", ".join(f"{kind.name} ({kind.dim})" for kind in dict.fromkeys(graph.kinds))
    ax.set_title(f"H of {graph.num_variables} variables of mixed sizes: {sizes}\n{n} x {n}, "
                 f"{upper} entries on and above the diagonal can be nonzero (dark: the stored upper triangle)",
                 fontsize=9)
    return fig


def solve(graph: FactorGraph, impl="solutions", method="gauss-newton"):
    """``(problem, run)``: ``graph`` solved by ``method`` with ``impl``'s Jets, ``autodiff_factor`` and
    ``factor_linearisation``, the step by scipy's sparse LU (so that no other chapter's exercise is needed)."""
    problem = FactorGraphProblem(graph, impl, solver=SuperLUSolver())
    return problem, minimize(problem, method, impl=impl)


def run_line(run, what: str) -> str:
    """One line for a solve: chi2 at the start and at the end, iterations, why it stopped."""
    stop = str(getattr(run.stop_reason, "value", run.stop_reason))
    return (f"{what}: chi2 {run.initial_chi2:.6g} -> {run.final_chi2:.10g} in {run.iterations} iterations "
            f"({stop}, {1e3 * run.seconds:.0f} ms)")


# ---------------------------------------------------------------- experiments


def _blockwise(got, want) -> float:
    """The largest difference per factor relative to that factor's largest entry, over all factors."""
    got, want = np.asarray(got, dtype=float), np.asarray(want, dtype=float)
    scale = np.maximum(np.abs(want).max(axis=(1, 2)), np.finfo(float).tiny)
    return float((np.abs(got - want).max(axis=(1, 2)) / scale).max())


def _analytic(name: str, impl):
    """``(factor graph, [analytic J_a (M, m, d_a)])`` of dataset ``name`` (its chapter's problem)."""
    if name == "ladybug-49":
        from course.problems.bal.dataset import load_bal
        from course.problems.bal.factor_graph import as_factor_graph as bal_graph

        data = load_bal(name)
        _, J_cam, J_point = exercise("bundle_adjustment", impl).reprojection_residuals_and_jacobians(
            data.cameras, data.points, data.camera_index, data.point_index, data.observations)
        return bal_graph(data), [J_cam, J_point]
    if name == "sphere2500":
        from course.problems.posegraph3d import dataset as datasets_3d
        from course.problems.posegraph3d.factor_graph import as_factor_graph as graph_3d

        g3 = datasets_3d.load_dataset(name)
        _, A, B = exercise("pose_graph_3d", impl).edge_errors_and_jacobians(g3.t, g3.R, g3.edges_i, g3.edges_j,
                                                                            g3.t_z, g3.R_z)
        return graph_3d(g3), [A, B]
    from course.problems.posegraph import dataset as datasets_2d
    from course.problems.posegraph.factor_graph import as_factor_graph as graph_2d

    g2 = datasets_2d.load_dataset(name)
    _, A, B = exercise("pose_graph_fast", impl).edge_errors_and_jacobians(g2.poses, g2.edges_i, g2.edges_j,
                                                                          g2.measurements)
    return graph_2d(g2), [A, B]


@dataclass
class Agreement:
    """One graph's automatic (``autodiff``) and central-difference (``numeric``) Jacobians against the
    analytic ones: the largest difference per factor relative to its largest entry; ``note`` when not run."""

    name: str
    factors: int = 0
    autodiff: float = float("nan")
    numeric: float = float("nan")
    note: str = ""


def jacobian_agreement(names, impl="solutions") -> list[Agreement]:
    """An :class:`Agreement` per dataset of ``names``, at its start (the blocks of fixed variables, 0 on the
    factor graph's paths, compared with 0); a row saying why where its data is not here or an exercise it
    needs is not written."""
    rows = []
    for name in names:
        try:
            graph, analytic = _analytic(name, impl)
            # a fixed variable is not differentiated (its blocks 0): the analytic ones compared where it is free
            held = np.isin(next(iter(graph.groups.values())).arrays()[0], sorted(graph.fixed))
            analytic = [np.where(held[:, a, None, None], 0.0, block) for a, block in enumerate(analytic)]
            got = {}
            for jacobians in ("autodiff", "numeric"):
                problem = FactorGraphProblem(graph, impl, jacobians=jacobians, solver=SuperLUSolver())
                _, blocks = problem.factor_jacobians(problem.x0, 0)
                got[jacobians] = max(_blockwise(b, a) for b, a in zip(blocks, analytic))
            rows.append(Agreement(name, graph.num_factors, got["autodiff"], got["numeric"]))
        except DatasetError as exc:
            rows.append(Agreement(name, note=f"skipped ({str(exc).splitlines()[0]})"))
        except NotImplementedError as exc:
            rows.append(Agreement(name, note=not_implemented_reason(exc)))
    return rows


def agreement_table(rows) -> str:
    """The rows of :func:`jacobian_agreement` as a table."""
    lines = [f"{'graph':12} {'factors':>8} {'autodiff':>10} {'numeric':>10}   (largest difference from the "
             "analytic Jacobians, relative per factor)"]
    for row in rows:
        if row.note:
            lines.append(f"{row.name:12} {row.note}")
        else:
            lines.append(f"{row.name:12} {row.factors:8d} {row.autodiff:10.1e} {row.numeric:10.1e}")
    return "\n".join(lines)


#: the back ends the experiments set side by side: ours (analytic Jacobians), the factor graph by Jets and by
#: central differences
BACKENDS = ["ours", "ours-autodiff", "ours-numeric"]


def solve_runs(name: str, impl="solutions", method="lm-type3") -> list:
    """``compare``'s runs of ``method`` on dataset ``name`` (a 2D or 3D pose graph) by :data:`BACKENDS`,
    same start; a row naming the TODO for a back end whose exercise is not written. Loads ``name``
    (``DatasetError`` where its data is not here)."""
    from course.app import compare

    if name in ("sphere2500", "torus3D", "smallGrid3D"):
        from course.problems.posegraph3d import dataset as datasets_3d

        return compare.run_posegraph3d(datasets_3d.load_dataset(name), impl=impl, methods=[method],
                                       backends=BACKENDS, unimplemented="row")
    from course.problems.posegraph import dataset as datasets_2d

    return compare.run_posegraph(datasets_2d.load_dataset(name), impl=impl, methods=[method], backends=BACKENDS,
                                 unimplemented="row")


def minimum_line(runs) -> str:
    """How far each factor-graph run's final chi2 is from ours (analytic Jacobians), relative."""
    ours = {r.method: r for r in runs if r.backend == "ours" and not r.not_run}
    parts = []
    for r in runs:
        if r.backend != "ours" and r.backend.startswith("ours") and not r.not_run and r.method in ours:
            rel = abs(r.final_chi2 - ours[r.method].final_chi2) / ours[r.method].final_chi2
            parts.append(f"{r.backend} {r.method} {rel:.1e}")
    return ("final chi2 against ours, relative: " + ", ".join(parts)) if parts else \
        "no factor-graph run to set beside ours (see the rows above)"


# ---------------------------------------------------------------- experiment: a new factor


@dataclass
class GpsDrive:
    """A drive: ``truth`` (N, 3) SE(2) poses; ``odometry`` (N - 1, 3) each pose seen from the last, noisy;
    ``gps_keys`` (K, 1) the poses with a position fix, ``gps`` (K, 2) the fixes, noisy; the noise's
    standard deviations ``odometry_sigma`` (3,) and ``gps_sigma``."""

    truth: np.ndarray
    odometry: np.ndarray
    gps_keys: np.ndarray
    gps: np.ndarray
    odometry_sigma: np.ndarray
    gps_sigma: float


def gps_drive(poses=80, every=8, seed=1, odometry_sigma=(0.05, 0.05, 0.02), gps_sigma=0.5) -> GpsDrive:
    """A loop of ``poses`` poses driven at 1 m a step, turning left; a fix on every ``every``-th pose."""
    rng = np.random.default_rng(seed)
    turn = 2.0 * np.pi / poses * (1.0 + 0.3 * np.sin(np.arange(poses) / 5.0))
    truth = np.zeros((poses, 3))
    for k in range(1, poses):
        theta = truth[k - 1, 2]
        truth[k] = truth[k - 1] + [np.cos(theta), np.sin(theta), turn[k]]
        truth[k, 2] = float(jetmath.wrap_angle(truth[k, 2]))
    sigma = np.asarray(odometry_sigma, dtype=float)
    odometry = np.array([_relative_pose(truth[k], truth[k + 1]) for k in range(poses - 1)])
    odometry = odometry + rng.normal(0.0, 1.0, odometry.shape) * sigma
    keys = np.arange(0, poses, every)[:, None]
    gps = truth[keys[:, 0], :2] + rng.normal(0.0, gps_sigma, (len(keys), 2))
    return GpsDrive(truth, odometry, keys, gps, sigma, float(gps_sigma))


def dead_reckoning(drive: GpsDrive) -> np.ndarray:
    """The poses (N, 3) the odometry alone gives, composed from the first true pose."""
    poses = [drive.truth[0]]
    for dx, dy, dtheta in drive.odometry:
        x, y, theta = poses[-1]
        poses.append(np.array([x + np.cos(theta) * dx - np.sin(theta) * dy, y + np.sin(theta) * dx
                               + np.cos(theta) * dy, float(jetmath.wrap_angle(theta + dtheta))]))
    return np.array(poses)


def odometry_graph(drive: GpsDrive) -> FactorGraph:
    """The drive's poses (keys ``x0..``, at the dead reckoning) and its odometry as ``BETWEEN_SE2`` factors;
    nothing fixed."""
    graph = FactorGraph("a drive")
    for k, pose in enumerate(dead_reckoning(drive)):
        graph.add_variable(f"x{k}", SE2, pose)
    pairs = np.stack([np.arange(len(drive.odometry)), np.arange(1, len(drive.odometry) + 1)], axis=1)
    graph.add_many(BETWEEN_SE2, pairs, drive.odometry, np.diag(1.0 / drive.odometry_sigma**2))
    return graph


def position_error(poses, truth) -> float:
    """The root mean square distance (m) between ``poses`` and ``truth`` (positions only, no alignment)."""
    return float(np.sqrt(np.mean(np.sum((np.asarray(poses)[:, :2] - truth[:, :2]) ** 2, axis=1))))


def drive_figure(drive: GpsDrive, solved=None):
    """The true path, the dead reckoning, the fixes and (when given, (N, 3)) the solved poses."""
    fig = plot.figure(6.4, 5.6)
    ax = fig.subplots()
    reckoned = dead_reckoning(drive)
    ax.plot(drive.truth[:, 0], drive.truth[:, 1], "k-", lw=1.2, label="truth")
    ax.plot(reckoned[:, 0], reckoned[:, 1], "-", color="tab:red", lw=1.0,
            label=f"odometry alone ({position_error(reckoned, drive.truth):.2f} m rms)")
    ax.plot(drive.gps[:, 0], drive.gps[:, 1], "x", color="tab:green", ms=7,
            label=f"position fixes (sigma {drive.gps_sigma:g} m)")
    if solved is not None:
        ax.plot(solved[:, 0], solved[:, 1], "-", color="tab:blue", lw=1.2,
                label=f"the graph with the GPS factor ({position_error(solved, drive.truth):.2f} m rms)")
    ax.set_aspect("equal")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8)
    ax.set_title(f"a drive of {len(drive.truth)} poses, a fix every {int(np.diff(drive.gps_keys[:, 0])[0])}",
                 fontsize=9)
    return fig


# ---------------------------------------------------------------- range-only SLAM, built from the library


@dataclass
class RangeOnly:
    """The drive of :func:`gps_drive` with beacons in place of the fixes: ``beacons`` (B, 2) their true
    positions, ``beacon_start`` (B, 2) where the solve starts them (a rough survey); ``range_keys`` (K, 2)
    (pose, beacon) pairs, ``ranges`` (K,) the measured distances, noisy, with standard deviation
    ``range_sigma``; ``prior_sigma`` (3,) that of the prior on the first pose."""

    drive: GpsDrive
    beacons: np.ndarray
    beacon_start: np.ndarray
    range_keys: np.ndarray
    ranges: np.ndarray
    range_sigma: float
    prior_sigma: np.ndarray


def range_only(seed=4, beacons=((6.0, 3.0), (-4.0, 10.0), (9.0, 14.0), (2.0, 20.0)), reach=14.0, range_sigma=0.1,
               survey_sigma=1.5) -> RangeOnly:
    """Range-only SLAM on the 80-pose loop of :func:`gps_drive` (no fixes): every pose ranges every beacon
    within ``reach`` m; the beacons start ``survey_sigma`` m off (Gaussian)."""
    rng = np.random.default_rng(seed)
    drive = gps_drive(seed=seed)
    drive = GpsDrive(drive.truth, drive.odometry, np.zeros((0, 1), dtype=np.int64), np.zeros((0, 2)),
                     drive.odometry_sigma, drive.gps_sigma)
    marks = np.asarray(beacons, dtype=float)
    distance = np.linalg.norm(drive.truth[:, None, :2] - marks[None], axis=2)
    keys = np.argwhere(distance <= reach)
    ranges = distance[keys[:, 0], keys[:, 1]] + rng.normal(0.0, range_sigma, len(keys))
    start = marks + rng.normal(0.0, survey_sigma, marks.shape)
    return RangeOnly(drive, marks, start, keys, ranges, float(range_sigma), np.array([0.05, 0.05, 0.01]))


def range_only_graph(problem: RangeOnly) -> FactorGraph:
    """The factor graph of ``problem`` from the library alone: poses ``x<k>`` (SE2, at the dead reckoning)
    and beacons ``b<j>`` (Vector(2), at their rough positions); ``prior(SE2)`` on ``x0`` at the true start,
    ``between(SE2)`` the odometry, ``RANGE_2D`` the ranges. Nothing fixed: the prior holds the gauge."""
    graph = FactorGraph("range-only SLAM")
    for k, pose in enumerate(dead_reckoning(problem.drive)):
        graph.add_variable(f"x{k}", SE2, pose)
    for j, mark in enumerate(problem.beacon_start):
        graph.add_variable(f"b{j}", Vector(2), mark)
    graph.add(prior(SE2), ["x0"], problem.drive.truth[0], noise=noise.sigmas(problem.prior_sigma))
    odometry = noise.sigmas(problem.drive.odometry_sigma)
    for k, z in enumerate(problem.drive.odometry):
        graph.add(between(SE2), [f"x{k}", f"x{k + 1}"], z, noise=odometry)
    poses = len(problem.drive.truth)
    graph.add_many(RANGE_2D, problem.range_keys + [0, poses], problem.ranges[:, None],
                   noise=noise.isotropic(1, problem.range_sigma))
    return graph


def range_only_runs(problem: RangeOnly, impl="solutions", repeat=3) -> dict:
    """``{"ours": run, "gtsam": run}``: the graph solved from the same start by our Levenberg-Marquardt
    (Nielsen's rule, the implementation's Jets) and by GTSAM's on its own factors
    (``course.backends.factorgraph.gtsam_native``); each run's ``seconds`` the fastest of ``repeat`` (the
    solve alone, GTSAM's ``optimize()``), ``final_chi2`` our error on its solution. Without GTSAM installed
    its entry is a line saying so."""
    from course.core import peers

    graph = range_only_graph(problem)
    options = SolverOptions(max_iterations=100, cost_tolerance=1e-12)
    runs: dict = {}
    for _ in range(repeat):
        run = minimize(FactorGraphProblem(graph, impl), "lm-type3", impl=impl, options=options)
        if "ours" not in runs or run.seconds < runs["ours"].seconds:
            runs["ours"] = run
    if not peers.installed("gtsam"):
        runs["gtsam"] = "gtsam is not installed here (pip install gtsam): its row is left out"
        return runs
    from course.backends.factorgraph import gtsam_native

    for _ in range(repeat):
        run = gtsam_native.solve(graph, "levenberg-marquardt", relative_error_tol=1e-12, absolute_error_tol=1e-12)
        if "gtsam" not in runs or run.seconds < runs["gtsam"].seconds:
            runs["gtsam"] = run
    return runs


def range_only_table(problem: RangeOnly, runs: dict) -> str:
    """One line per solve: chi2 (ours, on each solution), iterations, time, and the error of poses and
    beacons against the truth."""
    poses = len(problem.drive.truth)
    lines = [f"{poses} poses, {len(problem.beacons)} beacons, {len(problem.ranges)} ranges "
             f"(sigma {problem.range_sigma:g} m); start chi2 "
             f"{runs['ours'].initial_chi2:.6g}, odometry alone "
             f"{position_error(dead_reckoning(problem.drive), problem.drive.truth):.2f} m rms"]
    for name, run in runs.items():
        if isinstance(run, str):
            lines.append(f"{name:6s} {run}")
            continue
        x = np.asarray(run.params, dtype=float)
        pose_error = position_error(x[:3 * poses].reshape(-1, 3), problem.drive.truth)
        beacon_error = float(np.sqrt(np.mean(np.sum((x[3 * poses:].reshape(-1, 2) - problem.beacons) ** 2, axis=1))))
        lines.append(f"{name:6s} chi2 {run.final_chi2:.10g}  {run.iterations:3d} iterations  "
                     f"{1e3 * run.seconds:7.1f} ms  poses {pose_error:.3f} m rms  beacons {beacon_error:.3f} m rms")
    if not isinstance(runs.get("gtsam"), str) and "gtsam" in runs:
        ours, theirs = runs["ours"].final_chi2, runs["gtsam"].final_chi2
        lines.append(f"ours - gtsam: {ours - theirs:+.3e} in chi2 ({(ours - theirs) / theirs:+.2e} relative; "
                     "both on our error, which ours minimises)")
    return "\n".join(lines)


# ---------------------------------------------------------------- the retraction's derivative as the seed


def plus_jacobian_study(pose2=(1.0, 2.0, 0.7), phi=(0.3, -0.2, 0.5), t=(1.0, 2.0, 3.0), h=1e-6) -> dict:
    """Each pose kind's ``plus_jacobian(x)`` (the Jet seed, Ceres' ``Manifold::PlusJacobian``) beside the
    central difference of its retraction at ``delta = 0``: ``{kind: (P (n, d), largest difference)}``."""
    out = {}
    pose3 = se3_value(np.asarray(t, dtype=float), exp_many(np.asarray(phi, dtype=float)[None])[0])
    for kind, x in ((SE2, np.asarray(pose2, dtype=float)), (SE3, pose3)):
        P = kind.plus_jacobian(x[None])[0]
        numeric = np.zeros_like(P)
        for j in range(kind.dim):
            e = np.zeros((1, kind.dim))
            e[0, j] = h
            numeric[:, j] = (kind.retract(x[None], e)[0] - kind.retract(x[None], -e)[0]).ravel() / (2 * h)
        out[kind.name] = (P, float(np.abs(P - numeric).max()))
    return out


def plus_jacobian_text(study: dict) -> str:
    """The plus-Jacobians of :func:`plus_jacobian_study`, printed with their check."""
    lines = []
    with np.printoptions(precision=3, suppress=True, linewidth=110):
        for name, (P, diff) in study.items():
            lines.append(f"{name}.plus_jacobian(x): d vec(x (+) delta) / d delta at delta = 0, "
                         f"{P.shape[0]} x {P.shape[1]} (central differences of the retraction agree to {diff:.1e})")
            lines.append(str(P))
    return "\n".join(lines)
