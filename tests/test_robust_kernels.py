"""Robust kernels: the reference exercise module (Huber, Cauchy, Tukey and the robust weighting),
the robust loss in bundle adjustment (course.solver.robust, course.problems.bal.problem) and the outlier
experiment (course.problems.bal.outliers)."""

import re

import numpy as np
import pytest

from course.core.errors import SingularSystemError
from course.problems.bal import outliers
from course.problems.bal.dataset import synthetic
from course.problems.bal.problem import BundleAdjustmentProblem
from course.solver import robust
from solutions import bundle_adjustment as ba
from solutions import robust_kernels as rk

KERNELS = {"huber": rk.huber, "cauchy": rk.cauchy, "tukey": rk.tukey}
SCALES = (0.5, 1.0, 2.5)


def _ratios():
    """s / a^2 in every region, away from the thresholds (where rho' or rho'' has a kink)."""
    return np.array([1e-4, 0.05, 0.15, 0.3, 0.6, 0.9, 1.1, 1.7, 4.0, 30.0])


# ------------------------------------------------------------------ the kernels


@pytest.mark.parametrize("name", sorted(KERNELS))
@pytest.mark.parametrize("a", SCALES)
def test_derivatives_match_central_differences(name, a):
    kernel = KERNELS[name]
    s = _ratios() * a * a
    rho, d_rho, dd_rho = kernel(s, a)
    h = 1e-6 * s
    plus, minus = kernel(s + h, a), kernel(s - h, a)
    np.testing.assert_allclose(d_rho, (plus[0] - minus[0]) / (2 * h), rtol=1e-6, atol=1e-9)
    np.testing.assert_allclose(dd_rho, (plus[1] - minus[1]) / (2 * h), rtol=1e-5, atol=1e-9 / (a * a))


@pytest.mark.parametrize("name", sorted(KERNELS))
@pytest.mark.parametrize("a", SCALES)
def test_rho_is_s_near_zero(name, a):
    kernel = KERNELS[name]
    rho, d_rho, dd_rho = kernel(np.array([0.0]), a)
    assert rho[0] == 0.0 and d_rho[0] == 1.0
    s = np.array([1e-10, 1e-8]) * a * a
    rho, _, _ = kernel(s, a)
    np.testing.assert_allclose(rho, s, rtol=1e-7, atol=0.0)  # rho = s + O(s^2 / a^2)


def test_second_derivatives_at_zero():
    a = 2.5
    for kernel, expected in ((rk.huber, 0.0), (rk.cauchy, -1.0 / a**2), (rk.tukey, -2.0 / a**2)):
        assert kernel(np.array([0.0]), a)[2][0] == pytest.approx(expected, rel=1e-15, abs=0.0)


@pytest.mark.parametrize("name", sorted(KERNELS))
@pytest.mark.parametrize("a", SCALES)
def test_continuity_at_the_threshold(name, a):
    """rho and rho' are continuous at s = a^2 (Tukey's rho'' too: u = 0 there); Huber's rho'' jumps."""
    kernel = KERNELS[name]
    a2 = a * a
    below, at, above = (kernel(np.array([v]), a) for v in (a2 * (1 - 1e-9), a2, a2 * (1 + 1e-9)))
    for k, tol in ((0, 1e-8 * a2), (1, 1e-8)):
        assert abs(below[k][0] - at[k][0]) <= tol and abs(above[k][0] - at[k][0]) <= tol, (name, k)
    if name == "tukey":
        assert at[2][0] == 0.0 and abs(below[2][0]) <= 1e-8 / a2
    if name == "huber":
        assert at[2][0] == 0.0 and above[2][0] == pytest.approx(-0.5 / a2, rel=1e-8)


def test_values_at_known_points():
    a = 2.0
    s = np.array([0.0, 2.0, 4.0, 9.0, 16.0])
    np.testing.assert_allclose(rk.huber(s, a)[0], [0.0, 2.0, 4.0, 2 * 2 * 3 - 4, 2 * 2 * 4 - 4], rtol=1e-15)
    np.testing.assert_allclose(rk.cauchy(s, a)[0], 4 * np.log(1 + s / 4), rtol=1e-15)
    np.testing.assert_allclose(rk.tukey(s, a)[0], [0.0, 4 / 3 * (1 - 0.5**3), 4 / 3, 4 / 3, 4 / 3], rtol=1e-15)
    np.testing.assert_array_equal(rk.tukey(s, a)[1][2:], 0.0)
    np.testing.assert_array_equal(rk.tukey(s, a)[2][2:], 0.0)
    assert not np.signbit(rk.tukey(s, a)[2][2:]).any()  # 0, not -0


