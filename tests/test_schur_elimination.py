"""The factor graph's elimination of point-like variables (course.factorgraph.schur_elimination): the step is
the whole H's, the graphs that have no such variables solve the whole H, and a singular block is named."""

import numpy as np
import pytest
import scipy.sparse as sp

from course.core.errors import SingularSystemError
from course.factorgraph import BETWEEN_SE2, RANGE_BEARING, SE2, FactorGraph, FactorGraphProblem, Vector
from course.factorgraph.factors import REPROJECTION_BAL
from course.factorgraph.problem import eliminated_kind
from course.factorgraph.variables import BAL_CAMERA
from course.solver import SolverOptions, StopReason, minimize


def _slam(poses=6, marks=12, seed=0):
    """A robot on a circle seeing every landmark by range and bearing, odometry between poses; the
    landmarks are added between the poses (so the eliminated variables are not last), pose 2 fixed."""
    rng = np.random.default_rng(seed)
    truth = np.stack([np.cos(np.arange(poses) * 0.4), np.sin(np.arange(poses) * 0.4), np.arange(poses) * 0.4 + 1.2],
                     axis=1)
    landmarks = rng.uniform(-3, 3, (marks, 2))
    graph = FactorGraph("slam")
    for k in range(max(poses, marks)):
        if k < poses:
            graph.add_variable(f"x{k}", SE2, truth[k] + rng.normal(0, 0.05, 3))
        if k < marks:
            graph.add_variable(f"l{k}", Vector(2), landmarks[k] + rng.normal(0, 0.2, 2))
    graph.fix("x2")
    for k in range(poses - 1):
        c, s = np.cos(truth[k, 2]), np.sin(truth[k, 2])
        d = truth[k + 1, :2] - truth[k, :2]
        graph.add(BETWEEN_SE2, [f"x{k}", f"x{k + 1}"], [c * d[0] + s * d[1], -s * d[0] + c * d[1], 0.4],
                  np.diag([100.0, 100.0, 400.0]))
    for k in range(poses):
        for j in range(marks):
            d = landmarks[j] - truth[k, :2]
            graph.add(RANGE_BEARING, [f"x{k}", f"l{j}"],
                      [np.hypot(*d) + rng.normal(0, 0.01), np.arctan2(d[1], d[0]) - truth[k, 2]])
    return graph


def test_the_landmarks_are_eliminated_and_the_step_is_the_whole_hs():
    graph = _slam()
    assert eliminated_kind(graph) == Vector(2)
    schur, whole = FactorGraphProblem(graph), FactorGraphProblem(graph, eliminate=None)
    assert schur.eliminated == Vector(2) and whole.eliminated is None
    lin = schur.linearize(schur.x0)
    for damping in (None, 1e-3 * lin.diagonal()):
        h, h_ref = schur.solve(lin, damping), whole.solve(lin, damping)
        np.testing.assert_allclose(h, h_ref, rtol=0, atol=1e-10 * np.abs(h_ref).max())
        assert np.all(h[10:13] == 0.0) and np.all(h[:10] != 0.0)  # x2, after x0 l0 x1 l1, is fixed
    for method in ("gauss-newton", "lm-type3", "dogleg"):
        assert minimize(schur, method).final_chi2 == pytest.approx(minimize(whole, method).final_chi2, rel=1e-9)


def test_a_large_reduced_system_is_solved_sparsely_and_a_duplicate_entry_summed(monkeypatch):
    from course.factorgraph import schur_elimination

    graph = _slam()
    schur, whole = FactorGraphProblem(graph), FactorGraphProblem(graph, eliminate=None)
    lin = schur.linearize(schur.x0)
    damping = 1e-3 * lin.diagonal()
    h_ref = whole.solve(lin, damping)
    H = lin.H  # its first stored entry split in two halves, stored twice: not canonical
    data = np.concatenate([[0.5 * H.data[0], 0.5 * H.data[0]], H.data[1:]])
    indices = np.concatenate([[H.indices[0]], H.indices])
    split = sp.csc_matrix((data, indices, np.concatenate([[0], H.indptr[1:] + 1])), shape=H.shape)
    assert not split.has_canonical_format
    for limit in (schur_elimination.DENSE_LIMIT, 0):  # S dense, then sparse
        monkeypatch.setattr(schur_elimination, "DENSE_LIMIT", limit)
        for lin.H in (H, split):
            np.testing.assert_allclose(schur.solve(lin, damping), h_ref, rtol=0, atol=1e-10 * np.abs(h_ref).max())


def test_graphs_without_point_like_variables_solve_the_whole_h():
    graph = _slam(poses=6, marks=2)  # 4 landmark dofs against 18 pose dofs: not worth it
    assert eliminated_kind(graph) is None
    chain = FactorGraph("chain")
    for k in range(3):
        chain.add_variable(f"x{k}", SE2, [k, 0, 0])
    chain.add_many(BETWEEN_SE2, np.array([[0, 1], [1, 2]]), np.array([[1.0, 0, 0], [1.0, 0, 0]]))
    assert eliminated_kind(chain) is None  # a factor joins two SE2 variables
    with pytest.raises(ValueError, match="eliminate must be 'auto' or None"):
        FactorGraphProblem(chain, eliminate="points")


