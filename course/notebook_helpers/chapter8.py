"""Chapter 8's lesson: elimination, orderings and fill, marginal covariances.

What the notebook's cells call, section by section (each takes the implementation's module, so that the
student's own ``elimination``, ``orderings`` and ``marginal_covariances`` run):

* ``LinearGraph``, ``small_graph``, ``stacked``, ``elimination_check``: a linear Gaussian factor graph of
  three 2-vectors, the factors adjacent to one variable stacked, and a check of one elimination by the
  identity the contract states (at random points, no reference answer).
* ``eliminate_all``, ``back_substitute``, ``bayes_net_table``: variable elimination, one variable at a time
  (a Bayes net of conditionals), and the solution read back from it, against a dense least squares.
* ``game_graph``, ``game_figure``: the elimination game on a small pose graph with landmarks, two orderings.
* ``bayes_tree_check``: the Bayes tree of the elimination game's graph, drawn as text, and the properties a
  Bayes tree has (every variable frontal in one clique, each separator inside its parent's variables).
* ``affected_check``, ``wildfire_check``: the student's incremental update on the game's Bayes tree: the
  top and orphans of a few updates, and the partial state update, tested by the properties the contract states.
* ``online_run``, ``online_table``, ``online_figure``: a pose graph fed one pose per step to the smoother on
  the student's pieces, GTSAM's ISAM2 and batch re-solves (``course.app.online``), and the time per step.
* ``graph_of``, ``ordering_rows``, ``ordering_table``: the fill and the factor's size under the natural order,
  the student's minimum degree, reverse Cuthill-McKee (scipy) and AMD (cvxopt, where installed).
* ``pose_graph_information``, ``square_root_information``, ``marginals_run``, ``ellipse_figure``: a 2D pose
  graph solved, its square-root information in the student's ordering, every pose's marginal covariance by
  the student's recursion against the dense inverse, and the poses' 3-sigma ellipses.
"""

from __future__ import annotations

import time
from typing import NamedTuple

import numpy as np
import scipy.linalg
import scipy.sparse as sp
from scipy.sparse.csgraph import reverse_cuthill_mckee

from course.app.plot import figure
from course.core import peers
from course.notebook_helpers.lesson import exercise, todo_as_one_line  # noqa: F401 (the cells call them here)

# ---------------------------------------------------------------- section 1: one elimination


class LinearGraph(NamedTuple):
    """A linear Gaussian factor graph: ``sizes[v]`` the size of variable ``v``; each factor
    ``(keys, blocks, b)`` adds ``||sum_a blocks[a] x_keys[a] - b||^2`` (whitened: ``blocks[a]`` (m, sizes[key])).
    """

    sizes: tuple
    factors: list


def small_graph(seed: int = 0) -> LinearGraph:
    """Three 2-vectors ``x0, x1, x2``: a prior on ``x0``, odometry ``x0-x1`` and ``x1-x2``, a loop ``x0-x2``
    and a one-row measurement of ``x2``; random whitened blocks (well conditioned)."""
    rng = np.random.default_rng(seed)

    def block(m):
        return rng.normal(0.0, 1.0, (m, 2)) + 2.0 * np.eye(m, 2)

    factors = [((0,), [block(2)], rng.normal(size=2)),
               ((0, 1), [block(2), -block(2)], rng.normal(size=2)),
               ((1, 2), [block(2), -block(2)], rng.normal(size=2)),
               ((0, 2), [block(2), -block(2)], rng.normal(size=2)),
               ((2,), [block(1)], rng.normal(size=1))]
    return LinearGraph((2, 2, 2), factors)


def stacked(graph: LinearGraph, v: int, factors=None):
    """``(A_x, A_s, b, separator)``: the factors of ``factors`` (default: the graph's) that touch ``v``,
    stacked; ``separator`` their other variables, sorted, ``A_s``'s column blocks in that order."""
    factors = graph.factors if factors is None else factors
    adjacent = [f for f in factors if v in f[0]]
    separator = sorted({key for keys, _, _ in adjacent for key in keys if key != v})
    offsets = np.concatenate([[0], np.cumsum([graph.sizes[s] for s in separator])]).astype(int)
    rows = sum(len(b) for _, _, b in adjacent)
    A_x = np.zeros((rows, graph.sizes[v]))
    A_s = np.zeros((rows, int(offsets[-1])))
    b = np.zeros(rows)
    row = 0
    for keys, blocks, rhs in adjacent:
        m = len(rhs)
        for key, block in zip(keys, blocks):
            if key == v:
                A_x[row:row + m] += block
            else:
                k = separator.index(key)
                A_s[row:row + m, offsets[k]:offsets[k + 1]] += block
        b[row:row + m] = rhs
        row += m
    return A_x, A_s, b, separator


