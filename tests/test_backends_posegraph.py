"""Peer back ends on 2D pose graphs: g2o, Ceres and GTSAM agree with each other."""

import numpy as np
import pytest

for _library in ("pyceres", "g2opy", "gtsam"):  # the peers extra, where they have wheels
    pytest.importorskip(_library, reason=f"{_library} is not installed here (the peers extra, where it has wheels)")

from course.backends import registry  # noqa: E402
from course.backends.posegraph import ceres as ceres_posegraph  # noqa: E402
from course.backends.posegraph import g2o as g2o_posegraph  # noqa: E402
from course.backends.posegraph import gtsam as gtsam_posegraph  # noqa: E402
from course.core.backend_names import OURS  # noqa: E402
from course.core.data import data_dir  # noqa: E402
from course.geometry import se2 as geometry  # noqa: E402
from course.problems.posegraph import dataset as datasets  # noqa: E402
from course.problems.posegraph.graph import PoseGraph  # noqa: E402
from solutions.ceres_edge_cost import SE2EdgeCost  # noqa: E402

RTOL = 1e-6
INTEL_GN_CHI2 = 65.402048  # REFERENCES.md, "Measured here on the peers"
RUNS = [(backend, method) for backend, method in registry.pairs("posegraph") if backend != OURS]


@pytest.fixture(scope="module")
def intel():
    if not data_dir().is_dir():
        pytest.skip(f"data folder {data_dir()} not found (set COURSE_DATA)")
    return datasets.load_dataset("intel")


@pytest.fixture(scope="module")
def intel_runs(intel):
    return {
        "g2o": registry.peer_solver("posegraph", "g2o")(intel, "gauss-newton"),
        "gtsam": registry.peer_solver("posegraph", "gtsam")(intel, "gauss-newton"),
        "ceres": registry.peer_solver("posegraph", "ceres")(intel, "levenberg-marquardt"),
    }


@pytest.fixture(scope="module")
def w100():
    graph = datasets.load_dataset("w100")
    # A second fixed vertex, so that edges from and to fixed vertices both occur.
    graph.fixed = np.array([0, 50])
    return graph


@pytest.fixture(scope="module")
def w100_runs(w100):
    return {(b, m): registry.peer_solver("posegraph", b)(w100, m) for b, m in RUNS}


def test_registry_matches_modules():
    for backend, module in (("g2o", g2o_posegraph), ("ceres", ceres_posegraph), ("gtsam", gtsam_posegraph)):
        assert registry.peer_solver("posegraph", backend) is module.solve


def test_intel_g2o_gauss_newton_reference(intel, intel_runs):
    run = intel_runs["g2o"]
    assert (intel.num_poses, intel.num_edges) == (729, 3070)
    assert run.initial_chi2 == pytest.approx(2.05e6, rel=0.01)
    assert run.final_chi2 == pytest.approx(INTEL_GN_CHI2, rel=RTOL)
    assert run.stop_reason.startswith("gain_threshold")
    assert run.iterations < 10


@pytest.mark.parametrize("backend", ["gtsam", "ceres"])
def test_intel_peers_agree_with_g2o(intel_runs, backend):
    assert intel_runs[backend].final_chi2 == pytest.approx(intel_runs["g2o"].final_chi2, rel=RTOL)
    difference = intel_runs[backend].params - intel_runs["g2o"].params
    difference[:, 2] = geometry.wrap_angle(difference[:, 2])
    np.testing.assert_allclose(difference, 0.0, atol=1e-5)
    assert np.all(np.abs(intel_runs[backend].params[:, 2]) <= np.pi)


@pytest.mark.parametrize("backend", ["g2o", "gtsam", "ceres"])
def test_intel_trace(intel, intel_runs, backend):
    run = intel_runs[backend]
    chi2 = np.array([r.chi2 for r in run.trace])
    assert [r.iteration for r in run.trace] == list(range(len(run.trace)))
    assert len(run.trace) == run.iterations + 1
    assert chi2[0] == pytest.approx(run.initial_chi2, rel=1e-12)
    assert chi2[-1] == pytest.approx(run.final_chi2, rel=1e-9)
    assert run.seconds > 0
    assert all(r.seconds > 0 for r in run.trace[1:])
    if run.method == "gauss-newton":  # non-increasing up to rounding
        assert np.all(np.diff(chi2) <= 1e-12 * chi2[1:])


