"""Chapter 7's engine: a factor graph whose Jacobians come from the Jets, against the chapters' analytic
Jacobians and minima (intel, sphere2500), central differences, and bad input named."""

import numpy as np
import pytest

from course.core import impl as impl_loader
from course.factorgraph import BETWEEN_SE2, RANGE_BEARING, SE2, FactorGraph, FactorGraphProblem, Vector, jetmath
from course.solver import SolverOptions, minimize


def _held_still(problem, group, blocks):
    """``blocks`` (one (M, m, d_a) per slot) with the blocks of fixed variables 0: they are not
    differentiated (no Jet directions), and the assembly holds them still anyway."""
    keys = list(problem.graph.groups.values())[group].arrays()[0]
    held = np.isin(keys, sorted(problem.graph.fixed))
    assert held.any()  # the graph has a fixed variable in this group
    return [np.where(held[:, a, None, None], 0.0, block) for a, block in enumerate(blocks)]


def _blockwise(got, want):
    """The largest difference per edge relative to that edge's largest entry (M, m, d) -> float."""
    scale = np.maximum(np.abs(want).max(axis=(1, 2)), np.finfo(float).tiny)
    return float((np.abs(got - want).max(axis=(1, 2)) / scale).max())


def test_intel_autodiff_jacobians_are_the_analytic_ones_and_the_solve_ends_at_chapter_2s_minimum(data_folder):
    from course.problems.posegraph import dataset
    from course.problems.posegraph.factor_graph import as_factor_graph
    from course.problems.posegraph.problem import PoseGraphProblem

    graph = dataset.load_dataset("intel")
    problem = FactorGraphProblem(as_factor_graph(graph))
    r, (A, B) = problem.factor_jacobians(problem.x0, 0)
    e, A_ref, B_ref = impl_loader.load("solutions").module("pose_graph_fast").edge_errors_and_jacobians(
        graph.poses, graph.edges_i, graph.edges_j, graph.measurements)
    np.testing.assert_allclose(r, e, rtol=0, atol=1e-12)
    A_ref, B_ref = _held_still(problem, 0, [A_ref, B_ref])
    assert _blockwise(A, A_ref) <= 1e-12 and _blockwise(B, B_ref) <= 1e-12
    _, (A_num, _) = FactorGraphProblem(as_factor_graph(graph), jacobians="numeric").factor_jacobians(problem.x0, 0)
    assert 1e-13 < _blockwise(A_num, A_ref) < 1e-7  # central differences: close, not exact
    ours = minimize(problem, "lm-type3")
    reference = minimize(PoseGraphProblem(graph), "lm-type3")
    assert ours.final_chi2 == pytest.approx(reference.final_chi2, rel=1e-9)
    assert reference.final_chi2 == pytest.approx(65.40, abs=0.01)


def test_sphere2500_autodiff_jacobians_are_the_analytic_ones_and_the_solve_ends_at_chapter_6s_minimum(data_folder):
    from course.problems.posegraph3d import dataset
    from course.problems.posegraph3d.factor_graph import as_factor_graph
    from course.problems.posegraph3d.problem import PoseGraph3DProblem

    graph = dataset.load_dataset("sphere2500")
    problem = FactorGraphProblem(as_factor_graph(graph))
    r, (A, B) = problem.factor_jacobians(problem.x0, 0)
    e, A_ref, B_ref = impl_loader.load("solutions").module("pose_graph_3d").edge_errors_and_jacobians(
        graph.t, graph.R, graph.edges_i, graph.edges_j, graph.t_z, graph.R_z)
    np.testing.assert_allclose(r, e, rtol=0, atol=1e-12)
    A_ref, B_ref = _held_still(problem, 0, [A_ref, B_ref])
    assert _blockwise(A, A_ref) <= 1e-12 and _blockwise(B, B_ref) <= 1e-12
    ours = minimize(problem, "gauss-newton")
    reference = minimize(PoseGraph3DProblem(graph), "gauss-newton")
    assert ours.final_chi2 == pytest.approx(reference.final_chi2, rel=1e-9)


