"""Chapter 2: pose-graph problem, reference pieces and agreement with the peers."""

import numpy as np
import pytest
from conftest import needs

from course.backends import registry
from course.core.errors import SingularSystemError
from course.problems.posegraph import dataset as datasets
from course.problems.posegraph.problem import PoseGraphProblem
from course.solver import minimize
from solutions import pose_graph_assembly, pose_graph_edge, pose_graph_fast, sparse_solve

REL = 1e-6


@pytest.fixture
def intel(data_folder):
    return datasets.load_dataset("intel")


def numeric_jacobians(x_i, x_j, z, step=1e-6):
    A, B = np.zeros((3, 3)), np.zeros((3, 3))
    for k in range(3):
        d = np.zeros(3)
        d[k] = step
        A[:, k] = (pose_graph_edge.edge_error_and_jacobians(x_i + d, x_j, z)[0]
                   - pose_graph_edge.edge_error_and_jacobians(x_i - d, x_j, z)[0]) / (2 * step)
        B[:, k] = (pose_graph_edge.edge_error_and_jacobians(x_i, x_j + d, z)[0]
                   - pose_graph_edge.edge_error_and_jacobians(x_i, x_j - d, z)[0]) / (2 * step)
    return A, B


def test_edge_jacobians_match_finite_differences():
    rng = np.random.default_rng(3)
    for _ in range(20):
        x_i, x_j, z = rng.uniform(-2, 2, (3, 3))
        x_i[2], x_j[2], z[2] = rng.uniform(-3, 3, 3)
        e, A, B = pose_graph_edge.edge_error_and_jacobians(x_i, x_j, z)
        if abs(abs(e[2]) - np.pi) < 1e-3:
            continue  # finite differences straddle the wrap
        A_num, B_num = numeric_jacobians(x_i, x_j, z)
        np.testing.assert_allclose(A, A_num, atol=1e-7)
        np.testing.assert_allclose(B, B_num, atol=1e-7)
        assert -np.pi <= e[2] < np.pi


def test_vectorized_edges_equal_the_per_edge_function():
    g = datasets.manhattan(200, seed=1)
    e, A, B = pose_graph_fast.edge_errors_and_jacobians(g.poses, g.edges_i, g.edges_j, g.measurements)
    for k in range(g.num_edges):
        e1, A1, B1 = pose_graph_edge.edge_error_and_jacobians(
            g.poses[g.edges_i[k]], g.poses[g.edges_j[k]], g.measurements[k])
        np.testing.assert_allclose(e[k], e1, atol=1e-12)
        np.testing.assert_allclose(A[k], A1, atol=1e-12)
        np.testing.assert_allclose(B[k], B1, atol=1e-12)


@needs("gtsam")
@pytest.mark.parametrize("fixed", [[0], [0, 7], [3, 4]])
def test_sparse_assembly_equals_the_loop(fixed):
    g = datasets.load_dataset("w100")
    H, b, chi2 = pose_graph_assembly.assemble_normal_equations(
        g.poses, g.edges_i, g.edges_j, g.measurements, g.information, fixed)
    assembler = pose_graph_fast.SparseAssembler(g.num_poses, g.edges_i, g.edges_j, fixed)
    H_up, b_fast, chi2_fast = assembler.assemble(
        *pose_graph_fast.edge_errors_and_jacobians(g.poses, g.edges_i, g.edges_j, g.measurements),
        g.information)
    np.testing.assert_allclose(H_up.toarray(), np.triu(H), rtol=1e-12, atol=1e-9)
    np.testing.assert_allclose(b_fast, b, rtol=1e-12, atol=1e-9)
    assert chi2_fast == pytest.approx(chi2, rel=1e-12)
    assert chi2 == pytest.approx(g.chi2(), rel=1e-12)
    np.testing.assert_allclose(H_up.data[assembler.diagonal_positions], np.diag(H), rtol=1e-12)


