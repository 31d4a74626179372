"""The factor library, written once: every factor type solved on ours, JAX and gtsam-custom to the same
minimum; a user's factor type reaches all three by itself; noise models; partial fixing (some dofs
held) and bundle adjustment's gauge fixed as chapter 4 fixes it."""

import re

import numpy as np
import pytest
from conftest import needs

from course.factorgraph import (
    BEARING_2D,
    BEARING_3D,
    GPS,
    PINHOLE,
    POINT_TO_PLANE,
    POSITION_2D,
    RANGE_2D,
    RANGE_3D,
    RANGE_BEARING,
    SE2,
    SE3,
    SO3,
    FactorGraph,
    FactorGraphProblem,
    FactorType,
    Vector,
    between,
    jetmath,
    noise,
    prior,
    se3_value,
)
from course.factorgraph.factors import BETWEEN_SE2, BETWEEN_SE3, BETWEEN_SO3, PRIOR_SE2, PRIOR_SE3, PRIOR_SO3
from course.geometry.so3 import so3_exp
from course.solver import SolverOptions, minimize

OPTIONS = SolverOptions(max_iterations=200, gradient_tolerance=1e-14, step_tolerance=1e-14, cost_tolerance=1e-16)


def _noisy(rng, value, sigma):
    return np.asarray(value, dtype=float) + sigma * rng.standard_normal(np.shape(value))


def _graph_2d():
    """Four SE(2) poses and three landmarks: prior and between on SE2 and Vector2, range, bearing,
    range-bearing and position, with sigmas, a full covariance and an isotropic noise."""
    rng = np.random.default_rng(3)
    poses = np.array([[0.0, 0.0, 0.1], [1.0, 0.2, 0.5], [1.6, 1.1, 1.4], [1.2, 2.0, 2.6]])
    marks = np.array([[2.5, 0.5], [0.5, 2.5], [3.0, 2.8]])
    g = FactorGraph("library 2d")
    for k, p in enumerate(poses):
        g.add_variable(f"x{k}", SE2, _noisy(rng, p, 0.1))
    for k, m in enumerate(marks):
        g.add_variable(f"l{k}", Vector(2), _noisy(rng, m, 0.2))
    g.add(prior(SE2), ["x0"], poses[0], noise=noise.sigmas([0.05, 0.05, 0.02]))
    cov = np.array([[0.01, 0.002, 0.0], [0.002, 0.02, 0.001], [0.0, 0.001, 0.005]])
    for k in range(3):
        a, b = poses[k], poses[k + 1]
        c, s = np.cos(a[2]), np.sin(a[2])
        d = b[:2] - a[:2]
        z = [c * d[0] + s * d[1], -s * d[0] + c * d[1], b[2] - a[2]]
        g.add(between(SE2), [f"x{k}", f"x{k + 1}"], _noisy(rng, z, 0.02), noise=noise.covariance(cov))
    for k, p in enumerate(poses):
        for j, m in enumerate(marks):
            d = m - p[:2]
            rng_, brg = np.hypot(*d), np.arctan2(d[1], d[0]) - p[2]
            if (k + j) % 3 == 0:
                g.add(RANGE_BEARING, [f"x{k}", f"l{j}"], _noisy(rng, [rng_, brg], 0.01),
                      noise=noise.sigmas([0.05, 0.01]))
            elif (k + j) % 3 == 1:
                g.add(RANGE_2D, [f"x{k}", f"l{j}"], _noisy(rng, [rng_], 0.01), noise=noise.isotropic(1, 0.05))
            else:
                g.add(BEARING_2D, [f"x{k}", f"l{j}"], _noisy(rng, [brg], 0.01), noise=noise.isotropic(1, 0.01))
    g.add(POSITION_2D, ["x3"], _noisy(rng, poses[3, :2], 0.05), noise=noise.isotropic(2, 0.1))
    g.add(prior(Vector(2)), ["l2"], _noisy(rng, marks[2], 0.1), noise=noise.isotropic(2, 0.3))
    g.add(between(Vector(2)), ["l0", "l1"], _noisy(rng, marks[1] - marks[0], 0.05), noise=noise.isotropic(2, 0.1))
    return g


