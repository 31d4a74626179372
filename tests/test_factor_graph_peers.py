"""Chapter 7's peers on the same residual: GTSAM's ``CustomFactor`` (our residual, our Jets' Jacobians per
Python callback: ``gtsam-custom``) and JAX (the same residual traced, ``jacfwd`` under ``vmap`` and
``jit``, for our minimizer: ``jax``). Each ends at our minimum; each is a row, not a traceback, where its
library is missing."""

import json
import sys

import numpy as np
import pytest
from conftest import needs

from course.app import compare
from course.core import peers
from course.factorgraph import FactorGraphProblem
from course.solver import SolverOptions, minimize

OPTIONS = SolverOptions(max_iterations=100)


def _blockwise(got, want):
    """The largest difference per factor relative to that factor's largest entry (M, m, d) -> float."""
    scale = np.maximum(np.abs(want).max(axis=(1, 2)), np.finfo(float).tiny)
    return float((np.abs(got - want).max(axis=(1, 2)) / scale).max())


def _intel():
    from course.problems.posegraph import dataset
    from course.problems.posegraph.factor_graph import as_factor_graph

    graph = dataset.load_dataset("intel")
    return graph, as_factor_graph(graph)


def _our_minimum(graph):
    from course.problems.posegraph.problem import PoseGraphProblem

    return minimize(PoseGraphProblem(graph), "lm-type3", options=OPTIONS).final_chi2


# ---------------------------------------------------------------- jax


@needs("jax")
def test_jax_jacobians_are_ours_on_intels_edges(data_folder):
    from course.backends.factorgraph import jax_factors

    _, fg = _intel()
    ours = FactorGraphProblem(fg)
    theirs = jax_factors.problem(fg)
    assert theirs.jacobians.compilations == 1 and theirs.jacobians.compile_seconds > 0
    x = ours.x0 + 0.05 * np.random.default_rng(7).standard_normal(ours.x0.shape)  # angles past pi too
    for at in (ours.x0, x):
        r, J = ours.factor_jacobians(at, 0)
        r_jax, J_jax = theirs.factor_jacobians(at, 0)
        np.testing.assert_allclose(r_jax, r, rtol=0, atol=1e-12 * np.abs(r).max())
        assert all(_blockwise(got, want) <= 1e-12 for got, want in zip(J_jax, J))
    assert theirs.jacobians.compilations == 1  # one compilation per factor type and size


@needs("jax")
def test_jax_jacobians_are_ours_on_3d_edges_and_bal_observations():
    """To 1e-12, but on the 3D edges whose rotation error is within 1e-2 of pi, where Log's ``sin t``
    carries few digits and both sides round differently (smallGrid3D's start has one at 3.1414)."""
    from course.backends.factorgraph import jax_factors
    from course.problems.bal.dataset import load_bal
    from course.problems.bal.factor_graph import as_factor_graph as bal_graph
    from course.problems.posegraph3d import dataset
    from course.problems.posegraph3d.factor_graph import as_factor_graph

    for fg in (as_factor_graph(dataset.load_dataset("smallGrid3D")), bal_graph(load_bal("dubrovnik-3-7"))):
        ours, theirs = FactorGraphProblem(fg), FactorGraphProblem(fg, jacobians=jax_factors.JaxJacobians())
        for group, ftype in enumerate(g.type for g in fg.groups.values()):
            (r, J), (r_jax, J_jax) = ours.factor_jacobians(ours.x0, group), theirs.factor_jacobians(ours.x0, group)
            np.testing.assert_allclose(r_jax, r, rtol=0, atol=1e-12 * np.abs(r).max())
            near_pi = np.linalg.norm(r[:, 3:], axis=1) > np.pi - 1e-2 if ftype.name == "between_se3" else \
                np.zeros(len(r), dtype=bool)
            assert near_pi.sum() <= 1
            for got, want in zip(J_jax, J):
                assert _blockwise(got[~near_pi], want[~near_pi]) <= 1e-12, fg.name
                if near_pi.any():
                    assert _blockwise(got[near_pi], want[near_pi]) <= 1e-9, fg.name


@needs("jax")
def test_jax_ends_at_our_minimum_on_intel(data_folder):
    from course.backends.factorgraph import jax_factors

    graph, fg = _intel()
    result = minimize(jax_factors.problem(fg), "lm-type3", options=OPTIONS)
    assert result.final_chi2 == pytest.approx(_our_minimum(graph), rel=1e-9)