@needs("qdldl")
def test_dense_and_sparse_solves_agree():
    problem = PoseGraphProblem(datasets.manhattan(300, seed=2))
    lin = problem.linearize(problem.x0)
    full = lin.H.toarray()
    full = full + full.T - np.diag(full.diagonal())
    dense = sparse_solve.dense_solve(full, lin.b)
    sparse = sparse_solve.SparseCholeskySolver().solve(lin.H, lin.b)
    np.testing.assert_allclose(sparse, dense, rtol=1e-8, atol=1e-10)
    np.testing.assert_allclose(full @ dense, -lin.b, atol=1e-6)


def test_loop_and_vectorized_problems_reach_the_same_minimum():
    g = datasets.manhattan(150, seed=4)
    fast = minimize(PoseGraphProblem(g), "gauss-newton")
    loop = minimize(PoseGraphProblem(g, vectorized=False), "gauss-newton")
    assert loop.final_chi2 == pytest.approx(fast.final_chi2, rel=1e-9)
    np.testing.assert_allclose(loop.params, fast.params, atol=1e-8)


def test_intel_gauss_newton_reaches_the_source_figure(intel):
    result = minimize(PoseGraphProblem(intel), "gauss-newton")
    assert result.initial_chi2 == pytest.approx(2.05e6, rel=0.01)
    assert result.final_chi2 == pytest.approx(65.40, abs=0.01)
    np.testing.assert_array_equal(result.params.reshape(-1, 3)[0], intel.poses[0])
    chi2 = [r.chi2 for r in result.trace]
    assert chi2[0] == result.initial_chi2 and chi2[-1] == pytest.approx(result.final_chi2, rel=1e-12)
    assert all(r.factorizations == k for k, r in enumerate(result.trace))


@needs("pyceres", "g2opy", "gtsam")
def test_intel_agrees_with_g2o_ceres_and_gtsam(intel):
    ours = minimize(PoseGraphProblem(intel), "gauss-newton").final_chi2
    for backend, method in [("g2o", "gauss-newton"), ("ceres", "levenberg-marquardt"),
                            ("gtsam", "gauss-newton")]:
        theirs = registry.peer_solver("posegraph", backend)(intel, method).final_chi2
        assert theirs == pytest.approx(ours, rel=REL), backend


@needs("g2opy", "gtsam")
@pytest.mark.parametrize("name", ["test_quadrat", "intel-g2o", "m3500", "mit", "csail", "fr079", "w100"])
def test_named_datasets_agree_with_g2o(name, data_folder):
    graph = datasets.load_dataset(name)
    g2o = registry.peer_solver("posegraph", "g2o")(graph, "gauss-newton").final_chi2
    ours = minimize(PoseGraphProblem(graph), "gauss-newton").final_chi2
    assert ours == pytest.approx(g2o, rel=REL)


def test_unfixed_graph_is_reported_as_singular():
    g = datasets.manhattan(50, seed=0)
    g.fixed = np.array([], dtype=np.int64)
    with pytest.raises(SingularSystemError, match="positive definite"):
        minimize(PoseGraphProblem(g), "gauss-newton")


def test_damping_strategies_work_unchanged_on_pose_graphs():
    g = datasets.manhattan(200, seed=5)
    gn = minimize(PoseGraphProblem(g), "gauss-newton")
    for method in ("lm-type1", "lm-type2", "lm-type3"):
        result = minimize(PoseGraphProblem(g), method)
        assert result.final_chi2 == pytest.approx(gn.final_chi2, rel=REL), method
        accepted = [r.chi2 for r in result.trace if r.accepted]
        assert all(b <= a * (1 + 1e-12) for a, b in zip(accepted, accepted[1:]))


@pytest.mark.parametrize("method", ["gauss-newton", "lm-type3", "dogleg"])
def test_the_final_chi2_is_the_trusted_chi2_of_the_final_poses(intel, method):
    """The minimizer reports the last accepted trial's chi2 in place of evaluating it again: it is the
    problem's own ``chi2`` of the returned point, to the bit."""
    problem = PoseGraphProblem(intel)
    result = minimize(problem, method, options=None)
    assert result.final_chi2 == problem.chi2(result.params)
