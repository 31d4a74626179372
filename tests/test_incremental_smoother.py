"""The incremental smoother (course.incremental) against batch solves of the same problems."""

import numpy as np
import pytest

from course.factorgraph import (
    BETWEEN_SE2,
    BETWEEN_SE3,
    PRIOR_SE2,
    PRIOR_SE3,
    RANGE_BEARING,
    SE2,
    SE3,
    FactorGraph,
    FactorGraphProblem,
    Vector,
    prior,
)
from course.incremental import IncrementalSmoother
from course.incremental.online import OnlineSequence, compose
from course.problems.posegraph.dataset import manhattan
from course.problems.posegraph.factor_graph import as_factor_graph
from course.solver.minimizer import minimize
from course.solver.options import SolverOptions


def batch_graph(smoother, values=None) -> FactorGraph:
    """The smoother's factors as one chapter-7 graph, its variables at ``values`` (default the linearisation
    point)."""
    g = FactorGraph("batch")
    for v, key in enumerate(smoother.keys):
        g.add_variable(key, smoother.kinds[v], smoother.theta[v] if values is None else values[key])
    store = smoother.factors
    for typed in store.types.values():
        for row, i in enumerate(typed.ids):
            W = typed.W[row]
            g.add(typed.type, [smoother.keys[v] for v in store.keys[i]], typed.z[row],
                  information=None if W is None else W.T @ W)
    return g


def batch_step(smoother) -> np.ndarray:
    """The Gauss-Newton step of the whole linearised system at the smoother's linearisation point, by the
    chapter-7 problem's own assembly and sparse solve."""
    problem = FactorGraphProblem(batch_graph(smoother), eliminate=None)
    return problem.solve(problem.linearize(problem.x0))


def batch_minimum(smoother) -> float:
    problem = FactorGraphProblem(batch_graph(smoother, smoother.estimate()), eliminate=None)
    result = minimize(problem, "lm-type3", options=SolverOptions(max_iterations=200))
    return float(result.final_chi2)


def feed(graph: FactorGraph, smoother, check=None):
    """Feed ``graph`` one variable per step; ``check(smoother, k)`` after each update."""
    sequence = OnlineSequence(graph)
    previous = None
    for k in range(len(sequence)):
        factors, values = sequence.step(k, previous)
        smoother.update(factors, values)
        previous = smoother.estimate_of(k)
        if check:
            check(smoother, k)
    return smoother


def assert_step_is_batch(smoother, k=None):
    ours = np.concatenate(smoother.delta)
    np.testing.assert_allclose(ours, batch_step(smoother), rtol=0, atol=1e-9, err_msg=f"after update {k}")


def iterate(smoother, times=30):
    """The last update iterated (every variable relinearised) until chi2 stops falling; the final chi2."""
    smoother.relinearize_threshold = smoother.wildfire_threshold = 0.0
    last = smoother.chi2()
    for _ in range(times):
        smoother.update()
        chi2 = smoother.chi2()
        if abs(last - chi2) <= 1e-13 * last:
            break
        last = chi2
    return chi2


def path_with_loops_2d(n=30):
    return as_factor_graph(manhattan(n, seed=3))


def path_with_loops_3d(n=12, seed=0) -> FactorGraph:
    """A 3D path of ``n`` poses turning and climbing, odometry and closures to the pose 4 back and to pose 0."""
    rng = np.random.default_rng(seed)
    truth = [np.concatenate([np.zeros(3), np.eye(3).ravel()])]
    step = np.concatenate([[1.0, 0.2, 0.1], _rotation([0.05, 0.1, 0.3]).ravel()])
    for _ in range(n - 1):
        truth.append(compose(SE3, truth[-1], step))
    g = FactorGraph("3d path")
    for k, value in enumerate(truth):
        noisy = value.copy()
        noisy[:3] += 0.1 * rng.normal(size=3)
        noisy[3:] = (value[3:].reshape(3, 3) @ _rotation(0.05 * rng.normal(size=3))).ravel()
        g.add_variable(f"x{k}", SE3, noisy if k else value)
    pairs = [(k - 1, k) for k in range(1, n)] + [(k - 4, k) for k in range(4, n, 3)] + [(0, n - 1)]
    for i, j in pairs:
        ti, Ri = truth[i][:3], truth[i][3:].reshape(3, 3)
        tj, Rj = truth[j][:3], truth[j][3:].reshape(3, 3)
        z = np.concatenate([Ri.T @ (tj - ti) + 0.01 * rng.normal(size=3),
                            (Ri.T @ Rj @ _rotation(0.01 * rng.normal(size=3))).ravel()])
        g.add(BETWEEN_SE3, [f"x{i}", f"x{j}"], z, information=np.diag([100.0] * 3 + [400.0] * 3))
    return g


