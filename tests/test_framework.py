"""The framework the students build on, pinned: the linearization's algebra against dense
algebra, the damping loop's bookkeeping (diag(H) refreshed after an accepted step, the
acceptance threshold), the stop reasons, and the trajectory error on hand-computed cases.

Each test is written so that a one-line framework mistake fails it (a ``matvec`` that
counts the diagonal twice, a stale ``diag(H)``, accepting at rho > 0).
"""

import numpy as np
import pytest
import scipy.sparse as sp

from course.problems.posegraph.trajectory import absolute_trajectory_error
from course.solver import minimize
from course.solver.linearization import Linearization


def _spd(n, seed):
    rng = np.random.default_rng(seed)
    A = sp.random(3 * n, n, density=0.3, random_state=seed) + sp.eye(3 * n, n)
    H = (A.T @ A).toarray() + np.diag(rng.uniform(0.5, 2.0, n))
    return H, rng.normal(size=n)


@pytest.mark.parametrize("positions", [False, True])
def test_upper_storage_behaves_like_the_dense_matrix(positions):
    H, v = _spd(12, 3)
    upper = sp.triu(sp.csc_matrix(H), format="csc")
    upper.sort_indices()
    diag_at = None
    if positions:
        diag_at = np.array([upper.indptr[j] + np.flatnonzero(upper.indices[upper.indptr[j]:upper.indptr[j + 1]] == j)[0]
                            for j in range(12)])
    dense, stored = Linearization(H, v, 1.0), Linearization(upper, v, 1.0, upper=True, diagonal_positions=diag_at)
    np.testing.assert_allclose(stored.matvec(v), H @ v, rtol=1e-13, atol=1e-13)
    np.testing.assert_allclose(dense.matvec(v), H @ v, rtol=1e-13, atol=1e-13)
    np.testing.assert_array_equal(stored.diagonal(), np.diag(H))
    d = np.linspace(0.1, 1.2, 12)
    damped = stored.with_diagonal_added(d)
    np.testing.assert_allclose(damped.toarray(), np.triu(H + np.diag(d)), rtol=1e-15, atol=0)
    np.testing.assert_allclose(dense.with_diagonal_added(d), H + np.diag(d), rtol=1e-15, atol=0)
    np.testing.assert_array_equal(upper.toarray(), np.triu(H))  # the stored matrix is left alone
    assert stored.with_diagonal_added(None) is upper


class _Quadratic:
    """``chi2(x) = sum c_k (x_k - 1)^2 + extra(x)``: H = diag(2 c(x)) changes with x, so a
    loop that keeps an old diag(H) is seen; ``chi2_at`` overrides chi2 at trial points."""

    def __init__(self, chi2_at=None):
        self.x0 = np.zeros(2)
        self.chi2_at = chi2_at
        self.diagonals = []

    def weights(self, x):
        return np.array([1.0 + x[0] ** 2, 3.0 + x[1] ** 2])

    def chi2(self, x):
        if self.chi2_at is not None and np.any(x != self.x0):
            return self.chi2_at(x)
        return float(np.sum(self.weights(x) * (x - 1.0) ** 2))

    def linearize(self, x):
        w = self.weights(x)
        H = np.diag(2.0 * w)
        return Linearization(H, 2.0 * w * (x - 1.0), self.chi2(x))

    def solve(self, lin, damping=None):
        self.diagonals.append(np.diag(lin.H).copy())
        return np.linalg.solve(lin.with_diagonal_added(damping), -lin.b)

    def retract(self, x, h):
        return x + h


class _Recording:
    """A reference damping rule that records the diag(H) it is handed."""

    def __init__(self, strategy):
        self.strategy, self.seen = strategy, []

    def __getattr__(self, name):
        return getattr(self.strategy, name)

    def damping_diagonal(self, diag_H, lam):
        self.seen.append(np.array(diag_H, dtype=float))
        return self.strategy.damping_diagonal(diag_H, lam)


