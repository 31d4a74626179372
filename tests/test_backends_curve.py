"""Chapter 1 peers: Ceres (pyceres) and scipy.optimize.least_squares on the curve."""

import importlib

import numpy as np
import pytest
from conftest import needs

from course.backends import registry
from course.backends.curve import scipy as scipy_curve
from course.problems.curve.problem import CurveProblem, generate
from course.solver import minimize

RTOL = 1e-6
NEEDS_CERES = needs("pyceres")
PEERS = [pytest.param(importlib.import_module(registry.CURVE_PEERS[backend][0]) if backend == "scipy" else backend,
                      method, marks=NEEDS_CERES if backend == "ceres" else (), id=f"{backend}-{method}")
         for backend, (_, methods) in registry.CURVE_PEERS.items() for method in methods]


def peer(module):
    """A peer's module, from itself or from its back-end name (imported when the test runs)."""
    return importlib.import_module(registry.CURVE_PEERS[module][0]) if isinstance(module, str) else module


@pytest.fixture(scope="module")
def data():
    return generate()


@pytest.fixture(scope="module")
def reference(data):
    return minimize(CurveProblem(data), "lm-type3")


@pytest.fixture(scope="module")
def peer_runs(data):
    """``(module name, method) -> RunResult``, each solved on first use."""
    class Runs(dict):
        def __missing__(self, key):
            self[key] = importlib.import_module(key[0]).solve(data, key[1])
            return self[key]

    return Runs()


@pytest.mark.parametrize(("module", "method"), PEERS)
def test_peer_agrees_with_ours(peer_runs, reference, module, method):
    module = peer(module)
    run = peer_runs[(module.__name__, method)]
    np.testing.assert_allclose(run.params, reference.params, rtol=RTOL)
    assert run.final_chi2 == pytest.approx(reference.final_chi2, rel=1e-9)
    assert run.initial_chi2 == pytest.approx(reference.initial_chi2, rel=1e-12)
    assert run.method == method
    assert run.backend == ("scipy" if module is scipy_curve else "ceres")


@pytest.mark.parametrize(("module", "method"), PEERS)
def test_peer_trace_schema(peer_runs, module, method):
    run = peer_runs[(peer(module).__name__, method)]
    trace = run.trace
    assert run.iterations == len(trace) - 1 > 0
    assert [r.iteration for r in trace] == list(range(len(trace)))
    assert trace[0].chi2 == pytest.approx(run.initial_chi2, rel=1e-9)  # Ceres: 2 * cost
    kept = trace[0].chi2
    for record in trace[1:]:
        if record.accepted:
            assert record.chi2 <= kept * (1 + 1e-12), record
            kept = record.chi2
    assert kept == pytest.approx(run.final_chi2, rel=1e-9)
    times = [r.seconds for r in trace]
    assert times == sorted(times)
    assert 0 < run.seconds < 5
    json = run.to_json()
    assert json["backend"] in ("ceres", "scipy") and len(json["trace"]) == len(trace)


@NEEDS_CERES
def test_ceres_reports_half_chi2_and_counts_attempts(data, peer_runs):
    run = peer_runs[(peer("ceres").__name__, "levenberg-marquardt")]
    # far start: Ceres' first LM steps (radius 1e4) overflow and are rejected
    assert not run.trace[1].accepted
    assert run.trace[0].damping == pytest.approx(1e-4)  # 1 / initial radius
    assert "convergence" in run.stop_reason


@NEEDS_CERES
def test_ceres_one_block_per_point_gives_the_same_minimum(data, reference):
    run = peer("ceres").solve(data, "levenberg-marquardt", per_point=True)
    np.testing.assert_allclose(run.params, reference.params, rtol=RTOL)


def test_scipy_lm_trace_counts_residual_evaluations(peer_runs):
    run = peer_runs[(scipy_curve.__name__, "lm")]
    assert "nfev" in run.stop_reason
    nfev = int(run.stop_reason.split("nfev ")[1].split(",")[0])
    assert run.iterations == nfev - 1 == len(run.trace) - 1


@pytest.mark.parametrize(("module", "method"), PEERS)
def test_peers_use_the_weights(module, method):
    module = peer(module)
    weights = np.where(np.arange(40) % 3 == 0, 4.0, 0.25)
    d = generate(num_points=40, seed=5, weights=weights, start=(0.5, 1.5, 0.5))
    ours = minimize(CurveProblem(d), "lm-type1")
    unweighted = minimize(CurveProblem(generate(num_points=40, seed=5, start=(0.5, 1.5, 0.5))), "lm-type1")
    assert not np.allclose(ours.params, unweighted.params, rtol=1e-3)  # the weights matter here
    run = module.solve(d, method)
    np.testing.assert_allclose(run.params, ours.params, rtol=RTOL)
    assert run.final_chi2 == pytest.approx(ours.final_chi2, rel=1e-9)


@NEEDS_CERES
def test_max_iterations_is_honoured(data):
    assert peer("ceres").solve(data, "levenberg-marquardt", max_iterations=3).iterations <= 3
    assert scipy_curve.solve(data, "trf", max_iterations=3).iterations <= 3


@NEEDS_CERES
def test_unknown_method_and_option(data):
    ceres_curve = peer("ceres")
    with pytest.raises(ValueError, match="unknown method"):
        ceres_curve.solve(data, "gauss-newton")
    with pytest.raises(ValueError, match="unknown method"):
        scipy_curve.solve(data, "dogbox")
    with pytest.raises(ValueError, match="no option 'not_an_option'"):
        ceres_curve.solve(data, "dogleg", not_an_option=1)


@pytest.mark.parametrize(("module", "method"), PEERS)
def test_peers_run_the_implementations_model(data, module, method, tmp_path):
    """The peers take the residuals and the Jacobian from the implementation's ``curve_model``, as our
    solvers do (no analytic copy of the exercise's answer in the framework): the stubs stop them at the
    TODO, and a model shifted by 1 moves their minimum away from the reference's."""
    from course.core.impl import REPO_ROOT

    module = peer(module)
    with pytest.raises(NotImplementedError, match="curve_model"):
        module.solve(data, method, impl="exercises")
    folder = tmp_path / "shifted"
    folder.mkdir()
    (folder / "__init__.py").write_text("")
    source = (REPO_ROOT / "solutions" / "curve_model.py").read_text()
    (folder / "curve_model.py").write_text(source.replace("    r = y_hat - y\n", "    r = y_hat - y + 1.0\n"))
    shifted, reference = module.solve(data, method, impl=str(folder)), module.solve(data, method)
    assert not np.allclose(shifted.params, reference.params, rtol=1e-3)