def _rotation(w):
    w = np.asarray(w, dtype=float)
    theta = np.linalg.norm(w)
    K = np.array([[0, -w[2], w[1]], [w[2], 0, -w[0]], [-w[1], w[0], 0]])
    if theta < 1e-12:
        return np.eye(3) + K
    return np.eye(3) + np.sin(theta) / theta * K + (1 - np.cos(theta)) / theta**2 * K @ K


def test_each_update_solves_the_linearised_system_exactly():
    feed(path_with_loops_2d(), IncrementalSmoother(wildfire_threshold=0.0), assert_step_is_batch)


@pytest.mark.parametrize("variant", ["elim_qr_route", "elim_cholesky_then_eigh"])
def test_a_correct_but_different_elimination_keeps_the_updates_exact(variant, tmp_path):
    """A group of cliques is eliminated in one call and each clique's conditional read from its rows: an
    orthogonal factorisation (row signs free, rounding where the structure has zeros) gives the same steps."""
    from student_variants import ALTERNATIVES_ELIMINATION, build

    assert variant in ALTERNATIVES_ELIMINATION
    impl = build(variant, tmp_path)
    feed(path_with_loops_2d(), IncrementalSmoother(impl=str(impl), wildfire_threshold=0.0), assert_step_is_batch)


def counting(smoother, counts: list):
    """``smoother`` with its ``update`` appending the number of variables it relinearised to ``counts``."""
    update = smoother.update

    def counted(*args):
        result = update(*args)
        counts.append(result.relinearized)
        return result

    smoother.update = counted
    return smoother


def test_gtsams_rule_relinearises_the_separators_cliques_and_stays_exact():
    totals = {}
    for neighbours in (True, False):
        smoother = IncrementalSmoother(wildfire_threshold=0.0, relinearize_neighbours=neighbours)
        counts: list = []
        feed(path_with_loops_2d(), counting(smoother, counts), assert_step_is_batch)
        totals[neighbours] = sum(counts)
    assert totals[True] > totals[False] > 0  # the rule adds variables on this graph's loop closures


def test_the_separators_cliques_are_found_alike_for_few_and_many_variables():
    """GTSAM's rule adds the frontals of every clique whose separator holds a relinearised variable: found by
    walking down from each variable's home when they are few, by one pass over the separators when many."""
    smoother = feed(path_with_loops_2d(), IncrementalSmoother())
    tree = smoother.tree
    for relin in ([0], [3, 7], list(range(len(smoother.keys)))):
        want = set(relin)
        for F, S in zip(tree.frontals, tree.separators):
            if set(S) & set(relin):
                want.update(F)
        assert smoother._with_neighbours(relin) == sorted(want)


def test_the_default_thresholds_stay_near_the_batch_step():
    def close(smoother, k):
        ours = np.concatenate(smoother.delta)
        assert np.abs(ours - batch_step(smoother)).max() < 0.01, f"after update {k}"
    feed(path_with_loops_2d(), IncrementalSmoother(), close)


def test_relinearising_everything_and_iterating_reaches_the_batch_minimum():
    smoother = feed(path_with_loops_2d(16), IncrementalSmoother(relinearize_threshold=0.0, wildfire_threshold=0.0))
    chi2 = iterate(smoother)
    assert chi2 == pytest.approx(batch_minimum(smoother), rel=1e-6)


def test_a_3d_path():
    smoother = feed(path_with_loops_3d(), IncrementalSmoother(wildfire_threshold=0.0), assert_step_is_batch)
    assert iterate(smoother) == pytest.approx(batch_minimum(smoother), rel=1e-6)


def mixed_graph(poses=8, landmarks=4, seed=1) -> FactorGraph:
    """SE(2) poses along a line and 2D landmarks beside it, odometry and range-bearing factors."""
    rng = np.random.default_rng(seed)
    g = FactorGraph("poses and landmarks")
    truth = np.column_stack([np.arange(poses, dtype=float), np.zeros(poses), np.zeros(poses)])
    marks = np.column_stack([np.linspace(0, poses, landmarks), np.full(landmarks, 2.0)])
    for k in range(poses):
        g.add_variable(f"x{k}", SE2, truth[k] + [0.1 * k, 0.05 * k, 0.02 * k])
    for j in range(landmarks):
        g.add_variable(f"l{j}", Vector(2), marks[j] + rng.normal(size=2) * 0.3)
    for k in range(1, poses):
        g.add(BETWEEN_SE2, [f"x{k - 1}", f"x{k}"], [1.0, 0.0, 0.0] + rng.normal(size=3) * 0.01,
              information=np.diag([100.0, 100.0, 400.0]))
    for k in range(poses):
        for j in range(landmarks):
            d = marks[j] - truth[k, :2]
            if np.hypot(*d) < 3.5:
                z = [np.hypot(*d) + rng.normal() * 0.01, np.arctan2(d[1], d[0]) + rng.normal() * 0.01]
                g.add(RANGE_BEARING, [f"x{k}", f"l{j}"], z, information=np.diag([100.0, 400.0]))
    return g