def test_the_loop_hands_the_strategy_the_current_diagonal(monkeypatch):
    from course.solver import minimizer as trust_region
    from course.solver import strategies

    recorders = []
    original = trust_region.make_strategy

    def recording(method, impl="solutions", options=None):
        strategy = original(method, impl, options)
        recorders.append(_Recording(strategy.rule))
        return strategies.LevenbergMarquardtStrategy(recorders[-1])

    monkeypatch.setattr(trust_region, "make_strategy", recording)
    problem = _Quadratic()
    result = minimize(problem, "lm-type1")
    assert sum(r.accepted for r in result.trace[1:]) >= 2
    # every damped solve used the H of the current point, and so did the strategy
    assert len(recorders[0].seen) == len(problem.diagonals) == result.iterations
    for seen, used in zip(recorders[0].seen, problem.diagonals):
        np.testing.assert_array_equal(seen, used)


def test_a_step_below_the_acceptance_threshold_is_rejected():
    # chi2 falls, but by 5% of the predicted decrease: 0 < rho < eps_4 = 0.1
    problem = _Quadratic()
    start = problem.chi2(problem.x0)
    lin = problem.linearize(problem.x0)
    from course.core import impl as impl_loader

    strategy = impl_loader.load("solutions").module("damping").STRATEGIES["lm-type1"]()
    state = strategy.initial_state(lin.diagonal())
    h = np.linalg.solve(lin.with_diagonal_added(strategy.damping_diagonal(lin.diagonal(), state.lam)), -lin.b)
    predicted = strategy.gain_denominator(h, lin.b, lin.diagonal(), state.lam)
    problem.chi2_at = lambda x: start - 0.05 * predicted
    result = minimize(problem, "lm-type1")
    first = result.trace[1]
    assert 0 < first.rho < 0.1 and not first.accepted
    assert strategy.accepts(0.1 + 1e-9) and not strategy.accepts(0.1) and not strategy.accepts(0.05)


def test_stop_reasons():
    from course.problems.curve.problem import CurveProblem, generate
    from course.solver.options import SolverOptions

    curve = CurveProblem(generate())
    assert minimize(curve, "gauss-newton").stop_reason == "cost_tolerance"
    capped = minimize(curve, "lm-type3", options=SolverOptions(max_iterations=3))
    assert capped.stop_reason == "max_iterations" and capped.iterations == 3
    at_minimum = _Quadratic()
    at_minimum.x0 = np.ones(2)  # b = 0 at the start
    result = minimize(at_minimum, "lm-type1")
    assert result.stop_reason == "gradient_tolerance" and result.iterations == 0
    tiny = minimize(_Quadratic(), "gauss-newton", options=SolverOptions(step_tolerance=10.0))
    assert tiny.stop_reason == "step_tolerance" and tiny.iterations == 0


def test_trajectory_error_of_a_rigidly_moved_copy_is_zero():
    rng = np.random.default_rng(4)
    truth = np.column_stack([rng.uniform(-5, 5, (20, 2)), rng.uniform(-np.pi, np.pi, 20)])
    phi, t = 0.7, np.array([3.0, -1.5])
    c, s = np.cos(phi), np.sin(phi)
    moved = np.column_stack([truth[:, :2] @ np.array([[c, s], [-s, c]]) + t, truth[:, 2] + phi])
    ate = absolute_trajectory_error(moved, truth)
    for part in ("translation", "rotation"):
        assert ate[part]["rmse"] == pytest.approx(0.0, abs=1e-12)