@pytest.mark.parametrize("backend,method", RUNS)
def test_w100_every_method_same_minimum(w100, w100_runs, backend, method):
    run = w100_runs[(backend, method)]
    reference = w100_runs[("g2o", "gauss-newton")].final_chi2
    assert run.backend == backend and run.method == method
    assert run.initial_chi2 == pytest.approx(w100.chi2())
    assert run.final_chi2 == pytest.approx(reference, rel=RTOL)
    assert run.final_chi2 < 0.02 * run.initial_chi2
    assert 0 < run.iterations < 100
    assert run.trace[0].chi2 == pytest.approx(run.initial_chi2, rel=1e-12)
    assert run.seconds > 0


@pytest.mark.parametrize("backend,method", RUNS)
def test_fixed_poses_stay_exactly(w100, w100_runs, backend, method):
    run = w100_runs[(backend, method)]
    assert run.params.shape == w100.poses.shape
    np.testing.assert_array_equal(run.params[w100.fixed], w100.poses[w100.fixed])
    assert np.abs(run.params - w100.poses).max() > 0.1  # the others moved


def test_edges_between_fixed_vertices():
    """Adjacent fixed vertices: an edge with no free end (pyceres cannot take it)."""
    graph = datasets.load_dataset("w100")
    graph.fixed = np.array([0, 1, 2])
    assert np.any(np.isin(graph.edges_i, graph.fixed) & np.isin(graph.edges_j, graph.fixed))
    runs = [registry.peer_solver("posegraph", b)(graph, m) for b, m in RUNS]
    for run in runs:
        np.testing.assert_array_equal(run.params[graph.fixed], graph.poses[graph.fixed])
        assert run.trace[0].chi2 == pytest.approx(graph.chi2(), rel=1e-12)
        assert run.final_chi2 == pytest.approx(runs[0].final_chi2, rel=RTOL)
        assert run.trace[-1].chi2 == pytest.approx(run.final_chi2, rel=1e-9)


@pytest.mark.parametrize("backend", sorted(registry.POSE_GRAPH_PEERS))
def test_unknown_method_raises(w100, backend):
    with pytest.raises(ValueError, match="choose one of") as info:
        registry.peer_solver("posegraph", backend)(w100, "newton-raphson")
    for method in registry.peer_methods("posegraph", backend):
        assert method in str(info.value)


def _random_cost(rng):
    z = rng.normal(size=3)
    a = rng.normal(size=(3, 3))
    root = ceres_posegraph.sqrt_information(a @ a.T + np.eye(3))
    return z, root, SE2EdgeCost(z, root)


def _evaluate(cost, xi, xj):
    """Residuals (3,) and Jacobians [(3, 3), (3, 3)] through Ceres' C++ CostFunction API."""
    residuals, jacobians = cost.evaluate(np.array(xi, dtype=float), np.array(xj, dtype=float))
    return residuals.reshape(3), [np.asarray(j).reshape(3, 3) for j in jacobians]


def test_ceres_edge_cost_residual_is_whitened_error():
    rng = np.random.default_rng(0)
    for _ in range(20):
        z, root, cost = _random_cost(rng)
        xi, xj = rng.uniform(-3, 3, size=3), rng.uniform(-3, 3, size=3)
        residuals, _ = _evaluate(cost, xi, xj)
        e = geometry.edge_errors(np.array([xi, xj]), np.array([0]), np.array([1]), z[None])[0]
        np.testing.assert_allclose(residuals, root @ e, rtol=1e-12, atol=1e-12)


def test_ceres_edge_cost_jacobians_match_finite_differences():
    rng = np.random.default_rng(1)
    h = 1e-6
    for _ in range(20):
        _, _, cost = _random_cost(rng)
        x = [rng.uniform(-3, 3, size=3), rng.uniform(-3, 3, size=3)]
        _, jacobians = _evaluate(cost, *x)
        for block in range(2):
            numeric = np.zeros((3, 3))
            for k in range(3):
                plus = [p.copy() for p in x]
                minus = [p.copy() for p in x]
                plus[block][k] += h
                minus[block][k] -= h
                numeric[:, k] = (_evaluate(cost, *plus)[0] - _evaluate(cost, *minus)[0]) / (2 * h)
            np.testing.assert_allclose(jacobians[block], numeric, rtol=1e-6, atol=1e-6)
        # Ceres may ask for one block's Jacobian only (the other is None).
        residuals, only_j = np.zeros(3), [None, np.zeros(9)]
        assert cost.Evaluate(x, residuals, only_j)
        np.testing.assert_allclose(only_j[1].reshape(3, 3), jacobians[1], rtol=1e-15)