def test_poses_and_landmarks_of_two_kinds():
    """Each step: a pose, its odometry, and a landmark the first time it is seen, with every measurement."""
    g = mixed_graph()
    smoother = IncrementalSmoother(wildfire_threshold=0.0)
    groups = {name: group.arrays() for name, group in g.groups.items()}
    for k in range(8):
        step = FactorGraph(f"step {k}")
        values = {}
        rows = []
        for name, (keys, z, info) in groups.items():
            for r, row in enumerate(keys):
                if g.keys[row[0]] == f"x{k}" or name == "between_se2" and g.keys[row[1]] == f"x{k}":
                    rows.append((g.groups[name].type, [g.keys[v] for v in row], z[r], info[r]))
        used = {key for _, keys, _, _ in rows for key in keys} | {f"x{k}"}
        for key in used:
            step.add_variable(key, g.kinds[g.index[key]], g.values[g.index[key]])
            if key not in smoother.index:
                values[key] = g.values[g.index[key]]
        if k == 0:
            step.add(PRIOR_SE2, ["x0"], g.values[0], information=np.eye(3) * 1e4)
        for ftype, keys, z, info in rows:
            step.add(ftype, keys, z, information=info)
        smoother.update(step, values)
        assert_step_is_batch(smoother, k)
    assert any(key.startswith("l") for key in smoother.keys)
    assert iterate(smoother) == pytest.approx(batch_minimum(smoother), rel=1e-6)


def one_pose_graph(key="x0", value=(0.0, 0.0, 0.0)):
    g = FactorGraph("prior")
    g.add_variable(key, SE2, value)
    g.add(PRIOR_SE2, [key], value, information=np.eye(3))
    return g


def test_the_first_update_and_a_variable_with_a_prior_alone():
    smoother = IncrementalSmoother(wildfire_threshold=0.0)
    result = smoother.update(one_pose_graph(value=(1.0, 2.0, 0.5)), {"x0": [0.0, 0.0, 0.0]})
    assert result.reeliminated == 1 and result.cliques == 1
    np.testing.assert_allclose(smoother.delta[0], [1.0, 2.0, 0.5], atol=1e-12)
    smoother.update(one_pose_graph("y", (3.0, 0.0, 0.0)), {"y": [0.0, 0.0, 0.0]})  # a second component, alone
    assert len(smoother.tree) == 2
    assert_step_is_batch(smoother)


def test_two_disconnected_components():
    a, b = as_factor_graph(manhattan(10, seed=1)), as_factor_graph(manhattan(10, seed=2))
    smoother = IncrementalSmoother(wildfire_threshold=0.0)
    for graph, letter in ((a, "a"), (b, "b")):
        sequence = OnlineSequence(graph)
        for k in range(len(sequence)):
            factors, values = sequence.step(k)
            renamed = FactorGraph(f"{letter} step {k}")
            for key, kind, value in zip(factors.keys, factors.kinds, factors.values):
                renamed.add_variable(letter + key, kind, value)
            for group in factors.groups.values():
                keys, z, info = group.arrays()
                for r, row in enumerate(keys):
                    renamed.add(group.type, [letter + factors.keys[v] for v in row], z[r],
                                information=None if info is None else info[r])
            smoother.update(renamed, {letter + key: value for key, value in values.items()})
    assert_step_is_batch(smoother)
    roots = np.flatnonzero(smoother.tree.parents == -1)
    assert len(roots) == 2


def test_a_loop_closure_to_the_first_pose():
    g = FactorGraph("ring")
    n = 8
    for k in range(n):
        angle = 2 * np.pi * k / n
        g.add_variable(f"x{k}", SE2, [np.cos(angle) + 0.05 * k, np.sin(angle), angle + np.pi / 2])
    z = [2 * np.sin(np.pi / n), 0.0, 2 * np.pi / n]
    for k in range(1, n):
        g.add(BETWEEN_SE2, [f"x{k - 1}", f"x{k}"], z, information=np.eye(3) * 100)
    g.add(BETWEEN_SE2, [f"x{n - 1}", "x0"], z, information=np.eye(3) * 100)
    smoother = feed(g, IncrementalSmoother(wildfire_threshold=0.0), assert_step_is_batch)
    assert iterate(smoother) == pytest.approx(batch_minimum(smoother), rel=1e-6, abs=1e-12)


