"""Chapter 5's sliding-window VIO back end: the problem's Jacobians, and the comparison of the
window with the marginalisation prior, the window that drops old frames, and the batch."""

import numpy as np
import pytest

from course.app import vio as vio_app
from course.core.errors import SingularSystemError
from course.problems.vio import problem as vp
from course.problems.vio import window as vw
from course.problems.vio.problem import VioProblem, gauge_directions
from course.problems.vio.sim import load_vio_sim
from course.solver.linearization import Linearization

#: the analytic reprojection and the central-difference IMU Jacobians against central
#: differences of the whole residual (whitened units; entries reach 1e5)
JACOBIAN_TOL = 1e-5
#: the issue's criterion: with the prior within 20% of the batch's APE rmse
BATCH_MARGIN = 1.20


def _small_problem():
    sim = load_vio_sim("vio-sim:2:0")
    kfs = vw.Keyframes(sim, 5)
    frame_ids = list(range(4))
    states = {k: kfs.truth(k) for k in frame_ids}
    import solutions.imu_preintegration as imu

    preints = {k: kfs.preintegrate(imu, k, states[k]) for k in frame_ids[:-1]}
    points = {}
    lm_ids = vw.add_landmarks(sim, kfs, frame_ids, states, points)
    data = vw.window_data(sim, kfs, frame_ids, lm_ids, preints, [])  # no frame prior: its Jacobian is first-order
    return VioProblem(np.array([states[f] for f in frame_ids]), sim.landmarks[lm_ids], data, loss=None)


def test_the_jacobian_matches_central_differences():
    problem = _small_problem()
    x = problem.retract(problem.x0, 1e-3 * np.random.default_rng(0).standard_normal(problem.n))
    r, J, _ = problem.residual_and_jacobian(x)
    J = J.toarray()
    step = 1e-6
    numeric = np.zeros_like(J)
    for col in range(problem.n):
        h = np.zeros(problem.n)
        h[col] = step
        numeric[:, col] = (problem.residual_and_jacobian(problem.retract(x, h))[0]
                           - problem.residual_and_jacobian(problem.retract(x, -h))[0]) / (2 * step)
    assert np.abs(J - numeric).max() <= JACOBIAN_TOL * max(1.0, np.abs(J).max())
    assert problem.chi2(x) == pytest.approx(float(r @ r), rel=1e-12)


def test_the_four_gauge_directions_are_null_directions_of_the_factors():
    problem = _small_problem()  # IMU and reprojections, no prior
    x = problem.retract(problem.x0, 1e-2 * np.random.default_rng(1).standard_normal(problem.n))
    _, J, _ = problem.residual_and_jacobian(x)
    N = gauge_directions(problem.frames(x), problem.landmarks(x))
    assert N.shape == (problem.n, 4)
    assert np.linalg.norm(J @ N) <= 1e-6 * np.linalg.norm(J.toarray()) * np.linalg.norm(N)
    # and nothing else is: J has exactly 4 singular values at rounding level
    s = np.linalg.svd(J.toarray(), compute_uv=False)
    assert s[-4] <= 1e-9 * s[0] and s[-5] >= 1e3 * s[-4]


def test_the_marginal_system_holds_the_leaving_factors_only():
    """What leaves with frame 0 goes into the prior; what stays must not (it would count twice)."""
    problem = _small_problem()
    x = problem.x0
    d = problem.data
    only_frame0 = [lm for lm in range(problem.num_landmarks) if set(d.obs_frame[d.obs_landmark == lm]) == {0}]
    remove = problem.columns([0], only_frame0)
    H_m, b_m = problem.marginal_system(x, remove)
    lin = problem.linearize(x)
    H_stay = lin.H - H_m
    scale = np.abs(lin.H).max()
    assert np.abs(H_stay[remove]).max() <= 1e-12 * scale  # every factor on a removed variable is in H_m
    assert np.abs((lin.b - b_m)[remove]).max() <= 1e-12 * np.abs(lin.b).max()
    neighbours = problem.columns([0, 1], sorted(set(d.obs_landmark[d.obs_frame == 0])))
    outside = np.setdiff1d(np.arange(problem.n), neighbours)
    assert np.abs(H_m[np.ix_(outside, outside)]).max() == 0.0  # and nothing else
    assert np.abs(H_stay[np.ix_(outside, outside)]).max() > 0.0


