"""course.solver.schur_reduction: the compiled pass and scipy's BSR product give the same R as a
dense sum over the pairs, on structures with the odd cases a BAL file can hold."""

import numpy as np
import pytest

from course.core import jit, peers
from course.solver import schur_reduction as sr
from tests.conftest import kernel_path, needs


def _structure(seed=3, cameras=7, points=40):
    """Observations with a camera that sees nothing, a point seen twice by one camera, a point
    seen once, and observations in no particular order."""
    rng = np.random.default_rng(seed)
    ci, pi = [], []
    for p in range(points):
        seen = rng.choice(cameras - 1, size=rng.integers(1, 5), replace=False)  # camera C-1 sees nothing
        ci += list(seen)
        pi += [p] * len(seen)
    ci += [2, 2]  # point 0 seen twice by camera 2
    pi += [0, 0]
    order = rng.permutation(len(ci))
    ci, pi = np.array(ci)[order], np.array(pi)[order]
    W = rng.normal(size=(len(ci), 9, 3))
    A = rng.normal(size=(points, 3, 3))
    V_inv = np.matmul(A, A.transpose(0, 2, 1)) + 3 * np.eye(3)
    return W, V_inv, ci, pi, cameras


def _dense(W, V_inv, ci, pi, C):
    """The definition, pair by pair."""
    R = np.zeros((9 * C, 9 * C))
    for k in range(len(ci)):
        for m in np.flatnonzero(pi == pi[k]):
            R[9 * ci[k]:9 * ci[k] + 9, 9 * ci[m]:9 * ci[m] + 9] += W[k] @ V_inv[pi[k]] @ W[m].T
    return R


@pytest.fixture(params=["compiled", "bsr"])
def path(request, monkeypatch):
    kernel_path(request.param == "compiled", monkeypatch)
    return request.param


def test_the_reduction_is_the_sum_over_pairs(path):
    W, V_inv, ci, pi, C = _structure()
    R = sr.schur_reduction(W, V_inv, ci, pi, C)
    assert R.shape == (9 * C, 9 * C) and R.blocksize == (9, 9)
    dense = _dense(W, V_inv, ci, pi, C)
    np.testing.assert_allclose(R.toarray(), dense, rtol=1e-12, atol=1e-10)
    np.testing.assert_allclose(R.toarray(), R.toarray().T, rtol=1e-12, atol=1e-10)
    assert R.has_sorted_indices


def test_one_camera(path):
    W, V_inv, _, pi, _ = _structure(seed=5)
    ci = np.zeros_like(pi)
    np.testing.assert_allclose(sr.schur_reduction(W, V_inv, ci, pi, 1).toarray(), _dense(W, V_inv, ci, pi, 1),
                               rtol=1e-12, atol=1e-10)


@needs("numba")
def test_the_paths_agree_on_ladybug(monkeypatch, data_folder):
    from course.problems.bal.dataset import load_bal
    from course.problems.bal.problem import BundleAdjustmentProblem

    problem = BundleAdjustmentProblem(load_bal("ladybug-49"))
    lin = problem.linearize(problem.x0)
    V_inv = np.linalg.inv(lin.V + np.eye(3))
    args = (lin.W, V_inv, lin.camera_index, lin.point_index, problem.num_cameras)
    monkeypatch.delenv(jit.NO_JIT, raising=False)
    compiled = sr.schur_reduction(*args).toarray()
    monkeypatch.setenv(jit.NO_JIT, "1")
    product = sr.schur_reduction(*args).toarray()
    np.testing.assert_allclose(compiled, product, rtol=1e-12, atol=1e-12 * np.abs(product).max())


def test_the_autograder_children_do_not_compile():
    from autograder import sandbox

    assert sandbox.child_env()[jit.NO_JIT] == "1"
    assert sandbox.isolated_env("/nowhere")[jit.NO_JIT] == "1"


def test_without_numba_the_product_is_used_and_said(monkeypatch, capsys):
    monkeypatch.delenv(jit.NO_JIT, raising=False)
    monkeypatch.setattr(peers, "installed", lambda name: name != "numba")
    monkeypatch.setattr(peers, "_announced", set())
    monkeypatch.setattr(sr, "_pattern_of", lambda *args: pytest.fail("compiled without numba"))
    W, V_inv, ci, pi, C = _structure()
    np.testing.assert_allclose(sr.schur_reduction(W, V_inv, ci, pi, C).toarray(), _dense(W, V_inv, ci, pi, C),
                               rtol=1e-12, atol=1e-10)
    assert "numba is not installed here" in capsys.readouterr().err


def test_a_kept_pattern_is_used_for_the_same_observations_only(path):
    W, V_inv, ci, pi, C = _structure(seed=11)
    other = np.roll(ci, 1)  # the same sizes, other pairs
    for cams in (ci, other, ci):
        np.testing.assert_allclose(sr.schur_reduction(W, V_inv, cams, pi, C).toarray(),
                                   _dense(W, V_inv, cams, pi, C), rtol=1e-12, atol=1e-10)


@pytest.mark.parametrize("slip", ["camera out of range", "point out of range", "W too short"])
def test_bad_input_is_a_clear_error_not_a_crash(path, slip):
    W, V_inv, ci, pi, C = _structure()
    if slip == "camera out of range":
        ci = ci.copy()
        ci[3] = C
    elif slip == "point out of range":
        pi = pi.copy()
        pi[0] = -1
    else:
        W = W[:-1]
    with pytest.raises(ValueError, match="schur_reduction"):
        sr.schur_reduction(W, V_inv, ci, pi, C)


def test_long_camera_rows(path):
    """A row of more than SHORT_ROW blocks (a point every camera sees) is listed in column order too."""
    C = sr.SHORT_ROW + 16
    rng = np.random.default_rng(5)
    ci = np.concatenate([rng.permutation(C), rng.integers(0, C, size=40)])
    pi = np.concatenate([np.zeros(C, dtype=int), rng.integers(1, 20, size=40)])
    W = rng.normal(size=(len(ci), 9, 3))
    V_inv = np.broadcast_to(np.eye(3), (20, 3, 3)) * 0.5
    R = sr.schur_reduction(W, V_inv, ci, pi, C)
    assert R.has_sorted_indices and np.diff(R.indptr).max() == C
    np.testing.assert_allclose(R.toarray(), _dense(W, V_inv, ci, pi, C), rtol=1e-12, atol=1e-10)


def test_the_right_side_term_is_the_sum_over_observations_in_the_same_pass(path):
    """With ``g_point``: ``sum_k W_k V_p^-1 g_p`` into block c_k, beside the same R (a camera that sees
    nothing gets 0, a point seen twice by one camera counts twice)."""
    W, V_inv, ci, pi, C = _structure()
    g = np.random.default_rng(4).normal(size=(len(V_inv), 3))
    R, term = sr.schur_reduction(W, V_inv, ci, pi, C, g_point=g)
    want = np.zeros((C, 9))
    for k in range(len(ci)):
        want[ci[k]] += W[k] @ V_inv[pi[k]] @ g[pi[k]]
    assert term.shape == (C, 9) and not term[C - 1].any()
    np.testing.assert_allclose(term, want, rtol=1e-12, atol=1e-10)
    np.testing.assert_array_equal(R.toarray(), sr.schur_reduction(W, V_inv, ci, pi, C).toarray())
    with pytest.raises(ValueError, match="g_point"):
        sr.schur_reduction(W, V_inv, ci, pi, C, g_point=g[:-1])