@needs("jax")
def test_a_users_factor_type_reaches_jax_by_itself_and_an_untraceable_one_is_named():
    from course.backends.factorgraph import jax_factors
    from course.factorgraph import SE2, FactorGraph, FactorType

    graph = FactorGraph("odd")
    graph.add_variable("x0", SE2, [0, 0, 0])
    graph.add(FactorType("odd", (SE2,), 1, lambda z, x: x[..., :1] - z), ["x0"], [1.0])
    r, J = jax_factors.problem(graph).factor_jacobians(np.zeros(3), 0)
    np.testing.assert_array_equal(r, [[-1.0]])
    np.testing.assert_array_equal(J[0], [[[1.0, 0.0, 0.0]]])

    graph = FactorGraph("numpy")
    graph.add_variable("x0", SE2, [0, 0, 0])
    graph.add(FactorType("numpy_norm", (SE2,), 1, lambda z, x: np.asarray(x)[..., :1] - z), ["x0"], [1.0])
    with pytest.raises(ValueError, match="factor type 'numpy_norm' cannot be traced by JAX") as error:
        jax_factors.problem(graph)
    assert "\n" not in str(error.value)


# ---------------------------------------------------------------- gtsam-custom


@needs("gtsam")
def test_gtsam_custom_error_is_half_our_chi2_and_its_jacobians_ours_whitened():
    import gtsam

    from course.backends.factorgraph import gtsam_custom
    from course.problems.posegraph import dataset
    from course.problems.posegraph.factor_graph import as_factor_graph

    fg = as_factor_graph(dataset.load_dataset("manhattan:60"))
    ours = FactorGraphProblem(fg)
    factors, values, free, constant = gtsam_custom.build(fg)
    assert free == [v for v in range(fg.num_variables) if v not in fg.fixed] and constant == 0.0
    assert 2.0 * factors.error(values) == pytest.approx(ours.chi2(ours.x0), rel=1e-12)
    r, (A, B) = ours.factor_jacobians(ours.x0, 0)
    keys, _, info = fg.groups["between_se2"].arrays()
    for m in (5, 17, 40):  # factors whose poses are both free: GTSAM's whitened [A B] is W [J_i J_j]
        i, j = keys[m]
        if 0 in (i, j):
            continue
        factor = next(factors.at(k) for k in range(factors.size()) if list(factors.at(k).keys()) == [i, j])
        A_gtsam, _ = factor.linearize(values).jacobian()
        W = np.linalg.cholesky(info[m]).T
        np.testing.assert_allclose(A_gtsam, W @ np.hstack([A[m], B[m]]), rtol=0, atol=1e-12 * np.abs(A_gtsam).max())
    assert isinstance(values.atVector(1), np.ndarray)  # vector values: GTSAM retracts by addition
    assert gtsam.Values  # the library is there


@needs("gtsam")
def test_gtsam_custom_pose3_jacobians_are_in_gtsams_tangent_order():
    """GTSAM's Pose3 tangent is (rotation, translation): the callback's Jacobian against central
    differences through GTSAM's own retraction."""
    import gtsam

    from course.backends.factorgraph import gtsam_custom
    from course.problems.posegraph3d import dataset
    from course.problems.posegraph3d.factor_graph import as_factor_graph

    factors, values, _, _ = gtsam_custom.build(as_factor_graph(dataset.load_dataset("smallGrid3D")))
    step = 1e-6
    for k in (3, 50, 200):
        factor = factors.at(k)
        A, _ = factor.linearize(values).jacobian()
        columns = []
        for key in factor.keys():
            for j in range(6):
                delta = np.zeros(6)
                delta[j] = step
                plus, minus = gtsam.Values(values), gtsam.Values(values)
                plus.update(key, values.atPose3(key).retract(delta))
                minus.update(key, values.atPose3(key).retract(-delta))
                columns.append((factor.unwhitenedError(plus) - factor.unwhitenedError(minus)) / (2 * step))
        numeric = factor.noiseModel().R() @ np.array(columns).T
        assert np.abs(A - numeric).max() <= 1e-7 * np.abs(A).max()


@needs("gtsam")
def test_gtsam_custom_holds_fixed_variables_and_ends_at_our_minimum_on_a_3d_graph():
    from course.backends.factorgraph import gtsam_custom
    from course.problems.posegraph3d import dataset
    from course.problems.posegraph3d.factor_graph import as_factor_graph

    fg = as_factor_graph(dataset.load_dataset("tinyGrid3D"))
    result = gtsam_custom.solve(fg)
    ours = minimize(FactorGraphProblem(fg), "lm-type3", options=OPTIONS)
    assert result.backend == "gtsam-custom" and result.stop_reason.startswith("converged")
    assert result.final_chi2 == pytest.approx(ours.final_chi2, rel=1e-9)
    fixed = np.concatenate([np.arange(12 * v, 12 * v + 12) for v in fg.fixed])
    np.testing.assert_array_equal(result.params[fixed], ours.params[fixed])
    assert result.trace[-1].chi2 == pytest.approx(result.final_chi2, rel=1e-12)  # 2 * GTSAM's error is ours