@pytest.mark.slow
def test_the_prior_carries_no_gauge_information():
    sim = load_vio_sim("vio-sim:3.5:0")
    run = vw.sliding_window(sim, "prior", keep_hessians_at=9)
    assert run.steps[-1]["prior_rank"] > 0
    h = run.hessians
    assert len(h["removed"]) >= 15 and np.array_equal(h["removed"][:15], np.arange(15))
    J, N = h["prior_J"], gauge_directions(h["prior_frame_lin"], h["prior_landmark_lin"])
    assert np.linalg.norm(J @ N) <= 1e-9 * np.linalg.norm(J) * np.linalg.norm(N)
    assert np.linalg.matrix_rank(J) == J.shape[0] and J.shape[0] <= J.shape[1] - 4
    # the same run keeping the first frame's gauge in the chain: the prior is stiff along N
    kept = vw.sliding_window(sim, "prior", keep_hessians_at=9, gauge="keep").hessians
    N = gauge_directions(kept["prior_frame_lin"], kept["prior_landmark_lin"])
    assert np.linalg.norm(kept["prior_J"] @ N) > 1e2 * np.linalg.norm(kept["prior_J"]) * 1e-9 * np.linalg.norm(N)


@pytest.mark.slow
@pytest.mark.parametrize("name", ["vio-sim:12:0", "vio-sim:8:0"])
def test_the_prior_beats_dropping_and_is_near_the_batch(name):
    results = vio_app.compare(name, peers=False)
    print("\n" + vio_app.format_comparison(results))
    with_prior, without, batch = (results[label]["rmse"] for label in
                                  ("window 10 (with prior)", "window 10 (without prior)", "batch"))
    assert with_prior < without
    assert with_prior <= BATCH_MARGIN * batch


@pytest.mark.slow
def test_the_window_and_gtsam_on_a_short_run():
    """4 s: the prior beats dropping; GTSAM's batch reaches our batch's optimum (same problem)."""
    pytest.importorskip("gtsam")
    results = vio_app.compare("vio-sim:4:0")
    print("\n" + vio_app.format_comparison(results))
    assert results["window 10 (with prior)"]["rmse"] < 0.5 * results["window 10 (without prior)"]["rmse"]
    assert results["batch"]["rmse"] == pytest.approx(results["GTSAM batch"]["rmse"], abs=1e-3)
    assert results["GTSAM fixed-lag (window 10)"]["solves"] == results["window 10 (with prior)"]["solves"]
    speed = vio_app.speed_ratios(results)
    assert set(speed) == {"window per solve", "batch per iteration"} and all(v > 0 for v in speed.values())
    assert "ours over GTSAM, same run: window per solve" in vio_app.format_comparison(results)


@pytest.mark.slow
def test_the_vio_benchmark_gives_both_ratios_over_gtsam():
    pytest.importorskip("gtsam")
    from course.app import benchmark_vio

    rows = benchmark_vio.speed("vio-sim:3:0", repeats=2)
    assert [row.what for row in rows] == list(benchmark_vio.ROWS)
    for row in rows:
        assert len(row.ours) == len(row.theirs) == 2 and min(row.ours + row.theirs) > 0
        low, high = row.spread
        assert low <= row.ratio * (1 + 1e-12) and row.ratio <= high * (1 + 1e-12)
    table = benchmark_vio.format_speed(rows, "vio-sim:3:0", 2)
    assert "medians of 2 interleaved runs" in table and "window per solve" in table and "batch per iteration" in table


def test_the_vio_benchmark_of_an_unwritten_todo_is_one_line():
    pytest.importorskip("gtsam")
    from course.app import benchmark_vio

    lines = []
    benchmark_vio.main(("vio-sim:2:0",), repeats=1, impl="exercises", out=lines.append)
    assert len(lines) == 1 and lines[0].startswith("vio-sim:2:0 sliding window against GTSAM not run:")
    assert "TODO" in lines[0]