def elimination_check(module, graph: LinearGraph | None = None, v: int = 0, points: int = 5, out=print) -> bool:
    """Eliminate ``v`` with ``module.eliminate_variable`` and check the contract at random points: R upper
    triangular, and ``||A_x x + A_s s - b||^2 - ||R x + S s - d||^2 - ||A_new s - b_new||^2`` the same
    constant ``c >= 0`` everywhere (the two sides differ by no function of ``x`` or ``s``)."""
    graph = small_graph() if graph is None else graph
    A_x, A_s, b, separator = stacked(graph, v)
    R, S, d, A_new, b_new = (np.asarray(a, dtype=float) for a in module.eliminate_variable(A_x, A_s, b))
    upper = R.shape == (A_x.shape[1],) * 2 and bool(np.allclose(np.tril(R, -1), 0.0, atol=1e-12))
    out(f"R {R.shape}, S {S.shape}, d {d.shape}, new factor {A_new.shape} on x{', x'.join(map(str, separator))}; "
        f"R upper triangular: {'yes' if upper else 'NO'}")
    rng = np.random.default_rng(1)
    gaps = []
    for _ in range(points):
        x, s = rng.normal(0.0, 3.0, A_x.shape[1]), rng.normal(0.0, 3.0, A_s.shape[1])
        whole = np.sum((A_x @ x + A_s @ s - b) ** 2)
        split = np.sum((R @ x + S @ s - d) ** 2) + np.sum((A_new @ s - b_new) ** 2)
        gaps.append(whole - split)
    gap = np.asarray(gaps)
    spread = float(np.ptp(gap))
    constant = spread < 1e-9 * max(1.0, float(np.max(np.abs(gap)))) and float(np.min(gap)) > -1e-9
    out(f"||A_x x + A_s s - b||^2 - (||R x + S s - d||^2 + ||A_new s - b_new||^2) at {points} random points: "
        f"{gap[0]:.6g} (spread {spread:.1e}): {'a constant c >= 0, right' if constant else 'NOT a constant c >= 0'}")
    return upper and constant


def eliminate_all(module, graph: LinearGraph, ordering) -> list:
    """Variable elimination: for each ``v`` of ``ordering``, its adjacent factors replaced by the new factor
    on its separator; returns the Bayes net ``[(v, separator, R, S, d)]`` in elimination order."""
    factors = list(graph.factors)
    net = []
    for v in ordering:
        A_x, A_s, b, separator = stacked(graph, v, factors)
        R, S, d, A_new, b_new = (np.asarray(a, dtype=float) for a in module.eliminate_variable(A_x, A_s, b))
        net.append((v, separator, R, S, d))
        factors = [f for f in factors if v not in f[0]]
        if separator and len(b_new):
            offsets = np.concatenate([[0], np.cumsum([graph.sizes[s] for s in separator])]).astype(int)
            factors.append((tuple(separator), [A_new[:, offsets[k]:offsets[k + 1]] for k in range(len(separator))],
                            b_new))
    return net


def back_substitute(net: list, sizes) -> list:
    """The solution from the Bayes net, last eliminated first: ``x_v = R^-1 (d - S x_separator)``."""
    x: dict = {}
    for v, separator, R, S, d in reversed(net):
        s = np.concatenate([x[k] for k in separator]) if separator else np.zeros(0)
        x[v] = scipy.linalg.solve_triangular(R, d - S @ s)  # back-substitution: R upper triangular by contract
    return [x[v] for v in range(len(sizes))]


