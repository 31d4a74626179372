"""Checks of Gavin's three damping strategies in ``damping`` (``GavinType1``, ``GavinType2``,
``GavinType3``): initial lambda, damping diagonal, gain-ratio denominator, type 2's line
search, and the accept/reject update, each graded alone on given inputs.

Public inputs: two small systems (see ``checks.gauss_newton.systems``) and update cases
in each branch (accepted, rejected, clamped), the edges among them: type 1's lambda already at
a bound, types 2 and 3 taking lambda past 1e7 or below 1e-7 (they have no bound there), and
type 2's alpha above 1 or with a negative denominator; hidden inputs: other systems, and the
same cases with lambda, nu and rho moved within their branch.
"""

import numpy as np

from autograder.checks import Call
from autograder.checks.common import check
from autograder.checks.edges import Edge
from autograder.checks.gauss_newton import systems
from autograder.feedback import fmt, values

MODULES = ("damping",)
LAM_RTOL, LAM_ATOL = 1e-10, 0.0


def _target(cls, method):
    return f"damping:{cls}.{method}"


def _state(lam, nu=2.0):
    from course.solver.damping import DampingState

    return DampingState(lam=lam, nu=nu)


def _descent_step(H, b, d):
    """A descent direction of the damped model (a Jacobi step, not the exact solve)."""
    return -b / (np.diag(H) + d)


def _initial_calls(cls, custom):
    """With the default constructor and with a custom lambda_0 / tau (``custom``)."""

    def build(seed=None):
        diag = np.diag(systems(seed)[0][0]).copy()
        calls = []
        for init in ({}, custom):
            made = f" with {cls}({', '.join(f'{k}={v}' for k, v in init.items())})" if init else ""
            calls.append(Call(_target(cls, "initial_state"), (diag,), init=init, returns="state",
                              where=f"for diag(H) = {fmt(diag)}{made}"))
        return calls

    return build


def _diagonal_calls(cls):
    def build(seed=None):
        lams = (0.07, 2.5) if seed is None else tuple(np.round(np.random.default_rng([seed, 301]).uniform(
            [0.01, 1.0], [0.5, 5.0]), 4))
        return [Call(_target(cls, "damping_diagonal"), (np.diag(H).copy(), lam),
                     where=f"for diag(H) = {fmt(np.diag(H))}, lambda = {lam}")
                for (H, _), lam in zip(systems(seed), lams)]

    return build


def _gain_calls(cls, kind):
    def build(seed=None):
        lams = (0.01, 3.0) if seed is None else tuple(np.round(np.random.default_rng([seed, 302]).uniform(
            [0.005, 1.0], [0.1, 5.0]), 4))
        calls = []
        for (H, b), lam in zip(systems(seed), lams):
            diag = np.diag(H).copy()
            h = _descent_step(H, b, lam * diag if kind == 1 else lam * np.ones_like(diag))
            calls.append(Call(_target(cls, "gain_denominator"), (h, b, diag, lam),
                              where=f"for a step of size {len(h)} with lambda = {lam}"))
        return calls

    return build


def _update_call(cls, state, rho, accepted, alpha=1.0, dchi2=0.0):
    where = (f"for lambda = {state.lam:g}, nu = {state.nu:g}, rho = {rho:g}, "
             f"{'accepted' if accepted else 'rejected'}"
             + (f", alpha = {alpha:g}, dchi2 = {dchi2:g}" if cls == "GavinType2" else ""))
    return Call(_target(cls, "update"), (state, rho, accepted), {"alpha": alpha, "dchi2": dchi2},
                returns="state", where=where)