def test_ladybug_49_autodiff_jacobians_are_the_analytic_ones_and_the_solves_step_alike(data_folder):
    """Every observation's Jacobians to 1e-12; the first 10 steps of Levenberg-Marquardt equal to rounding.
    Beyond them the two paths part (1e-6 by step 20) in ladybug-49's flat valley, and neither converges
    to 1e-9 within a thousand steps (both end 1.5e-8 apart, still falling): the minimum is not compared."""
    from course.problems.bal.dataset import load_bal
    from course.problems.bal.factor_graph import as_factor_graph
    from course.problems.bal.problem import BundleAdjustmentProblem

    bal = load_bal("ladybug-49")
    problem = FactorGraphProblem(as_factor_graph(bal))
    r, (J_cam, J_point) = problem.factor_jacobians(problem.x0, 0)
    r_ref, J_cam_ref, J_point_ref = impl_loader.load("solutions").module(
        "bundle_adjustment").reprojection_residuals_and_jacobians(bal.cameras, bal.points, bal.camera_index,
                                                                   bal.point_index, bal.observations)
    np.testing.assert_allclose(r, r_ref, rtol=1e-13, atol=1e-9)
    assert _blockwise(J_cam, J_cam_ref) <= 1e-12 and _blockwise(J_point, J_point_ref) <= 1e-12
    options = SolverOptions(max_iterations=10)
    ours, reference = minimize(problem, "lm-type3", options=options), \
        minimize(BundleAdjustmentProblem(bal), "lm-type3", options=options)
    assert ours.final_chi2 == pytest.approx(reference.final_chi2, rel=1e-12)
    assert reference.final_chi2 == pytest.approx(43653.2973, rel=1e-8)


def test_a_new_factor_needs_no_jacobian_written_by_hand():
    """A robot at three poses sees two landmarks by range and bearing: the graph is solved from a
    perturbed start back to the truth, with the Jacobians of the range-bearing residual by Jets."""
    rng = np.random.default_rng(3)
    poses = np.array([[0.0, 0.0, 0.0], [1.0, 0.2, 0.3], [2.0, 0.1, -0.2]])
    marks = np.array([[1.5, 2.0], [0.5, -1.5]])
    graph = FactorGraph("range and bearing")
    for k, pose in enumerate(poses):
        graph.add_variable(f"x{k}", SE2, pose + (rng.normal(0, 0.05, 3) if k else 0))
    for k, mark in enumerate(marks):
        graph.add_variable(f"l{k}", Vector(2), mark + rng.normal(0, 0.1, 2))
    graph.fix("x0")
    for k in range(2):
        rel = np.array([[np.cos(poses[k, 2]), np.sin(poses[k, 2])], [-np.sin(poses[k, 2]), np.cos(poses[k, 2])]]) \
            @ (poses[k + 1, :2] - poses[k, :2])
        graph.add(BETWEEN_SE2, [f"x{k}", f"x{k + 1}"], [rel[0], rel[1], poses[k + 1, 2] - poses[k, 2]], np.eye(3))
    for k, pose in enumerate(poses):
        for j, mark in enumerate(marks):
            d = mark - pose[:2]
            graph.add(RANGE_BEARING, [f"x{k}", f"l{j}"], [np.hypot(*d), np.arctan2(d[1], d[0]) - pose[2]])
    result = minimize(FactorGraphProblem(graph), "lm-type3")
    assert result.final_chi2 < 1e-20
    x = result.params
    np.testing.assert_allclose(x[:9].reshape(3, 3), poses, atol=1e-9)
    np.testing.assert_allclose(x[9:].reshape(2, 2), marks, atol=1e-9)


