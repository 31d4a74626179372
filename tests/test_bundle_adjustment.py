"""Bundle adjustment: the BAL reader and named problems, the reference exercise module
(residuals, Jacobians, normal equations, Schur step) and the minimizer on BAL problems."""

import numpy as np
import pytest

from course.core.data import gtsam_data_dir
from course.core.errors import DatasetError, SingularSystemError
from course.problems.bal.dataset import (
    BALProblem,
    behind_camera,
    cost,
    load_bal,
    read_bal,
    residuals,
    rotate,
    synthetic,
    write_bal,
)
from course.problems.bal.problem import BundleAdjustmentProblem
from course.solver import minimize
from course.solver.options import SolverOptions
from solutions import bundle_adjustment as ba

#: ladybug-49's BAL cost at its start and after a converged LM (REFERENCES.md)
LADYBUG_INITIAL_COST = 850912.4607
LADYBUG_TARGET_COST = 13344.2411


def _args(p: BALProblem):
    return p.camera_index, p.point_index, p.observations


# ------------------------------------------------------------------ reader and named problems


def test_ladybug_initial_cost_and_behind_camera(data_folder):
    p = load_bal("ladybug-49")
    assert (p.num_cameras, p.num_points, p.num_observations) == (49, 7776, 31843)
    assert cost(p) == pytest.approx(LADYBUG_INITIAL_COST, rel=1e-9)
    assert behind_camera(p) == 31


def test_dubrovnik_from_gtsam():
    if gtsam_data_dir() is None:
        with pytest.raises(DatasetError, match="gtsam"):
            load_bal("dubrovnik-3-7")
        pytest.skip("gtsam not installed here: its Data folder is absent")
    p = load_bal("dubrovnik-3-7")
    assert (p.num_cameras, p.num_points, p.num_observations) == (3, 7, 19)
    assert cost(p) == pytest.approx(2764.22, rel=1e-5)  # gtsam's error at the start (all in front)


def test_write_read_round_trip(tmp_path):
    p = synthetic(4, 20, seed=2)
    write_bal(p, tmp_path / "p.txt")
    q = read_bal(tmp_path / "p.txt")
    for name in ("cameras", "points", "camera_index", "point_index", "observations"):
        np.testing.assert_array_equal(getattr(q, name), getattr(p, name))
    assert q.name == "p"


GOOD = "2 2 3\n0 0 1.0 2.0\n1 0 3.0 4.0\n1 1 5.0 6.0\n" + "0.1\n" * 18 + "1.0\n" * 6


@pytest.mark.parametrize("text, line, words", [
    ("2 2\n", 1, ["header", "expected 3 values"]),
    ("2 x 3\n", 1, ["num_points", "not an integer"]),
    (GOOD.replace("1 0 3.0 4.0", "1 0 3.0 abc"), 3, ["observation 1 field y", "not a finite number", "abc"]),
    (GOOD.replace("1 1 5.0", "1 7 5.0"), 4, ["observation 2 field point_index", "out of range"]),
    (GOOD.replace("1 0 3.0", "2 0 3.0"), 3, ["observation 1 field camera_index", "out of range"]),
    (GOOD.replace("1 0 3.0", "0.5 0 3.0"), 3, ["camera_index", "not an integer"]),
    ("\n".join(GOOD.splitlines()[:-2]) + "\n", 26, ["point 1 field Y", "truncated"]),
    (GOOD + "9.0\n", 29, ["extra value", "1 values more"]),
    (GOOD.replace("0.1\n", "nan\n", 1), 5, ["camera 0 field w_x", "not a finite number"]),
])
def test_reader_errors_name_file_line_field(tmp_path, text, line, words):
    path = tmp_path / "bad.txt"
    path.write_text(text)
    with pytest.raises(DatasetError) as info:
        read_bal(path)
    message = str(info.value)
    assert message.startswith(f"{path}:{line}: "), message
    for word in words:
        assert word in message