def _update_calls(cls, cases, key):
    """Public: ``cases`` as given; hidden: lambda scaled by 0.6-1.4 and rho, alpha, dchi2
    moved a little, every case staying in its branch (the clamp cases stay clamped)."""

    def build(seed=None):
        calls = []
        rng = None if seed is None else np.random.default_rng([seed, 303, key])
        for state, rho, accepted, *rest in cases:
            lam, nu = state[0], (state[1] if len(state) > 1 else 2.0)
            alpha, dchi2 = (rest + [1.0, 0.0][len(rest):])[:2]
            if rng is not None:
                high = 1.0 if lam < 1e-6 or lam >= 1e7 else 1.4  # clamps stay clamped, bounds not passed
                lam = float(np.round(lam * rng.uniform(0.6, high), 12))
                rho = float(np.round(rho + rng.uniform(-0.02, 0.02), 4)) if 0.26 < rho < 0.99 else rho
                alpha = float(np.round(alpha * rng.uniform(0.8, 1.0), 4))
                dchi2 = float(np.round(dchi2 * rng.uniform(0.7, 1.3), 4))
            calls.append(_update_call(cls, _state(lam, nu), rho, accepted, alpha, dchi2))
        return calls

    return build


def _alpha_calls(seed=None):
    H, b = systems(seed)[0]
    h = _descent_step(H, b, 0.05 * np.ones(len(b)))
    gh = float(-b @ h)
    chi2 = 50.0 if seed is None else float(np.round(np.random.default_rng([seed, 304]).uniform(20, 200), 3))
    calls = []
    for change, what in ((gh, "chi2 rose by g^T h"), (-1.5 * gh, "chi2 fell by 1.5 g^T h"),
                         (1e6 * gh, "chi2 rose a lot (alpha hits its lower bound)"),
                         (-3.0 * gh, "chi2 fell by 3 g^T h (alpha = 2, above 1)"),
                         (-6.0 * gh, "chi2 fell by 6 g^T h (the denominator is negative)")):
        calls.append(Call(_target("GavinType2", "step_scale"), (h, b, chi2, chi2 + change),
                          where=f"for chi2 = {chi2:g}, chi2(p + h) = {chi2 + change:.6g} ({what})"))
    return calls


UPDATE_HINTS = {
    1: "accepted: max(lambda / 9, 1e-7); rejected: min(lambda * 11, 1e7)",
    2: "accepted: max(lambda / (1 + alpha), 1e-7); rejected: lambda + |dchi2| / (2 alpha)",
    3: "accepted: lambda max(1/3, 1 - (2 rho - 1)^3), nu = 2; rejected: lambda nu, nu = 2 nu",
}

#: (title, points, cases) of each type's update checks; a case is (state, rho, accepted[, alpha, dchi2])
UPDATE_CASES = {
    1: [("update (accepted step)", 1, [((0.05,), 0.7, True), ((2.0,), 0.3, True)]),
        ("update (rejected step)", 1, [((0.05,), -0.4, False), ((3.0,), 0.05, False)]),
        ("update (lambda clamped to [1e-7, 1e7])", 1, [((5e-7,), 0.9, True), ((2e6,), -1.0, False),
                                                       ((1e-7,), 0.8, True), ((1e7,), -0.5, False)])],
    2: [("update (accepted step)", 1, [((0.5,), 0.6, True, 0.4, -3.0), ((1.5e-7,), 0.9, True, 1.0, -2.0)]),
        ("update (rejected step)", 1, [((0.5,), -0.3, False, 0.25, 3.0), ((2.0,), 0.05, False, 0.3, -0.2),
                                       ((5e6,), -0.5, False, 0.5, 2e7)])],
    3: [("update (accepted step, nu reset)", 2, [((0.4, 8.0), 0.5, True), ((0.4, 4.0), 0.95, True),
                                                ((0.4, 16.0), 0.3, True), ((2e-7, 4.0), 0.95, True)]),
        ("update (rejected step, nu doubled)", 1, [((0.4, 4.0), -0.2, False), ((0.1, 2.0), 0.05, False),
                                                   ((6e6, 4.0), -0.3, False)])],
}