def _pose(rng, t, phi):
    return se3_value(np.asarray(t, dtype=float), so3_exp(np.asarray(phi, dtype=float)))


def _graph_3d():
    """Three SE(3) camera poses, six points and two rotations: prior and between on SE3, SO3 and Vector3,
    GPS, range, 3D bearing, pinhole projections and point-to-plane errors."""
    rng = np.random.default_rng(5)
    truth = [_pose(rng, [0.0, 0.0, 0.0], [0.0, 0.0, 0.0]), _pose(rng, [1.0, 0.1, 0.0], [0.05, -0.1, 0.08]),
             _pose(rng, [2.0, -0.1, 0.2], [-0.05, 0.1, 0.15])]
    points = np.array([[0.5, 0.3, 5.0], [1.5, -0.4, 6.0], [-0.5, 0.6, 4.5], [2.5, 0.5, 5.5], [1.0, 1.0, 7.0],
                       [0.0, -1.0, 5.0]])
    g = FactorGraph("library 3d")
    for k, x in enumerate(truth):
        start = _pose(rng, x[:3] + 0.05 * rng.standard_normal(3), 0.03 * rng.standard_normal(3))
        start[3:] = (x[3:].reshape(3, 3) @ start[3:].reshape(3, 3)).ravel()
        g.add_variable(f"x{k}", SE3, start)
    for k, p in enumerate(points):
        g.add_variable(f"p{k}", Vector(3), _noisy(rng, p, 0.1))
    R_a, R_b = so3_exp([0.2, -0.1, 0.3]), so3_exp([0.1, 0.4, -0.2])
    g.add_variable("Ra", SO3, R_a @ so3_exp([0.05, 0.02, -0.03]))
    g.add_variable("Rb", SO3, R_b @ so3_exp([-0.04, 0.03, 0.02]))
    g.add(prior(SE3), ["x0"], truth[0], noise=noise.sigmas([0.01] * 3 + [0.005] * 3))
    for k in range(2):
        Ti, Tj = truth[k], truth[k + 1]
        Ri, Rj = Ti[3:].reshape(3, 3), Tj[3:].reshape(3, 3)
        z = se3_value(Ri.T @ (Tj[:3] - Ti[:3]), Ri.T @ Rj @ so3_exp(0.01 * rng.standard_normal(3)))
        g.add(between(SE3), [f"x{k}", f"x{k + 1}"], z, noise=noise.isotropic(6, 0.05))
    K = np.array([500.0, 480.0, 320.0, 240.0])
    for k, x in enumerate(truth):
        t, R = x[:3], x[3:].reshape(3, 3)
        for j, p in enumerate(points):
            P = R.T @ (p - t)
            uv = K[:2] * P[:2] / P[2] + K[2:]
            g.add(PINHOLE, [f"x{k}", f"p{j}"], np.concatenate([_noisy(rng, uv, 0.5), K]), noise=noise.isotropic(2, 1.0))
        g.add(GPS, [f"x{k}"], _noisy(rng, t, 0.05), noise=noise.isotropic(3, 0.1))
        direction = _noisy(rng, R.T @ (points[k + 3] - t), 0.01)
        g.add(BEARING_3D, [f"x{k}", f"p{k + 3}"], direction / np.linalg.norm(direction), noise=noise.isotropic(2, 0.01))
        g.add(RANGE_3D, [f"x{k}", f"p{k}"], [np.linalg.norm(points[k] - t) + 0.01], noise=noise.isotropic(1, 0.05))
    R1, t1 = truth[1][3:].reshape(3, 3), truth[1][:3]
    for _ in range(12):  # the scan of pose x1 against planes of the world
        n = rng.standard_normal(3)
        n /= np.linalg.norm(n)
        p = rng.standard_normal(3) * 2.0
        q = R1 @ p + t1 + np.cross(n, rng.standard_normal(3))  # on the plane through R1 p + t1
        g.add(POINT_TO_PLANE, ["x1"], np.concatenate([p, q, n]), noise=noise.isotropic(1, 0.02))
    g.add(prior(Vector(3)), ["p5"], _noisy(rng, points[5], 0.05), noise=noise.isotropic(3, 0.1))
    g.add(between(Vector(3)), ["p0", "p1"], points[1] - points[0] + 0.01, noise=noise.isotropic(3, 0.1))
    g.add(prior(SO3), ["Ra"], R_a, noise=noise.isotropic(3, 0.02))
    g.add(between(SO3), ["Ra", "Rb"], R_a.T @ R_b @ so3_exp([0.01, 0.0, -0.01]), noise=noise.isotropic(3, 0.02))
    return g