def test_reader_good_file_and_missing_file(tmp_path):
    (tmp_path / "good.txt").write_text(GOOD)
    p = read_bal(tmp_path / "good.txt")
    assert p.cameras.shape == (2, 9) and p.points.shape == (2, 3)
    np.testing.assert_array_equal(p.camera_index, [0, 1, 1])
    with pytest.raises(DatasetError, match="does not exist"):
        read_bal(tmp_path / "missing.txt")


def test_named_problem_errors():
    with pytest.raises(DatasetError, match="bal-synthetic:CAMS:POINTS"):
        load_bal("bal-synthetic:3")
    with pytest.raises(DatasetError, match="known names"):
        load_bal("no-such-problem")


def test_synthetic_generator():
    p = load_bal("bal-synthetic:6:50:3")
    assert p.name == "bal-synthetic:6:50:3" and p.ground_truth is not None
    counts = np.bincount(p.point_index, minlength=p.num_points)
    assert counts.min() >= 2
    assert np.all(np.bincount(p.camera_index, minlength=p.num_cameras) > 0)
    assert behind_camera(p, *p.ground_truth) == 0
    exact = synthetic(6, 50, seed=3, noise=0.0)
    assert cost(exact, *exact.ground_truth) < 1e-20
    noisy = synthetic(6, 50, seed=3, noise=1.0)
    assert 0.5 * 0.5 * 2 * noisy.num_observations < cost(noisy, *noisy.ground_truth) < 2 * noisy.num_observations
    p1, p2 = synthetic(6, 50, seed=3), synthetic(6, 50, seed=3)
    np.testing.assert_array_equal(p1.observations, p2.observations)


# ------------------------------------------------------------------ the exercise module


def _small_problem():
    p = synthetic(5, 30, seed=3)
    cameras = p.cameras.copy()
    cameras[0, :3] = [1e-9, -2e-9, 5e-10]  # the small-angle branch
    cameras[1, :3] *= 30.0  # a large angle (several turns)
    cameras[:, 7] = [0.2, -0.1, 0.05, 0.3, -0.2]  # distortion that matters
    cameras[:, 8] = [0.05, 0.02, -0.03, 0.01, 0.0]
    return p, cameras


def test_rotate_matches_matrix_exponential():
    from scipy.spatial.transform import Rotation

    rng = np.random.default_rng(0)
    w = rng.normal(size=(20, 3))
    w[0] = [1e-9, 0, 0]
    w[1] = 0.0
    X = rng.normal(size=(20, 3))
    np.testing.assert_allclose(rotate(w, X), Rotation.from_rotvec(w).apply(X), rtol=1e-12, atol=1e-12)


def test_residuals_match_framework_projection():
    p, cameras = _small_problem()
    r, _, _ = ba.reprojection_residuals_and_jacobians(cameras, p.points, *_args(p))
    np.testing.assert_allclose(r, residuals(cameras, p.points, *_args(p)), rtol=1e-12, atol=1e-9)


def test_jacobians_match_central_differences():
    p, cameras = _small_problem()
    points = p.points
    _, J_cam, J_point = ba.reprojection_residuals_and_jacobians(cameras, points, *_args(p))

    def r_of(c, x):
        return ba.reprojection_residuals_and_jacobians(c, x, *_args(p))[0]

    fd_cam = np.zeros_like(J_cam)
    for c in range(p.num_cameras):
        for j in range(9):
            h = 1e-6 * max(1.0, abs(cameras[c, j]))
            plus, minus = cameras.copy(), cameras.copy()
            plus[c, j] += h
            minus[c, j] -= h
            rows = p.camera_index == c
            fd_cam[rows, :, j] = ((r_of(plus, points) - r_of(minus, points)) / (2 * h))[rows]
    fd_point = np.zeros_like(J_point)
    for q in range(p.num_points):
        for j in range(3):
            plus, minus = points.copy(), points.copy()
            plus[q, j] += 1e-6
            minus[q, j] -= 1e-6
            rows = p.point_index == q
            fd_point[rows, :, j] = ((r_of(cameras, plus) - r_of(cameras, minus)) / 2e-6)[rows]
    for J, fd in ((J_cam, fd_cam), (J_point, fd_point)):
        scale = np.max(np.abs(J), axis=(0, 1))  # per parameter column
        assert np.max(np.abs(J - fd) / scale) < 1e-6