def test_trajectory_error_by_hand():
    truth = np.array([[-1.0, 0.0, 0.0], [1.0, 0.0, 0.0]])
    estimate = np.array([[-2.0, 0.0, 0.0], [2.0, 0.0, 0.1]])  # best alignment: identity
    ate = absolute_trajectory_error(estimate, truth)
    assert ate["translation"] == pytest.approx({"rmse": 1.0, "median": 1.0, "std": 0.0, "max": 1.0, "min": 1.0})
    assert ate["rotation"] == pytest.approx({"rmse": np.sqrt(0.005), "median": 0.05, "std": 0.05,
                                             "max": 0.1, "min": 0.0})


def test_stop_reasons_are_named_with_a_message():
    from course.problems.curve.problem import CurveProblem, generate
    from course.solver import StopReason

    result = minimize(CurveProblem(generate()), "gauss-newton")
    assert result.stop_reason is StopReason.COST_TOLERANCE and result.stop_reason == "cost_tolerance"
    assert all(reason.message for reason in StopReason)
    assert json_roundtrip(result.to_json())["stop_reason"] == "cost_tolerance"


def json_roundtrip(data):
    import json

    return json.loads(json.dumps(data))


@pytest.mark.parametrize("method", ["gauss-newton", "lm-type2", "dogleg"])
def test_the_callback_sees_every_step_attempt_and_can_stop(method):
    from course.problems.curve.problem import CurveProblem, generate

    problem, seen = CurveProblem(generate()), []
    result = minimize(problem, method, callback=seen.append)
    assert [r.iteration for r in seen] == [r.iteration for r in result.trace[1:]] and len(seen) > 3
    stopped = minimize(problem, method, callback=lambda record: record.iteration >= 2)
    assert stopped.iterations == 2 and stopped.stop_reason == "callback"


@pytest.mark.parametrize("bad", [{"max_iterations": -1}, {"max_iterations": 2.5}, {"gradient_tolerance": -1e-3},
                                 {"cost_tolerance": float("nan")}, {"initial_radius": 0.0},
                                 {"step_tolerance": float("inf")}])
def test_options_are_validated(bad):
    from course.solver import SolverOptions

    with pytest.raises(ValueError, match="SolverOptions." + next(iter(bad))):
        SolverOptions(**bad)


def test_the_dogleg_starts_from_the_initial_radius():
    from course.solver import SolverOptions

    result = minimize(_Quadratic(), "dogleg", options=SolverOptions(initial_radius=0.01, max_iterations=3))
    assert result.trace[0].damping == 0.01 and result.trace[1].step_norm == pytest.approx(0.01)
    assert minimize(_Quadratic(), "dogleg").final_chi2 == 0.0  # one Gauss-Newton step; b = 0 there


def test_the_scaled_nielsen_rule_is_type_1s_system_with_type_3s_update():
    """``lm-scaled-nielsen`` adds no formula: a slip in either of the student's rules shows in it."""
    from course.core import impl as impl_loader
    from course.solver.scaled_nielsen import ScaledNielsen

    rules = impl_loader.load("solutions").module("damping").STRATEGIES
    type1, type3 = rules["lm-type1"](), rules["lm-type3"]()
    rule = ScaledNielsen(type1, type3)
    diag_H, h, b = np.array([4.0, 0.01, 900.0]), np.array([0.1, -2.0, 0.003]), np.array([-1.0, 0.5, -2.0])
    state = rule.initial_state(diag_H)
    assert (state.lam, state.nu) == (type1.initial_state(diag_H).lam, 2.0)
    np.testing.assert_array_equal(rule.damping_diagonal(diag_H, 0.3), type1.damping_diagonal(diag_H, 0.3))
    assert rule.gain_denominator(h, b, diag_H, 0.3) == type1.gain_denominator(h, b, diag_H, 0.3)
    for rho, accepted in ((0.9, True), (0.2, True), (-1.0, False)):
        assert rule.update(state, rho, accepted) == type3.update(state, rho, accepted)
    # a rejected step doubles nu, then an accepted one resets it (Nielsen), where type 1 would divide by 9
    rejected = rule.update(state, -1.0, False)
    assert (rejected.lam, rejected.nu) == (2 * state.lam, 4.0)
    result = minimize(_Quadratic(), "lm-scaled-nielsen")
    assert result.final_chi2 < 1e-12 * result.initial_chi2