def least_squares(graph: LinearGraph) -> list:
    """The whole system stacked and solved densely (numpy's least squares): the comparison."""
    offsets = np.concatenate([[0], np.cumsum(graph.sizes)]).astype(int)
    rows = []
    rhs = []
    for keys, blocks, b in graph.factors:
        A = np.zeros((len(b), offsets[-1]))
        for key, block in zip(keys, blocks):
            A[:, offsets[key]:offsets[key + 1]] = block
        rows.append(A)
        rhs.append(b)
    x = np.linalg.lstsq(np.vstack(rows), np.concatenate(rhs), rcond=None)[0]
    return [x[offsets[v]:offsets[v + 1]] for v in range(len(graph.sizes))]


def bayes_net_table(module, graph: LinearGraph | None = None) -> str:
    """For two orderings: the conditionals (each variable given its separator) and the largest difference
    between the back-substituted solution and numpy's least squares."""
    graph = small_graph() if graph is None else graph
    want = np.concatenate(least_squares(graph))
    lines = []
    for ordering in ([0, 1, 2], [1, 0, 2]):
        net = eliminate_all(module, graph, ordering)
        got = np.concatenate(back_substitute(net, graph.sizes))
        conditionals = ", ".join(f"p(x{v}{' | x' + ', x'.join(map(str, s)) if s else ''})" for v, s, *_ in net)
        lines.append(f"order {ordering}: {conditionals}; |x - x_lstsq| = {np.max(np.abs(got - want)):.1e}")
    return "\n".join(lines)


# ---------------------------------------------------------------- section 2: orderings and fill


def game_graph():
    """``(n, edges, positions)``: six poses around a loop (0..5, odometry and one closure 5-0) and two
    landmarks (6 seen from 0, 1 and 2; 7 from 3, 4 and 5), with positions for the figure."""
    angles = np.linspace(0.0, 2.0 * np.pi, 6, endpoint=False)
    poses = np.column_stack([np.cos(angles), np.sin(angles)]) * 2.0
    positions = np.vstack([poses, [[1.0, 0.9], [-1.0, -0.9]]])
    edges = [(k, (k + 1) % 6) for k in range(6)] + [(p, 6) for p in (0, 1, 2)] + [(p, 7) for p in (3, 4, 5)]
    return 8, np.array(edges), positions


def game_figure(module, orderings: dict | None = None):
    """One panel per ordering: the graph's edges, the fill of ``module.symbolic_elimination`` (red, dashed)
    and each variable's position in the ordering; the natural order and ``module.minimum_degree_ordering``
    by default."""
    n, edges, positions = game_graph()
    if orderings is None:
        orderings = {"natural": np.arange(n), "minimum degree": np.asarray(module.minimum_degree_ordering(n, edges))}
    fig = figure(4.2 * len(orderings), 4.2)
    for k, (name, ordering) in enumerate(orderings.items()):
        ax = fig.add_subplot(1, len(orderings), k + 1)
        _, parents, fill = module.symbolic_elimination(n, edges, ordering)
        fill = np.asarray(fill, dtype=int).reshape(-1, 2)
        for i, j in edges:
            ax.plot(*positions[[i, j]].T, color="0.3", lw=1.5, zorder=1)
        for i, j in fill:
            ax.plot(*positions[[i, j]].T, color="tab:red", lw=1.2, ls="--", zorder=1)
        position = np.empty(n, dtype=int)
        position[np.asarray(ordering, dtype=int)] = np.arange(n)
        for v in range(n):
            x, y = positions[v]
            ax.scatter(x, y, s=380, color="tab:orange" if v >= 6 else "tab:blue", zorder=2)
            ax.text(x, y, f"{v}\n#{position[v] + 1}", ha="center", va="center", fontsize=7, color="white", zorder=3)
        roots = int(np.sum(np.asarray(parents) < 0))
        ax.set_title(f"{name}: {len(fill)} fill edge(s), {roots} root(s)\n"
                     "poses blue, landmarks orange, fill red; #k: eliminated k-th", fontsize=8)
        ax.set_aspect("equal")
        ax.axis("off")
    return fig