def test_ceres_twice_cost_is_our_chi2(w100, w100_runs):
    problem, blocks, costs, constant = ceres_posegraph.build_problem(w100)
    assert constant == 0.0
    assert problem.num_residual_blocks() == w100.num_edges
    edges = zip(costs, w100.edges_i, w100.edges_j)
    residuals = np.concatenate([_evaluate(c, blocks[i], blocks[j])[0] for c, i, j in edges])
    assert residuals @ residuals == pytest.approx(w100.chi2(), rel=1e-12)
    for k in w100.fixed:
        assert problem.is_parameter_block_constant(blocks[k])
    for method in ceres_posegraph.METHODS:  # Ceres' own 2 * cost at the start and the end
        run = w100_runs[("ceres", method)]
        assert run.trace[0].chi2 == pytest.approx(w100.chi2(), rel=1e-12)
        assert run.trace[-1].chi2 == pytest.approx(run.final_chi2, rel=1e-12)


def test_ceres_accepts_another_cost_class(w100, w100_runs):
    class Doubled(SE2EdgeCost):
        """Residuals times 2: chi2 times 4, same minimizer."""

        def __init__(self, measurement, sqrt_information):
            super().__init__(measurement, 2.0 * np.asarray(sqrt_information))

    run = ceres_posegraph.solve(w100, "levenberg-marquardt", cost_class=Doubled)
    assert run.trace[0].chi2 == pytest.approx(4 * run.initial_chi2, rel=1e-12)
    reference = w100_runs[("ceres", "levenberg-marquardt")].final_chi2
    assert run.final_chi2 == pytest.approx(reference, rel=RTOL)


def test_gtsam_fixed_vertex_elimination_is_exact(w100):
    """Edges to and from fixed vertices become priors with the same error."""
    import gtsam

    factors, values, free = gtsam_posegraph.build_factor_graph(w100, fix="eliminate")
    reference, all_values, _ = gtsam_posegraph.build_factor_graph(w100, fix="prior")
    assert set(w100.fixed.tolist()).isdisjoint(free.tolist())
    rng = np.random.default_rng(2)
    poses = w100.poses + 0.1 * rng.normal(size=w100.poses.shape)
    poses[w100.fixed] = w100.poses[w100.fixed]
    moved, moved_all = gtsam.Values(), gtsam.Values()
    free = set(free.tolist())
    for k, p in enumerate(poses.tolist()):
        moved_all.insert(k, gtsam.Pose2(*p))
        if k in free:
            moved.insert(k, gtsam.Pose2(*p))
    # The "prior" graph also holds the edges between fixed vertices: none in w100 here.
    assert factors.error(moved) == pytest.approx(reference.error(moved_all), rel=1e-12)


def test_gtsam_failure_is_reported_not_raised():
    """A vertex whose heading no edge constrains: GTSAM's Gauss-Newton throws, we report."""
    base = datasets.manhattan(30)
    n = base.num_poses
    graph = PoseGraph(
        np.vstack([base.poses, [100.0, 0.0, 0.0]]),
        np.append(base.edges_i, n - 1),
        np.append(base.edges_j, n),
        np.vstack([base.measurements, [1.0, 0.0, 0.0]]),
        np.concatenate([base.information, np.diag([1.0, 1.0, 0.0])[None]]),
    )
    run = gtsam_posegraph.solve(graph, "gauss-newton")
    assert run.stop_reason.startswith("failed: Indeterminate linear system")
    assert run.iterations == 0
    np.testing.assert_array_equal(run.params, graph.poses)
    assert run.final_chi2 == run.initial_chi2
    with pytest.raises(RuntimeError, match="Indeterminate"):
        gtsam_posegraph.solve(graph, "gauss-newton", raise_on_failure=True)