def test_a_point_seen_by_one_camera_is_named_when_undamped():
    rng = np.random.default_rng(1)
    graph = FactorGraph("two cameras")
    for k in range(2):
        graph.add_variable(f"c{k}", BAL_CAMERA, [0.01, -0.02, 0.0, 0.1 * k, 0.0, 0.0, 500.0, 0.0, 0.0])
    points = rng.uniform(-1, 1, (8, 3)) + [0, 0, -6]
    for k, X in enumerate(points):
        graph.add_variable(f"p{k}", Vector(3), X)
    for k in range(8):
        for c in range(2 if k != 5 else 1):  # p5 is seen by c0 alone: its 3x3 block has rank 2
            graph.add(REPROJECTION_BAL, [f"c{c}", f"p{k}"], rng.normal(0, 50, 2))
    problem = FactorGraphProblem(graph)
    assert problem.eliminated == Vector(3)
    lin = problem.linearize(problem.x0)
    with pytest.raises(SingularSystemError, match="eliminated variable 'p5' .* not positive definite"):
        problem.solve(lin)
    h = problem.solve(lin, 1e-3 * lin.diagonal())
    np.testing.assert_allclose(h, FactorGraphProblem(graph, eliminate=None).solve(lin, 1e-3 * lin.diagonal()),
                               rtol=0, atol=1e-9 * np.abs(h).max())


def test_ladybug_49s_step_with_the_points_eliminated_is_the_whole_hs(data_folder):
    from course.problems.bal.dataset import load_bal
    from course.problems.bal.factor_graph import as_factor_graph

    graph = as_factor_graph(load_bal("ladybug-49"))
    schur, whole = FactorGraphProblem(graph), FactorGraphProblem(graph, eliminate=None)
    assert schur.eliminated == Vector(3)
    lin = schur.linearize(schur.x0)
    damping = 1e-4 * lin.diagonal()
    h, h_ref = schur.solve(lin, damping), whole.solve(lin, damping)
    assert np.abs(h - h_ref).max() <= 1e-9 * np.abs(h_ref).max()


@pytest.mark.parametrize("loss", [("huber", 2.0), ("cauchy", 1.0), ("tukey", 4.0)])
def test_a_robust_loss_on_the_graph_is_chapter_4s(loss):
    """Bundle adjustment with 10% outliers and a robust loss: the factor graph's chi2, b and step are the
    chapter-4 problem's with the same loss, and with Huber's (where both solves converge) its minimum."""
    from course.problems.bal.dataset import synthetic
    from course.problems.bal.factor_graph import as_factor_graph
    from course.problems.bal.problem import BundleAdjustmentProblem

    bal = synthetic(6, 80, seed=2, noise=1.0, outliers=0.1)
    chapter4, graph = BundleAdjustmentProblem(bal, loss=loss), FactorGraphProblem(as_factor_graph(bal, loss=loss))
    plain = FactorGraphProblem(as_factor_graph(bal))
    x0 = chapter4.x0
    assert graph.chi2(x0) == pytest.approx(chapter4.chi2(x0), rel=1e-12) and graph.chi2(x0) < 0.9 * plain.chi2(x0)
    ours, theirs = graph.linearize(x0), chapter4.linearize(x0)
    assert ours.chi2 == pytest.approx(theirs.chi2, rel=1e-12)
    np.testing.assert_allclose(ours.b, theirs.b, rtol=0, atol=1e-9 * np.abs(theirs.b).max())
    damping = 1e-3 * theirs.diagonal() + 1e-6  # Tukey leaves a point whose every observation is an outlier no block
    h, h_ref = graph.solve(ours, damping), chapter4.solve(theirs, damping)
    assert np.abs(h - h_ref).max() <= 1e-8 * np.abs(h_ref).max()
    if loss[0] == "huber":  # convex in the residual: both converge (in about 140 steps) to one minimum
        options = SolverOptions(max_iterations=300)
        ours, theirs = minimize(graph, "lm-type3", options=options), minimize(chapter4, "lm-type3", options=options)
        assert ours.stop_reason == theirs.stop_reason == StopReason.COST_TOLERANCE
        assert ours.final_chi2 == pytest.approx(theirs.final_chi2, rel=1e-9)


def test_gtsam_custom_translates_a_robust_loss_its_error_half_our_chi2():
    pytest.importorskip("gtsam")
    from course.backends.factorgraph import gtsam_custom

    graph = _slam(poses=3, marks=2)
    for group in list(graph.groups.values()):
        keys, z, _ = group.arrays()
        graph.add_many(group.type, keys[:1], z[:1] + 3.0, loss=("huber", 1.0))
    factors, values, _, constant = gtsam_custom.build(graph, "solutions")
    ours = FactorGraphProblem(graph)
    assert 2.0 * factors.error(values) + constant == pytest.approx(ours.chi2(ours.x0), rel=1e-12)
