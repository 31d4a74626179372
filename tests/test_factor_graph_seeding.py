"""The retraction's derivative as the Jets' seed (Ceres' ``Manifold::PlusJacobian``): each kind's
``plus_jacobian`` against differences of its retraction, and the factor graph's Jacobians seeded with
it against the same Jets seeded through the whole retraction (the path before it), and against central
differences, on intel, a slice of sphere2500, a slice of ladybug-49 and a mixed graph whose fixed
variables are not differentiated."""

import numpy as np
import pytest

from course.core import impl as impl_loader
from course.factorgraph import (
    BETWEEN_SE3,
    PRIOR_SE3,
    SE2,
    SE3,
    SO3,
    FactorGraph,
    FactorGraphProblem,
    FactorType,
    Vector,
    jetmath,
    se3_parts,
    se3_value,
)
from course.factorgraph.numeric import central_differences
from course.factorgraph.variables import BAL_CAMERA
from course.geometry.so3 import exp_many

Jet = impl_loader.load("solutions").module("jets").Jet


def through_the_retraction(residual, retractions, dims, xs):
    """The Jacobians as they were taken before the plus-Jacobians: every step seeded as a Jet at 0 in
    its own directions and moved through the whole retraction on Jets."""
    k = int(sum(dims))
    offsets = np.concatenate([[0], np.cumsum(dims)]).astype(int)
    moved = [retract(x, Jet.seed(np.zeros((len(x), d)), int(o), k))
             for retract, d, o, x in zip(retractions, dims, offsets, xs)]
    r = residual(*moved)
    return r.value, [r.grad[..., offsets[a]:offsets[a + 1]] for a in range(len(dims))]


def _blockwise(got, want):
    """The largest difference per factor relative to that factor's largest entry (M, m, d) -> float."""
    scale = np.maximum(np.abs(want).max(axis=(1, 2)), 1e-300)
    return float((np.abs(got - want).max(axis=(1, 2)) / scale).max())


@pytest.mark.parametrize("kind", [SE3, SO3, SE2, Vector(2), BAL_CAMERA], ids=lambda k: k.name)
def test_each_kinds_plus_jacobian_is_its_retractions_derivative_at_zero(kind):
    rng = np.random.default_rng(5)
    M = 4
    R = exp_many(rng.normal(0.0, 1.5, (M, 3)))
    x = {"SE3": se3_value(rng.normal(size=(M, 3)), R), "SO3": R}.get(kind.name, rng.normal(size=(M,) + kind.shape))
    P = kind.plus_jacobian(x)
    assert P.shape == (M, int(np.prod(kind.shape)), kind.dim)
    h = 1e-6
    for j in range(kind.dim):
        step = np.zeros((M, kind.dim))
        step[:, j] = h
        diff = (np.reshape(kind.retract(x, step), (M, -1)) - np.reshape(kind.retract(x, -step), (M, -1))) / (2 * h)
        np.testing.assert_allclose(P[:, :, j], diff, rtol=0, atol=1e-9)
    moved = kind.retract(x, Jet.seed(np.zeros((M, kind.dim)), 0, kind.dim))  # the Jets through the retraction
    np.testing.assert_allclose(P, np.reshape(moved.grad, (M, -1, kind.dim)), rtol=0, atol=1e-15)


def _compare(problem, rows=None, numeric_tol=1e-6):
    """Every group's Jacobians of ``problem`` (factors ``rows`` of each, all if None) against the Jets
    seeded through the retraction and against central differences; fixed variables' blocks 0."""
    fixed = sorted(problem.graph.fixed)
    x = problem.x0
    compared = 0
    for group, factor_group in enumerate(problem.graph.groups.values()):
        ftype = factor_group.type
        keys, z, _ = factor_group.arrays()
        part = slice(None) if rows is None else rows
        r, J = problem.factor_jacobians(x, group)
        r, J = r[part], [block[part] for block in J]
        xs = [problem.values(x, keys[part, a]) for a in range(keys.shape[1])]

        def residual(*points, z=z[part], ftype=ftype):
            return ftype.residual(z, *points)

        retractions = [kind.retract for kind in ftype.kinds]
        dims = [kind.dim for kind in ftype.kinds]
        r_old, J_old = through_the_retraction(residual, retractions, dims, xs)
        _, J_num = central_differences(residual, retractions, dims, xs)
        np.testing.assert_allclose(r, r_old, rtol=0, atol=1e-12 * max(1.0, np.abs(r_old).max()))
        held = np.isin(keys[part], fixed)
        for a, (got, old, num) in enumerate(zip(J, J_old, J_num)):
            free = ~held[:, a]
            assert not got[~free].any(), (ftype.name, a)  # a fixed variable is not differentiated
            if free.any():
                assert _blockwise(got[free], old[free]) <= 1e-13, (ftype.name, a)
                assert _blockwise(got[free], num[free]) <= numeric_tol, (ftype.name, a)
                compared += int(free.sum())
    assert compared
    return compared


def test_intel_the_plus_jacobian_seed_gives_the_retractions_jacobians(data_folder):
    from course.problems.posegraph import dataset
    from course.problems.posegraph.factor_graph import as_factor_graph

    problem = FactorGraphProblem(as_factor_graph(dataset.load_dataset("intel")))
    assert problem.graph.fixed
    _compare(problem)