def _solve(graph, backend):
    if backend == "gtsam-custom":
        from course.backends.factorgraph import gtsam_custom

        result = gtsam_custom.solve(graph, max_iterations=200, relative_error_tol=1e-15, absolute_error_tol=1e-15)
        return result.final_chi2, result.params
    if backend == "jax":
        from course.backends.factorgraph import jax_factors

        problem = jax_factors.problem(graph)
    elif backend == "numeric":
        problem = FactorGraphProblem(graph, jacobians="numeric")
    else:
        problem = FactorGraphProblem(graph)
    result = minimize(problem, "lm-type3", options=OPTIONS)
    return result.final_chi2, result.params


def _same_minimum(graph, backends=("jax", "gtsam-custom")):
    chi2, x = _solve(graph, "ours")
    start = FactorGraphProblem(graph).chi2(FactorGraphProblem(graph).x0)
    assert chi2 < 0.5 * start
    for backend in backends:
        theirs, y = _solve(graph, backend)
        assert theirs == pytest.approx(chi2, rel=1e-8), backend
        np.testing.assert_allclose(y, x, rtol=0, atol=1e-6, err_msg=backend)
    return chi2, x


def test_the_library_has_a_prior_and_a_between_for_every_kind_made_once():
    assert (prior(SE2), between(SE2), prior(SE3), between(SE3), prior(SO3), between(SO3)) == \
        (PRIOR_SE2, BETWEEN_SE2, PRIOR_SE3, BETWEEN_SE3, PRIOR_SO3, BETWEEN_SO3)
    assert prior(Vector(3)) is prior(Vector(3)) and between(Vector(2)) is between(Vector(2))
    assert prior(Vector(3)) is not prior(Vector(2))
    with pytest.raises(ValueError, match="no prior or between factor for variables of kind"):
        prior("SE7")


@pytest.mark.parametrize("make", [_graph_2d, _graph_3d], ids=["2d", "3d"])
def test_every_factor_of_the_library_gives_ours_the_minimum_its_jacobians_agree_with_differences(make):
    graph = make()
    problem = FactorGraphProblem(graph)
    numeric = FactorGraphProblem(graph, jacobians="numeric")
    for group in range(len(graph.groups)):
        _, J = problem.factor_jacobians(problem.x0, group)
        _, J_num = numeric.factor_jacobians(problem.x0, group)
        for got, want in zip(J, J_num):
            np.testing.assert_allclose(got, want, rtol=1e-6, atol=1e-6 * max(1.0, np.abs(want).max()))
    result = minimize(problem, "lm-type3", options=OPTIONS)
    assert result.final_chi2 < 0.05 * problem.chi2(problem.x0)


@needs("jax", "gtsam")
@pytest.mark.parametrize("make", [_graph_2d, _graph_3d], ids=["2d", "3d"])
def test_every_factor_of_the_library_solves_to_one_minimum_on_ours_jax_and_gtsam_custom(make):
    _same_minimum(make())