def _type_checks(kind):
    cls = f"GavinType{kind}"
    ex = f"damping.{cls}"
    custom = {"lambda_0": 0.3} if kind == 1 else {"tau": 0.5}
    checks = [
        check(ex, "initial_state", 1, _initial_calls(cls, custom),
               values(("lam", "nu"), LAM_RTOL, LAM_ATOL,
                      "type 1: lambda_0 as given" if kind == 1 else "lambda_0 = tau max diag(H), nu = 2")),
        check(ex, "damping_diagonal", 2 if kind == 1 else 1, _diagonal_calls(cls),
               values(("value",), 1e-12, 0.0, "d = lambda diag(H)" if kind == 1 else "d = lambda (1, ..., 1)",
                      labels={"value": "d"})),
        check(ex, "gain_denominator", 2 if kind == 1 else 1, _gain_calls(cls, kind),
               values(("value",), 1e-9, 1e-12,
                      "Gavin eq. 16: h^T (lambda diag(H) h - b)" if kind == 1 else "Gavin eq. 15: h^T (lambda h - b)",
                      labels={"value": "denominator"}, scalar=True)),
    ]
    if kind == 2:
        checks.append(check(ex, "step_scale", 2, _alpha_calls,
                             values(("value",), 1e-9, 0.0,
                                    "alpha = g^T h / ((chi2(p+h) - chi2(p)) / 2 + 2 g^T h), g = -b, at least 0.1",
                                    labels={"value": "alpha"}, scalar=True)))
    judge = values(("lam", "nu"), LAM_RTOL, LAM_ATOL, UPDATE_HINTS[kind])
    for key, (title, points, cases) in enumerate(UPDATE_CASES[kind]):
        checks.append(check(ex, title, points, _update_calls(cls, cases, 10 * kind + key), judge))
    return checks


CHECKS = [*_type_checks(1), *_type_checks(2), *_type_checks(3)]


LAMBDA_MIN, LAMBDA_MAX = 1e-7, 1e7


def _update_edge(kind, accepted, holds):
    """An edge of type ``kind``'s update: a call in the branch ``accepted`` whose inputs pass ``holds(lam, nu,
    rho, alpha, dchi2)``."""

    def on_edge(call):
        state, rho, taken = call.args
        return bool(taken) == accepted and holds(state.lam, state.nu, rho, call.kwargs["alpha"], call.kwargs["dchi2"])

    return on_edge


def _alpha_parts(call):
    """(g^T h, the denominator of alpha) of a step_scale call."""
    h, b, chi2, full = call.args
    gh = float(-b @ h)
    return gh, (full - chi2) / 2.0 + 2.0 * gh


EDGES = (
    Edge("type 1: lambda at 1e-7 and the step accepted: it stays 1e-7", _target("GavinType1", "update"),
         _update_edge(1, True, lambda lam, *_: lam == LAMBDA_MIN)),
    Edge("type 1: lambda at 1e7 and the step rejected: it stays 1e7", _target("GavinType1", "update"),
         _update_edge(1, False, lambda lam, *_: lam == LAMBDA_MAX)),
    Edge("type 2: a rejected step takes lambda past 1e7 (type 2 has no upper bound)", _target("GavinType2", "update"),
         _update_edge(2, False, lambda lam, nu, rho, alpha, dchi2: lam + abs(dchi2) / (2 * alpha) > LAMBDA_MAX)),
    Edge("type 2: alpha above 1 (chi2 fell by more than 2 g^T h; no upper bound)", _target("GavinType2", "step_scale"),
         lambda call: 0 < _alpha_parts(call)[1] < _alpha_parts(call)[0]),
    Edge("type 2: alpha's denominator negative (chi2 fell by more than 4 g^T h): alpha = 0.1",
         _target("GavinType2", "step_scale"), lambda call: _alpha_parts(call)[1] < 0),
    Edge("type 3: an accepted step takes lambda below 1e-7 (type 3 has no lower bound)",
         _target("GavinType3", "update"),
         _update_edge(3, True, lambda lam, nu, rho, *_: lam * max(1 / 3, 1 - (2 * rho - 1) ** 3) < LAMBDA_MIN)),
    Edge("type 3: a rejected step takes lambda past 1e7 (type 3 has no upper bound)", _target("GavinType3", "update"),
         _update_edge(3, False, lambda lam, nu, *_: lam * nu > LAMBDA_MAX)),
)