def bayes_tree_check(orderings_module, bayes_module, out=print) -> bool:
    """The Bayes tree of :func:`game_graph` in ``orderings_module``'s minimum-degree order, from its
    symbolic elimination and ``bayes_module.bayes_tree``: one line per clique, ``frontals : separator``,
    indented by depth; then the properties every Bayes tree has: each variable a frontal of exactly one
    clique, one root per connected component (here 1), and each clique's separator inside its parent's
    frontals and separator (the running intersection)."""
    n, edges, _ = game_graph()
    ordering = np.asarray(orderings_module.minimum_degree_ordering(n, edges), dtype=int)
    separators, _, _ = orderings_module.symbolic_elimination(n, edges, ordering)
    frontals, clique_separators, parents = bayes_module.bayes_tree(ordering, [list(s) for s in separators])
    parents = np.asarray(parents, dtype=int)
    depth = np.zeros(len(frontals), dtype=int)
    for c, p in enumerate(parents):  # a parent is created before its children
        depth[c] = 0 if p < 0 else depth[p] + 1
    for c, (f, sep) in enumerate(zip(frontals, clique_separators)):
        out(f"{'    ' * depth[c]}clique {c}: {' '.join(map(str, f))} : {' '.join(map(str, sep)) or '(root)'}")
    held = sorted(int(v) for f in frontals for v in f)
    once = held == list(range(n))
    roots = int(np.sum(parents < 0))
    running = all(p < 0 or set(map(int, sep)) <= set(map(int, frontals[p])) | set(map(int, clique_separators[p]))
                  for sep, p in zip(clique_separators, parents))
    out(f"each variable a frontal once: {'yes' if once else 'NO'}; roots: {roots}; each separator inside its "
        f"parent's variables: {'yes' if running else 'NO'}")
    return once and roots == 1 and running


# ---------------------------------------------------------------- section 4: the incremental update


def _game_tree(orderings_module, bayes_module):
    """``(frontals, clique_separators, parents)`` of :func:`game_graph` in the minimum-degree order."""
    n, edges, _ = game_graph()
    ordering = np.asarray(orderings_module.minimum_degree_ordering(n, edges), dtype=int)
    separators, _, _ = orderings_module.symbolic_elimination(n, edges, ordering)
    frontals, clique_separators, parents = bayes_module.bayes_tree(ordering, [list(s) for s in separators])
    return ([[int(v) for v in f] for f in frontals], [[int(v) for v in s] for s in clique_separators],
            np.asarray(parents, dtype=int))


def affected_check(orderings_module, bayes_module, incremental_module, updates=None, out=print) -> bool:
    """The top and the orphans of ``updates`` (``[(label, new_keys, relinearised)]``) on the game's Bayes
    tree by the student's ``affected_cliques``, one line each, and the properties the contract states: the
    top is closed towards the root, holds every clique with a new key as a frontal and every clique whose
    frontals or separator hold a relinearised variable; the orphans are outside the top, with their parent in
    it. (Whether the top is the *smallest* such set is for the checks to judge.)"""
    frontals, separators, parents = _game_tree(orderings_module, bayes_module)
    updates = updates or [("a measurement between poses 4 and 5", [4, 5], []),
                          ("a loop closure between poses 0 and 3", [0, 3], []),
                          ("pose 3 relinearised", [], [3]),
                          ("pose 1 relinearised", [], [1])]
    ok = True
    for label, new_keys, relinearised in updates:
        top, orphans = incremental_module.affected_cliques(frontals, separators, parents, new_keys, relinearised)
        top, orphans = [int(c) for c in top], [int(c) for c in orphans]
        inside = set(top)
        closed = all(parents[c] < 0 or parents[c] in inside for c in top)
        news = all(c in inside for c, f in enumerate(frontals) if set(f) & set(new_keys))
        relin = all(c in inside for c, (f, s) in enumerate(zip(frontals, separators)) if set(f + s) & set(relinearised))
        hanging = all(c not in inside and parents[c] in inside for c in orphans)
        fine = closed and news and relin and hanging
        ok = ok and fine
        out(f"{label}: top {top} (re-eliminates {sorted(v for c in top for v in frontals[c])}), orphans {orphans}; "
            f"closed towards the root: {'yes' if closed else 'NO'}; holds the marked cliques: "
            f"{'yes' if news and relin else 'NO'}; orphans hang from it: {'yes' if hanging else 'NO'}")
    return ok