def relative_position(z, x, landmark):
    """A user's factor: the landmark in the pose's frame, ``R(theta)^T (l - t) - z``, written with jetmath."""
    d = landmark - x[..., :2]
    R_T = jetmath.transpose(jetmath.rotation2d(x[..., 2]))
    return jetmath.matvec(R_T, d) - z


RELATIVE_POSITION = FactorType("relative_position", (SE2, Vector(2)), 2, relative_position)


def _user_graph():
    g = FactorGraph("user factor")
    g.add_variable("x0", SE2, [0.0, 0.0, 0.0])
    g.add_variable("x1", SE2, [0.9, 0.2, 0.3])
    g.add_variable("l0", Vector(2), [2.2, 0.8])
    g.add_variable("l1", Vector(2), [0.7, 1.9])
    g.fix("x0")
    g.add(BETWEEN_SE2, ["x0", "x1"], [1.0, 0.0, 0.2], noise=noise.isotropic(3, 0.1))
    for pose, truth in (("x0", [0.0, 0.0, 0.0]), ("x1", [1.0, 0.0, 0.2])):
        c, s = np.cos(truth[2]), np.sin(truth[2])
        for mark, at in (("l0", [2.0, 1.0]), ("l1", [0.5, 2.0])):
            d = np.subtract(at, truth[:2])
            g.add(RELATIVE_POSITION, [pose, mark], [c * d[0] + s * d[1] + 0.01, -s * d[0] + c * d[1]],
                  noise=noise.sigmas([0.05, 0.05]))
    return g


@needs("jax", "gtsam")
def test_a_users_factor_type_runs_on_ours_jax_and_gtsam_custom_by_itself():
    from course.backends.factorgraph import jax_factors

    assert not hasattr(jax_factors, "RESIDUALS")
    _same_minimum(_user_graph(), backends=("numeric", "jax", "gtsam-custom"))
    # nothing was registered anywhere: a second type of the same residual, made here, runs as well
    again = FactorType("relative_position_again", (SE2, Vector(2)), 2, relative_position)
    g = _user_graph()
    g.add(again, ["x1", "l0"], [0.9, 0.9], noise=noise.sigmas([0.05, 0.05]))
    _same_minimum(g)


# ---------------------------------------------------------------- noise models


def test_noise_models_give_the_information_and_the_loss():
    np.testing.assert_allclose(noise.sigmas([0.5, 2.0]).information, np.diag([4.0, 0.25]))
    np.testing.assert_allclose(noise.isotropic(3, 0.1).information, 100.0 * np.eye(3))
    C = np.array([[2.0, 0.5], [0.5, 1.0]])
    np.testing.assert_allclose(noise.covariance(C).information @ C, np.eye(2), atol=1e-14)
    robust = noise.sigmas([1.0, 1.0]).robust("huber", 1.5)
    assert (robust.loss.kernel, robust.loss.scale) == ("huber", 1.5)
    with pytest.raises(ValueError, match="not positive definite"):
        noise.covariance([[1.0, 2.0], [2.0, 1.0]])
    with pytest.raises(ValueError, match="positive finite standard deviations"):
        noise.sigmas([0.1, 0.0])


def test_a_noise_model_is_the_information_and_loss_it_holds():
    def graph(**kwargs):
        g = FactorGraph("noise")
        g.add_variable("x0", SE2, [0.1, 0.2, 0.3])
        g.add(PRIOR_SE2, ["x0"], [0.0, 0.0, 0.0], **kwargs)
        return FactorGraphProblem(g)

    by_noise = graph(noise=noise.sigmas([0.1, 0.2, 0.05]).robust("cauchy", 1.0))
    by_hand = graph(information=np.diag([100.0, 25.0, 400.0]), loss=("cauchy", 1.0))
    assert by_noise.chi2(by_noise.x0) == pytest.approx(by_hand.chi2(by_hand.x0), rel=1e-15)
    with pytest.raises(ValueError, match="not both"):
        graph(noise=noise.isotropic(3, 1.0), information=np.eye(3))
    with pytest.raises(ValueError, match="a noise model of size 2 for a residual of size 3"):
        graph(noise=noise.isotropic(2, 1.0))