@pytest.mark.parametrize("qdldl_installed", [True, False])
def test_spd_solve_agrees_with_a_dense_solve(monkeypatch, qdldl_installed):
    import sys

    from course.solver.spd import spd_solve

    if not qdldl_installed:
        monkeypatch.setitem(sys.modules, "qdldl", None)  # the SuperLU fallback
    else:
        pytest.importorskip("qdldl", reason="qdldl has no wheel here")
    rng = np.random.default_rng(3)
    A = sp.random(60, 60, density=0.05, random_state=4) + sp.eye(60)
    H = (A @ A.T + sp.eye(60)).tocsc()
    rhs = rng.standard_normal((60, 3))
    expected = np.linalg.solve(H.toarray(), rhs)
    np.testing.assert_allclose(spd_solve(H, rhs), expected, rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(spd_solve(H, rhs[:, 1]), expected[:, 1], rtol=1e-10, atol=1e-12)
    # given its upper triangle alone, the same solve; the lower triangle is then never read
    upper = sp.triu(H, format="csc")
    np.testing.assert_allclose(spd_solve(upper, rhs, upper=True), expected, rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(spd_solve(upper, rhs[:, 1], upper=True), expected[:, 1], rtol=1e-10, atol=1e-12)


@pytest.mark.parametrize("keys", [np.array([], dtype=np.int64), np.array([5]), np.array([3, 3, 3]),
                                  np.random.default_rng(0).integers(0, 50, 300),
                                  np.sort(np.random.default_rng(1).integers(0, 10**9, 1000)) - 7])
def test_unique_inverse_is_numpys(keys):
    from course.solver.unique import unique_inverse

    unique, inverse = unique_inverse(keys)
    expected_unique, expected_inverse = np.unique(keys, return_inverse=True)
    assert np.array_equal(unique, expected_unique) and np.array_equal(inverse, expected_inverse)
    assert inverse.dtype == np.int64 and np.array_equal(unique[inverse], keys)


def test_spd_solve_shares_an_analysis_only_inside_the_block(monkeypatch):
    """Inside ``shared_analysis`` a second system of the same pattern is factorized numerically only (and
    solved right); another pattern is analysed anew; outside the block every solve analyses its own."""
    qdldl = pytest.importorskip("qdldl", reason="qdldl has no wheel here")
    from course.solver.spd import shared_analysis, spd_solve

    A = sp.random(40, 40, density=0.08, random_state=2) + sp.eye(40)
    H1 = sp.triu((A @ A.T + sp.eye(40)).tocsc(), format="csc")
    H2 = H1.copy()
    H2.data = 2.0 * H2.data  # the same pattern, other values
    H3 = sp.triu((A @ A.T + 3 * sp.eye(40)).tocsc() + sp.eye(40, k=39), format="csc")  # another pattern
    rhs = np.arange(40.0)
    made = []
    solver = qdldl.Solver
    monkeypatch.setattr(qdldl, "Solver", lambda *a, **k: made.append(1) or solver(*a, **k))

    def full(U):
        return (U + sp.triu(U, k=1).T).toarray()

    with shared_analysis():
        x1 = spd_solve(H1, rhs, upper=True)
        x2 = spd_solve(H2, rhs, upper=True)
        assert len(made) == 1
        x3 = spd_solve(H3, rhs, upper=True)
        assert len(made) == 2
    for H, x in ((H1, x1), (H2, x2), (H3, x3)):
        np.testing.assert_allclose(full(H) @ x, rhs, rtol=1e-9, atol=1e-9)
    made.clear()
    spd_solve(H1, rhs, upper=True)
    spd_solve(H1, rhs, upper=True)
    assert len(made) == 2