def test_trajectories_carry_the_rotations_in_w_x_y_z_order():
    from course.problems.vio.trajectory_io import quaternion_to_rotation

    sim = load_vio_sim("vio-sim:1:0")
    truth = vw.ground_truth(sim)
    assert np.abs(quaternion_to_rotation(truth.quaternions) - sim.rotations).max() <= 1e-12
    kfs = vw.Keyframes(sim, 5)
    run = vw.VioRun("truth", kfs.times, np.array([kfs.truth(k) for k in range(len(kfs))]), [], [])
    assert np.abs(quaternion_to_rotation(run.trajectory().quaternions) - sim.rotations[kfs.imu_index]).max() <= 1e-12


def _ratios(parts):
    return {name: (chi2 / dof, np.sqrt(2.0 / dof)) for name, (chi2, dof) in parts.items() if name != "priors"}


def test_the_factors_model_the_simulators_noise():
    """At the truth every factor type's chi2 / dof is 1 within 4 standard deviations of its
    chi-square (sqrt(2 / dof)): the covariances are the simulator's noise. Claiming a quieter
    accelerometer or camera than the data's is caught."""
    import dataclasses

    sim = load_vio_sim("vio-sim:12:0")
    parts = vio_app.consistency(sim)
    print("\n" + vio_app.format_consistency(parts))
    assert set(parts) == {"IMU rotation", "IMU velocity", "IMU position", "gyroscope bias walk",
                          "accelerometer bias walk", "reprojection", "priors"}
    for name, (ratio, sd) in _ratios(parts).items():
        assert abs(ratio - 1.0) <= 4 * sd, (name, ratio)
    quiet_accel = _ratios(vio_app.consistency(dataclasses.replace(sim, accel_noise=sim.accel_noise / 3)))
    ratio, sd = quiet_accel["IMU velocity"]
    assert ratio > 1 + 4 * sd
    quiet_camera = _ratios(vio_app.consistency(dataclasses.replace(sim, pixel_noise=sim.pixel_noise / 2)))
    ratio, sd = quiet_camera["reprojection"]
    assert ratio > 1 + 4 * sd


@pytest.mark.slow
def test_the_seed_table_compares_the_window_and_the_batch_per_seed():
    rows = vio_app.seeds(2, seconds=3)
    assert [row["name"] for row in rows] == ["vio-sim:3:0", "vio-sim:3:1"]
    assert all(0 < row["window"] < 1 and 0 < row["batch"] < 1 and 0.9 < row["batch scale"] < 1.1 for row in rows)
    table = vio_app.format_seeds(rows)
    assert "mean" in table and "median" in table and "of 2" in table


def test_the_sparse_and_the_dense_step_agree():
    """The batch's sparse H (upper triangle, the implementation's sparse Cholesky) gives the dense
    step, and a problem above ``SPARSE_FROM`` unknowns takes the sparse path by itself."""

    sparse, dense = _small_problem(), _small_problem()
    sparse.sparse = True
    x = sparse.retract(sparse.x0, 1e-3 * np.random.default_rng(2).standard_normal(sparse.n))
    lin_s, lin_d = sparse.linearize(x), dense.linearize(x)
    assert lin_s.upper and not lin_d.upper
    # the dense H is summed factor by factor, the sparse one by J^T J: entries of up to 1e10 (whitened
    # IMU rows) summed in another order, so equal to rounding of the largest
    np.testing.assert_allclose(lin_s.H.toarray() + np.triu(lin_s.H.toarray(), 1).T, lin_d.H, rtol=0,
                               atol=1e-14 * np.abs(lin_d.H).max())
    np.testing.assert_allclose(lin_s.b, lin_d.b, rtol=0, atol=1e-14 * np.abs(lin_d.H).max())
    assert lin_s.chi2 == pytest.approx(lin_d.chi2, rel=1e-14)
    for damping in (np.full(sparse.n, 1.0), np.full(sparse.n, 10.0)):  # no prior here: H alone is singular
        h_s, h_d = sparse.solve(lin_s, damping), dense.solve(lin_d, damping)
        A = lin_d.H + np.diag(damping)  # entries from 1 to 1e10 (whitened IMU rows): compare by residuals
        for h in (h_s, h_d):
            assert np.linalg.norm(A @ h + lin_d.b) <= 1e-9 * np.linalg.norm(lin_d.b)
        np.testing.assert_allclose(h_s, h_d, rtol=0, atol=1e-6 * np.abs(h_d).max())
    # one solver of the implementation's, and H's pattern the same at every point: it is analysed once
    solver = sparse._sparse_solver
    again = sparse.linearize(sparse.retract(x, 1e-3 * np.random.default_rng(3).standard_normal(sparse.n)))
    sparse.solve(again, np.full(sparse.n, 1.0))
    assert sparse._sparse_solver is solver
    assert np.array_equal(again.H.indptr, lin_s.H.indptr) and np.array_equal(again.H.indices, lin_s.H.indices)
    batch = vw.batch_problem(load_vio_sim("vio-sim:3:0"), vw.true_states(load_vio_sim("vio-sim:3:0")))
    assert (batch.n >= vp.SPARSE_FROM) == batch.sparse