# ---------------------------------------------------------------- partial fixing


def _partly_fixed_graph():
    g = _user_graph()
    g.fix("x1", dofs=[0, 2])  # hold x and theta, let y move
    g.fix("l0", dofs=[1])
    return g


def test_a_partial_fix_holds_exactly_the_given_dofs():
    g = _partly_fixed_graph()
    problem = FactorGraphProblem(g)
    lin = problem.linearize(problem.x0)
    h = problem.solve(lin)
    held, moving = [3, 5, 7], [4, 6, 8, 9]  # x1's x and theta, l0's y; x1's y, l0's x, l1
    assert np.all(h[held] == 0.0) and np.all(h[:3] == 0.0)
    assert np.all(np.abs(h[moving]) > 1e-6)
    result = minimize(problem, "gauss-newton", options=OPTIONS)
    x = result.params
    np.testing.assert_array_equal(x[held], problem.x0[held])
    assert np.all(np.abs(x[moving] - problem.x0[moving]) > 1e-4)
    # a minimum in the free dofs: the gradient of the graph without the partial fix is 0 along them
    free = FactorGraphProblem(_user_graph())
    b = free.linearize(x).b
    assert np.abs(b[moving]).max() <= 1e-9 * np.abs(free.linearize(free.x0).b).max()
    assert np.abs(b[held]).max() > 1e-3


@needs("jax", "gtsam")
def test_a_partial_fix_is_held_on_jax_and_gtsam_custom_at_the_same_minimum():
    _, x = _same_minimum(_partly_fixed_graph())
    np.testing.assert_array_equal(x[[3, 5, 7]], [0.9, 0.3, 0.8])


def test_fixing_every_dof_fixes_the_variable_and_a_wrong_dof_is_named():
    g = _user_graph()
    g.fix("x1", dofs=[0, 1])
    g.fix("x1", dofs=[2])
    assert g.num_variables == 4 and 1 in g.fixed and 1 not in g.fixed_dofs
    with pytest.raises(ValueError, match=r"fix\('l0', dofs=\[2\]\).*tangent indices 0 to 1"):
        g.fix("l0", dofs=[2])
    with pytest.raises(ValueError, match="non-empty list of integers"):
        g.fix("l0", dofs=[])


def test_a_partly_fixed_eliminated_variable_is_held():
    """Landmarks are eliminated first (no factor joins two); one held in part keeps those dofs still."""
    from course.factorgraph.factors import RANGE_BEARING as RB

    g = FactorGraph("eliminated")
    for k in range(3):
        g.add_variable(f"x{k}", SE2, [float(k), 0.1 * k, 0.05 * k])
    for j in range(4):
        g.add_variable(f"l{j}", Vector(3), [1.0 + j, 2.0 - j, 0.5])
    g.fix("x0")
    g.fix("l2", dofs=[0, 2])
    for k in range(2):
        g.add(BETWEEN_SE2, [f"x{k}", f"x{k + 1}"], [1.0, 0.0, 0.0])
    planar = FactorType("planar_range_bearing", (SE2, Vector(3)), 3,
                        lambda z, x, mark: jetmath.concatenate([RB.residual(z[..., :2], x, mark[..., :2]),
                                                                mark[..., 2:] - z[..., 2:]]))
    for k in range(3):
        for j in range(4):
            g.add(planar, [f"x{k}", f"l{j}"], [2.0 + 0.1 * j, 0.3 * j - 0.2 * k, 0.4])
    problem = FactorGraphProblem(g)
    assert problem.eliminated == Vector(3)
    h = problem.solve(problem.linearize(problem.x0))
    l2 = 9 + 3 * 2
    assert h[l2] == 0.0 and h[l2 + 2] == 0.0 and abs(h[l2 + 1]) > 1e-6
    whole = FactorGraphProblem(g, eliminate=None)
    np.testing.assert_allclose(h, whole.solve(whole.linearize(whole.x0)), rtol=1e-9, atol=1e-12)


