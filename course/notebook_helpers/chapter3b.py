"""Chapter 3b's lesson: the figures of the theory of initialisation.

``drift_basin``: chi2 along a family of starts that add a growing heading drift to the minimum,
and where Gauss-Newton ends from each (the basin of the minimum, and other stationary points).
``tree_start``: the spanning-tree start against the file's poses, the hop distances, and the edges
it leaves out. ``relaxation``: the rotation costs of one edge, and the chordal relaxation of one
free orientation between anchored neighbours. ``check_relaxed_jacobians``: ``course.check_jacobian``
on your Jacobians of the relaxed rotation residual of one edge. ``basin_starts``: the experiments'
basin of convergence (the file's and the chordal start, and our Gauss-Newton from each).

Each takes the implementation (``impl``): while an exercise it needs is a TODO, it prints one line
naming it and returns None (or draws what it can).
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable, Sequence

import numpy as np

from course.app import compare, plot
from course.app.starts import initialise
from course.geometry import se2
from course.notebook_helpers.chapter3 import todo_note
from course.solver import SolverOptions, minimize

#: the total heading drift (radians) added along the trajectory in ``drift_basin``
DRIFTS = np.linspace(-2.0 * np.pi, 2.0 * np.pi, 33)


def basin_starts(graph, impl="solutions", inits: Sequence[str] = ("file", "chordal")) -> dict | None:
    """``{init: (graph at that start, our Gauss-Newton's RunResult from it)}`` for each start of ``inits``,
    printing one line per start (its time, chi2 before and after, iterations, outcome); None, after one
    line naming the TODO, while an exercise it needs is not written."""
    from course.notebook_helpers.common import outcome

    starts = {}
    for init in inits:
        try:
            start, seconds = initialise(graph, init, impl)
        except NotImplementedError as exc:
            print(todo_note(exc, f"the {init} start needs it"))
            return None
        (gn,) = compare.run_posegraph(graph, impl=impl, methods=["gauss-newton"], backends=["ours"], init=init,
                                      unimplemented="row")
        if gn.not_run:
            print(f"not written yet: {gn.not_run.removeprefix('not implemented: ')} (Gauss-Newton from {init})")
            return None
        starts[init] = (start, gn)
        print(f"{graph.name} from {init} ({1e3 * seconds:.1f} ms): chi2 {gn.initial_chi2:.4g} -> "
              f"{gn.final_chi2:.6g} in {gn.iterations} iterations ({outcome(gn)})")
    return starts


def drifted(poses, drift: float) -> np.ndarray:
    """``poses`` (N, 3) rebuilt along the chain 0 -> 1 -> ... -> N-1 from their consecutive relative
    poses, each relative heading turned by ``drift / (N - 1)``: pose 0 stays, the last pose's heading is
    off by ``drift``, as dead reckoning with a constant gyro bias would be."""
    poses = np.asarray(poses, dtype=float)
    rel = se2.between(poses[:-1], poses[1:])
    rel[:, 2] += drift / len(rel)
    out = np.empty_like(poses)
    out[0] = poses[0]
    for k in range(len(rel)):
        out[k + 1] = se2.compose(out[k], rel[k])
    return out


def drift_basin(graph, impl="solutions", drifts=DRIFTS, show: float = 4.32):
    """Two panels on ``graph``: (left) chi2 of the drifted starts ``drifted(x*, d)`` against the drift d,
    with x* our Gauss-Newton's minimum from the file's poses, and the chi2 where Gauss-Newton
    (``impl``'s, at most 50 iterations) ends from each; (right) where Gauss-Newton ends from the drift
    nearest ``show``, over the minimum x*. Prints the drifts from which it reaches the minimum.
    None (after one line naming the TODO) while ``impl``'s pose-graph pieces are not written."""
    from course.problems.posegraph.problem import PoseGraphProblem

    (best,) = compare.run_posegraph(graph, impl=impl, methods=["gauss-newton"], backends=["ours"],
                                    unimplemented="row")
    if best.not_run:
        print(f"not written yet: {best.not_run.removeprefix('not implemented: ')} "
              "(this figure runs your Gauss-Newton on a pose graph: chapter 2)")
        return None
    x_star = np.asarray(best.params).reshape(-1, 3)
    drift = np.asarray(drifts, dtype=float)
    start_chi2: list = []
    end_chi2: list = []
    runs: list = []
    for d in drift:
        start = graph.with_poses(drifted(x_star, d))
        run = minimize(PoseGraphProblem(start, impl), "gauss-newton", impl=impl,
                       options=SolverOptions(max_iterations=50))
        start_chi2.append(start.chi2())
        end_chi2.append(run.final_chi2)
        runs.append(run)
    drifts, starts, ends = drift, np.array(start_chi2), np.array(end_chi2)
    home = np.abs(ends - best.final_chi2) <= 1e-6 * best.final_chi2
    fig = plot.figure(12.0, 4.8)
    left, right = fig.subplots(1, 2)
    left.semilogy(drifts, starts, ".-", color="0.5", label="chi2 at the drifted start")
    left.semilogy(drifts[home], ends[home], "o", color="C0", label="Gauss-Newton ends at the minimum")
    left.semilogy(drifts[~home], ends[~home], "o", color="C3", label="Gauss-Newton ends elsewhere")
    left.axhline(best.final_chi2, color="k", linestyle=":", linewidth=1, label=f"the minimum, {best.final_chi2:.6g}")
    left.set_xlabel("heading drift added along the trajectory (rad)")
    left.set_ylabel("chi2")
    left.set_title(f"{graph.name}: where Gauss-Newton ends from each drifted start")
    left.legend(fontsize=8)
    k = int(np.argmin(np.abs(drifts - show)))
    end = np.asarray(runs[k].params).reshape(-1, 3)
    plot.draw_graph(right, graph, x_star, "0.6")
    plot.draw_graph(right, graph, end, "C0" if home[k] else "C3")
    right.set_title(f"from the start drifted by {drifts[k]:.2f} rad (chi2 {starts[k]:.3g}), Gauss-Newton ends\n"
                    f"at chi2 {ends[k]:.3g} (colour); grey: the minimum", fontsize=9)
    inside = drifts[home]
    edges = graph.num_poses - 1
    print(f"{graph.name}: the minimum chi2 {best.final_chi2:.6g}; Gauss-Newton returns to it from "
          f"{int(home.sum())} of {len(drifts)} drifted starts, every drift in "
          f"[{inside.min():.2f}, {inside.max():.2f}] rad (spread over the {edges} edges of the chain: "
          f"up to {max(abs(inside.min()), inside.max()) / edges:.4f} rad per edge)")
    if (~home).any():
        print(f"from the others it stops at chi2 {ends[~home].min():.3g} to {ends[~home].max():.3g} "
              f"(starts from {starts[~home].min():.3g} to {starts[~home].max():.3g})")
    return fig


def hops(num_poses: int, edges_i, edges_j, root: int) -> np.ndarray:
    """Hop distance (N,) of every pose from ``root``, the edges undirected (a plain breadth-first search)."""
    neighbours: list[list[int]] = [[] for _ in range(num_poses)]
    for i, j in zip(np.asarray(edges_i).tolist(), np.asarray(edges_j).tolist()):
        neighbours[i].append(j)
        neighbours[j].append(i)
    distance = np.full(num_poses, -1)
    distance[root] = 0
    queue = deque([root])
    while queue:
        u = queue.popleft()
        for v in neighbours[u]:
            if distance[v] < 0:
                distance[v] = distance[u] + 1
                queue.append(v)
    return distance


def edge_chi2(graph, poses) -> np.ndarray:
    """Each edge's ``e_k^T Omega_k e_k`` (M,) at ``poses`` (the framework's own error)."""
    e = graph.errors(poses)
    return np.einsum("mi,mij,mj->m", e, graph.information, e)


def tree_start(graph, impl="solutions"):
    """Two panels on ``graph``: (left) the file's poses, coloured by their index along the chain; (right)
    ``impl``'s spanning-tree start, coloured by hop distance from the anchor, with the edges it does
    not satisfy (those left out of the tree) in red. Prints how the chi2 splits between the edges.
    None (after one line naming the TODO) while ``spanning_tree_poses`` is not written."""
    try:
        tree, seconds = initialise(graph, "tree", impl)
    except NotImplementedError as exc:
        print(todo_note(exc, "the figure of the tree start needs it"))
        return None
    anchor = int(graph.fixed[0])
    distance = hops(graph.num_poses, graph.edges_i, graph.edges_j, anchor)
    per_edge = edge_chi2(graph, tree.poses)
    exact = per_edge <= 1e-9 * max(1.0, float(per_edge.max()))
    fig = plot.figure(12.0, 5.2)
    left, right = fig.subplots(1, 2)
    plot.draw_graph(left, graph, graph.poses, "0.7")
    dots = left.scatter(graph.poses[:, 0], graph.poses[:, 1], c=np.arange(graph.num_poses), s=6, cmap="viridis")
    fig.colorbar(dots, ax=left, label="index along the file's chain")
    left.set_title(f"the file's poses: chi2 {graph.chi2():.4g}", fontsize=9)
    from matplotlib.collections import LineCollection

    segments = np.stack([tree.poses[graph.edges_i, :2], tree.poses[graph.edges_j, :2]], axis=1)
    right.add_collection(LineCollection(list(segments[exact]), colors="0.7", linewidths=0.4))
    right.add_collection(LineCollection(list(segments[~exact]), colors="C3", linewidths=0.6, alpha=0.7))
    dots = right.scatter(tree.poses[:, 0], tree.poses[:, 1], c=distance, s=6, cmap="viridis")
    fig.colorbar(dots, ax=right, label="hops from the anchor")
    right.set_aspect("equal", adjustable="datalim")
    right.autoscale()
    right.set_title(f"the tree start: chi2 {tree.chi2():.4g}; red: the {int((~exact).sum())} edges it does not "
                    "satisfy", fontsize=9)
    print(f"{graph.name}: {graph.num_poses} poses, {graph.num_edges} edges; the tree start ({1e3 * seconds:.1f} ms) "
          f"satisfies {int(exact.sum())} edges exactly (N - 1 = {graph.num_poses - 1}), and the "
          f"{int((~exact).sum())} others carry its chi2 {tree.chi2():.4g}")
    print(f"hops from the anchor: at most {distance.max()}, mean {distance.mean():.1f}; along the file's "
          f"chain: up to {graph.num_poses - 1}")
    return fig


def relaxation(spreads: Sequence[float] = (0.4, 2.8), offsets: Sequence[float] = (-1.0, 0.3, 1.0),
               weights: Sequence[float] = (1.0, 2.0, 0.5)):
    """Three panels. (left) The rotation cost of one edge against its angle error phi: the squared
    wrapped angle (the pose graph's) and the chordal ``|v_j - R(theta_ij) v_i|^2 = 2 - 2 cos phi`` of
    unit vectors. (middle, right) One free orientation v = (c, s) whose anchored neighbours each
    predict a unit vector ``R(theta_ij) v_i`` (a "vote", ``weights`` its w) at ``offsets`` times half
    of ``spreads[k]`` radians from 0.6 rad: the relaxed least-squares v (the constraint |v| = 1
    dropped), its projection v / |v|, and the angle that minimizes the wrapped cost. Prints |v| and
    the angles."""
    fig = plot.figure(13.0, 4.4)
    axes = fig.subplots(1, 3)
    phi = np.linspace(-np.pi, np.pi, 400)
    axes[0].plot(phi, se2.wrap_angle(phi) ** 2, label="wrapped angle squared (the pose graph's)")
    axes[0].plot(phi, 2.0 - 2.0 * np.cos(phi), label="chordal: 2 - 2 cos(phi)")
    axes[0].set_xlabel("angle error of the edge, phi (rad)")
    axes[0].set_ylabel("cost of one edge (w = 1)")
    axes[0].set_title("the chordal cost: the same near 0, bounded", fontsize=9)
    axes[0].legend(fontsize=8)
    w = np.asarray(weights, dtype=float)
    circle = np.linspace(0.0, 2.0 * np.pi, 200)
    for ax, spread in zip(axes[1:], spreads):
        angles = 0.6 + np.asarray(offsets, dtype=float) * spread / 2.0
        votes = np.column_stack([np.cos(angles), np.sin(angles)])
        # least squares over v of sum_k w_k |v - vote_k|^2, written as rows sqrt(w_k) (v - vote_k)
        rows = np.kron(np.sqrt(w)[:, None], np.eye(2))
        v = np.linalg.lstsq(rows, (np.sqrt(w)[:, None] * votes).ravel(), rcond=None)[0]
        projected = v / np.linalg.norm(v)
        grid = np.linspace(-np.pi, np.pi, 20001)
        geodesic = grid[np.argmin([np.sum(w * se2.wrap_angle(t - angles) ** 2) for t in grid])]
        ax.plot(np.cos(circle), np.sin(circle), color="0.7", linewidth=0.8)
        for k, (vote, wk) in enumerate(zip(votes, w)):
            ax.plot([0.0, vote[0]], [0.0, vote[1]], color="C0", linewidth=0.6 + wk,
                    label="votes R(theta_ij) v_i (width: w)" if k == 0 else None)
        ax.plot([v[0]], [v[1]], "o", color="C3", label=f"relaxed v, |v| = {np.linalg.norm(v):.3f}")
        ax.plot([0.0, projected[0]], [0.0, projected[1]], "--", color="C3", linewidth=0.8)
        ax.plot([projected[0]], [projected[1]], "s", color="C3", label="projected: v / |v|")
        ax.plot([np.cos(geodesic)], [np.sin(geodesic)], "x", color="k", markersize=9,
                label="minimum of the wrapped cost")
        ax.set_aspect("equal")
        ax.set_xlim(-1.15, 1.15)
        ax.set_ylim(-1.15, 1.15)
        ax.set_xlabel("c")
        ax.set_ylabel("s")
        ax.set_title(f"votes spread over {spread:g} rad", fontsize=9)
        ax.legend(fontsize=7, loc="lower left")
        print(f"votes spread over {spread:g} rad: relaxed |v| = {np.linalg.norm(v):.3f}, projected angle "
              f"{np.arctan2(v[1], v[0]):.4f} rad, minimum of the wrapped cost {geodesic:.4f} rad")
    return fig


def relaxed_residual(theta_ij: float) -> Callable:
    """``r(v_i, v_j) = v_j - R(theta_ij) v_i`` (2,): one edge's relaxed rotation residual."""
    R = se2.rotation(theta_ij)
    return lambda v_i, v_j: np.asarray(v_j, dtype=float) - R @ np.asarray(v_i, dtype=float)


def check_relaxed_jacobians(jacobians: Callable, theta_ij: float = 0.7, seed: int = 3):
    """``course.check_jacobian`` of your ``jacobians(theta_ij) -> (J_i, J_j)`` (2, 2) each against central
    differences of :func:`relaxed_residual` at random ``v_i, v_j``; the check's result, or None after one
    line while ``jacobians`` raises ``NotImplementedError``."""
    from course.geometry.jacobian_check import check_jacobian

    try:
        J_i, J_j = jacobians(theta_ij)
    except NotImplementedError as exc:
        print(f"not written yet: {exc} (then run this cell: check_jacobian compares your J_i, J_j with "
              "central differences of the residual)")
        return None
    v_i, v_j = np.random.default_rng(seed).normal(size=(2, 2))
    return check_jacobian(relaxed_residual(theta_ij), [v_i, v_j], J=[J_i, J_j], names=["v_i", "v_j"])