@pytest.mark.parametrize("name", sorted(KERNELS))
def test_kernel_errors_name_the_field(name):
    kernel = KERNELS[name]
    with pytest.raises(ValueError, match=r"s\[1\] = -0.5 is negative"):
        kernel(np.array([1.0, -0.5]), 1.0)
    with pytest.raises(ValueError, match=r"s\[0\] = nan is not a finite number"):
        kernel(np.array([np.nan]), 1.0)
    with pytest.raises(ValueError, match=r"s must be an array \(K,\)"):
        kernel(np.ones((2, 2)), 1.0)
    for scale in (0.0, -1.0, np.inf, "a"):
        with pytest.raises(ValueError, match=f"robust_kernels.{name}: scale must be"):
            kernel(np.ones(2), scale)


# ------------------------------------------------------------------ the weighting


def _residuals(rng, K, n):
    L = rng.normal(size=(K, n, n))
    return rng.normal(0.0, 2.0, (K, n)), np.matmul(L, L.transpose(0, 2, 1)) + 0.5 * np.eye(n)


def _weighting_inputs(name, x, seed=0, n=3):
    """(e, Omega, s, d_rho, dd_rho) with s_k / a_k^2 = x_k for the kernel ``name``."""
    rng = np.random.default_rng(seed)
    e, Omega = _residuals(rng, len(x), n)
    e[x == 0] = 0.0  # s = 0, any scale
    s = np.einsum("ki,kij,kj->k", e, Omega, e)
    a = np.sqrt(s / np.where(x > 0, x, 1.0)) + (x == 0) * 1.5
    d_rho, dd_rho = np.zeros(len(x)), np.zeros(len(x))
    for k in range(len(x)):  # one scale per residual
        _, d1, d2 = KERNELS[name](s[k:k + 1], a[k])
        d_rho[k], dd_rho[k] = d1[0], d2[0]
    return e, Omega, s, a, d_rho, dd_rho


def _half_hessian_in_e(name, e, Omega, a, step=1e-5):
    """Central differences of the gradient of rho(e^T Omega e)/2 in e, rho' Omega e (exact, from the kernel)."""
    n = len(e)
    H = np.zeros((n, n))
    for j in range(n):
        d = np.zeros(n)
        d[j] = step
        grads = []
        for sign in (1.0, -1.0):
            x = e + sign * d
            _, d1, _ = KERNELS[name](np.array([x @ Omega @ x]), a)
            grads.append(d1[0] * Omega @ x)
        H[:, j] = (grads[0] - grads[1]) / (2 * step)
    return H


@pytest.mark.parametrize("name, x", [("cauchy", 0.3), ("cauchy", 0.9), ("tukey", 0.1), ("huber", 0.5)])
def test_corrected_form_is_half_the_hessian_of_the_kernel(name, x):
    e, Omega, _, a, d_rho, dd_rho = _weighting_inputs(name, np.array([x]))
    W = rk.robust_information(e, Omega, d_rho, dd_rho)[0]
    np.testing.assert_allclose(W, _half_hessian_in_e(name, e[0], Omega[0], a[0]), rtol=1e-6,
                               atol=1e-7 * np.abs(W).max())
    assert np.linalg.eigvalsh(W).min() > 0


@pytest.mark.parametrize("name, x", [("cauchy", 1.0), ("cauchy", 3.0), ("huber", 1.5), ("huber", 20.0),
                                     ("tukey", 0.25), ("tukey", 0.9), ("tukey", 2.0)])
def test_first_order_where_the_corrected_form_is_not_definite(name, x):
    e, Omega, s, _, d_rho, dd_rho = _weighting_inputs(name, np.array([x]))
    assert d_rho[0] + 2 * dd_rho[0] * s[0] <= 1e-12 * max(d_rho[0], 1e-300)  # the corrected form is not definite
    W = rk.robust_information(e, Omega, d_rho, dd_rho)
    np.testing.assert_allclose(W, d_rho[:, None, None] * Omega, rtol=1e-15, atol=0.0)


