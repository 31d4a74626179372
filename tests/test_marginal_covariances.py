"""The marginal covariances from the square-root information: the reference against the dense inverse on
small factor graphs, at the edges of its contract (one variable, scalar variables, a stored 0, CSR or CSC,
keys out of order, a long chain) and its errors naming the argument and the entry."""

import time

import numpy as np
import pytest
import scipy.sparse as sp

from autograder.checks.marginal_covariances import factor_graph, problem, stored
from autograder.tasks.marginal_covariances import matrix
from course.core.errors import SingularSystemError
from solutions.marginal_covariances import joint_marginal, marginal_covariances


def _graph(sizes, loops=3, seed=0, fmt="csc"):
    R, rows, coupled = factor_graph(np.random.default_rng(seed), sizes, loops)
    return matrix(len(R), fmt, *stored(R, rows, fmt)), np.linalg.inv(R.T @ R), rows, coupled


def _starts(sizes):
    return np.concatenate([[0], np.cumsum(sizes)])


@pytest.mark.parametrize("fmt", ["csr", "csc"])
def test_every_marginal_is_the_block_of_the_dense_inverse(fmt):
    sizes = [2, 1, 3, 6, 1, 2, 3, 1, 6, 2]
    R, Sigma, _, _ = _graph(sizes, fmt=fmt)
    blocks = marginal_covariances(R, sizes)
    s = _starts(sizes)
    assert len(blocks) == len(sizes)
    for v, block in enumerate(blocks):
        want = Sigma[s[v]:s[v + 1], s[v]:s[v + 1]]
        assert block.shape == (sizes[v], sizes[v])
        np.testing.assert_allclose(block, want, rtol=1e-10, atol=1e-12 * np.abs(want).max())


def test_the_root_is_r_nn_inverse_times_its_transpose():
    sizes = [3, 2, 6]
    R, _, _, _ = _graph(sizes, loops=1)
    Rnn = R.toarray()[-6:, -6:]
    want = np.linalg.inv(Rnn) @ np.linalg.inv(Rnn).T
    np.testing.assert_allclose(marginal_covariances(R, sizes)[-1], want, rtol=1e-10, atol=1e-12 * np.abs(want).max())


def test_one_variable_and_one_scalar():
    R = sp.csr_matrix(np.triu(np.arange(1.0, 10.0).reshape(3, 3)) + 2 * np.eye(3))
    (block,) = marginal_covariances(R, [3])
    np.testing.assert_allclose(block, np.linalg.inv(R.toarray().T @ R.toarray()), rtol=1e-12)
    (scalar,) = marginal_covariances(sp.csc_matrix([[-4.0]]), [1])
    assert scalar.shape == (1, 1) and scalar[0, 0] == pytest.approx(1.0 / 16.0)


def test_scalar_variables_and_a_stored_zero_in_the_fill():
    sizes = [1] * 12
    R, _, rows, coupled = _graph(sizes, loops=4, seed=2, fmt="csr")
    fill = [(i, j) for i, cols in enumerate(rows) for j in cols if j > i and not coupled[i, j]]
    assert fill
    dense = R.toarray()
    dense[fill[0]] = 0.0
    R = sp.csr_matrix((dense[np.repeat(np.arange(12), np.diff(R.indptr)), R.indices],
                       R.indices, R.indptr), shape=R.shape)
    assert R.nnz == sum(len(c) for c in rows) and np.any(R.data == 0.0)
    Sigma = np.linalg.inv(dense.T @ dense)
    got = np.array([b[0, 0] for b in marginal_covariances(R, sizes)])
    np.testing.assert_allclose(got, np.diag(Sigma), rtol=1e-10)
    dropped = R.copy()
    dropped.eliminate_zeros()  # the pattern is no longer closed: said, not guessed
    with pytest.raises(ValueError, match="not closed under elimination"):
        marginal_covariances(dropped, sizes)