@pytest.mark.slow
@needs("gtsam")
def test_gtsam_custom_ends_at_our_minimum_on_intel(data_folder):
    from course.backends.factorgraph import gtsam_custom

    graph, fg = _intel()
    result = gtsam_custom.solve(fg)
    assert result.stop_reason.startswith("converged")
    assert result.final_chi2 == pytest.approx(_our_minimum(graph), rel=1e-9)


# ---------------------------------------------------------------- compare, the benchmark, and missing libraries


@needs("jax", "gtsam")
def test_compare_runs_both_when_named_and_they_end_where_ours_does(tmp_path):
    from course.app.cli import main

    out = tmp_path / "runs.json"
    assert main(["compare", "manhattan:200", "--backends", "ours,jax,gtsam,gtsam-custom",
                 "--methods", "lm-type3,levenberg-marquardt", "--json", str(out)]) == 0
    runs = {(r["backend"], r["method"]): r for r in json.loads(out.read_text())["runs"]}
    best = runs[("ours", "lm-type3")]["final_chi2"]
    assert runs[("jax", "lm-type3")]["final_chi2"] == pytest.approx(best, rel=1e-9)
    assert runs[("gtsam-custom", "levenberg-marquardt")]["final_chi2"] == pytest.approx(best, rel=1e-9)
    assert runs[("jax", "lm-type3")]["compile_seconds"] > 0
    assert "compile_seconds" not in runs[("ours", "lm-type3")]
    order = [b for b, _ in compare.plan_for("posegraph", backends=["gtsam", "gtsam-custom"],
                                            methods=["levenberg-marquardt"])]
    assert order == ["gtsam", "gtsam-custom"]  # GTSAM on our residual beside its native factors


def _hide(monkeypatch, library):
    monkeypatch.setitem(sys.modules, library, None)
    monkeypatch.setattr(peers, "_announced", set())


@pytest.mark.parametrize("library, backend, method", [("jax", "jax", "lm-type3"),
                                                       ("gtsam", "gtsam-custom", "levenberg-marquardt")])
def test_a_missing_library_is_a_row_and_one_line(monkeypatch, capsys, library, backend, method):
    from course.problems.posegraph import dataset

    _hide(monkeypatch, library)
    runs = compare.run_posegraph(dataset.load_dataset("manhattan:60"), backends=["ours", backend],
                                 methods=["lm-type3", method], max_iterations=20)
    missing = [r for r in runs if r.backend == backend]
    assert missing and all(r.not_run == f"not run: {library} is not installed here" for r in missing)
    assert all(np.isfinite(r.final_chi2) for r in runs if r.backend == "ours")
    assert capsys.readouterr().err.count(peers.missing_message(library)) == 1


def test_the_benchmark_has_a_row_for_each_or_says_it_did_not_run(monkeypatch):
    from course.app import benchmark_autodiff

    lines: list = []
    monkeypatch.setattr(benchmark_autodiff, "GTSAM_CUSTOM_ITERATIONS", 2)
    benchmark_autodiff.main(repeats=1, graphs=("manhattan:60",), out=lines.append)
    for backend, library in (("jax", "jax"), ("gtsam-custom", "gtsam")):
        row = [line for line in lines if line.split()[:2] == ["manhattan:60", backend]]
        assert row, lines
        if peers.installed(library):
            assert len(row[0].split()) == 8 and "not run" not in row[0]
        else:
            assert row[0].endswith(f"not run: {library} is not installed here")
    if peers.installed("jax"):
        assert any("compiled in" in line for line in lines)
    if peers.installed("gtsam"):
        assert any("per iteration, gtsam-custom / ours-autodiff" in line for line in lines)


def test_the_benchmark_says_which_reference_stopped_at_a_todo_and_prints_the_rest(monkeypatch):
    pytest.importorskip("pyceres")
    from course.app import benchmark_autodiff

    def unwritten(self):
        if self.backend == "ceres":
            raise NotImplementedError("TODO ceres_edge_cost.SE2EdgeCost: not implemented")
        return solve(self)

    solve = benchmark_autodiff._Reference.solve
    monkeypatch.setattr(benchmark_autodiff._Reference, "solve", unwritten)
    monkeypatch.setattr(benchmark_autodiff, "GTSAM_CUSTOM_ITERATIONS", 1)
    lines: list = []
    benchmark_autodiff.main(repeats=1, graphs=("manhattan:60",), out=lines.append)
    assert "manhattan:60 ceres          not run: TODO ceres_edge_cost.SE2EdgeCost: not implemented" in lines
    assert any(line.split()[:2] == ["manhattan:60", "ours-autodiff"] and len(line.split()) == 8 for line in lines)
