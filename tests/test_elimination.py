"""The reference's elimination of one variable at the edges: the split holds for every x and s, one factor
of n_x rows leaves no new factor, no separator, a scalar, a zero block, ill-scaled blocks, and clear errors
for a variable its factors do not determine and for shapes that disagree."""

import numpy as np
import pytest

from course.core.errors import ShapeError, SingularSystemError
from course.core.impl import load

eliminate_variable = load("solutions").module("elimination").eliminate_variable


def split_holds(A_x, A_s, b, seed=0, rtol=1e-10):
    """||A_x x + A_s s - b||^2 - (||R x + S s - d||^2 + ||A_new s - b_new||^2) is the same c >= 0 at random x, s."""
    R, S, d, A_new, b_new = eliminate_variable(A_x, A_s, b)
    rng = np.random.default_rng(seed)
    gaps = []
    for _ in range(5):
        x, s = rng.normal(size=A_x.shape[1]), rng.normal(size=A_s.shape[1])
        whole = np.sum((A_x @ x + A_s @ s - b) ** 2)
        parts = np.sum((R @ x + S @ s - d) ** 2) + np.sum((A_new @ s - b_new) ** 2)
        gaps.append(whole - parts)
    scale = np.sum(b**2) + np.sum(np.hstack([A_x, A_s]) ** 2)
    assert np.ptp(gaps) <= rtol * scale and min(gaps) >= -rtol * scale
    assert np.allclose(R, np.triu(R)) and np.all(np.abs(np.diag(R)) > 0)
    return R, S, d, A_new, b_new


def random_rows(m, n_x, n_s, seed=1):
    rng = np.random.default_rng(seed)
    return rng.normal(size=(m, n_x)), rng.normal(size=(m, n_s)), rng.normal(size=m)


def test_the_split_holds_and_matches_the_information():
    A_x, A_s, b = random_rows(9, 3, 4)
    R, S, d, A_new, b_new = split_holds(A_x, A_s, b)
    np.testing.assert_allclose(R.T @ R, A_x.T @ A_x, atol=1e-12)
    np.testing.assert_allclose(R.T @ S, A_x.T @ A_s, atol=1e-12)
    np.testing.assert_allclose(R.T @ d, A_x.T @ b, atol=1e-12)
    P = np.eye(9) - A_x @ np.linalg.solve(A_x.T @ A_x, A_x.T)  # the projection off A_x's columns
    np.testing.assert_allclose(A_new.T @ A_new, A_s.T @ P @ A_s, atol=1e-12)
    np.testing.assert_allclose(A_new.T @ b_new, A_s.T @ P @ b, atol=1e-12)


def test_one_factor_of_n_x_rows_leaves_no_new_factor():
    A_x, A_s, b = random_rows(3, 3, 3)
    *_, A_new, b_new = split_holds(A_x, A_s, b)
    assert A_new.shape[1] == 3 and len(b_new) == len(A_new)
    np.testing.assert_allclose(A_new.T @ A_new, 0.0, atol=1e-12)


def test_no_separator():
    A_x, A_s, b = random_rows(5, 2, 0)
    R, S, d, A_new, b_new = split_holds(A_x, A_s, b)
    assert S.shape == (2, 0) and A_new.shape[1] == 0 and len(b_new) == len(A_new)
    np.testing.assert_allclose(np.linalg.solve(R, d), np.linalg.lstsq(A_x, b, rcond=None)[0], atol=1e-12)


def test_a_scalar_variable():
    A_x, A_s, b = np.array([[2.0], [-1.0], [1.0]]), np.array([[0.0, 0.0], [1.0, 0.0], [0.0, -1.0]]), np.ones(3)
    R, S, d, A_new, b_new = split_holds(A_x, A_s, b)
    assert R.shape == (1, 1) and abs(R[0, 0]) == pytest.approx(np.sqrt(6.0))


def test_fewer_rows_than_unknowns_and_a_zero_block():
    """5 rows for n_x + n_s = 8: the new factor has rank 2; the separator's last column is touched by no
    row (a zero block), so nothing is said about it."""
    A_x, A_s, b = random_rows(5, 3, 6)
    A_s[:, -1] = 0.0
    *_, A_new, b_new = split_holds(A_x, A_s, b)
    info = A_new.T @ A_new
    assert np.linalg.matrix_rank(info, tol=1e-9) == 2 and np.all(info[-1] == 0.0) and np.all(A_new[:, -1] == 0.0)


def test_ill_scaled_blocks_keep_their_small_entries():
    A_x, A_s, b = random_rows(8, 3, 5)
    A_x[:3] *= 1e3
    A_s[:, 3:] *= 1e-3
    R, S, d, A_new, b_new = split_holds(A_x, A_s, b)
    P = np.eye(8) - A_x @ np.linalg.solve(A_x.T @ A_x, A_x.T)
    want = A_s.T @ P @ A_s
    np.testing.assert_allclose(A_new.T @ A_new, want, rtol=1e-8, atol=1e-12 * np.abs(want).max())
    np.testing.assert_allclose((A_new.T @ A_new)[3:, 3:], want[3:, 3:], rtol=1e-6)


def test_many_rows_a_direction_no_row_measures_and_ill_scaled_separator():
    """20 rows for n_x + n_s = 9, but the separator's last two unknowns only move together with x (their
    columns are x's first column, scaled by 1e3 and 1e-3): the new factor is singular, and its small scale
    is kept, not taken for rounding."""
    A_x, A_s, b = random_rows(20, 3, 6)
    A_s[:, 4] = 1e3 * A_x[:, 0]
    A_s[:, 5] = 1e-3 * A_x[:, 0]
    A_s[:, 2] *= 1e-3
    *_, A_new, b_new = split_holds(A_x, A_s, b)
    P = np.eye(20) - A_x @ np.linalg.solve(A_x.T @ A_x, A_x.T)
    want = A_s.T @ P @ A_s
    assert len(A_new) == 4 and np.linalg.matrix_rank(A_new.T @ A_new, tol=1e-9 * np.abs(want).max()) == 4
    np.testing.assert_allclose(A_new.T @ A_new, want, atol=1e-9 * np.abs(want).max())
    np.testing.assert_allclose((A_new.T @ A_new)[2, 2], want[2, 2], rtol=1e-6)
    np.testing.assert_allclose(A_new.T @ b_new, A_s.T @ P @ b, atol=1e-9 * np.abs(A_s.T @ P @ b).max())


def test_a_variable_its_factors_do_not_determine_is_a_clear_error():
    A_x, A_s, b = random_rows(4, 3, 2)
    A_x[:, 2] = A_x[:, 0] + A_x[:, 1]
    with pytest.raises(SingularSystemError, match="rank 2 < n_x = 3"):
        eliminate_variable(A_x, A_s, b)
    with pytest.raises(SingularSystemError, match="rank 2 < n_x = 3"):  # fewer rows than unknowns
        eliminate_variable(*random_rows(2, 3, 2))


@pytest.mark.parametrize("args, name", [
    ((np.ones((3, 2)), np.ones((4, 1)), np.ones(3)), "A_s"),
    ((np.ones((3, 2)), np.ones((3, 1)), np.ones(4)), "A_x"),
    ((np.ones((3, 2)), np.ones((3, 1)), np.ones((3, 1))), "b"),
    ((np.ones(3), np.ones((3, 1)), np.ones(3)), "A_x"),
])
def test_shapes_that_disagree_name_the_argument(args, name):
    with pytest.raises(ShapeError, match=name):
        eliminate_variable(*args)