def wildfire_check(orderings_module, bayes_module, incremental_module, seed: int = 0, out=print) -> bool:
    """The student's ``wildfire_update`` on the game's Bayes tree with random conditionals (poses of 3
    unknowns, landmarks of 2), tested by what the contract states: with every clique replaced and threshold 0,
    every clique's conditional ``R x_F + S x_S = d`` holds; after a small change of the root's ``d`` alone
    (only the root replaced), the cliques it does not recompute keep their steps exactly, and the ones it does
    satisfy their conditionals again."""
    frontals, separators, parents = _game_tree(orderings_module, bayes_module)
    rng = np.random.default_rng(seed)
    sizes = [3] * 6 + [2] * 2
    conditionals = []
    for f_vars, s_vars in zip(frontals, separators):
        f, s = sum(sizes[v] for v in f_vars), sum(sizes[v] for v in s_vars)
        R = np.triu(rng.normal(size=(f, f)), 1) + np.diag(rng.uniform(1.0, 2.0, f))
        conditionals.append((R, rng.normal(size=(f, s)) * 0.3, rng.normal(size=f)))

    def residual(delta, c):
        R, S, d = conditionals[c]
        x = np.concatenate([delta[v] for v in frontals[c]])
        s = np.concatenate([delta[v] for v in separators[c]]) if separators[c] else np.zeros(0)
        return float(np.max(np.abs(R @ x + S @ s - d)))

    zero = [np.zeros(k) for k in sizes]
    everything = list(range(len(frontals)))
    full, recomputed = incremental_module.wildfire_update(frontals, separators, parents, conditionals, zero,
                                                          everything, 0.0)
    worst = max(residual(full, c) for c in everything)
    first = worst < 1e-9 and sorted(int(c) for c in recomputed) == everything
    out(f"every clique replaced, threshold 0: recomputed {len(recomputed)} of {len(frontals)} cliques, largest "
        f"|R x_F + S x_S - d| = {worst:.1e} ({'fine' if first else 'WRONG'})")
    root = int(np.flatnonzero(parents < 0)[0])
    R, S, d = conditionals[root]
    conditionals[root] = (R, S, d + 1e-5)
    after, recomputed = incremental_module.wildfire_update(frontals, separators, parents, conditionals, full,
                                                           [root], 1e-3)
    recomputed = sorted(int(c) for c in recomputed)
    kept = all(np.array_equal(after[v], full[v]) for c in everything if c not in recomputed for v in frontals[c])
    solved = all(residual(after, c) < 1e-9 for c in recomputed)
    second = kept and solved and root in recomputed
    out(f"the root's d moved by 1e-5, threshold 1e-3: recomputed cliques {recomputed}; the others kept their "
        f"steps: {'yes' if kept else 'NO'}; the recomputed ones satisfy their conditionals: "
        f"{'yes' if solved else 'NO'}")
    return first and second


def graph_of(name: str):
    """``(n, edges)`` of the 2D pose graph ``name`` (a named dataset, or ``manhattan:N``): the poses and the
    pairs of poses joined by an edge."""
    from course.problems.posegraph.dataset import load_dataset

    graph = load_dataset(name)
    return graph.num_poses, np.column_stack([graph.edges_i, graph.edges_j]).astype(int)


def _block_adjacency(n: int, edges) -> sp.csr_matrix:
    edges = np.asarray(edges, dtype=int).reshape(-1, 2)
    edges = edges[edges[:, 0] != edges[:, 1]]
    A = sp.coo_matrix((np.ones(len(edges)), (edges[:, 0], edges[:, 1])), shape=(n, n))
    return ((A + A.T) > 0).astype(float).tocsr()


def _amd(n: int, edges):
    """AMD's ordering of the graph (cvxopt's, SuiteSparse), or None where cvxopt is not installed."""
    if not peers.installed("cvxopt"):
        return None
    import cvxopt
    from cvxopt import amd

    A = sp.tril(_block_adjacency(n, edges) + sp.eye(n)).tocoo()
    matrix = cvxopt.spmatrix(1.0, A.row.astype(np.int64), A.col.astype(np.int64), (n, n))
    return np.array(amd.order(matrix, uplo="L")).ravel().astype(int)