def test_the_joint_marginal_keeps_the_order_of_the_keys_and_the_cross_covariances():
    sizes = [2, 1, 3, 6, 1, 2]
    R, Sigma, _, _ = _graph(sizes, loops=2, seed=4)
    s = _starts(sizes)
    for keys in ([4, 0, 2], [5], [1, 3, 0, 5, 2, 4]):
        cols = np.concatenate([np.arange(s[k], s[k + 1]) for k in keys])
        got = joint_marginal(R, sizes, keys)
        np.testing.assert_allclose(got, Sigma[np.ix_(cols, cols)], rtol=1e-10, atol=1e-12 * np.abs(Sigma).max())


def test_a_chain_of_20000_variables_without_a_dense_matrix():
    p = problem("chain")
    R = matrix(p["n"], p["fmt"], p["indptr"], p["indices"], p["data"])
    start = time.perf_counter()
    blocks = marginal_covariances(R, p["sizes"])
    assert time.perf_counter() - start < 5.0
    d, e = R.diagonal(), R.diagonal(1)
    # the last variable is 1 / R_nn^2; the one before it through the 2 x 2 corner
    assert blocks[-1][0, 0] == pytest.approx(1.0 / d[-1] ** 2, rel=1e-14)
    corner = np.array([[d[-2], e[-1]], [0.0, d[-1]]])
    assert blocks[-2][0, 0] == pytest.approx(np.linalg.inv(corner.T @ corner)[0, 0], rel=1e-12)
    J = joint_marginal(R, p["sizes"], [p["n"] - 1, p["n"] - 2])
    np.testing.assert_allclose(J, np.linalg.inv(corner.T @ corner)[::-1, ::-1], rtol=1e-12)


@pytest.mark.parametrize("R, sizes, pattern", [
    (sp.csr_matrix(np.ones((2, 3))), [2], "square"),
    (sp.csr_matrix(np.array([[1.0, 0.0], [0.5, 1.0]])), [1, 1], r"upper triangular: R\[1, 0\]"),
    (sp.csr_matrix(np.array([[1.0, 2.0], [0.0, 1.0]])), [1, 2], "sum to n = 2"),
    (sp.csr_matrix(np.array([[1.0, 2.0], [0.0, 1.0]])), [2, 0], r"sizes\[1\] = 0"),
    (np.eye(2), [1, 1], "scipy.sparse"),
    (sp.csr_matrix(np.array([[1.0, 0.0], [0.0, 1.0]])), [2], "variable 0's diagonal block whole"),
])
def test_bad_input_names_the_argument(R, sizes, pattern):
    with pytest.raises((ValueError, TypeError), match=pattern):
        marginal_covariances(R, sizes)
    with pytest.raises((ValueError, TypeError), match=pattern):
        joint_marginal(R, sizes, [0])


def test_a_zero_on_the_diagonal_names_its_row():
    # R[1, 1] stored with the value 0
    R = sp.csr_matrix((np.array([1.0, 2.0, 0.0, 1.0, 3.0]), np.array([0, 1, 1, 2, 2]), np.array([0, 2, 4, 5])),
                      shape=(3, 3))
    with pytest.raises(SingularSystemError, match=r"R\[1, 1\] \(row 1\)"):
        marginal_covariances(R, [1, 1, 1])
    with pytest.raises(SingularSystemError, match="row 1"):
        joint_marginal(R, [1, 1, 1], [2])


def test_a_stored_zero_below_the_diagonal_is_no_entry():
    dense = np.array([[2.0, 1.0], [0.0, 3.0]])
    R = sp.csr_matrix((np.array([2.0, 1.0, 0.0, 3.0]), np.array([0, 1, 0, 1]), np.array([0, 2, 4])), shape=(2, 2))
    (block,) = marginal_covariances(R, [2])
    np.testing.assert_allclose(block, np.linalg.inv(dense.T @ dense), rtol=1e-12)


@pytest.mark.parametrize("keys, pattern", [
    ([0, 3], r"keys\[1\] = 3 is not a variable index in \[0, 3\)"),
    ([-1], r"keys\[0\] = -1"),
    ([2, 0, 2], r"keys\[2\] = 2 repeats keys\[0\]"),
    ([], "non-empty"),
])
def test_bad_keys_name_the_entry(keys, pattern):
    R = sp.csr_matrix(np.triu(np.ones((3, 3))) + np.eye(3))
    with pytest.raises(ValueError, match=pattern):
        joint_marginal(R, [1, 1, 1], keys)
