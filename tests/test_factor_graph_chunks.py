"""The factor graph's linearisation in chunks: each chunk of the Jets' output whitened as it comes gives
the H, b and chi2 of one chunk, and those of the dense sums of the whitened ``factor_jacobians``; a
non-finite Jacobian in a later chunk is named by its factor in the group, its type and its keys."""

import numpy as np
import pytest

from course.core.errors import NonFiniteError
from course.factorgraph import (
    BETWEEN_SE2,
    BETWEEN_SE3,
    PRIOR_SE3,
    SE2,
    SE3,
    FactorGraph,
    FactorGraphProblem,
    FactorType,
    se3_value,
)
from course.factorgraph import problem as problem_module
from course.factorgraph.noise import information
from course.geometry.so3 import exp_many

N = 130  # poses: the between factors take four chunks of CHUNK_MIN (40 here) when CHUNK_BYTES is 1
HELD = ["x0", "x60"]  # fixed: held in the first and the second chunk
PARTLY = ("x100", [1, 4])  # dofs held of a partly fixed pose
#: its slot 0 is x0 in every factor: fixed in whole chunks (a constant there, its blocks 0)
SEEN_FROM_X0 = FactorType("between from x0", (SE3, SE3), 6, BETWEEN_SE3.residual)


def _graph(diagonal=False):
    rng = np.random.default_rng(3)
    graph = FactorGraph("chunks")
    for k in range(N):
        graph.add_variable(f"x{k}", SE3, se3_value(rng.normal(size=3), exp_many(rng.normal(size=(1, 3)))[0]))
    for key in HELD:
        graph.fix(key)
    graph.fix(*PARTLY)
    A = rng.normal(size=(N - 1, 6, 6))
    info = A @ A.transpose(0, 2, 1) + 6.0 * np.eye(6)  # a full information per factor, or its diagonal alone
    info = info * np.eye(6) if diagonal else info
    z = np.stack([se3_value(rng.normal(size=3), R) for R in exp_many(rng.normal(size=(N - 1, 3)))])
    graph.add_many(BETWEEN_SE3, [[f"x{k}", f"x{k + 1}"] for k in range(N - 1)], z, noise=information(info))
    graph.add_many(SEEN_FROM_X0, [["x0", f"x{k}"] for k in range(1, N, 2)], z[: len(range(1, N, 2))])
    graph.add_many(PRIOR_SE3, [["x1"], ["x90"]], z[:2])  # fewer factors than poses: their own plus-Jacobians
    return graph


def _linearize(monkeypatch, chunk_bytes, diagonal, x=None):
    monkeypatch.setattr(problem_module, "CHUNK_BYTES", chunk_bytes)
    monkeypatch.setattr(problem_module, "CHUNK_MIN", 40)
    problem = FactorGraphProblem(_graph(diagonal), eliminate=None)
    x = problem.retract(problem.x0, 0.01 * np.sin(np.arange(6 * N))) if x is None else x
    return problem, x, problem.linearize(x)


@pytest.mark.parametrize("diagonal", [False, True], ids=["full information", "diagonal information"])
def test_chunks_whitened_as_they_come_are_one_chunk_and_the_dense_sums(monkeypatch, diagonal):
    problem, x, chunked = _linearize(monkeypatch, 1, diagonal)
    assert problem_module.chunk_size(BETWEEN_SE3) == problem_module.CHUNK_MIN < N - 1
    _, _, whole = _linearize(monkeypatch, 1 << 40, diagonal, x)
    assert problem_module.chunk_size(BETWEEN_SE3) > N
    assert np.array_equal(chunked.H.toarray(), whole.H.toarray())
    assert np.array_equal(chunked.b, whole.b) and chunked.chi2 == whole.chi2

    # the dense sums of the whitened factor_jacobians, the held dofs' columns 0 and their diagonal 1
    n = 6 * N
    H, b, chi2 = np.zeros((n, n)), np.zeros(n), 0.0
    held = [6 * problem.graph.keys.index(key) + d for key in HELD for d in range(6)]
    held += [6 * problem.graph.keys.index(PARTLY[0]) + d for d in PARTLY[1]]
    for group, g in enumerate(problem.graph.groups.values()):
        keys, _, info = g.arrays()
        r, J = problem.factor_jacobians(x, group)
        for a in range(keys.shape[1]):  # a fixed variable is not differentiated: its blocks 0
            fixed = np.isin(keys[:, a], [problem.graph.keys.index(key) for key in HELD])
            assert not np.any(J[a][fixed]) and np.all(np.any(J[a][~fixed], axis=(1, 2)))
        L_T = np.broadcast_to(np.eye(6), (len(r), 6, 6)) if info is None else \
            np.linalg.cholesky(info).transpose(0, 2, 1)
        r = np.einsum("mab,mb->ma", L_T, r)
        rows = np.zeros((len(r), 6, n))  # each factor's whitened Jacobian row block (6, n)
        for a in range(keys.shape[1]):
            for f, v in enumerate(keys[:, a]):
                rows[f, :, 6 * v:6 * v + 6] += L_T[f] @ J[a][f]
        rows[:, :, held] = 0.0
        H += np.einsum("mai,maj->ij", rows, rows)
        b += np.einsum("mai,ma->i", rows, r)
        chi2 += float(np.vdot(r, r))
    H[held, held] = 1.0
    scale = np.abs(H).max()
    assert np.abs(np.triu(H) - whole.H.toarray()).max() <= 1e-12 * scale
    assert np.abs(b - whole.b).max() <= 1e-12 * np.abs(b).max()
    assert whole.chi2 == pytest.approx(chi2, rel=1e-12) and problem.chi2(x) == pytest.approx(chi2, rel=1e-12)


def test_a_non_finite_jacobian_in_a_later_chunk_is_named_by_its_factor_in_the_group(monkeypatch):
    monkeypatch.setattr(problem_module, "CHUNK_BYTES", 1)
    monkeypatch.setattr(problem_module, "CHUNK_MIN", 100)
    graph = FactorGraph("chain")
    for k in range(300):
        graph.add_variable(f"x{k}", SE2, [k, 0.0, 0.1 * k])
    graph.fix("x0")
    graph.add_many(BETWEEN_SE2, [[f"x{k}", f"x{k + 1}"] for k in range(299)], np.tile([1.0, 0.0, 0.1], (299, 1)))
    # exp(-1/u^2) is 0 at u = 0, its derivative exp(-inf) * inf: nan at x250 alone (the third chunk)
    flat = FactorType("flat_x", (SE2,), 1, lambda z, x: np.exp(-1.0 / (x[..., :1] - 250.0) ** 2) - z)
    graph.add_many(flat, [[f"x{k}"] for k in range(1, 300)], np.zeros((299, 1)))
    problem = FactorGraphProblem(graph)
    message = (r"autodiff_factor\.tangent_jacobians returned a non-finite J\[0\] for factor 249 of type 'flat_x' "
               r"on 'x250' \(chain\): J\[0\]\[249, 0, 0\] = nan")
    with pytest.raises(NonFiniteError, match=message):
        with np.errstate(all="ignore"):
            problem.linearize(problem.x0)