def test_weighting_is_positive_semi_definite_everywhere_and_broadcasts_omega():
    x = np.array([0.0, 0.05, 0.3, 0.9, 1.0, 1.5, 10.0])
    for name in KERNELS:
        e, Omega, _, _, d_rho, dd_rho = _weighting_inputs(name, x, seed=3)
        W = rk.robust_information(e, Omega, d_rho, dd_rho)
        assert W.shape == (len(x), 3, 3)
        np.testing.assert_allclose(W, W.transpose(0, 2, 1), rtol=0, atol=1e-12 * np.abs(W).max())
        assert np.linalg.eigvalsh(W).min() >= -1e-12 * np.abs(W).max()
        shared = rk.robust_information(e, Omega[1], d_rho, dd_rho)
        each = rk.robust_information(e, np.broadcast_to(Omega[1], Omega.shape), d_rho, dd_rho)
        np.testing.assert_array_equal(shared, each)


def test_weighting_errors_name_the_field():
    e, Omega = np.ones((4, 2)), np.eye(2)
    ones = np.ones(4)
    with pytest.raises(ValueError, match=r"e must be an array \(K, n\)"):
        rk.robust_information(np.ones(4), Omega, ones, ones)
    with pytest.raises(ValueError, match=r"Omega must have shape \(2, 2\) or \(4, 2, 2\)"):
        rk.robust_information(e, np.eye(3), ones, ones)
    with pytest.raises(ValueError, match=r"dd_rho must have shape \(4,\)"):
        rk.robust_information(e, Omega, ones, np.ones(3))


# ------------------------------------------------------------------ the robust loss in bundle adjustment


def _linearized(seed=3):
    p = synthetic(5, 30, seed=seed, outliers=0.2)
    r, J_cam, J_point = ba.reprojection_residuals_and_jacobians(p.cameras, p.points, p.camera_index, p.point_index,
                                                                p.observations)
    return p, r, J_cam, J_point


@pytest.mark.parametrize("loss", [("huber", 3.0), ("cauchy", 3.0), ("tukey", 8.0)])
def test_reweight_gives_the_weighted_normal_equations(loss):
    p, r, J_cam, J_point = _linearized()
    loss = robust.RobustLoss.of(loss)
    r_t, (Jc_t, Jp_t), chi2 = robust.reweight(rk, loss, r, (J_cam, J_point))
    s = np.sum(r * r, axis=1)
    rho, d_rho, dd_rho = getattr(rk, loss.kernel)(s, loss.scale)
    assert chi2 == pytest.approx(float(np.sum(rho)), rel=1e-14)
    W = rk.robust_information(r, np.eye(2), d_rho, dd_rho)
    for J, J_t in ((J_cam, Jc_t), (J_point, Jp_t)):
        want = np.einsum("kai,kab,kbj->kij", J, W, J)
        np.testing.assert_allclose(np.einsum("kai,kaj->kij", J_t, J_t), want, rtol=1e-9, atol=1e-9 * np.abs(want).max())
        grad = np.einsum("kai,ka->ki", J, d_rho[:, None] * r)
        np.testing.assert_allclose(np.einsum("kai,ka->ki", J_t, r_t), grad, rtol=1e-9, atol=1e-9 * np.abs(grad).max())
    if loss.kernel == "tukey":  # beyond the threshold: no weight, no gradient
        beyond = s > loss.scale**2
        assert beyond.any() and np.all(r_t[beyond] == 0) and np.all(Jc_t[beyond] == 0)


@pytest.mark.parametrize("loss", [("huber", 3.0), ("cauchy", 3.0), ("tukey", 8.0)])
def test_robust_problem_gradient_is_half_the_gradient_of_its_chi2(loss):
    """b = J^T rho' r is half the gradient of chi2 = sum rho(|r|^2): LM's gain ratio is consistent."""
    p = synthetic(4, 20, seed=5, outliers=0.2)
    problem = BundleAdjustmentProblem(p, loss=loss)
    lin = problem.linearize(problem.x0)
    assert lin.chi2 == pytest.approx(problem.chi2(problem.x0), rel=1e-13)
    rng = np.random.default_rng(2)
    for _ in range(3):
        v = rng.normal(size=len(problem.x0)) * np.abs(problem.x0).clip(1e-3, 1.0)
        t = 1e-6
        slope = (problem.chi2(problem.x0 + t * v) - problem.chi2(problem.x0 - t * v)) / (2 * t)
        assert slope == pytest.approx(2 * lin.b @ v, rel=1e-5)


