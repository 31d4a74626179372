"""Chapter 3: the dogleg pieces and the minimizer that never refactorizes on rejection."""

import numpy as np
import pytest

from course.problems.curve import problem as curve
from course.problems.posegraph import dataset as datasets
from course.problems.posegraph.problem import PoseGraphProblem
from course.solver import minimize
from solutions import dogleg


def quadratic(n=5, seed=0):
    rng = np.random.default_rng(seed)
    J = rng.normal(size=(3 * n, n))
    H = J.T @ J
    g = rng.normal(size=n)
    return H, g, np.linalg.solve(H, -g)


def model_decrease(H, g, h):
    return -(g @ h) - 0.5 * h @ H @ h


def test_cauchy_point_minimizes_along_steepest_descent():
    H, g, _ = quadratic()
    h_cp, alpha = dogleg.cauchy_point(g, H @ g)
    assert alpha == pytest.approx(g @ g / (g @ H @ g))
    for t in (0.9, 1.1):
        assert model_decrease(H, g, h_cp) > model_decrease(H, g, t * h_cp)


@pytest.mark.parametrize("radius_factor, case", [
    (2.0, dogleg.GAUSS_NEWTON), (0.3, dogleg.STEEPEST_DESCENT), (None, dogleg.DOGLEG)])
def test_dogleg_cases_and_exact_predicted_decrease(radius_factor, case):
    H, g, h_gn = quadratic(seed=1)
    _, alpha = dogleg.cauchy_point(g, H @ g)
    a_norm, gn_norm = alpha * np.linalg.norm(g), np.linalg.norm(h_gn)
    assert a_norm < gn_norm
    if radius_factor is None:
        radius = 0.5 * (a_norm + gn_norm)
    elif case == dogleg.GAUSS_NEWTON:
        radius = radius_factor * gn_norm
    else:
        radius = radius_factor * a_norm
    h, predicted, got = dogleg.dogleg_step(g, h_gn, alpha, radius)
    assert got == case
    assert predicted == pytest.approx(model_decrease(H, g, h), rel=1e-10)
    if case != dogleg.GAUSS_NEWTON:
        assert np.linalg.norm(h) == pytest.approx(radius, rel=1e-12)


def test_beta_is_stable_when_the_cauchy_point_is_almost_on_the_boundary():
    # radius^2 - |a|^2 cancels here; the naive root of the quadratic is off by ~1e-4
    g = np.array([1.0, 0.0])
    h_gn = np.array([-1e8, 1e4])
    radius = 1.0 + 2.0**-40
    h, _, case = dogleg.dogleg_step(g, h_gn, 1.0, radius)  # Cauchy point (-1, 0)
    assert case == dogleg.DOGLEG
    a = np.array([-1.0, 0.0])
    d = h_gn - a
    c = a @ d
    assert c > 0
    gap = (radius - 1.0) * (radius + 1.0)  # radius^2 - |a|^2 without cancellation
    beta = gap / (np.sqrt(c * c + (d @ d) * gap) + c)
    np.testing.assert_allclose(h, a + beta * d, rtol=1e-10)


def test_radius_update():
    assert dogleg.update_radius(1.0, 0.9, 0.5) == 1.5
    assert dogleg.update_radius(2.0, 0.9, 0.5) == 2.0
    assert dogleg.update_radius(1.0, 0.1, 0.5) == 0.5
    assert dogleg.update_radius(1.0, 0.5, 0.5) == 1.0


def test_dogleg_matches_gauss_newton_on_the_curve():
    problem = curve.CurveProblem(curve.generate())
    gn, dl = minimize(problem, "gauss-newton"), minimize(problem, "dogleg")
    assert dl.final_chi2 == pytest.approx(gn.final_chi2, rel=1e-6)
    np.testing.assert_allclose(dl.params, gn.params, rtol=1e-6)
    assert dl.factorizations < gn.factorizations


@pytest.mark.parametrize("name", ["intel", "mit", "intel-g2o", "m3500", "csail", "fr079"])
def test_dogleg_matches_gauss_newton_on_pose_graphs(name, data_folder):
    graph = datasets.load_dataset(name)
    gn = minimize(PoseGraphProblem(graph), "gauss-newton")
    dl = minimize(PoseGraphProblem(graph), "dogleg")
    assert dl.final_chi2 == pytest.approx(gn.final_chi2, rel=1e-6)


def test_a_rejected_step_costs_no_factorization(data_folder):
    result = minimize(PoseGraphProblem(datasets.load_dataset("intel-g2o")), "dogleg")
    trace = result.trace
    rejected = [k for k, r in enumerate(trace) if not r.accepted]
    assert rejected, "intel-g2o from its start is expected to reject dogleg steps"
    for k in rejected:
        if k + 1 < len(trace):
            assert trace[k + 1].factorizations == trace[k].factorizations
            assert trace[k + 1].damping < trace[k].damping
    accepted = len(trace) - 1 - len(rejected)
    assert accepted <= result.factorizations <= accepted + 1
