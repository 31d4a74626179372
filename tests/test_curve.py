"""Chapter 1: the curve problem and our minimizers on it."""

import shutil

import numpy as np
import pytest

from course.app import compare
from course.core.errors import NonFiniteError, ShapeError
from course.core.impl import REPO_ROOT
from course.problems.curve.problem import TRUTH, CurveProblem, generate
from course.solver import minimize

RTOL = 1e-6
LM_TYPES = ("lm-type1", "lm-type2", "lm-type3")


@pytest.fixture(scope="module")
def data():
    return generate()


@pytest.fixture(scope="module")
def ours(data):
    """Every method of ours (dogleg too once it exists), on the default data."""
    return {r.method: r for r in compare.run_curve(data=data, backends=["ours"])}


def test_generate_is_seeded_and_validated():
    a, b = generate(seed=3), generate(seed=3)
    np.testing.assert_array_equal(a.y, b.y)
    assert not np.array_equal(a.y, generate(seed=4).y)
    assert a.x.shape == a.y.shape == a.weights.shape == (100,)
    np.testing.assert_array_equal(a.truth, TRUTH)
    with pytest.raises(ValueError, match="at least 3"):
        generate(num_points=2)
    with pytest.raises(ValueError, match="weights"):
        generate(num_points=5, weights=[1, 1, -1, 1, 1])


def test_jacobian_matches_finite_differences(data):
    problem = CurveProblem(data)
    p = np.array([0.7, 1.6, 0.9])
    r, J = problem.residuals_and_jacobian(p)
    eps = 1e-6
    numeric = np.stack(
        [(problem.residuals_and_jacobian(p + eps * e)[0] - problem.residuals_and_jacobian(p - eps * e)[0]) / (2 * eps)
         for e in np.eye(3)], axis=1)
    np.testing.assert_allclose(J, numeric, rtol=1e-6, atol=1e-6)


def test_chi2_and_linearization_use_the_weights():
    d = generate(num_points=20, weights=np.linspace(0.5, 2.0, 20))
    problem = CurveProblem(d)
    p = np.array([0.5, 1.0, 1.0])
    r, J = problem.residuals_and_jacobian(p)
    lin = problem.linearize(p)
    assert problem.chi2(p) == pytest.approx(float(np.sum(d.weights * r**2)), rel=1e-12)
    np.testing.assert_allclose(lin.H, J.T @ np.diag(d.weights) @ J, rtol=1e-12)
    np.testing.assert_allclose(lin.b, J.T @ (d.weights * r), rtol=1e-12)


def test_every_method_converges_to_the_same_minimum(ours):
    assert set(LM_TYPES) | {"gauss-newton"} <= set(ours)
    reference = ours["lm-type1"].params
    for method, run in ours.items():
        assert run.stop_reason != "max_iterations", method
        np.testing.assert_allclose(run.params, reference, rtol=RTOL, err_msg=method)
        assert run.final_chi2 == pytest.approx(ours["lm-type1"].final_chi2, rel=1e-9), method
        assert run.final_chi2 < 1e-2 * run.initial_chi2


def test_the_minimum_is_near_the_truth_within_the_noise(ours, data):
    best = ours["lm-type3"]
    H = CurveProblem(data).linearize(best.params).H
    stderr = np.sqrt(np.diag(np.linalg.inv(H)))
    assert np.all(np.abs(best.params - data.truth) < 4 * stderr)
    # chi2 of 100 unit-variance residuals: about 97 degrees of freedom
    assert 50 < best.final_chi2 < 150


def test_gradient_vanishes_at_the_minimum(ours, data):
    lin = CurveProblem(data).linearize(ours["lm-type1"].params)
    assert np.max(np.abs(lin.b)) < 1e-5 * np.max(np.abs(CurveProblem(data).linearize(data.start).b))


@pytest.mark.parametrize("method", ["gauss-newton", *LM_TYPES])
def test_trace_schema(ours, method):
    run = ours[method]
    trace = run.trace
    assert [r.iteration for r in trace] == list(range(len(trace)))
    assert run.iterations == len(trace) - 1
    assert trace[0].chi2 == pytest.approx(run.initial_chi2, rel=1e-12)
    assert trace[0].accepted
    times = [r.seconds for r in trace]
    assert times == sorted(times) and times[-1] <= run.seconds
    assert run.backend == "ours" and run.method == method
    assert run.params.shape == (3,)


@pytest.mark.parametrize("method", LM_TYPES)
def test_accepted_steps_never_increase_chi2(ours, method):
    run = ours[method]
    kept = run.trace[0].chi2
    for record in run.trace[1:]:
        assert np.isfinite(record.damping) and record.damping > 0
        if record.accepted:
            assert record.chi2 <= kept, (method, record)
            kept = record.chi2
    assert run.final_chi2 == pytest.approx(kept, rel=1e-12)
    # each type rejects something from this far start, so both branches are exercised
    assert any(not r.accepted for r in run.trace[1:]) or method == "lm-type2"


def _broken_impl(tmp_path, body):
    """A copy of solutions/ whose curve model is replaced by ``body``."""
    target = tmp_path / "broken_impl"
    shutil.copytree(REPO_ROOT / "solutions", target, ignore=shutil.ignore_patterns("__pycache__"))
    (target / "curve_model.py").write_text(
        "import numpy as np\n\n\ndef residuals_and_jacobian(params, x, y):\n" + body
    )
    return str(target)


def test_nan_from_the_model_raises_naming_the_function(tmp_path, data):
    impl = _broken_impl(tmp_path, (
        "    r = np.exp(params[0] * x**2 + params[1] * x + params[2]) - y\n"
        "    r[7] = np.nan\n"
        "    return r, np.ones((len(x), 3))\n"
    ))
    with pytest.raises(NonFiniteError, match=r"curve_model\.residuals_and_jacobian.*non-finite r.*\[7\]"):
        minimize(CurveProblem(data, impl=impl), "lm-type1", impl=impl)


def test_nan_jacobian_raises_naming_the_output(tmp_path, data):
    impl = _broken_impl(tmp_path, (
        "    J = np.ones((len(x), 3))\n"
        "    J[3, 2] = np.inf\n"
        "    return np.zeros(len(x)), J\n"
    ))
    with pytest.raises(NonFiniteError, match=r"curve_model\.residuals_and_jacobian.*non-finite J"):
        CurveProblem(data, impl=impl).linearize(data.start)


def test_wrong_shape_raises(tmp_path, data):
    impl = _broken_impl(tmp_path, "    return np.zeros(len(x)), np.zeros((3, len(x)))\n")
    with pytest.raises(ShapeError, match=r"J of shape \(3, 100\), expected \(100, 3\)"):
        CurveProblem(data, impl=impl).linearize(data.start)


def test_unimplemented_exercise_names_the_todo(data):
    with pytest.raises(NotImplementedError, match="TODO curve_model.residuals_and_jacobian"):
        CurveProblem(data, impl="exercises").linearize(data.start)


def test_compare_table_lists_every_run(ours):
    table = compare.format_table(list(ours.values()), title="t")
    lines = table.splitlines()
    assert lines[0] == "t" and "params" in lines[1] and len(lines) == 3 + len(ours)
    assert "0.828262" in table