# ---------------------------------------------------------------- bundle adjustment's gauge


def test_bundle_adjustments_factor_graph_fixes_the_gauge_as_chapter_4_and_gauss_newton_ends_at_its_chi2():
    from course.problems.bal.dataset import load_bal
    from course.problems.bal.factor_graph import as_factor_graph
    from course.problems.bal.problem import BundleAdjustmentProblem, gauge_parameters

    bal = load_bal("bal-synthetic:4:40")
    graph = as_factor_graph(bal, fix_gauge=True)
    held = gauge_parameters(bal)
    assert graph.fixed_dofs == {k: tuple(np.flatnonzero(row).tolist()) for k, row in enumerate(held) if row.any()}
    fg = minimize(FactorGraphProblem(graph), "gauss-newton", options=SolverOptions(max_iterations=50))
    ch4 = minimize(BundleAdjustmentProblem(bal, fix_gauge=True), "gauss-newton",
                   options=SolverOptions(max_iterations=50))
    assert fg.final_chi2 == pytest.approx(ch4.final_chi2, rel=1e-6)
    x0 = FactorGraphProblem(graph).x0
    cameras = fg.params[:9 * bal.num_cameras].reshape(-1, 9)
    np.testing.assert_array_equal(cameras[held], x0[:9 * bal.num_cameras].reshape(-1, 9)[held])
    assert np.all(np.abs(cameras[~held] - x0[:9 * bal.num_cameras].reshape(-1, 9)[~held]).max() > 0)


def test_compare_runs_the_factor_graphs_gauss_newton_row_on_bundle_adjustment():
    from course.app import compare
    from course.problems.bal.dataset import load_bal

    bal = load_bal("bal-synthetic:4:40")
    rows = compare.run_bal(bal, methods=["gauss-newton"], backends=["ours", "ours-autodiff"])
    chi2 = {row.backend: row.final_chi2 for row in rows}
    assert chi2["ours-autodiff"] == pytest.approx(chi2["ours"], rel=1e-6)


def test_with_the_gauge_left_free_the_factor_graphs_gauss_newton_row_says_so():
    from course.app import compare
    from course.problems.bal.dataset import load_bal

    rows = compare.run_bal(load_bal("bal-synthetic:4:40"), methods=["gauss-newton"], backends=["ours-autodiff"],
                           fix_gauge=False)
    assert "a direction is free" in rows[0].not_run and "The gauge is free: the 44 variable(s) joined to 'c0' have " \
        "no fixed variable and no prior" in rows[0].not_run


@needs("gtsam")  # dubrovnik-3-7 ships with its wheel
def test_a_singular_reduced_system_with_the_gauge_held_does_not_blame_the_gauge():
    """dubrovnik-3-7: 19 observations (38 residuals) for 48 unknowns, the gauge held as chapter 4 holds it:
    the free directions are the scene's, and the error does not say that nothing is fixed."""
    from course.core.errors import SingularSystemError
    from course.problems.bal.dataset import load_bal
    from course.problems.bal.factor_graph import as_factor_graph

    problem = FactorGraphProblem(as_factor_graph(load_bal("dubrovnik-3-7"), fix_gauge=True))
    with pytest.raises(SingularSystemError, match="a direction is free") as caught:
        problem.solve(problem.linearize(problem.x0))
    assert "no fixed variable" not in str(caught.value) and "The gauge is free" not in str(caught.value)


def _robust_graph():
    """The 2D graph with its range-bearing factors under each robust kernel, and one outlier each."""
    g = _graph_2d()
    for k, kernel in enumerate(("huber", "cauchy", "tukey")):
        g.add(RANGE_BEARING, [f"x{k}", f"l{k}"], [4.0, 1.0], noise=noise.sigmas([0.05, 0.01]).robust(kernel, 2.0))
    return g


@needs("jax", "gtsam")
def test_robust_noise_models_solve_to_one_minimum_on_ours_jax_and_gtsam_custom():
    _same_minimum(_robust_graph())


