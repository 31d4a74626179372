"""The elimination game and the minimum-degree ordering (chapter 8): the reference on small graphs worked
by hand, at the edges of its contract (one variable, repeated pairs, self-pairs, two components), its
errors, and its agreement with a dense elimination of a random symmetric pattern."""

import numpy as np
import pytest

from solutions.orderings import minimum_degree_ordering, symbolic_elimination


def test_a_chain_in_natural_order_has_no_fill():
    separators, parents, fill = symbolic_elimination(5, [[0, 1], [1, 2], [2, 3], [3, 4]], [0, 1, 2, 3, 4])
    assert separators == [[1], [2], [3], [4], []]
    assert parents.tolist() == [1, 2, 3, 4, -1] and parents.dtype.kind == "i"
    assert fill.shape == (0, 2) and fill.dtype.kind == "i"


def test_a_chain_from_the_middle_fills_outwards():
    separators, parents, fill = symbolic_elimination(5, [[0, 1], [1, 2], [2, 3], [3, 4]], [2, 1, 3, 0, 4])
    assert separators == [[4], [3, 0], [1, 3], [0, 4], []]
    assert parents.tolist() == [4, 3, 1, 0, -1]
    assert fill.tolist() == [[0, 3], [0, 4], [1, 3]]


def test_a_star_centre_first_makes_its_leaves_a_clique_and_leaves_first_no_fill():
    edges = [[2, v] for v in (0, 1, 3, 4)]
    separators, parents, fill = symbolic_elimination(5, edges, [2, 4, 0, 3, 1])
    assert separators[2] == [4, 0, 3, 1]  # by elimination position, not by index
    assert parents[2] == 4 and parents[1] == -1
    assert fill.tolist() == [[0, 1], [0, 3], [0, 4], [1, 3], [1, 4], [3, 4]]
    separators, parents, fill = symbolic_elimination(5, edges, [4, 0, 3, 1, 2])
    assert separators == [[2], [2], [], [2], [2]] and fill.shape == (0, 2)


def test_one_variable_and_no_edges():
    for edges in ([], np.zeros((0, 2), dtype=int)):
        separators, parents, fill = symbolic_elimination(1, edges, [0])
        assert separators == [[]] and parents.tolist() == [-1] and fill.shape == (0, 2)
        assert minimum_degree_ordering(1, edges).tolist() == [0]


def test_repeated_pairs_and_self_pairs_change_nothing():
    plain = [[0, 1], [1, 2], [2, 0], [2, 3]]
    noisy = [[1, 0], [0, 1], [1, 2], [3, 3], [2, 0], [0, 2], [2, 3], [3, 2], [1, 1]]
    ordering = [2, 0, 3, 1]
    a, b = symbolic_elimination(4, plain, ordering), symbolic_elimination(4, noisy, ordering)
    assert a[0] == b[0] and np.array_equal(a[1], b[1]) and np.array_equal(a[2], b[2])
    assert np.array_equal(minimum_degree_ordering(4, plain), minimum_degree_ordering(4, noisy))


def test_two_components_have_two_roots():
    _, parents, _ = symbolic_elimination(5, [[0, 2], [2, 4], [1, 3]], [4, 3, 0, 1, 2])
    assert sorted(np.flatnonzero(parents == -1).tolist()) == [1, 2]


def test_minimum_degree_updates_the_degrees_with_the_fill_and_breaks_ties_low():
    assert minimum_degree_ordering(4, [[0, 1], [1, 2], [2, 3]]).tolist() == [0, 1, 2, 3]
    # a star: the leaves (degree 1) by index, then the centre and the last leaf tie at degree 1
    assert minimum_degree_ordering(5, [[0, v] for v in range(1, 5)]).tolist() == [1, 2, 3, 0, 4]
    # a 3-cycle with a tail 2-3: 3 (degree 1) first, then 0 (degree 2, the smallest of 0, 1, 2)
    assert minimum_degree_ordering(4, [[0, 1], [1, 2], [2, 0], [2, 3]]).tolist() == [3, 0, 1, 2]
    # a 4-cycle: eliminating 0 joins 1 and 3 (fill): 1, 2 and 3 all keep degree 2, and 1 is next
    assert minimum_degree_ordering(4, [[0, 1], [1, 2], [2, 3], [3, 0]]).tolist() == [0, 1, 2, 3]