def test_plain_problem_is_unchanged_and_losses_are_validated():
    p = synthetic(4, 20, seed=5)
    plain = BundleAdjustmentProblem(p)
    assert plain.loss is None and plain.chi2(plain.x0) == pytest.approx(2 * plain.cost(plain.x0))
    for bad, words in ((("welsch", 1.0), "unknown kernel 'welsch'"), (("huber", -1.0), "scale of huber"),
                       ("huber", "expected None or (kernel, scale)")):
        with pytest.raises(ValueError, match=re.escape(words)):
            BundleAdjustmentProblem(p, loss=bad)


def test_a_weight_that_is_not_definite_is_a_clear_error():
    class Indefinite:  # the corrected form everywhere, also where it is indefinite
        huber = staticmethod(rk.huber)

        @staticmethod
        def robust_information(e, Omega, d_rho, dd_rho):
            v = e @ Omega
            return d_rho[:, None, None] * Omega + 4.0 * dd_rho[:, None, None] * v[:, :, None] * v[:, None, :]

    _, r, J_cam, J_point = _linearized()
    with pytest.raises(SingularSystemError, match=r"not positive definite for residual \d+"):
        robust.reweight(Indefinite, robust.RobustLoss("huber", 1.0), r, (J_cam, J_point))


# ------------------------------------------------------------------ the outlier experiment


def test_outlier_pair_shares_start_and_inliers():
    dirty, clean, inlier = outliers.outlier_pair(6, 60, seed=2, outliers=0.1)
    np.testing.assert_array_equal(dirty.cameras, clean.cameras)
    np.testing.assert_array_equal(dirty.points, clean.points)
    np.testing.assert_array_equal(dirty.observations[inlier], clean.observations[inlier])
    moved = np.linalg.norm(dirty.observations[~inlier] - clean.observations[~inlier], axis=1)
    assert 0.05 < np.mean(~inlier) < 0.2 and moved.min() > 0


def test_a_robust_kernel_recovers_the_outlier_free_inliers_rms():
    """12 cameras, 300 points, 10% of the observations moved by N(0, 50^2) pixels: least squares
    leaves the inliers' RMS far above the outlier-free solution's; Cauchy brings it within 10%."""
    reference, (plain, cauchy) = outliers.run(12, 300, seed=1, losses=(None, ("cauchy", 2.45)))
    assert reference.stop_reason == "cost_tolerance" and cauchy.stop_reason == "cost_tolerance"
    assert 0.6 < reference.rms < 0.9  # 1 pixel of noise, less the parameters' share
    assert abs(cauchy.ratio - 1.0) <= 0.1
    assert plain.ratio > 1.1 and plain.ratio > 5.0  # not within 10%: many times the outlier-free RMS
    text = outliers.table(reference, [plain, cauchy])
    assert "cauchy(a=2.45)" in text and "least squares" in text


@pytest.mark.parametrize("loss", [("huber", 3.0), ("cauchy", 3.0), ("tukey", 8.0)])
def test_the_written_out_2x2_factor_is_lapacks(loss, monkeypatch):
    """Pixel blocks take reweight's 2x2 path; the general path (LAPACK's Cholesky) gives the same to rounding."""
    _, r, J_cam, J_point = _linearized()
    loss = robust.RobustLoss.of(loss)
    fast = robust.reweight(rk, loss, r, (J_cam, J_point))
    monkeypatch.setattr(robust, "_reweight_2", lambda *args: None)
    general = robust.reweight(rk, loss, r, (J_cam, J_point))
    np.testing.assert_allclose(fast[0], general[0], rtol=1e-12, atol=1e-14 * np.abs(general[0]).max())
    for a, b in zip(fast[1], general[1]):
        np.testing.assert_allclose(a, b, rtol=1e-12, atol=1e-14 * np.abs(b).max())
    assert fast[2] == general[2]
