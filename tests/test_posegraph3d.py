"""Chapter 6's framework: SE(3) geometry, the 3D graph readers, the problem solved by the
reference, and the g2o and GTSAM peers on the same graph (our error on every solution)."""

import numpy as np
import pytest
from conftest import needs

from course.core.errors import DatasetError
from course.geometry import quaternion, se3, so3
from course.problems.posegraph3d.dataset import load_dataset, read_graph, write_g2o
from course.problems.posegraph3d.graph import PoseGraph3D
from course.problems.posegraph3d.problem import PoseGraph3DProblem, unpack
from course.solver.minimizer import minimize

RNG = np.random.default_rng(3)


def test_vectorized_so3_maps_agree_with_the_scalar_ones_at_every_angle():
    phi = RNG.normal(size=(50, 3))
    phi[0], phi[1], phi[2] = 1e-9, [np.pi - 1e-7, 0.0, 0.0], [0.0, 2.0, 2.0]
    phi = phi[np.linalg.norm(phi, axis=1) < np.pi]
    R = so3.exp_many(phi)
    for k in range(len(phi)):
        np.testing.assert_allclose(R[k], so3.so3_exp(phi[k]), atol=1e-15)
        np.testing.assert_allclose(so3.right_jacobian_inverse_many(phi[k:k + 1])[0] @ so3.right_jacobian(phi[k]),
                                   np.eye(3), atol=1e-9)
    np.testing.assert_allclose(so3.log_many(R), phi, atol=1e-9)


def test_quaternions_round_trip_and_q_and_minus_q_are_one_rotation():
    R = so3.exp_many(RNG.normal(size=(40, 3)))
    q = quaternion.from_matrix(R)
    assert np.all(q[:, 3] >= 0)
    np.testing.assert_allclose(quaternion.to_matrix(q), R, atol=1e-14)
    np.testing.assert_allclose(quaternion.to_matrix(-3.0 * q), R, atol=1e-14)


def test_the_error_is_zero_at_the_measurement_and_its_chart_is_g2os_to_first_order():
    t, R = RNG.normal(size=(2, 3)), so3.exp_many(RNG.normal(size=(2, 3)))
    t_z, R_z = se3.between(t[0], R[0], t[1], R[1])
    e = se3.edge_errors(t, R, np.array([0]), np.array([1]), t_z[None], R_z[None])
    np.testing.assert_allclose(e, 0.0, atol=1e-12)
    small = se3.retract(t[1:], R[1:], np.r_[0, 0, 0, 1e-4, -2e-4, 3e-4])
    moved = se3.edge_errors(np.r_[t[:1], small[0]], np.r_[R[:1], small[1]], np.array([0]), np.array([1]),
                            t_z[None], R_z[None])[0]
    vec_q = quaternion.from_matrix(so3.exp_many(moved[None, 3:]))[0, :3]  # g2o's rotation error
    np.testing.assert_allclose(moved[3:], se3.G2O_SCALE[3:] * vec_q, rtol=1e-7)


def test_every_named_graph_loads_with_its_documented_size(data_folder):
    sizes = {"sphere2500": (2500, 4949), "torus3D": (5000, 9048), "parking-garage": (1661, 6275),
             "smallGrid3D": (125, 297), "tinyGrid3D": (9, 11)}
    for name, (n, m) in sizes.items():
        g = load_dataset(name)
        assert (g.num_poses, g.num_edges) == (n, m), name
        assert np.all(np.linalg.eigvalsh(g.information)[:, 0] > 0), name


@needs("gtsam")
def test_the_gtsam_wheels_graphs_load_without_the_data_folder():
    g = load_dataset("sphere_smallnoise")  # Euler angles, no information: the identity
    assert (g.num_poses, g.num_edges) == (2200, 8647) and np.all(g.information == np.eye(6))
    assert load_dataset("pose3example").num_edges == 6


def test_a_graph_written_and_read_gives_back_its_numbers(tmp_path, data_folder):
    g = load_dataset("smallGrid3D")
    write_g2o(g, tmp_path / "g.g2o")
    h = read_graph(tmp_path / "g.g2o")
    np.testing.assert_array_equal(h.information, g.information)
    np.testing.assert_allclose(h.R, g.R, atol=1e-15)
    np.testing.assert_array_equal(h.t, g.t)
    assert h.chi2() == pytest.approx(g.chi2(), rel=1e-12)


