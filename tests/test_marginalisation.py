"""Marginalisation: the Schur-complement prior is the information form of the Gaussian
marginal, its residual form reproduces it, and the reduced system gives the full system's
step on the kept variables."""

import numpy as np
import pytest

from autograder.checks.marginalisation import three_rooms, window
from solutions.marginalisation import marginalise, prior_residual, prior_update

TOL = 1e-9


def test_the_prior_is_the_inverse_of_the_marginal_covariance():
    H, b, remove, _ = window(None, "definite")
    keep = np.setdiff1d(np.arange(len(H)), remove)
    H_prior, _ = marginalise(H, b, remove)
    marginal = np.linalg.inv(H)[np.ix_(keep, keep)]
    np.testing.assert_allclose(H_prior, np.linalg.inv(marginal), rtol=1e-8, atol=TOL * np.abs(H).max())


def test_the_three_rooms_leave_a_direct_factor_between_x1_and_x3():
    H, b, _ = three_rooms()
    assert H[0, 2] == 0.0
    H_prior, b_prior = marginalise(H, b, [1])
    assert H_prior.shape == (2, 2) and abs(H_prior[0, 1]) > 1.0  # fill-in
    np.testing.assert_allclose(H_prior, np.linalg.inv(np.linalg.inv(H)[np.ix_([0, 2], [0, 2])]), rtol=1e-10)


@pytest.mark.parametrize("kind", ["definite", "seen once", "weak"])
def test_the_reduced_system_gives_the_same_kept_step(kind):
    H, b, remove, _ = window(None, kind)
    keep = np.setdiff1d(np.arange(len(H)), remove)
    H_prior, b_prior = marginalise(H, b, remove)
    full = -np.linalg.lstsq(H, b, rcond=None)[0] if kind != "weak" else None
    reduced = -np.linalg.solve(H_prior, b_prior)
    if full is not None:
        np.testing.assert_allclose(reduced, full[keep], rtol=1e-7, atol=1e-9 * np.abs(full).max())
    # the removed variables' optimal step given the kept one makes the full gradient vanish on the kept rows
    dx = np.zeros(len(H))
    dx[keep] = reduced
    rest = np.linalg.lstsq(H[np.ix_(remove, remove)], -(b[remove] + H[np.ix_(remove, keep)] @ reduced),
                           rcond=1e-13)[0]
    dx[remove] = rest
    assert np.abs((H @ dx + b)[keep]).max() <= 1e-6 * np.abs(b).max()


def test_the_residual_form_reproduces_the_prior_and_moves_to_first_order():
    H, b, remove, _ = window(None, "seen once")
    H_prior, b_prior = marginalise(H, b, remove)
    J, e = prior_residual(H_prior, b_prior)
    scale = np.abs(H_prior).max()
    np.testing.assert_allclose(J.T @ J, H_prior, rtol=0, atol=1e-10 * scale)
    np.testing.assert_allclose(J.T @ e, b_prior, rtol=0, atol=1e-10 * np.abs(b_prior).max())
    x_lin = np.linspace(0, 1, len(H_prior))
    dx = np.full(len(H_prior), 1e-3)
    e1 = prior_update(J, e, x_lin, x_lin + dx)
    # 1/2 |e + J dx|^2 - 1/2 |e|^2 = b_prior^T dx + 1/2 dx^T H_prior dx
    np.testing.assert_allclose(0.5 * (e1 @ e1 - e @ e), b_prior @ dx + 0.5 * dx @ H_prior @ dx, rtol=1e-8)


def test_a_rank_deficient_prior_gives_fewer_rows():
    A = np.random.default_rng(0).normal(size=(3, 5))
    J, e = prior_residual(A.T @ A, A.T @ np.ones(3))
    assert J.shape == (3, 5) and e.shape == (3,)


@pytest.mark.parametrize("remove, match", [([0, 0], "duplicate"), ([7], "outside"), ([0.5], "integer"),
                                            ([[0]], "1-D"), (list(range(3)), "nothing would be kept")])
def test_bad_indices_are_named(remove, match):
    H, b, _ = three_rooms()
    with pytest.raises(ValueError, match=match):
        marginalise(H, b, remove)


def test_bad_shapes_are_named():
    with pytest.raises(ValueError, match="H must be a square"):
        marginalise(np.zeros((2, 3)), np.zeros(2), [0])
    with pytest.raises(ValueError, match="b must have shape"):
        marginalise(np.eye(3), np.zeros(2), [0])
    with pytest.raises(ValueError, match="eps"):
        marginalise(np.eye(3), np.zeros(3), [0], eps=-1.0)
