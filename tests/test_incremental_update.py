"""The incremental update of a Bayes tree: the reference on a hand-built tree at the contract's edges, the
update of the checks' problems against a batch solve of the new problem, and the errors on bad input."""

import numpy as np
import pytest

from autograder.checks.incremental_update import problem
from course.core.errors import ShapeError, SingularSystemError
from solutions.incremental_update import affected_cliques, orphan_parents, relinearised_keys, wildfire_update

#: two trees: 0 = {4, 5} with children 1 = {3 | 4} (child 2 = {2 | 3, 4}) and 3 = {1 | 5} (child 4 = {0 | 1});
#: and 5 = {6} with child 6 = {7 | 6}
FRONTALS = [[4, 5], [3], [2], [1], [0], [6], [7]]
SEPARATORS = [[], [4], [3, 4], [5], [1], [], [6]]
PARENTS = np.array([-1, 0, 1, 0, 3, -1, 5])


def test_relinearised_keys_compare_the_largest_absolute_entry_strictly():
    delta = [np.full(6, 0.2), np.array([0.0, -0.5, 0.1]), np.array([0.25]), np.zeros(3), np.array([0.3])]
    assert relinearised_keys(delta, 0.25) == [1, 4]  # a norm would mark 0; 0.25 itself is not above
    assert relinearised_keys(delta, 0.0) == [0, 1, 2, 4]  # threshold 0: every step not exactly zero
    assert relinearised_keys([np.zeros(0), np.array([-(2.0 ** -40)])], 0.0) == [1]
    assert relinearised_keys([], 0.1) == []


def test_relinearised_keys_errors_name_the_argument():
    with pytest.raises(ValueError, match="threshold"):
        relinearised_keys([np.zeros(3)], -0.1)
    with pytest.raises(ValueError, match=r"delta\[1\]"):
        relinearised_keys([np.zeros(3), np.array([np.nan])], 0.1)


@pytest.mark.parametrize("new_keys, relinearised, top, orphans", [
    ([2], [], [0, 1, 2], [3]),  # a new factor's clique and its path to the root
    ([], [1], [0, 3, 4], [1]),  # 1 is a frontal of 3 and in 4's separator
    ([], [4], [0, 1, 2], [3]),  # only in separators below its own clique
    ([7], [], [5, 6], []),  # two roots, one untouched
    ([8, 9], [], [], []),  # new variables only: they join the (empty) top
    ([], [], [], []),  # nothing new
    ([0, 9], [6], [0, 3, 4, 5, 6], [1]),
])
def test_affected_cliques_mark_frontals_and_separators_then_close_upwards(new_keys, relinearised, top, orphans):
    assert affected_cliques(FRONTALS, SEPARATORS, PARENTS, new_keys, relinearised) == (top, orphans)


def test_affected_cliques_errors_name_the_argument_and_the_entry():
    with pytest.raises(ValueError, match=r"relinearised\[0\] = 8"):
        affected_cliques(FRONTALS, SEPARATORS, PARENTS, [], [8])
    with pytest.raises(ValueError, match=r"new_keys\[1\] = -1"):
        affected_cliques(FRONTALS, SEPARATORS, PARENTS, [0, -1], [])
    with pytest.raises(ValueError, match=r"parents\[1\] = 7"):
        affected_cliques(FRONTALS, SEPARATORS, [-1, 7, 1, 0, 3, -1, 5], [], [])
    with pytest.raises(ValueError, match="forest"):
        affected_cliques(FRONTALS, SEPARATORS, [-1, 2, 1, 0, 3, -1, 5], [], [])
    with pytest.raises(ValueError, match="exactly once"):
        affected_cliques(FRONTALS[:-1] + [[6]], SEPARATORS, PARENTS, [], [])
    with pytest.raises(ValueError, match=r"clique_separators\[2\]\[1\] = 9"):
        affected_cliques(FRONTALS, [[], [4], [3, 9], [5], [1], [], [6]], PARENTS, [], [])


def test_orphan_parents_take_the_first_eliminated_member_in_the_new_ordering():
    ordering, cliques = [7, 2, 5, 1], [[7], [2, 5], [1]]
    # [1, 2, 7]: 7 is eliminated first (not 1, the smallest, nor 1, listed first); [5, 1]: 5
    assert orphan_parents([[1, 2, 7], [5, 1], [1]], ordering, cliques).tolist() == [0, 1, 2]
    assert orphan_parents([], ordering, cliques).tolist() == []


def test_orphan_parents_errors_name_the_argument_and_the_entry():
    ordering, cliques = [7, 2, 5, 1], [[7], [2, 5], [1]]
    with pytest.raises(ValueError, match=r"orphan_separators\[1\] is empty"):
        orphan_parents([[2], []], ordering, cliques)
    with pytest.raises(ValueError, match=r"orphan_separators\[0\]\[1\] = 3"):
        orphan_parents([[2, 3]], ordering, cliques)
    with pytest.raises(ValueError, match="repeat"):
        orphan_parents([[2]], [7, 2, 2, 1], cliques)
    with pytest.raises(ValueError, match=r"missing \[1\]"):
        orphan_parents([[2]], ordering, cliques[:2])