def test_a_singular_system_after_diverging_steps_says_so_and_the_references_row_is_explained():
    from course.app import compare
    from course.core.errors import SingularSystemError
    from course.core.trace import IterationRecord, RunResult

    seen = []
    with pytest.raises(SingularSystemError, match=r"^S is singular \(after 2 steps, chi2 7.2e\+09, 4.4e\+18: "
                                                  r"the steps diverged first\)$"):
        with compare.steps_before_failure(seen.append) as watch:
            watch(IterationRecord(1, 7.2e9))
            watch(IterationRecord(2, 1e20, accepted=False))  # a rejected step is not where the solve went
            watch(IterationRecord(3, 4.4e18))
            raise SingularSystemError("S is singular")
    assert len(seen) == 3
    with pytest.raises(SingularSystemError, match=r"^at the start$"):  # no step taken: the message as it was
        with compare.steps_before_failure():
            raise SingularSystemError("at the start")
    with pytest.raises(SingularSystemError, match=r"\(after 2 steps, chi2 9, 3\)$"):  # no divergence claimed
        with compare.steps_before_failure() as watch:
            watch(IterationRecord(1, 9.0))
            watch(IterationRecord(2, 3.0))
            raise SingularSystemError("x")
    # the reference's own failed row is printed under the table, as every back end's is
    runs = [RunResult.skipped("ours", "gauss-newton", "failed: schur_solve: S is not positive definite"),
            RunResult.skipped("ours-autodiff", "gauss-newton", "failed: bal: block of 'p3' not positive definite")]
    assert compare.advice(runs, "bal", "solutions") == [
        "ours gauss-newton failed: schur_solve: S is not positive definite",
        "ours-autodiff gauss-newton failed: bal: block of 'p3' not positive definite"]


@pytest.mark.slow
def test_ladybug_49s_gauss_newton_rows_fail_alike_after_the_same_diverging_steps(data_folder):
    """``compare ladybug-49 --backends ours,ours-autodiff --methods gauss-newton``: the factor graph's row runs
    (no free gauge stops it) and ends as chapter 4's: two undamped steps that raise chi2 by 12 orders,
    then a system that is not positive definite, both said under the table."""
    from course.app import compare
    from course.problems.bal.dataset import load_bal

    rows = compare.run_bal(load_bal("ladybug-49"), methods=["gauss-newton"], backends=["ours", "ours-autodiff"])
    for row in rows:
        # the second chi2 is where two diverging steps led: its digits are rounding's (4.3e+18 or 4.4e+18
        # as the Jacobians' sums are ordered), its size is not
        found = re.search(r"\(after 2 steps, chi2 7\.2e\+09, (\S+): the steps diverged first\)$", row.not_run)
        assert found and 1e18 <= float(found[1]) < 1e19, row.not_run
    assert "the gauge is free" not in rows[1].not_run


@pytest.mark.slow
def test_ladybug_49s_factor_graph_with_the_gauge_fixed_steps_as_chapter_4s_gauss_newton(data_folder):
    """Undamped Gauss-Newton goes uphill from ladybug-49's start in both (chi2 1.7e6 to 7.2e9, then 4e18;
    chapter 4's row fails too, at its third solve): the factor graph's first step is chapter 4's, no
    longer stopped by a free gauge."""
    from course.problems.bal.dataset import load_bal
    from course.problems.bal.factor_graph import as_factor_graph
    from course.problems.bal.problem import BundleAdjustmentProblem

    bal = load_bal("ladybug-49")
    chi2 = {}
    for name, problem in (("ch4", BundleAdjustmentProblem(bal, fix_gauge=True)),
                          ("fg", FactorGraphProblem(as_factor_graph(bal, fix_gauge=True)))):
        x = problem.x0
        chi2[name] = problem.chi2(problem.retract(x, problem.solve(problem.linearize(x), None)))
    assert chi2["fg"] == pytest.approx(chi2["ch4"], rel=1e-6)