QUAT = "VERTEX_SE3:QUAT {} 0 0 0 0 0 0 1\n"
INFO = " ".join(["1 0 0 0 0 0", "1 0 0 0 0", "1 0 0 0", "4 0 0", "4 0", "4"])


@pytest.mark.parametrize("text, says", [
    (QUAT.format(0) + QUAT.format(1) + f"EDGE_SE3:QUAT 0 2 1 0 0 0 0 0 1 {INFO}\n",
     ":3: edge refers to missing vertex id 2"),
    (QUAT.format(0) + "VERTEX_SE3:QUAT 1 0 0 0 0 0 0\n", ":2: VERTEX_SE3:QUAT line has 7 values, expected 8"),
    (QUAT.format(0) + "VERTEX_SE3:QUAT 1 0 0 zero 0 0 0 1\n", ":2: field z is not a finite number: 'zero'"),
    (QUAT.format(0) + "VERTEX_SE3:QUAT 1 0 0 0 0 0 0 0\n", ":2: quaternion (qx, qy, qz, qw) has norm 0"),
    (QUAT.format(0) + QUAT.format(1) + f"EDGE_SE3:QUAT 0 1 1 0 0 0 0 0 1 {INFO.replace('4 0 0', '-4 0 0')}\n",
     ":3: information matrix is not symmetric positive definite"),
    (QUAT.format(0) + QUAT.format(0), ":2: duplicate vertex id 0 (first defined at line 1)"),
    ("VERTEX_SE2 0 0 0 0\n", ":1: unknown tag 'VERTEX_SE2'"),
    (QUAT.format(0) + "FIX 7\n", ":2: FIX refers to missing vertex id 7"),
])
def test_a_malformed_file_is_named_with_its_line_and_field(tmp_path, text, says):
    path = tmp_path / "bad.g2o"
    path.write_text(text)
    with pytest.raises(DatasetError, match=None) as raised:
        read_graph(path)
    assert str(raised.value).startswith(str(path)) and says in str(raised.value), str(raised.value)


def test_a_file_of_edges_only_starts_from_the_odometry_composed(tmp_path):
    t, R = RNG.normal(size=(4, 3)), so3.exp_many(RNG.normal(size=(4, 3)))
    lines = []
    for i, j in ((0, 1), (2, 1), (2, 3)):  # a tree, one edge walked backwards
        t_z, R_z = se3.between(t[i], R[i], t[j], R[j])
        q = quaternion.from_matrix(R_z[None])[0]
        lines.append(f"EDGE_SE3:QUAT {10 + i} {10 + j} {' '.join(map(repr, np.r_[t_z, q].tolist()))} {INFO}")
    path = tmp_path / "edges.g2o"
    path.write_text("\n".join(lines) + "\n")
    g = read_graph(path)
    assert g.ids.tolist() == [10, 11, 12, 13] and g.chi2() == pytest.approx(0.0, abs=1e-20)
    t_0, R_0 = se3.between(t[0], R[0], t, R)  # the truth seen from the first pose, which starts at the origin
    np.testing.assert_allclose(g.t, t_0, atol=1e-12)
    np.testing.assert_allclose(g.R, R_0, atol=1e-12)


@pytest.mark.parametrize("method", ["gauss-newton", "lm-type3"])
def test_our_solve_reaches_the_minimum_from_the_files_start(data_folder, method):
    g = load_dataset("smallGrid3D")
    result = minimize(PoseGraph3DProblem(g), method)
    assert result.final_chi2 == pytest.approx(462.4825302, rel=1e-8)
    t, R = unpack(result.params)
    np.testing.assert_array_equal(t[0], g.t[0])  # the fixed pose stays
    assert np.abs(np.einsum("nab,ncb->nac", R, R) - np.eye(3)).max() < 1e-12  # still rotations


@needs("g2opy", "gtsam")
@pytest.mark.parametrize("backend, method", [("g2o", "gauss-newton"), ("gtsam", "gauss-newton")])
def test_the_peers_end_where_we_do_in_our_error(data_folder, backend, method):
    """The peers minimise their own errors (g2o's half-angle rotation part, GTSAM's Logmap):
    on parking-garage, whose residual rotations are small, every final chi2 in our error is ours
    to 1e-6; on smallGrid3D, with residual rotations up to ~0.3 rad, theirs lie above ours."""
    from course.backends import registry

    solve = registry.peer_solver("posegraph3d", backend)
    for name, rel in (("parking-garage", 1e-6), ("smallGrid3D", 1e-3)):
        g = load_dataset(name)
        ours = minimize(PoseGraph3DProblem(g), "gauss-newton").final_chi2
        theirs = solve(g, method).final_chi2
        assert ours <= theirs * (1 + 1e-9) and theirs == pytest.approx(ours, rel=rel), (name, ours, theirs)