def test_a_key_added_twice_is_an_error():
    smoother = IncrementalSmoother()
    smoother.update(one_pose_graph(), {"x0": [0.0, 0.0, 0.0]})
    with pytest.raises(ValueError, match="'x0' is already in the smoother"):
        smoother.update(one_pose_graph(), {"x0": [0.0, 0.0, 0.0]})


def test_a_factor_on_a_key_with_no_value_is_an_error_naming_it():
    smoother = IncrementalSmoother()
    smoother.update(one_pose_graph(), {"x0": [0.0, 0.0, 0.0]})
    g = FactorGraph("odometry")
    g.add_variable("x0", SE2, [0.0, 0.0, 0.0])
    g.add_variable("x1", SE2, [0.0, 0.0, 0.0])
    g.add(BETWEEN_SE2, ["x0", "x1"], [1.0, 0.0, 0.0])
    with pytest.raises(ValueError, match="'x1', which has no value"):
        smoother.update(g, {})
    assert len(smoother.keys) == 1  # nothing was added


def test_fixed_variables_and_robust_losses_are_refused():
    g = one_pose_graph()
    g.fix("x0")
    with pytest.raises(ValueError, match="prior"):
        IncrementalSmoother().update(g, {"x0": [0.0, 0.0, 0.0]})


def test_marginals_are_the_inverse_of_the_information():
    smoother = feed(path_with_loops_2d(), IncrementalSmoother(wildfire_threshold=0.0))
    problem = FactorGraphProblem(batch_graph(smoother), eliminate=None)
    H = problem.linearize(problem.x0).H.toarray()
    H = H + np.triu(H, 1).T
    covariance = np.linalg.inv(H)
    keys = ["x3", "x17"]
    joint = smoother.marginals(keys)
    index = np.concatenate([np.arange(3 * smoother.index[k], 3 * smoother.index[k] + 3) for k in keys])
    np.testing.assert_allclose(joint, covariance[np.ix_(index, index)], rtol=1e-8, atol=1e-12)
    np.testing.assert_allclose(smoother.marginal("x5"), covariance[15:18, 15:18], rtol=1e-8, atol=1e-12)


def test_an_unwritten_piece_names_its_todo(tmp_path):
    smoother = IncrementalSmoother(impl="exercises")
    with pytest.raises(NotImplementedError, match="TODO"):
        smoother.update(one_pose_graph(), {"x0": [0.0, 0.0, 0.0]})


def test_a_3d_prior_and_between_chain_of_one_step():
    g = FactorGraph("3d")
    value = np.concatenate([[1.0, 2.0, 3.0], np.eye(3).ravel()])
    g.add_variable("x0", SE3, value)
    g.add(PRIOR_SE3, ["x0"], value, information=np.eye(6))
    smoother = IncrementalSmoother(wildfire_threshold=0.0)
    smoother.update(g, {"x0": value})
    assert prior(SE3) is PRIOR_SE3
    np.testing.assert_allclose(smoother.estimate()["x0"], value, atol=1e-12)


def test_the_wildfire_in_fronts_is_the_wildfire_on_the_whole_tree(monkeypatch):
    """Every update's fronts give the steps and the recomputed cliques of one call on the whole tree (the steps
    up to rounding: the first front solves each group of cliques eliminated together at once)."""
    import course.incremental.smoother as smoother_module
    from course.core import impl

    whole = impl.load("solutions").module("incremental_update").wildfire_update
    in_fronts = smoother_module.wildfire_in_fronts
    compared = []

    def both(wildfire_update, tree, delta, replaced, threshold, dims, groups):
        steps, recomputed = in_fronts(wildfire_update, tree, delta, replaced, threshold, dims, groups)
        expected, expected_recomputed = whole(tree.frontals, tree.separators, tree.parents, tree.conditionals, delta,
                                              replaced, threshold)
        assert recomputed == expected_recomputed
        for ours, theirs in zip(steps, expected):
            np.testing.assert_allclose(ours, theirs, rtol=1e-12, atol=1e-12)
        compared.append(len(recomputed) < len(tree))
        return steps, recomputed

    monkeypatch.setattr(smoother_module, "wildfire_in_fronts", both)
    feed(as_factor_graph(manhattan(40, seed=5)), IncrementalSmoother(wildfire_threshold=0.01))
    assert any(compared)  # some update stopped before the leaves
