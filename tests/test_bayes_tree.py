"""The Bayes tree of an elimination: the reference on hand-built trees, the tree's invariants on the checks'
random patterns, and the errors on inputs that are not an elimination's."""

import numpy as np
import pytest

from autograder.checks.bayes_tree import PUBLIC, cases
from solutions.bayes_tree import bayes_tree, clique_of


def eliminate(n, edges, ordering):
    """A symbolic elimination (the tests' own): each variable's neighbours when it is eliminated, sorted by
    elimination position."""
    adjacent = [set() for _ in range(n)]
    for a, b in edges:
        adjacent[a].add(b)
        adjacent[b].add(a)
    position = {v: k for k, v in enumerate(ordering)}
    separators = [None] * n
    for v in ordering:
        S = sorted(adjacent[v], key=position.get)
        separators[v] = S
        for u in S:
            adjacent[u] |= set(S) - {u}
            adjacent[u].discard(v)
    return separators


def components(n, edges):
    root = list(range(n))

    def find(v):
        while root[v] != v:
            v = root[v]
        return v

    for a, b in edges:
        root[find(a)] = find(b)
    return len({find(v) for v in range(n)})


def edges_of(separators):
    return [(v, u) for v, S in enumerate(separators) for u in S]


@pytest.mark.parametrize("seed", [None, 1, 2, 3])
def test_the_checks_patterns_are_an_eliminations(seed):
    for what, ordering, separators in cases(seed):
        assert eliminate(len(ordering), edges_of(separators), ordering) == separators, what


def test_the_public_pose_graph_is_its_graph_eliminated():
    _, ordering, separators = PUBLIC[6]
    edges = [(i, i + 1) for i in range(9)] + [(0, 5), (2, 8), (4, 9)]
    assert eliminate(10, edges, ordering) == separators


def test_one_variable():
    frontals, separators, parents = bayes_tree([0], [[]])
    assert frontals == [[0]] and separators == [[]] and parents.tolist() == [-1]
    assert clique_of(frontals, 1).tolist() == [0]


def test_a_chain_is_one_clique_per_edge():
    frontals, separators, parents = bayes_tree(np.arange(6), [[1], [2], [3], [4], [5], []])
    assert frontals == [[4, 5], [3], [2], [1], [0]]
    assert separators == [[], [4], [3], [2], [1]]
    assert parents.tolist() == [-1, 0, 1, 2, 3]


def test_a_complete_graph_and_a_star_eliminated_centre_first_are_one_clique():
    ordering = [2, 0, 4, 1, 3]
    separators = eliminate(5, [(a, b) for a in range(5) for b in range(a)], ordering)
    assert bayes_tree(ordering, separators)[0] == [ordering]
    ordering = [0, 3, 1, 5, 2, 4]
    frontals, clique_separators, parents = bayes_tree(ordering, eliminate(6, [(0, k) for k in range(1, 6)], ordering))
    assert frontals == [ordering] and clique_separators == [[]] and parents.tolist() == [-1]


def test_a_star_eliminated_leaves_first_hangs_each_leaf_under_the_centre():
    frontals, separators, parents = bayes_tree([1, 2, 3, 4, 5, 0], [[], [0], [0], [0], [0], [0]])
    assert frontals == [[5, 0], [4], [3], [2], [1]]
    assert separators == [[], [0], [0], [0], [0]]
    assert parents.tolist() == [-1, 0, 0, 0, 0]


def test_two_components_give_two_roots():
    frontals, separators, parents = bayes_tree([3, 0, 4, 1, 5, 2], [[1, 2], [2], [], [4], [5], []])
    assert frontals == [[0, 1, 2], [4, 5], [3]] and separators == [[], [], [4]]
    assert parents.tolist() == [-1, -1, 1]


def test_a_strict_subset_starts_a_child_and_an_equal_set_joins_below_the_root():
    frontals, separators, parents = bayes_tree([5, 4, 3, 0, 1, 2], [[1, 2], [2], [], [0, 1], [3, 1], [3, 0, 1]])
    assert frontals == [[0, 1, 2], [5, 3], [4]]
    assert separators == [[], [0, 1], [3, 1]]  # clique 1 keeps the separator it was created with
    assert parents.tolist() == [-1, 0, 1]


@pytest.mark.parametrize("seed", [1, 2, 3, 4])
def test_the_tree_of_a_random_pattern_holds_every_conditional_once(seed):
    for what, ordering, separators in cases(seed):
        n = len(ordering)
        position = {v: k for k, v in enumerate(ordering)}
        frontals, clique_separators, parents = bayes_tree(ordering, separators)
        home = clique_of(frontals, n)
        assert sorted(v for F in frontals for v in F) == list(range(n)), what
        for c, (F, S) in enumerate(zip(frontals, clique_separators)):
            assert [position[v] for v in F] == sorted(position[v] for v in F), what
            assert S == separators[F[-1]], what  # created by its last-eliminated frontal
            assert set(separators[F[0]]) == set(F[1:]) | set(S), what  # the clique's joint conditional
            p = parents[c]
            assert (p == -1) == (not S), what
            if S:
                assert p < c and home[S[0]] == p, what
                assert set(S) <= set(frontals[p]) | set(clique_separators[p]), what  # running intersection
        assert int(np.sum(parents == -1)) == components(n, edges_of(separators)), what


@pytest.mark.parametrize("ordering, separators, says", [
    ([0, 0], [[], []], "permutation"),
    ([], [], "non-empty"),
    ([0.0, 1.0], [[1], []], "ints"),
    ([0, 1], [[1]], "one list per variable"),
    ([0, 1], [[2], []], "separators[0][0] = 2 is not a variable"),
    ([1, 0], [[1], []], "separators[0][0] = 1 is eliminated at position 0"),
    ([0, 1, 2], [[2, 1], [2], []], "separators[0] is not sorted"),
    ([0, 1, 2], [[1, 1], [2], []], "separators[0] is not sorted"),
    ([0, 1, 2, 3], [[1, 3], [2], [3], []], "separators[0] = [1, 3] is not the separator of an elimination"),
])
def test_inputs_that_are_not_an_eliminations_name_the_entry(ordering, separators, says):
    with pytest.raises(ValueError, match=r"(?s).*" + says.replace("[", r"\[").replace("]", r"\]")):
        bayes_tree(ordering, separators)


def test_clique_of_names_each_variables_clique_and_refuses_a_partial_cover():
    assert clique_of([[3, 1], [0], [2, 4]], 5).tolist() == [1, 0, 2, 0, 2]
    with pytest.raises(ValueError, match="exactly once"):
        clique_of([[0, 1], [1]], 2)
    with pytest.raises(ValueError, match="exactly once"):
        clique_of([[0]], 2)