def test_the_dense_normal_equations_are_j_transpose_j_with_every_prior():
    """The window's H and b, summed factor by factor with the priors' constant J^T J kept, equal J^T J
    and J^T r of the stacked rows, at two points (the second after the kept blocks are made), on
    windows with the first frame's prior and with the marginalisation prior and the anchor."""
    captured = []
    original = vw.minimize

    def capture(problem, *args, **kwargs):
        captured.append(problem)
        return original(problem, *args, **kwargs)

    vw.minimize = capture
    try:
        vw.sliding_window(load_vio_sim("vio-sim:3:0"), "prior", window=4)
    finally:
        vw.minimize = original
    with_frame_prior = captured[0]
    with_linear_prior = next(p for p in captured if p.data.linear_prior is not None and p.data.anchor is not None)
    assert with_frame_prior.data.frame_priors
    rng = np.random.default_rng(3)
    for problem in (with_frame_prior, with_linear_prior):
        assert not problem.sparse
        for scale in (1e-3, 1e-2):
            x = problem.retract(problem.x0, scale * rng.standard_normal(problem.n))
            lin = problem.linearize(x)
            r, J, chi2 = problem.residual_and_jacobian(x)
            H = (J.T @ J).toarray()
            np.testing.assert_allclose(lin.H, H, rtol=0, atol=1e-14 * np.abs(H).max())
            np.testing.assert_allclose(lin.b, J.T @ r, rtol=0, atol=1e-14 * np.abs(H).max())
            assert lin.chi2 == pytest.approx(chi2, rel=1e-13) and lin.chi2 == pytest.approx(problem.chi2(x), rel=1e-13)
    # the step with the free landmarks eliminated first is the whole system's, and says when H is not definite
    problem = with_linear_prior
    assert len(problem.data.linear_prior.landmarks) and problem.num_landmarks > len(problem.data.linear_prior.landmarks)
    lin = problem.linearize(problem.x0)
    for damping in (None, np.full(problem.n, 10.0)):
        A = lin.with_diagonal_added(damping)
        h = problem.solve(lin, damping)
        np.testing.assert_allclose(h, np.linalg.solve(A, -lin.b), rtol=0, atol=1e-8 * np.abs(h).max())
        assert np.linalg.norm(A @ h + lin.b) <= 1e-10 * np.linalg.norm(lin.b)
    indefinite = Linearization(H=lin.H - 2 * np.abs(np.linalg.eigvalsh(lin.H)).max() * np.eye(problem.n), b=lin.b,
                                  chi2=lin.chi2)
    with pytest.raises(SingularSystemError, match="not positive definite"):
        problem.solve(indefinite)
    # and the sparse path (the batch's) puts the same H, priors included, on its fixed pattern
    problem.sparse = True
    for x in (problem.x0, problem.retract(problem.x0, 1e-3 * rng.standard_normal(problem.n))):
        upper = problem.linearize(x)
        problem.sparse = False
        full = problem.linearize(x)
        problem.sparse = True
        H = upper.H.toarray()
        np.testing.assert_allclose(H + np.triu(H, 1).T, full.H, rtol=0, atol=1e-14 * np.abs(full.H).max())
        np.testing.assert_allclose(upper.b, full.b, rtol=0, atol=1e-14 * np.abs(full.H).max())
        np.testing.assert_allclose(upper.H.data[upper.diagonal_positions], np.diag(full.H), rtol=1e-14)