def _dense(p, J_cam, J_point):
    C, P, K = p.num_cameras, p.num_points, p.num_observations
    J = np.zeros((2 * K, 9 * C + 3 * P))
    for k, (c, q) in enumerate(zip(p.camera_index, p.point_index)):
        J[2 * k:2 * k + 2, 9 * c:9 * c + 9] = J_cam[k]
        J[2 * k:2 * k + 2, 9 * C + 3 * q:9 * C + 3 * q + 3] = J_point[k]
    return J


def test_normal_equations_match_dense_products():
    p, cameras = _small_problem()
    r, J_cam, J_point = ba.reprojection_residuals_and_jacobians(cameras, p.points, *_args(p))
    U, V, W, g_cam, g_point, chi2 = ba.normal_equations(r, J_cam, J_point, p.camera_index, p.point_index,
                                                        p.num_cameras, p.num_points)
    J = _dense(p, J_cam, J_point)
    H, g = J.T @ J, J.T @ r.ravel()
    C = 9 * p.num_cameras
    for c in range(p.num_cameras):
        np.testing.assert_allclose(U[c], H[9 * c:9 * c + 9, 9 * c:9 * c + 9], rtol=1e-12, atol=1e-9)
    for q in range(p.num_points):
        np.testing.assert_allclose(V[q], H[C + 3 * q:C + 3 * q + 3, C + 3 * q:C + 3 * q + 3], rtol=1e-12, atol=1e-9)
    for k, (c, q) in enumerate(zip(p.camera_index, p.point_index)):  # (camera, point) pairs are unique here
        np.testing.assert_allclose(W[k], H[9 * c:9 * c + 9, C + 3 * q:C + 3 * q + 3], rtol=1e-12, atol=1e-9)
    np.testing.assert_allclose(np.concatenate([g_cam.ravel(), g_point.ravel()]), g, rtol=1e-12, atol=1e-9)
    assert chi2 == pytest.approx(float(r.ravel() @ r.ravel()), rel=1e-12)


@pytest.mark.parametrize("dense", [True, False])
def test_schur_step_equals_full_damped_step(monkeypatch, dense):
    p, cameras = _small_problem()
    r, J_cam, J_point = ba.reprojection_residuals_and_jacobians(cameras, p.points, *_args(p))
    U, V, W, g_cam, g_point, _ = ba.normal_equations(r, J_cam, J_point, p.camera_index, p.point_index,
                                                     p.num_cameras, p.num_points)
    J = _dense(p, J_cam, J_point)
    H, g = J.T @ J, J.T @ r.ravel()
    d = 1e-3 * np.diag(H)
    full = np.linalg.solve(H + np.diag(d), -g)
    if not dense:  # the sparse branch, though the 4 cameras' S is dense
        monkeypatch.setattr(ba, "DENSE_LIMIT", 0)
        monkeypatch.setattr(ba, "DENSE_FILL", 2.0)
    n = 9 * p.num_cameras
    dx_cam, dx_point = ba.schur_solve(U, V, W, g_cam, g_point, p.camera_index, p.point_index,
                                      damping_cam=d[:n].reshape(-1, 9), damping_point=d[n:].reshape(-1, 3))
    step = np.concatenate([dx_cam.ravel(), dx_point.ravel()])
    assert np.linalg.norm(step - full) <= 1e-8 * np.linalg.norm(full)


def test_schur_undamped_gauge_is_a_clear_error():
    p, cameras = _small_problem()
    r, J_cam, J_point = ba.reprojection_residuals_and_jacobians(cameras, p.points, *_args(p))
    blocks = ba.normal_equations(r, J_cam, J_point, p.camera_index, p.point_index, p.num_cameras, p.num_points)
    U, V, W, g_cam, g_point, _ = blocks
    with pytest.raises(SingularSystemError, match="gauge"):
        ba.schur_solve(U, V, W, g_cam, g_point, p.camera_index, p.point_index)


# ------------------------------------------------------------------ the minimizer on BAL problems