def test_sphere2500_a_slice_the_plus_jacobian_seed_gives_the_retractions_jacobians(data_folder):
    from course.problems.posegraph3d import dataset
    from course.problems.posegraph3d.factor_graph import as_factor_graph

    problem = FactorGraphProblem(as_factor_graph(dataset.load_dataset("sphere2500")))
    assert _compare(problem, rows=np.r_[0:300, 4600:4949]) > 600  # the first edges (from the fixed pose) and loops


def test_ladybug_49_a_slice_the_plus_jacobian_seed_gives_the_retractions_jacobians(data_folder):
    from course.problems.bal.dataset import load_bal
    from course.problems.bal.factor_graph import as_factor_graph

    problem = FactorGraphProblem(as_factor_graph(load_bal("ladybug-49")))
    assert _compare(problem, rows=slice(0, 1500), numeric_tol=1e-5) == 3000


# ---------------------------------------------------------------- a mixed graph with fixed variables

def _seen(z, pose, point):
    """A point (Vector3) in the frame of an SE(3) pose, against ``z`` (3,)."""
    t, R = se3_parts(pose)
    return jetmath.matvec(jetmath.transpose(R), point - t) - z


def _attitude(z, R):
    """``Log(R_z^T R)`` of a rotation (SO3) against ``z`` (9,), a rotation stored row by row."""
    Rz = z.reshape(z.shape[:-1] + (3, 3))
    return jetmath.so3_log(np.swapaxes(Rz, -1, -2) @ R)


def _mounted(z, pose, mount, point):
    """A point seen by a sensor mounted on a pose with rotation ``mount`` (SO3): ``(R R_m)^T (l - t) - z``."""
    t, R = se3_parts(pose)
    return jetmath.matvec(jetmath.transpose(R @ mount), point - t) - z


SEEN = FactorType("seen", (SE3, Vector(3)), 3, _seen)
SEEN_FROM_THE_ANCHOR = FactorType("seen from the anchor", (SE3, Vector(3)), 3, _seen)
ATTITUDE = FactorType("attitude", (SO3,), 3, _attitude)
MOUNTED = FactorType("mounted", (SE3, SO3, Vector(3)), 3, _mounted)
ANCHOR_PRIOR = FactorType("anchor prior", (SE3,), 6, PRIOR_SE3.residual)


def mixed_graph():
    """Four SE(3) poses (x0 fixed), a mounting rotation (SO3), three points (l2 fixed): between factors
    (one back to x0), priors (one on x0), a type of prior on x0 alone (every variable fixed), points seen
    from poses, some from x0 alone in a type of their own (its slot 0 fixed in every factor), a mounted
    sensor (three kinds in one factor)."""
    rng = np.random.default_rng(11)
    graph = FactorGraph("mixed")
    truth = [se3_value(rng.normal(size=3), exp_many(rng.normal(0.0, 1.0, (1, 3)))[0]) for _ in range(4)]
    for k, pose in enumerate(truth):
        t, R = se3_parts(pose)
        graph.add_variable(f"x{k}", SE3, se3_value(t + 0.1 * rng.normal(size=3), R @ exp_many(
            0.1 * rng.normal(size=(1, 3)))[0]))
    graph.add_variable("m", SO3, exp_many(rng.normal(size=(1, 3)))[0])
    for k in range(3):
        graph.add_variable(f"l{k}", Vector(3), rng.normal(size=3))
    graph.fix("x0")
    graph.fix("l2")
    for i, j in ((0, 1), (1, 2), (2, 3), (3, 0)):
        graph.add(BETWEEN_SE3, [f"x{i}", f"x{j}"], se3_value(rng.normal(size=3), exp_many(rng.normal(size=(1, 3)))[0]))
    for k in (0, 2):
        graph.add(PRIOR_SE3, [f"x{k}"], truth[k])
    graph.add(ANCHOR_PRIOR, ["x0"], truth[1])  # on fixed variables alone: a constant of the error
    for k, j in ((1, 0), (2, 1), (3, 2), (0, 1)):
        graph.add(SEEN, [f"x{k}", f"l{j}"], rng.normal(size=3))
    for j in (0, 1, 2):
        graph.add(SEEN_FROM_THE_ANCHOR, ["x0", f"l{j}"], rng.normal(size=3))
    graph.add(ATTITUDE, ["m"], exp_many(rng.normal(size=(1, 3)))[0].ravel())
    for k, j in ((0, 0), (2, 2), (3, 1)):
        graph.add(MOUNTED, [f"x{k}", "m", f"l{j}"], rng.normal(size=3))
    return graph


def test_a_mixed_graph_with_fixed_variables(monkeypatch):
    graph = mixed_graph()
    problem = FactorGraphProblem(graph, eliminate=None)
    module = problem.impl.module("autodiff_factor")
    calls = []
    original = module.tangent_jacobians

    def spy(residual, plus_jacobians, xs, jet):
        calls.append([np.shape(P)[-1] for P in plus_jacobians])
        return original(residual, plus_jacobians, xs, jet)

    monkeypatch.setattr(module, "tangent_jacobians", spy)
    assert _compare(problem) >= 20
    # one call per slot that some factor of its group leaves free: the anchor's slot of "seen from the
    # anchor" is a constant, and the type of prior on x0 alone (every variable fixed) the residual alone
    fixed = sorted(graph.fixed)
    free_slots = sum(int((~np.isin(group.arrays()[0], fixed)).any(axis=0).sum()) for group in graph.groups.values())
    assert free_slots == 10 and len(calls) == free_slots and all(len(dims) == 1 for dims in calls)
    lin = problem.linearize(problem.x0)
    assert np.isfinite(lin.chi2) and lin.b[:6].tolist() == [0.0] * 6  # x0 held still