@needs("pyceres")
def test_ceres_minimises_our_error_itself(data_folder):
    """Ceres runs our edge error (a Python cost over translation and quaternion blocks): it ends at
    our Gauss-Newton's minimum, also where residual rotations are large (smallGrid3D)."""
    from course.backends.posegraph3d import ceres

    for name in ("tinyGrid3D", "smallGrid3D"):
        g = load_dataset(name)
        ours = minimize(PoseGraph3DProblem(g), "gauss-newton").final_chi2
        run = ceres.solve(g, "levenberg-marquardt")
        assert run.final_chi2 == pytest.approx(ours, rel=1e-9) and run.iterations > 0, (name, run.final_chi2, ours)


@needs("pyceres")
def test_ceres_plus_jacobian_is_the_derivative_of_its_left_quaternion_step():
    from course.backends.posegraph3d.ceres import plus_jacobian
    from course.geometry import quaternion

    rng = np.random.default_rng(3)
    q = rng.normal(size=4)
    q /= np.linalg.norm(q)

    def plus(d):  # Ceres' quaternion plus: q_delta(d) * q, q_delta = (cos|d|, sin|d| d/|d|)
        n = np.linalg.norm(d)
        w, v = np.cos(n), np.sin(n) / n * d
        x, s = q[:3], q[3]
        return np.r_[w * x + s * v + np.cross(v, x), w * s - v @ x]

    h = 1e-7
    numeric = np.stack([(plus(h * e) - plus(-h * e)) / (2 * h) for e in np.eye(3)], axis=1)
    np.testing.assert_allclose(plus_jacobian(q), numeric, atol=1e-8)
    np.testing.assert_allclose(plus_jacobian(q).T @ plus_jacobian(q), np.eye(3), atol=1e-12)
    # a left rotation by 2 d: R(q_delta(d) q) = Exp(2 d) R(q)
    d = np.array([1e-3, -2e-3, 5e-4])
    from course.geometry.so3 import exp_many
    np.testing.assert_allclose(quaternion.to_matrix(plus(d)[None])[0], exp_many((2 * d)[None])[0]
                               @ quaternion.to_matrix(q[None])[0], atol=1e-12)


def test_the_chordal_start_recovers_a_noise_free_graph_and_shortens_the_solve(data_folder):
    from course.problems.posegraph3d.initialise import initialise

    t, R = RNG.normal(0, 3.0, (6, 3)), so3.exp_many(RNG.normal(0, 1.5, (6, 3)))
    ei, ej = np.array([0, 1, 2, 3, 4, 5, 0, 3]), np.array([1, 2, 3, 4, 5, 0, 3, 1])
    t_z, R_z = se3.between(t[ei], R[ei], t[ej], R[ej])
    exact = PoseGraph3D(np.zeros((6, 3)), np.tile(np.eye(3), (6, 1, 1)), ei, ej, t_z, R_z,
                        np.tile(np.eye(6), (8, 1, 1)))
    exact.t[0], exact.R[0] = t[0], R[0]
    start, seconds = initialise(exact, "chordal")
    np.testing.assert_allclose(start.R, R, atol=1e-10)
    np.testing.assert_allclose(start.t, t, atol=1e-10)
    g = load_dataset("smallGrid3D")
    from_file = minimize(PoseGraph3DProblem(g), "gauss-newton")
    from_chordal = minimize(PoseGraph3DProblem(initialise(g, "chordal")[0]), "gauss-newton")
    assert from_chordal.final_chi2 == pytest.approx(from_file.final_chi2, rel=1e-9)
    assert from_chordal.iterations < from_file.iterations