def test_block_linearization_matvec_and_diagonal():
    p, cameras = _small_problem()
    problem = BundleAdjustmentProblem(BALProblem(cameras, p.points, *_args(p)))
    lin = problem.linearize(problem.x0)
    r, J_cam, J_point = ba.reprojection_residuals_and_jacobians(cameras, p.points, *_args(p))
    J = _dense(p, J_cam, J_point)
    H = J.T @ J
    v = np.random.default_rng(1).normal(size=len(problem.x0))
    np.testing.assert_allclose(lin.matvec(v), H @ v, rtol=1e-10, atol=1e-8 * np.abs(H @ v).max())
    np.testing.assert_allclose(lin.diagonal(), np.diag(H), rtol=1e-12)
    assert lin.chi2 == pytest.approx(2 * cost(BALProblem(cameras, p.points, *_args(p))), rel=1e-12)


def test_gauss_newton_fails_with_a_clear_message():
    problem = BundleAdjustmentProblem(synthetic(4, 30, seed=1))
    with pytest.raises(SingularSystemError, match="gauge freedom"):
        minimize(problem, "gauss-newton")


def _similarity(A, B):
    """Scale s, rotation R, translation t minimizing |s R A + t - B| (Umeyama)."""
    ma, mb = A.mean(0), B.mean(0)
    A0, B0 = A - ma, B - mb
    Uu, S, Vt = np.linalg.svd(B0.T @ A0)
    D = np.diag([1.0, 1.0, np.sign(np.linalg.det(Uu @ Vt))])
    R = Uu @ D @ Vt
    s = np.trace(np.diag(S) @ D) / np.sum(A0 * A0)
    return s, R, mb - s * R @ ma


@pytest.mark.parametrize("method", ["lm-type1", "lm-type2", "lm-type3", "dogleg"])
def test_zero_noise_recovers_ground_truth_up_to_gauge(method):
    p = synthetic(6, 60, seed=4, noise=0.0)
    problem = BundleAdjustmentProblem(p)
    result = minimize(problem, method)
    assert result.final_chi2 < 1e-12 * result.initial_chi2
    cameras, points = problem.unpack(result.params)
    true_cameras, true_points = p.ground_truth
    # intrinsics are gauge-free; points and camera centres agree up to a similarity
    np.testing.assert_allclose(cameras[:, 6:], true_cameras[:, 6:], rtol=1e-5, atol=1e-6)
    s, R, t = _similarity(points, true_points)
    np.testing.assert_allclose(s * points @ R.T + t, true_points, atol=1e-6)

    def centres(cams):
        return -rotate(-cams[:, :3], cams[:, 3:6])  # c = -R^T t

    np.testing.assert_allclose(s * centres(cameras) @ R.T + t, centres(true_cameras), atol=1e-6)


@pytest.mark.slow
def test_ladybug_lm_reaches_the_reference_cost(data_folder):
    # Nielsen's damping (lambda I, no floor) with the gauge fixed: the target by iteration 81 of 100
    problem = BundleAdjustmentProblem(load_bal("ladybug-49"), fix_gauge=True)
    result = minimize(problem, "lm-type3")
    assert result.initial_chi2 / 2 == pytest.approx(LADYBUG_INITIAL_COST, rel=1e-9)
    assert result.iterations <= 100
    assert result.final_chi2 / 2 <= LADYBUG_TARGET_COST * (1 + 1e-6)


def test_a_singular_damped_system_raises_lambda_tenfold_and_solves_again():
    from course.solver.strategies import SINGULAR_RETRIES

    class Fragile(BundleAdjustmentProblem):
        """Singular whenever the damping's smallest entry is below ``floor``."""

        floor = 0.0
        lambdas: list = []

        def solve(self, lin, damping=None):
            self.lambdas.append(float(np.min(damping)))
            if np.min(damping) < self.floor:
                raise SingularSystemError("schur_solve: S is singular (test)")
            return super().solve(lin, damping)

    problem = Fragile(synthetic(4, 30, seed=1, noise=0.0))
    lin = problem.linearize(problem.x0)
    lam0 = 1e-2 * float(np.max(lin.diagonal()))  # lm-type3's first lambda
    problem.floor = 50 * lam0
    result = minimize(problem, "lm-type3", options=SolverOptions(max_iterations=1))
    assert problem.lambdas[:3] == pytest.approx([lam0, 10 * lam0, 100 * lam0])
    assert result.factorizations == 3 and result.iterations == 1
    problem.floor, problem.lambdas = float("inf"), []
    with pytest.raises(SingularSystemError, match="singular"):
        minimize(problem, "lm-type3", options=SolverOptions(max_iterations=1))
    assert len(problem.lambdas) == SINGULAR_RETRIES + 1


