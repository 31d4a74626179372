"""Checks of ``gauss_newton.normal_equations`` and ``gauss_newton.solve_step``.

Public inputs: two seeded least-squares problems (unit and non-uniform weights) and two
small symmetric positive definite systems with a non-uniform diagonal (so lambda I and
lambda diag(H) differ); at the edges, a single residual (m = 1) and a single parameter
(n = 1) with non-uniform weights, and a 1x1 system; hidden inputs: the same kinds from
other seeds and sizes.
"""

import numpy as np

from autograder.checks import Call
from autograder.checks.common import check
from autograder.checks.edges import Edge
from autograder.feedback import fmt, values

MODULES = ("gauss_newton",)
NORMAL = "gauss_newton.normal_equations"
STEP = "gauss_newton.solve_step"


def spd_system(n, seed, scales):
    """A symmetric positive definite H (n, n) with a non-uniform diagonal, and b (n,)."""
    rng = np.random.default_rng(seed)
    A = rng.normal(size=(3 * n, n)) * np.asarray(scales, float)
    return A.T @ A + 0.05 * np.eye(n), rng.normal(size=n) * 3.0


def systems(seed=None):
    """Two systems; the public ones are fixed, hidden ones drawn from ``seed``."""
    if seed is None:
        return [spd_system(3, 1, [1.0, 6.0, 0.3]), spd_system(4, 2, [2.0, 0.5, 4.0, 1.0])]
    rng = np.random.default_rng([seed, 201])
    out = []
    for n in (3, int(rng.integers(4, 7))):
        scales = np.exp(rng.uniform(np.log(0.2), np.log(6.0), n))
        out.append(spd_system(n, int(rng.integers(1 << 30)), scales))
    return out


def _least_squares_inputs(rng, m, n, weights):
    J = rng.normal(size=(m, n))
    r = rng.normal(size=m)
    w = np.ones(m) if weights == "unit" else rng.uniform(0.2, 3.0, size=m)
    return J, r, w


def _normal_calls(weights):
    def build(seed=None):
        if seed is None:
            cases = [(np.random.default_rng(3), 12, 3), (np.random.default_rng(4), 30, 5)]
        else:
            rng = np.random.default_rng([seed, 202])
            cases = [(rng, int(rng.integers(8, 20)), 3), (rng, int(rng.integers(20, 40)), int(rng.integers(4, 7)))]
        if weights != "unit":  # the smallest sizes: one residual, one parameter
            cases += [(np.random.default_rng(5 if seed is None else [seed, 204]), 1, 3),
                      (np.random.default_rng(6 if seed is None else [seed, 205]), 9, 1)]
        calls = []
        for rng, m, n in cases:
            J, r, w = _least_squares_inputs(rng, m, n, weights)
            where = f"for J of shape ({m}, {n}) with {'unit' if weights == 'unit' else 'non-uniform'} weights"
            calls.append(Call("gauss_newton:normal_equations", (J, r, w), returns=("H", "b"), where=where))
        return calls

    return build


def _step_calls(damped):
    def build(seed=None):
        calls = []
        rng = np.random.default_rng(7 if seed is None else [seed, 203])
        one = np.random.default_rng(8 if seed is None else [seed, 206])
        single = (np.array([[float(np.round(one.uniform(0.5, 4.0), 3))]]), np.round(one.normal(size=1) * 3.0, 3))
        for H, b in [*systems(seed), single]:  # and a 1x1 system (n = 1)
            n = len(b)
            if damped:
                d = rng.uniform(0.3, 2.0, size=n) * np.diag(H)
                calls.append(Call("gauss_newton:solve_step", (H, b, d),
                                  where=f"with H of size {n} and damping {fmt(d)}"))
            else:
                calls.append(Call("gauss_newton:solve_step", (H, b), where=f"with H of size {n}, no damping"))
                calls.append(Call("gauss_newton:solve_step", (H, b, None), where=f"with H of size {n}, damping=None"))
        return calls

    return build


CHECKS = [
    check(NORMAL, "unit weights", 1, _normal_calls("unit"),
           values(("H", "b"), 1e-9, 1e-9, {"H": "H = J^T W J", "b": "b = J^T W r"})),
    check(NORMAL, "non-uniform weights", 3, _normal_calls("weighted"),
           values(("H", "b"), 1e-9, 1e-9, {"H": "H = J^T W J", "b": "b = J^T W r"})),
    check(STEP, "undamped step", 2, _step_calls(False),
           values(("value",), 1e-8, 1e-10, "h solves H h = -b", labels={"value": "h"},
                  errors={"LinAlgError": "H given here is symmetric positive definite"})),
    check(STEP, "damped step", 2, _step_calls(True),
           values(("value",), 1e-8, 1e-10, "h solves (H + diag(damping)) h = -b",
                  labels={"value": "h"}, errors={"LinAlgError": (
                      "H + diag(damping) is symmetric positive definite here; H + damping (a vector) "
                      "adds it to every row: use H + np.diag(damping)")})),
]


def _normal_size(call):
    return call.args[0].shape


EDGES = (
    Edge("normal_equations with a single residual (m = 1): H has rank one", "gauss_newton:normal_equations",
         lambda call: _normal_size(call)[0] == 1),
    Edge("normal_equations with a single parameter (n = 1): H is (1, 1) and b (1,)", "gauss_newton:normal_equations",
         lambda call: _normal_size(call)[1] == 1),
    Edge("solve_step with a single unknown (n = 1), damped and undamped: h is (1,)", "gauss_newton:solve_step",
         lambda call: len(call.args[1]) == 1),
)