def test_exp_and_log_on_jets_at_zero_and_away():
    Jet = impl_loader.load("solutions").module("jets").Jet
    phi = np.array([[0.0, 0.0, 0.0], [0.3, -0.2, 0.5], [1e-7, 0.0, 0.0]])
    seeded = Jet.seed(phi, 0, 3)
    R = jetmath.so3_exp(seeded)
    from course.geometry.so3 import exp_many, log_many, skew

    np.testing.assert_allclose(R.value, exp_many(phi), atol=1e-15)
    np.testing.assert_allclose(R.grad[0].transpose(2, 0, 1), skew(np.eye(3)), atol=1e-15)  # d Exp / d phi at 0
    w = jetmath.so3_log(R)
    np.testing.assert_allclose(w.value, log_many(exp_many(phi)), atol=1e-14)
    np.testing.assert_allclose(w.grad[0], np.eye(3), atol=1e-14)  # Log(Exp(phi)) = phi


def test_bad_input_is_named():
    graph = FactorGraph("g")
    graph.add_variable("x0", SE2, [0, 0, 0])
    graph.add_variable("l0", Vector(2), [1, 1])
    with pytest.raises(ValueError, match="variable 'x0' is added twice"):
        graph.add_variable("x0", SE2, [0, 0, 0])
    with pytest.raises(ValueError, match=r"a value of kind SE2 has shape \(3,\), got \(2,\)"):
        graph.add_variable("x1", SE2, [0, 0])
    with pytest.raises(ValueError, match="no variable 'x9'"):
        graph.add(BETWEEN_SE2, ["x0", "x9"], [1, 0, 0])
    with pytest.raises(ValueError, match="slot 1 takes a SE2 variable; 'l0' is a Vector2"):
        graph.add(BETWEEN_SE2, ["x0", "l0"], [1, 0, 0])
    graph.add_variable("x1", SE2, [1, 0, 0])
    graph.add(BETWEEN_SE2, ["x0", "x1"], [1, 0, 0], information=np.diag([1.0, 1.0, -1.0]))
    with pytest.raises(ValueError, match="between_se2: the information of factor 0 is not positive definite"):
        FactorGraphProblem(graph)


def test_compare_offers_the_factor_graph_back_ends_and_they_end_where_ours_does(tmp_path):
    import json

    from course.app.cli import main

    out = tmp_path / "runs.json"
    assert main(["compare", "manhattan:200", "--backends", "ours,ours-autodiff,ours-numeric",
                 "--methods", "gauss-newton,dogleg", "--json", str(out)]) == 0
    chi2 = {(r["backend"], r["method"]): r["final_chi2"] for r in json.loads(out.read_text())["runs"]}
    for method in ("gauss-newton", "dogleg"):
        for backend in ("ours-autodiff", "ours-numeric"):
            assert chi2[(backend, method)] == pytest.approx(chi2[("ours", method)], rel=1e-9)


def test_compare_runs_a_named_factor_graph_back_end_on_bundle_adjustment_with_chapter_4s_gauge(capsys, tmp_path):
    """Named without --methods, a factor-graph back end runs the default methods; its graph fixes the gauge
    as chapter 4 does (some dofs of two cameras), so its undamped Gauss-Newton runs to chapter 4's chi2."""
    import json

    from course.app.cli import main

    out = tmp_path / "runs.json"
    assert main(["compare", "bal-synthetic:4:40", "--backends", "ours,ours-autodiff", "--json", str(out)]) == 0
    capsys.readouterr()
    runs = {(r["backend"], r["method"]): r for r in json.loads(out.read_text())["runs"]}
    assert {m for b, m in runs if b == "ours-autodiff"} == {"gauss-newton", "lm-type1", "lm-type2", "lm-type3",
                                                            "dogleg"}
    for method in ("gauss-newton", "lm-type3", "dogleg"):
        assert runs[("ours-autodiff", method)]["final_chi2"] == pytest.approx(runs[("ours", method)]["final_chi2"],
                                                                              rel=1e-9)