def ordering_rows(module, n: int, edges, block: int = 3) -> list:
    """Per ordering (natural, the student's minimum degree, reverse Cuthill-McKee, AMD where installed):
    ``(name, seconds to order, fill edges, largest separator, elimination-tree height, nonzeros of R)``,
    R's nonzeros for variables of ``block`` unknowns (``block (block + 1) / 2`` on a diagonal block,
    ``block^2`` per separator variable), the separators from ``module.symbolic_elimination``."""
    candidates = [("natural", lambda: np.arange(n)),
                  ("minimum degree (yours)", lambda: np.asarray(module.minimum_degree_ordering(n, edges), dtype=int)),
                  ("reverse Cuthill-McKee (scipy)",
                   lambda: np.asarray(reverse_cuthill_mckee(_block_adjacency(n, edges), symmetric_mode=True)))]
    if peers.installed("cvxopt"):
        candidates.append(("AMD (SuiteSparse, cvxopt)", lambda: _amd(n, edges)))
    rows = []
    for name, order in candidates:
        start = time.perf_counter()
        ordering = order()
        seconds = time.perf_counter() - start
        separators, parents, fill = module.symbolic_elimination(n, edges, ordering)
        sizes = np.array([len(s) for s in separators])
        depth = np.zeros(n, dtype=int)
        for v in np.asarray(ordering, dtype=int)[::-1]:  # a parent is eliminated after its child
            p = int(parents[v])
            depth[v] = 0 if p < 0 else depth[p] + 1
        nnz = int(np.sum(block * (block + 1) // 2 + block * block * sizes))
        rows.append((name, seconds, len(np.asarray(fill).reshape(-1, 2)), int(sizes.max(initial=0)),
                     int(depth.max(initial=0)) + 1, nnz))
    return rows


def ordering_table(module, names) -> str:
    """:func:`ordering_rows` of each graph of ``names``, as a table."""
    lines = [f"{'graph':<14} {'ordering':<30} {'ms':>8} {'fill':>8} {'max sep':>8} {'height':>7} {'nnz(R)':>10}"]
    for name in names:
        n, edges = graph_of(name)
        for row in ordering_rows(module, n, edges):
            label, seconds, fill, largest, height, nnz = row
            lines.append(f"{name:<14} {label:<30} {seconds * 1e3:8.1f} {fill:8d} {largest:8d} {height:7d} {nnz:10d}")
    return "\n".join(lines)


# ---------------------------------------------------------------- section 3: marginal covariances


class Information(NamedTuple):
    """A solved 2D pose graph's information at its solution: ``H`` (3N, 3N) CSC, whole (both triangles),
    the first pose held still by an identity block; ``poses`` (N, 3); ``edges`` (E, 2)."""

    H: sp.csc_matrix
    poses: np.ndarray
    edges: np.ndarray


def pose_graph_information(name: str, impl, iterations: int = 20) -> Information:
    """Solve ``name`` by Gauss-Newton from the file's poses (chapter 2's problem, the implementation's
    pieces) and linearise at the solution."""
    from course.problems.posegraph.dataset import load_dataset
    from course.problems.posegraph.problem import PoseGraphProblem
    from course.solver import SolverOptions, minimize

    graph = load_dataset(name)
    problem = PoseGraphProblem(graph, impl)
    result = minimize(problem, "gauss-newton", impl=impl, options=SolverOptions(max_iterations=iterations))
    x = np.asarray(result.params, dtype=float).ravel()
    lin = problem.linearize(x)
    H = sp.csc_matrix(lin.H)
    if lin.upper:
        H = sp.csc_matrix(sp.triu(H) + sp.triu(H, 1).T)
    return Information(H, problem.poses(x), np.column_stack([graph.edges_i, graph.edges_j]).astype(int))


def square_root_information(info: Information, ordering, module) -> tuple:
    """``(R, block_order)``: H's upper Cholesky factor in the block ordering ``ordering`` (poses of 3
    unknowns), stored on the pattern of ``module.symbolic_elimination``'s separators (fill included, a
    stored entry may be 0), and the unknowns' order. Dense Cholesky: a graph of a few thousand poses."""
    n = len(info.poses)
    ordering = np.asarray(ordering, dtype=int)
    separators, _, _ = module.symbolic_elimination(n, info.edges, ordering)
    unknowns = (3 * ordering[:, None] + np.arange(3)).ravel()
    dense = info.H[unknowns][:, unknowns].toarray()
    U = scipy.linalg.cholesky(dense, lower=False)
    position = np.empty(n, dtype=int)
    position[ordering] = np.arange(n)
    rows, cols = [], []
    for v in range(n):
        i = position[v]
        blocks = [i] + [int(position[s]) for s in separators[v]]
        r = 3 * i + np.arange(3)
        c = (3 * np.asarray(blocks)[:, None] + np.arange(3)).ravel()
        rr, cc = np.meshgrid(r, c, indexing="ij")
        keep = cc >= rr
        rows.append(rr[keep])
        cols.append(cc[keep])
    r_all, c_all = np.concatenate(rows), np.concatenate(cols)
    R = sp.csc_matrix((U[r_all, c_all], (r_all, c_all)), shape=dense.shape)
    return R, unknowns


def marginals_run(info: Information, orderings_module, marginals_module) -> dict:
    """Every pose's marginal covariance (3, 3) by ``marginals_module.marginal_covariances`` on H's
    square-root information (the student's minimum-degree ordering), and the same blocks of the dense
    inverse of H; their times and the largest difference relative to each block's scale."""
    n = len(info.poses)
    ordering = np.asarray(orderings_module.minimum_degree_ordering(n, info.edges), dtype=int)
    R, _ = square_root_information(info, ordering, orderings_module)
    start = time.perf_counter()
    ours = marginals_module.marginal_covariances(R, [3] * n)
    seconds = time.perf_counter() - start
    start = time.perf_counter()
    inverse = np.linalg.inv(info.H.toarray())
    dense_seconds = time.perf_counter() - start
    by_pose = [None] * n
    for k, v in enumerate(ordering):
        by_pose[v] = np.asarray(ours[k], dtype=float)
    worst = max(float(np.max(np.abs(by_pose[v] - inverse[3 * v:3 * v + 3, 3 * v:3 * v + 3]))
                      / max(np.max(np.abs(inverse[3 * v:3 * v + 3, 3 * v:3 * v + 3])), 1e-300)) for v in range(n))
    return {"covariances": by_pose, "seconds": seconds, "dense_seconds": dense_seconds, "worst": worst,
            "nnz": R.nnz, "n": n}


def marginals_line(run: dict) -> str:
    return (f"{run['n']} poses: marginals by your recursion {run['seconds'] * 1e3:.1f} ms on R's {run['nnz']} stored "
            f"entries; the dense inverse {run['dense_seconds'] * 1e3:.1f} ms; largest difference "
            f"{run['worst']:.1e} of a block's scale")


def ellipse_figure(info: Information, covariances, every: int = 10, sigmas: float = 3.0):
    """The solved trajectory and the ``sigmas``-sigma ellipse of every ``every``-th pose's position marginal."""
    fig = figure(6.5, 6.0)
    ax = fig.add_subplot(1, 1, 1)
    poses = info.poses
    ax.plot(poses[:, 0], poses[:, 1], color="0.5", lw=0.6)
    circle = np.column_stack([np.cos(np.linspace(0, 2 * np.pi, 60)), np.sin(np.linspace(0, 2 * np.pi, 60))])
    for v in range(1, len(poses), every):
        values, vectors = np.linalg.eigh(covariances[v][:2, :2])
        shape = circle @ (vectors * (sigmas * np.sqrt(np.clip(values, 0.0, None)))).T
        ax.plot(poses[v, 0] + shape[:, 0], poses[v, 1] + shape[:, 1], color="tab:blue", lw=0.8)
    ax.set_aspect("equal")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_title(f"{sigmas:g}-sigma position ellipses (every {every}th pose), relative to the first pose", fontsize=9)
    return fig


# ---------------------------------------------------------------- section 6: online


def online_run(name: str, impl, poses: int | None = None) -> dict:
    """``name`` (its first ``poses`` poses) fed one pose per step to the smoother built on ``impl``'s five
    functions (``course.incremental``), to GTSAM's ISAM2 and to batch re-solves: ``course.app.online.compare``'s
    result (its rows name an unwritten TODO or a missing peer)."""
    from course.app import online

    return online.compare(name, impl, poses=poses)


def online_table(result: dict) -> str:
    from course.app import online

    return online.format_table(result)


def online_figure(result: dict):
    """The time per step over the sequence, log scale (``course.app.online.figure``)."""
    from course.app import online

    return online.figure(result)