@pytest.mark.parametrize("kind, seed", [("poses", None), ("mixed", None), ("poses", 3), ("mixed", 5)])
def test_the_full_wildfire_is_the_back_substitution_of_the_whole_tree(kind, seed):
    p = problem(kind, seed)
    zeros = [np.zeros_like(s) for s in p["delta"]]
    new, recomputed = wildfire_update(*p["tree"], p["conditionals"], zeros, range(len(p["tree"][0])), 0.0)
    assert recomputed == list(range(len(p["tree"][0])))
    np.testing.assert_allclose(np.concatenate(new), np.concatenate(p["delta"]), rtol=1e-9, atol=1e-10)


@pytest.mark.parametrize("kind, seed", [("poses", None), ("mixed", None), ("poses", 1), ("poses", 2), ("mixed", 4)])
def test_the_incremental_update_reproduces_the_batch_solution_of_the_new_problem(kind, seed):
    """Old tree -> the top of the new factors -> re-eliminated, the orphans reattached -> the wildfire from the
    old steps with threshold 0 over the replaced top: the new problem's least-squares solution."""
    p = problem(kind, seed)
    tree, conditionals, start, replaced = p["updated"]
    new, recomputed = wildfire_update(*tree, conditionals, start, replaced, 0.0)
    assert set(replaced) <= set(recomputed)
    np.testing.assert_allclose(np.concatenate(new), np.concatenate(p["solution"]), rtol=1e-9, atol=1e-10)
    frontals, seps, parents = tree
    for c, S in enumerate(seps):  # every clique's separator lies in its parent's variables
        if parents[c] != -1:
            assert set(S) <= set(frontals[parents[c]]) | set(seps[parents[c]])
        else:
            assert S == []


def test_a_threshold_above_every_change_recomputes_the_replaced_cliques_only():
    p = problem("poses")
    tree, conditionals, start, replaced = p["updated"]
    before = [s.copy() for s in start]
    new, recomputed = wildfire_update(*tree, conditionals, start, replaced, 1e9)
    assert recomputed == sorted(replaced)
    kept = [v for c in range(len(tree[0])) if c not in replaced for v in tree[0][c]]
    for v in kept:
        np.testing.assert_array_equal(new[v], start[v])
    assert all(np.array_equal(a, b) for a, b in zip(start, before)) and new is not start


def test_a_change_below_the_threshold_stops_the_update_below_it():
    p = problem("poses")
    tree, conditionals, start, replaced = p["updated"]
    _, _, parents = tree
    _, everything = wildfire_update(*tree, conditionals, start, replaced, 0.0)
    _, partial = wildfire_update(*tree, conditionals, start, replaced, 0.37)
    assert set(replaced) < set(partial) < set(everything)
    for c in set(everything) - set(partial):  # skipped: its whole subtree is skipped too
        assert not {k for k in range(len(parents)) if parents[k] == c} & set(partial)


def test_wildfire_errors_name_the_argument_and_the_entry():
    frontals, seps, parents = [[0], [1]], [[], [0]], [-1, 0]
    good = [(np.eye(3), np.zeros((3, 0)), np.ones(3)), (np.eye(1), np.ones((1, 3)), np.ones(1))]
    delta = [np.zeros(3), np.zeros(1)]
    new, recomputed = wildfire_update(frontals, seps, parents, good, delta, [0, 1], 0.0)
    assert recomputed == [0, 1] and new[1].tolist() == [-2.0]
    with pytest.raises(ShapeError, match=r"conditionals\[1\]: S has shape \(1, 2\)"):
        wildfire_update(frontals, seps, parents, [good[0], (np.eye(1), np.ones((1, 2)), np.ones(1))], delta, [0], 0.0)
    with pytest.raises(SingularSystemError, match=r"conditionals\[0\]: R\[1, 1\] is 0"):
        wildfire_update(frontals, seps, parents, [(np.diag([1.0, 0.0, 1.0]),) + good[0][1:], good[1]], delta, [0],
                        0.0)
    with pytest.raises(ValueError, match="closed upwards"):
        wildfire_update(frontals, seps, parents, good, delta, [1], 0.0)
    with pytest.raises(ValueError, match=r"replaced\[0\] = 2"):
        wildfire_update(frontals, seps, parents, good, delta, [2], 0.0)
    with pytest.raises(ValueError, match="one step per variable"):
        wildfire_update(frontals, seps, parents, good, delta[:1], [0], 0.0)
    with pytest.raises(ValueError, match=r"delta\[1\]"):
        wildfire_update(frontals, seps, parents, good, [np.zeros(3), np.array([np.inf])], [0], 0.0)
    with pytest.raises(ValueError, match="threshold"):
        wildfire_update(frontals, seps, parents, good, delta, [0], -1.0)