def test_fixed_gauge_lets_gauss_newton_converge():
    p = synthetic(5, 40, seed=6, noise=0.0)
    problem = BundleAdjustmentProblem(p, fix_gauge=True)
    assert problem.fixed.sum() == 7 and problem.fixed[0, :6].all()
    result = minimize(problem, "gauss-newton")
    assert result.final_chi2 < 1e-12 * result.initial_chi2
    cameras, _ = problem.unpack(result.params)
    np.testing.assert_array_equal(cameras[problem.fixed], p.cameras[problem.fixed])


def test_the_fixed_rows_of_W_are_zeroed_and_a_view_the_implementation_keeps_is_left_alone():
    """The gauge's fixed parameters' rows of W are zero in the linearization: zeroed in place in the
    implementation's fresh W, on a copy when W is a (read-only) view of an array the implementation keeps."""
    from types import SimpleNamespace

    p = synthetic(5, 40, seed=6, noise=0.5)
    problem = BundleAdjustmentProblem(p, fix_gauge=True)
    fixed_rows = problem.fixed[p.camera_index]  # (K, 9)
    r, J_cam, J_point = ba.reprojection_residuals_and_jacobians(*problem.unpack(problem.x0), *_args(p))
    raw_W = ba.normal_equations(r, J_cam, J_point, p.camera_index, p.point_index, p.num_cameras,
                                p.num_points)[2]
    assert np.abs(raw_W[fixed_rows]).max() > 0  # the gauge's rows are not zero before
    lin = problem.linearize(problem.x0)
    assert not lin.W[fixed_rows].any()
    np.testing.assert_array_equal(lin.W[~fixed_rows], raw_W[~fixed_rows])

    kept = {}

    def keeping(*args):  # W handed over as a read-only view of an array kept between calls
        U, V, W, g_cam, g_point, chi2 = ba.normal_equations(*args)
        kept["W"] = W
        view = W[:]
        view.flags.writeable = False
        return U, V, view, g_cam, g_point, chi2

    problem.ba = SimpleNamespace(reprojection_residuals_and_jacobians=ba.reprojection_residuals_and_jacobians,
                                 normal_equations=keeping)
    lin = problem.linearize(problem.x0)
    assert not lin.W[fixed_rows].any()
    np.testing.assert_array_equal(kept["W"], raw_W)  # untouched


def test_a_nearly_dense_reduced_system_is_solved_densely(monkeypatch):
    """9C above DENSE_LIMIT but S nearly dense: the dense factorization, the same step."""
    import scipy.sparse.linalg as spla

    p, cameras = _small_problem()
    r, J_cam, J_point = ba.reprojection_residuals_and_jacobians(cameras, p.points, *_args(p))
    U, V, W, g_cam, g_point, _ = ba.normal_equations(r, J_cam, J_point, p.camera_index, p.point_index,
                                                     p.num_cameras, p.num_points)
    d = 1e-3 * np.ones((p.num_cameras, 9)), 1e-3 * np.ones((p.num_points, 3))
    want = ba.schur_solve(U, V, W, g_cam, g_point, p.camera_index, p.point_index, *d)
    monkeypatch.setattr(ba, "DENSE_LIMIT", 0)
    monkeypatch.setattr(spla, "splu", lambda *a, **k: pytest.fail("a dense S went to the sparse solver"))
    got = ba.schur_solve(U, V, W, g_cam, g_point, p.camera_index, p.point_index, *d)
    for a, b in zip(got, want):
        assert np.allclose(a, b, rtol=1e-10, atol=1e-12)