@pytest.mark.parametrize("loss, weights", [(None, "random"), (("cauchy", 2.0), None)])
def test_a_weighted_or_robust_problems_gradient_is_half_the_gradient_of_its_chi2(data_folder, loss, weights):
    g = load_dataset("tinyGrid3D")
    w = RNG.uniform(0.0, 2.0, g.num_edges) if weights else None
    problem = PoseGraph3DProblem(g, weights=w, loss=loss)
    x = problem.retract(problem.x0, RNG.normal(0, 0.05, 6 * g.num_poses))
    lin = problem.linearize(x)
    assert lin.chi2 == pytest.approx(problem.chi2(x), rel=1e-12)
    h, gradient = 1e-6, np.zeros(6 * g.num_poses)
    for k in range(6 * g.num_poses):
        step = np.zeros(6 * g.num_poses)
        step[k] = h
        gradient[k] = (problem.chi2(problem.retract(x, step)) - problem.chi2(problem.retract(x, -step))) / (2 * h)
    free = np.ones(6 * g.num_poses, dtype=bool)
    free[:6] = False  # the fixed pose
    np.testing.assert_allclose(lin.b[free], gradient[free] / 2, rtol=1e-5, atol=1e-6)


def test_gnc_rejects_the_wrong_loop_closures_that_least_squares_keeps(data_folder):
    """20% of smallGrid3D's loop closures replaced by random ones: GNC (TLS) rejects at least 95% of
    them and keeps at least 95% of the right ones; least squares, judged by the same threshold on
    its residuals, keeps most of neither."""
    from course.problems.posegraph3d import robust
    from course.problems.posegraph3d.outliers import odometry, with_wrong_loop_closures

    graph = with_wrong_loop_closures(load_dataset("smallGrid3D"), 0.2, seed=1)
    right = ~graph.outliers & ~odometry(graph)
    assert graph.outliers.sum() == 35 and not np.any(graph.outliers & odometry(graph))
    gnc = robust.gnc(graph, "tls")
    precision, recall = robust.precision_recall(gnc.kept, graph.outliers)
    assert recall >= 0.95 and np.mean(gnc.kept[right]) >= 0.95, (precision, recall)
    assert np.all(gnc.kept[odometry(graph)])
    plain = robust.least_squares(graph)
    assert np.mean(plain.kept[right]) < 0.95


def test_the_outlier_experiment_holds_gnc_to_least_squares_without_the_wrong_closures(data_folder):
    from course.app import outliers3d

    rows, label = outliers3d.run("smallGrid3D", shares=(0.2,), peers=False)
    by = {(row["share"], row["method"]): row for row in rows}
    assert label == "our solution without outliers"
    assert [method for share, method in by if share == 0.2] == [
        "ours least squares", "ours oracle LS", "ours cauchy", "ours GNC TLS", "ours GNC GM"]
    oracle, tls, ls = by[0.2, "ours oracle LS"], by[0.2, "ours GNC TLS"], by[0.2, "ours least squares"]
    assert oracle["precision"] == oracle["recall"] == oracle["right_kept"] == 1.0  # the wrong closures known
    assert tls["recall"] >= 0.95 and tls["right_kept"] >= 0.9 > ls["right_kept"]
    assert tls["t_rmse"] < 0.1 * ls["t_rmse"]


def test_a_method_that_fails_is_a_row_of_the_outlier_table(monkeypatch, data_folder):
    from course.app import outliers3d
    from course.core.errors import SingularSystemError
    from course.problems.posegraph3d import robust

    def fails(*args, **kwargs):
        raise SingularSystemError("H is not positive definite")

    monkeypatch.setattr(robust, "gnc", fails)
    rows, _ = outliers3d.run("tinyGrid3D", shares=(0.5,), peers=False)
    failed = [row for row in rows if "failed" in row]
    assert [row["method"] for row in failed] == ["ours GNC TLS", "ours GNC GM"]
    assert outliers3d.format_row(failed[0]) == "  50% ours GNC TLS       failed: H is not positive definite"


@needs("pyceres")
def test_ceres_runs_the_implementations_edge_error_and_a_todo_surfaces_before_the_solve():
    from course.app import compare
    from course.backends.posegraph3d import ceres

    g = load_dataset("pose3example")
    with pytest.raises(NotImplementedError):
        ceres.solve(g, "levenberg-marquardt", impl="exercises")
    runs = compare.run_posegraph3d(g, impl="exercises", unimplemented="row", backends=["ceres"])
    assert [run.not_run for run in runs if run.backend == "ceres"] == [
        "not implemented: TODO pose_graph_3d.edge_errors_and_jacobians"]