def _dense_elimination(n, edges, ordering):
    """The same game on a dense symmetric matrix of booleans, variable by variable."""
    A = np.zeros((n, n), dtype=bool)
    for i, j in edges:
        if i != j:
            A[i, j] = A[j, i] = True
    original, alive, separators = A.copy(), np.ones(n, dtype=bool), [None] * n
    for v in ordering:
        alive[v] = False
        members = np.flatnonzero(A[v] & alive)
        separators[v] = set(members.tolist())
        A[np.ix_(members, members)] = True
    np.fill_diagonal(A, False)
    return separators, {tuple(p) for p in np.argwhere(np.triu(A & ~original, 1)).tolist()}


@pytest.mark.parametrize("seed", range(5))
def test_a_random_graph_agrees_with_a_dense_elimination(seed):
    rng = np.random.default_rng(seed)
    n = 25
    edges = rng.integers(0, n, (40, 2))
    ordering = rng.permutation(n)
    separators, parents, fill = symbolic_elimination(n, edges, ordering)
    dense, dense_fill = _dense_elimination(n, edges.tolist(), ordering)
    position = np.argsort(ordering)
    for v in range(n):
        assert set(separators[v]) == dense[v]
        assert [int(position[u]) for u in separators[v]] == sorted(int(position[u]) for u in separators[v])
        assert parents[v] == (separators[v][0] if separators[v] else -1)
    assert {tuple(row) for row in fill.tolist()} == dense_fill and fill.tolist() == sorted(fill.tolist())
    # each component has one root, and the minimum-degree ordering is a permutation
    assert np.array_equal(np.sort(minimum_degree_ordering(n, edges)), np.arange(n))


def test_minimum_degree_gives_less_fill_than_natural_order_on_a_grid():
    side = 6
    edges = [(r * side + c, r * side + c + 1) for r in range(side) for c in range(side - 1)]
    edges += [(r * side + c, (r + 1) * side + c) for r in range(side - 1) for c in range(side)]
    natural = symbolic_elimination(side * side, edges, np.arange(side * side))[2]
    greedy = symbolic_elimination(side * side, edges, minimum_degree_ordering(side * side, edges))[2]
    assert len(greedy) < len(natural)


@pytest.mark.parametrize("n, edges, ordering, message", [
    (0, [], [], "n must be an integer >= 1"),
    (2.0, [], [0, 1], "n must be an integer >= 1"),
    (3, [[0, 1], [1, 3]], [0, 1, 2], r"edges\[1\] = \(1, 3\) names a variable outside 0..2"),
    (3, [[0, -1]], [0, 1, 2], r"edges\[0\] = \(0, -1\)"),
    (3, [0, 1, 2], [0, 1, 2], r"edges must be an \(E, 2\) array"),
    (3, [[0.5, 1]], [0, 1, 2], "edges must hold integer"),
    (3, [[0, 1]], [0, 1, 1], "repeats variable 1 .*misses variable 2"),
    (3, [[0, 1]], [0, 1, 3], r"ordering\[2\] = 3 is not a variable"),
    (3, [[0, 1]], [0, 1], r"shape \(3,\)"),
])
def test_bad_inputs_name_the_argument_and_the_entry(n, edges, ordering, message):
    with pytest.raises(ValueError, match=message):
        symbolic_elimination(n, edges, ordering)


def test_minimum_degree_checks_its_graph():
    with pytest.raises(ValueError, match=r"edges\[0\] = \(0, 5\)"):
        minimum_degree_ordering(3, [[0, 5]])
    with pytest.raises(ValueError, match="n must be"):
        minimum_degree_ordering(0, [])


def test_the_inputs_are_not_modified():
    edges, ordering = np.array([[1, 0], [2, 1]]), np.array([1, 0, 2])
    symbolic_elimination(3, edges, ordering)
    minimum_degree_ordering(3, edges)
    assert edges.tolist() == [[1, 0], [2, 1]] and ordering.tolist() == [1, 0, 2]