@needs("gtsam")
def test_gtsams_initializepose3_is_a_3d_start_anchored_at_the_file_pose(data_folder):
    from course.app.starts import initialise, initialise_3d

    g = load_dataset("smallGrid3D")
    start, seconds = initialise_3d(g, "initializepose3")
    anchor = int(g.fixed[0])
    np.testing.assert_allclose(start.t[anchor], g.t[anchor], atol=1e-12)
    np.testing.assert_allclose(start.R[anchor], g.R[anchor], atol=1e-12)
    np.testing.assert_allclose(np.einsum("kji,kjl->kil", start.R, start.R), np.tile(np.eye(3), (g.num_poses, 1, 1)),
                               atol=1e-9)
    assert seconds > 0 and g.chi2(start.t, start.R) < g.chi2(g.t, g.R)
    from_file = minimize(PoseGraph3DProblem(g), "gauss-newton")
    assert minimize(PoseGraph3DProblem(start), "gauss-newton").final_chi2 == pytest.approx(from_file.final_chi2,
                                                                                           rel=1e-9)
    with pytest.raises(ValueError, match="3D pose graphs only"):
        initialise(object(), "initializepose3")
    with pytest.raises(ValueError, match="a 3D pose graph starts from one of file, chordal, initializepose3"):
        initialise_3d(g, "lago")


@needs("cvxopt", "qdldl")
def test_cholmod_keeps_its_analysis_for_a_pattern_and_redoes_it_for_another(data_folder):
    """Same steps as the exercise's sparse Cholesky, with new values in place for a known pattern."""
    import scipy.sparse as sp

    from course.solver.cholmod import CholmodSolver
    from solutions.sparse_solve import SparseCholeskySolver

    problem = PoseGraph3DProblem(load_dataset("smallGrid3D"))
    lin = problem.linearize(problem.x0)
    cholmod, exercise = CholmodSolver(), SparseCholeskySolver()
    for scale in (1.0, 2.0):
        H = lin.H.copy()
        H.data *= scale
        np.testing.assert_allclose(cholmod.solve(H, lin.b), exercise.solve(H, lin.b), rtol=1e-8, atol=1e-10)
    symbolic = cholmod._symbolic
    cholmod.solve(lin.H, lin.b)
    assert cholmod._symbolic is symbolic  # the analysis kept
    M = sp.random(60, 60, density=0.1, random_state=1)
    other = sp.triu(M + M.T + 60 * sp.eye(60), format="csc")
    b = np.ones(60)
    np.testing.assert_allclose(cholmod.solve(other, b), SparseCholeskySolver().solve(other, b), rtol=1e-9)
    assert cholmod._symbolic is not symbolic


@needs("cvxopt", "qdldl")
def test_cholmod_analyses_a_problems_pattern_when_the_problem_is_made(data_folder):
    """The ordering is found once, when the problem is made (as GTSAM's optimizer finds its ordering),
    and the solves keep it; an H whose rows come unsorted within each column gives the same step."""
    import scipy.sparse as sp

    from solutions.sparse_solve import SparseCholeskySolver

    problem = PoseGraph3DProblem(load_dataset("smallGrid3D"), solver="cholmod")
    cholmod = problem._solver
    symbolic = cholmod._symbolic
    assert symbolic is not None  # analysed ahead of the first solve
    lin = problem.linearize(problem.x0)
    step = problem.solve(lin)
    assert cholmod._symbolic is symbolic
    np.testing.assert_allclose(step, SparseCholeskySolver().solve(lin.H, lin.b), rtol=1e-8, atol=1e-10)
    H = lin.H
    reverse = np.concatenate([np.arange(H.indptr[c + 1] - 1, H.indptr[c] - 1, -1) for c in range(H.shape[0])])
    unsorted = sp.csc_matrix((H.data[reverse], H.indices[reverse], H.indptr), shape=H.shape)
    assert not unsorted.has_sorted_indices
    np.testing.assert_allclose(cholmod.solve(unsorted, lin.b), step, rtol=1e-12, atol=1e-14)
    assert cholmod._symbolic is not symbolic  # another pattern as given: analysed again
    np.testing.assert_allclose(cholmod.solve(unsorted, 2 * lin.b), 2 * step, rtol=1e-12, atol=1e-14)




@needs("g2opy")
def test_the_3d_benchmark_prints_each_of_our_solvers_against_g2o(data_folder):
    from course.app import benchmark_3d

    lines = []
    benchmark_3d.main(graphs=("tinyGrid3D",), repeats=1, out=lines.append)
    labels = list(benchmark_3d.our_solvers())
    assert any(all(label in line for label in labels) and "g2o" in line for line in lines)
    rows = [line for line in lines if line.startswith("tinyGrid3D")]
    assert len(rows) == 1 + len(labels)  # per iteration, then time to solution per solver
    assert all("skipped" not in row for row in rows)
