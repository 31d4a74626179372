"""Chapter 2's lesson (``notebooks/chapter2_pose_graphs.py``): the figures of the theory, one edge for
the Jacobian checker, and a guard that turns an unwritten exercise into one line.

Conventions (``course.geometry.se2``): a pose is ``(x, y, theta)``, ``p_world = R(theta) p_body + t``;
chapter 2 moves poses by plain addition (the angle wrapped to ``[-pi, pi)``); an edge ``i -> j``
measures ``z_ij ~ x_i^-1 o x_j``; H and b are ``3N x 3N`` and ``3N``, pose ``p`` in rows ``3p:3p+3``.

None of these needs an exercise: the Jacobians of the figures are central differences of the
framework's own edge error (``PoseGraph.errors``), and the sparsity patterns depend on the edges alone.

* ``todo_as_one_line``, ``exercise``, ``example_edge``, ``edge_error``, ``edges_apart``: what the checker
  cells use.
* ``edge_figure``: one edge, where its measurement puts pose j, and the error.
* ``block_structure_figure``: a small graph, and the blocks of J and H one of its edges fills.
* ``rigid_motions``, ``graph_jacobian``, ``gauge_table``, ``gauge_figure``: the three directions that
  move the whole graph, and the spectrum of H with every pose free against the first pose fixed.
* ``upper_pattern``, ``cholesky_pattern``, ``amd_order``, ``fill_in``, ``fill_in_figure``,
  ``fill_in_table``: the scalar pattern of H, of its Cholesky factor under an ordering, and its fill-in.
* ``growth_figure``: seconds per solve against the number of poses, dense and sparse.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from course.app import plot
from course.geometry.jacobian_check import numerical_jacobian
from course.geometry.se2 import between, compose, edge_errors
from course.notebook_helpers.lesson import exercise, todo_as_one_line  # noqa: F401 (the cells call them here)

# ---------------------------------------------------------------- every cell that runs your code




def example_edge() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """One edge ``(x_i, x_j, z_ij)`` (each (3,)) whose error is visibly nonzero: pose j lies 0.35 m and
    0.25 rad away from where the measurement puts it; no angle near +-pi."""
    x_i = np.array([1.0, 0.5, 0.4])
    z_ij = np.array([2.0, 0.6, 0.5])
    x_j = compose(x_i, z_ij) + np.array([0.3, -0.18, 0.25])
    return x_i, x_j, z_ij


def edge_error(x_i, x_j, z_ij) -> np.ndarray:
    """The error ``e_ij`` (3,) of one edge from its definition (the framework's, ``PoseGraph.errors``)."""
    poses = np.stack([np.asarray(x_i, dtype=float), np.asarray(x_j, dtype=float)])
    return edge_errors(poses, np.array([0]), np.array([1]), np.asarray(z_ij, dtype=float)[None])[0]


def edges_apart(function, X_i, X_j, z):
    """Call a vectorized ``function(poses, edges_i, edges_j, measurements)`` with edge ``k`` joining row
    ``k`` of ``X_i`` (M, 3) to row ``k`` of ``X_j`` (M, 3), so each pose array can be moved on its own
    (what ``check_jacobian`` does with a list of variables)."""
    X_i, X_j = np.atleast_2d(np.asarray(X_i, dtype=float)), np.atleast_2d(np.asarray(X_j, dtype=float))
    m = len(X_i)
    index = np.arange(m)
    return function(np.vstack([X_i, X_j]), index, index + m, np.atleast_2d(np.asarray(z, dtype=float)))


# ---------------------------------------------------------------- section 1: the edge


def _pose(ax, pose, colour, name, dashed=False, scale=0.45, offset=(-8, -15)):
    """A pose as a dot with its x axis (an arrow) and its y axis (a thin line), labelled."""
    x, y, theta = pose
    c, s = np.cos(theta), np.sin(theta)
    style = dict(color=colour, linestyle="--" if dashed else "-")
    ax.annotate("", xy=(x + scale * c, y + scale * s), xytext=(x, y),
                arrowprops=dict(arrowstyle="->", color=colour, linestyle="--" if dashed else "-", linewidth=1.5))
    ax.plot([x, x - 0.6 * scale * s], [y, y + 0.6 * scale * c], linewidth=0.8, **style)
    ax.plot([x], [y], "o", color=colour, markersize=5, fillstyle="none" if dashed else "full")
    ax.annotate(name, (x, y), textcoords="offset points", xytext=offset, color=colour, fontsize=9)


def edge_figure(x_i=None, x_j=None, z_ij=None):
    """One edge seen from above: pose i, pose j, and ``x_i o z_ij`` (where the measurement puts pose j,
    dashed), with the translation ``t_j - t_i`` and the error's translation (drawn in the world, the
    error itself is it in the dashed pose's axes); the title prints ``e_ij`` (from the definition)."""
    if x_i is None:
        x_i, x_j, z_ij = example_edge()
    predicted = compose(x_i, z_ij)
    e = between(predicted, x_j)
    fig = plot.figure(6.5, 4.6)
    ax = fig.subplots()
    ax.annotate("", xy=x_j[:2], xytext=x_i[:2], arrowprops=dict(arrowstyle="->", color="0.6", linewidth=0.8))
    middle = (x_i[:2] + x_j[:2]) / 2
    ax.annotate("$t_j - t_i$", middle, textcoords="offset points", xytext=(0, 6), color="0.45", fontsize=9)
    ax.annotate("", xy=x_j[:2], xytext=predicted[:2],
                arrowprops=dict(arrowstyle="->", color="tab:red", linewidth=1.8))
    ax.annotate("error (translation)", (predicted[:2] + x_j[:2]) / 2, textcoords="offset points",
                xytext=(-75, -22), color="tab:red", fontsize=9)
    _pose(ax, x_i, "tab:blue", "$x_i$")
    _pose(ax, x_j, "tab:green", "$x_j$", offset=(8, -4))
    _pose(ax, predicted, "tab:orange", r"$x_i \circ z_{ij}$", dashed=True, offset=(-40, 8))
    ax.set_aspect("equal", adjustable="datalim")
    ax.margins(0.25)
    ax.grid(True, alpha=0.3)
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_title(r"$e_{ij} = (x_i \circ z_{ij})^{-1} \circ x_j$" + f" = ({e[0]:.3f}, {e[1]:.3f}, {e[2]:.3f})",
                 fontsize=10)
    return fig


# ---------------------------------------------------------------- section 2: J, H and the gauge


def block_structure_figure(graph, edge: int):
    """Three panels: (left) ``graph``'s edges, its poses on a circle in trajectory order, edge ``edge``
    in red; (middle) the 3x3 blocks of J (block row k: edge k, block column p: pose p) that are nonzero,
    edge ``edge``'s two in colour; (right) the blocks of H, the four edge ``edge`` adds to in colour."""
    from matplotlib.colors import ListedColormap

    n, m = graph.num_poses, graph.num_edges
    ei, ej = graph.edges_i, graph.edges_j
    i, j = int(ei[edge]), int(ej[edge])
    J = np.zeros((m, n))
    J[np.arange(m), ei] = 1
    J[np.arange(m), ej] = 1
    J[edge, i], J[edge, j] = 2, 3
    H = np.zeros((n, n))
    H[np.arange(n), np.arange(n)] = 1
    H[ei, ej] = H[ej, ei] = 1
    H[i, i] = H[j, j] = 2
    H[i, j] = H[j, i] = 3
    colours = ListedColormap(["white", "0.55", "tab:blue", "tab:green"])
    fig = plot.figure(12.0, 4.4)
    left, middle, right = fig.subplots(1, 3, width_ratios=[1.2, 1.0, 1.0])
    angle = np.pi / 2 - 2 * np.pi * np.arange(n) / n  # the poses on a circle, in trajectory order
    ring = np.stack([np.cos(angle), np.sin(angle)], axis=1)
    for k in range(m):
        closure = abs(int(ei[k]) - int(ej[k])) != 1
        left.plot(*ring[[ei[k], ej[k]]].T, color="tab:red" if k == edge else "0.6",
                  linewidth=2.0 if k == edge else 0.8, linestyle=":" if closure and k != edge else "-")
    left.plot(*ring.T, "o", color="0.3", markersize=5)
    for p in range(n):
        left.annotate(str(p), ring[p] * 1.13, ha="center", va="center", fontsize=8,
                      color="tab:blue" if p == i else "tab:green" if p == j else "0.2")
    left.set_aspect("equal")
    left.set_xlim(-1.3, 1.3)
    left.set_ylim(-1.3, 1.3)
    left.axis("off")
    left.set_title(f"{graph.name}: odometry solid, loop closures dotted\n"
                   f"edge {edge} (red) joins pose {i} (blue) and {j} (green)", fontsize=9)
    for ax, matrix, title in ((middle, J, f"J: {m} x {n} blocks of 3x3\nrow {edge}: A at pose {i}, B at pose {j}"),
                              (right, H, f"H: {n} x {n} blocks of 3x3\nedge {edge} adds to ({i},{i}), ({i},{j}), "
                                         f"({j},{i}), ({j},{j})")):
        ax.imshow(matrix, cmap=colours, vmin=0, vmax=3, interpolation="nearest")
        ax.set_xticks(range(n))
        ax.set_xticklabels([str(p) for p in range(n)], fontsize=6)
        ax.set_yticks(range(len(matrix)))
        ax.set_yticklabels([str(r) for r in range(len(matrix))], fontsize=6)
        ax.set_xticks(np.arange(-0.5, n), minor=True)
        ax.set_yticks(np.arange(-0.5, len(matrix)), minor=True)
        ax.grid(which="minor", color="0.85", linewidth=0.5)
        ax.tick_params(which="minor", length=0)
        ax.set_xlabel("pose (block column)", fontsize=8)
        ax.set_title(title, fontsize=9)
    middle.set_ylabel("edge (block row)", fontsize=8)
    right.set_ylabel("pose (block row)", fontsize=8)
    return fig


def rigid_motions(poses) -> np.ndarray:
    """(3, 3N): the directions that move every pose by the same rigid motion, as plain increments of
    ``(x, y, theta)``: along x, along y, and the turn about the world's origin ``(-y_p, x_p, 1)`` per pose
    (the derivative of ``t_p -> R(alpha) t_p, theta_p -> theta_p + alpha`` at ``alpha = 0``)."""
    poses = np.asarray(poses, dtype=float)
    n = len(poses)
    out = np.zeros((3, n, 3))
    out[0, :, 0] = 1.0
    out[1, :, 1] = 1.0
    out[2, :, 0], out[2, :, 1], out[2, :, 2] = -poses[:, 1], poses[:, 0], 1.0
    return out.reshape(3, 3 * n)


def graph_jacobian(graph, poses=None) -> np.ndarray:
    """J (3M, 3N) of all edge errors at ``poses`` (default: the start), by central differences of the
    framework's edge error; row ``3k + r``: row r of edge k's error, column ``3p + c``: coordinate c of pose p."""
    poses = graph.poses if poses is None else np.asarray(poses, dtype=float)
    return numerical_jacobian(lambda x: graph.errors(x), poses, plus="se2")


def _hessian(graph, J) -> np.ndarray:
    """``J^T Omega J`` with ``Omega`` the block diagonal of the edges' information."""
    OJ = np.matmul(graph.information, J.reshape(graph.num_edges, 3, -1)).reshape(J.shape)
    return J.T @ OJ


def gauge_spectra(graph) -> tuple[np.ndarray, np.ndarray]:
    """The eigenvalues (ascending) of H at the start with every pose free (3N,), and with pose 0 fixed,
    i.e. its rows and columns removed (3N - 3,)."""
    H = _hessian(graph, graph_jacobian(graph))
    return np.linalg.eigvalsh(H), np.linalg.eigvalsh(H[3:, 3:])


def gauge_table(graph, seed=0) -> str:
    """``|J v| / |v|`` at the start of ``graph`` for the three rigid motions and, for comparison, a random
    direction; and the smallest eigenvalues of H free and with pose 0 fixed."""
    J = graph_jacobian(graph)
    motions = rigid_motions(graph.poses)
    random = np.random.default_rng(seed).normal(size=J.shape[1])
    free, fixed = gauge_spectra(graph)
    lines = [f"{graph.name}: {graph.num_poses} poses, {graph.num_edges} edges, at the start",
             f"{'direction v (every pose moved alike)':40} {'|J v| / |v|':>12}"]
    for name, v in zip(("along x", "along y", "turn about the origin (-y_p, x_p, 1)"), motions):
        lines.append(f"{name:40} {np.linalg.norm(J @ v) / np.linalg.norm(v):12.1e}")
    ratio = np.linalg.norm(J @ random) / np.linalg.norm(random)
    lines.append(f"{'a random direction (for comparison)':40} {ratio:12.1e}")
    lines.append("smallest eigenvalues of H, every pose free: " + ", ".join(f"{v:.1e}" for v in free[:4]))
    lines.append("smallest eigenvalues of H, pose 0 fixed:    " + ", ".join(f"{v:.1e}" for v in fixed[:4]))
    return "\n".join(lines)


def gauge_figure(graph):
    """The eigenvalues of H at the start of ``graph``, ascending, on a log scale: every pose free against
    pose 0 fixed (its rows and columns removed)."""
    free, fixed = gauge_spectra(graph)
    floor = 1e-12 * free[-1]
    fig = plot.figure(7.0, 4.2)
    ax = fig.subplots()
    ax.semilogy(np.arange(len(free)), np.maximum(np.abs(free), floor), ".", label="every pose free (3N values)")
    ax.semilogy(np.arange(3, 3 + len(fixed)), fixed, "x", markersize=4, label="pose 0 fixed (3N - 3 values)")
    ax.axhline(floor, color="grey", linewidth=0.5)
    ax.annotate("three eigenvalues at rounding level: the gauge", (3, floor), textcoords="offset points",
                xytext=(8, 6), fontsize=8)
    ax.set_xlabel("index (ascending)")
    ax.set_ylabel("eigenvalue of H (|value|, floored at 1e-12 max)")
    ax.set_title(f"{graph.name}: the spectrum of H at the start", fontsize=10)
    ax.legend(fontsize=8)
    ax.grid(True, which="major", alpha=0.3)
    return fig


# ---------------------------------------------------------------- section 3: Cholesky and fill-in


def upper_pattern(num_poses: int, edges_i, edges_j) -> sp.csc_matrix:
    """The pattern (ones) of H's upper triangle, diagonal included, (3N, 3N) CSC: every entry of the
    3x3 blocks of each pose and of each pair of poses an edge joins."""
    edges_i, edges_j = np.asarray(edges_i), np.asarray(edges_j)
    dof = np.concatenate([3 * edges_i[:, None] + np.arange(3), 3 * edges_j[:, None] + np.arange(3)], axis=1)
    rows = np.repeat(dof, 6, axis=1).ravel()
    cols = np.tile(dof, (1, 6)).ravel()
    n = 3 * num_poses
    rows, cols = np.concatenate([rows, np.arange(n)]), np.concatenate([cols, np.arange(n)])
    keep = rows <= cols
    pattern = sp.csc_matrix((np.ones(int(keep.sum())), (rows[keep], cols[keep])), shape=(n, n))
    pattern.data[:] = 1.0  # duplicates summed: back to ones
    return pattern


def cholesky_pattern(upper, order=None) -> sp.csc_matrix:
    """The pattern of the Cholesky factor L (lower, diagonal included) of the symmetric matrix whose
    upper triangle is ``upper`` (CSC), its rows and columns taken in ``order`` (default: as they are).

    Symbolic elimination: column k of L holds the rows below k of column k of the permuted matrix and
    those of every column whose first entry below the diagonal is k (its children in the elimination
    tree), the values never looked at."""
    upper = sp.csc_matrix(upper)
    n = upper.shape[0]
    if order is not None:
        order = np.asarray(order)
        full = upper + sp.triu(upper, k=1).T
        upper = sp.triu(sp.csc_matrix(full)[order][:, order], format="csc")
    lower = sp.csc_matrix(upper.T)  # column k: the rows >= k of column k of the lower triangle
    children: list[list[int]] = [[] for _ in range(n)]
    columns: list[set] = []
    indices, indptr = [], [0]
    for k in range(n):
        rows = set(lower.indices[lower.indptr[k]:lower.indptr[k + 1]].tolist())
        for child in children[k]:
            rows |= columns[child]
        rows.discard(k)
        columns.append(rows)
        if rows:
            children[min(rows)].append(k)  # k's parent in the elimination tree
        indices += [k, *sorted(rows)]
        indptr.append(len(indices))
    return sp.csc_matrix((np.ones(len(indices)), np.array(indices), np.array(indptr)), shape=(n, n))


def amd_order(upper) -> tuple[np.ndarray, str]:
    """A fill-reducing order of the matrix whose upper triangle is ``upper``, and its name: qdldl's
    approximate minimum degree (what ``SparseCholeskySolver`` gets), or SuperLU's minimum degree on
    ``A^T + A`` where qdldl is not installed. Only the pattern matters: the values are replaced by a
    diagonally dominant matrix with the same pattern."""
    upper = sp.csc_matrix(upper, dtype=float, copy=True)
    upper.data[:] = -1.0
    full = upper + sp.triu(upper, k=1).T
    degree = np.asarray(abs(full).sum(axis=1)).ravel()
    upper = upper + sp.diags(degree + 1.0)
    try:
        import qdldl
    except ImportError:
        from scipy.sparse.linalg import splu

        full = sp.csc_matrix(upper + sp.triu(upper, k=1).T)
        factor = splu(full, permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0, options={"SymmetricMode": True})
        return np.asarray(factor.perm_c), "minimum degree (SuperLU)"
    return np.asarray(qdldl.Solver(sp.triu(upper, format="csc"), upper=True).factors()[2]), "AMD (qdldl)"


def fill_in(upper, order=None) -> dict:
    """Entries of H's upper triangle and of L (diagonal included) under ``order``, the fill-in (L's
    entries that H's lower triangle does not have) and the flops of the numeric factorization
    (``sum_k c_k^2``, c_k the entries of column k of L below the diagonal):
    ``{"H": int, "L": int, "fill": int, "flops": int, "pattern": csc}``."""
    L = cholesky_pattern(upper, order)
    below = np.diff(L.indptr) - 1
    h = int(sp.csc_matrix(upper).nnz)
    return {"H": h, "L": int(L.nnz), "fill": int(L.nnz) - h, "flops": int(np.sum(below.astype(np.int64) ** 2)),
            "pattern": L}


def fill_in_figure(graph):
    """Three panels: H's upper triangle (poses in file order), the pattern of its Cholesky factor L in
    that order, and L under a fill-reducing order (:func:`amd_order`), each titled with its entries."""
    upper = upper_pattern(graph.num_poses, graph.edges_i, graph.edges_j)
    order, name = amd_order(upper)
    natural, reordered = fill_in(upper), fill_in(upper, order)
    fig = plot.figure(12.0, 4.3)
    panels = fig.subplots(1, 3)
    panels[0].spy(upper, markersize=0.4)
    panels[0].set_title(f"H, upper triangle: {natural['H']} entries", fontsize=9)
    panels[1].spy(natural["pattern"], markersize=0.4)
    panels[1].set_title(f"L, poses in file order: {natural['L']} entries", fontsize=9)
    panels[2].spy(reordered["pattern"], markersize=0.4)
    panels[2].set_title(f"L, {name} order: {reordered['L']} entries", fontsize=9)
    for ax in panels:
        ax.tick_params(labelsize=7)
    n = 3 * graph.num_poses
    fig.suptitle(f"{graph.name}: {graph.num_poses} poses, {graph.num_edges} edges; n = {n} "
                 f"(a dense triangle: {n * (n + 1) // 2} entries)", fontsize=10)
    return fig


def fill_in_table(graphs) -> str:
    """One row per graph: poses, edges, the entries of H's upper triangle, of L in file order and under
    a fill-reducing order, and the flops of each numeric factorization (:func:`fill_in`)."""
    head = (f"{'graph':16} {'poses':>5} {'edges':>5} {'H upper':>8} {'L file order':>12} {'flops':>11} "
            f"{'L reordered':>11} {'flops':>10}  order")
    lines = [head, "-" * len(head)]
    for g in graphs:
        upper = upper_pattern(g.num_poses, g.edges_i, g.edges_j)
        order, name = amd_order(upper)
        natural, reordered = fill_in(upper), fill_in(upper, order)
        lines.append(f"{g.name:16} {g.num_poses:5d} {g.num_edges:5d} {natural['H']:8d} {natural['L']:12d} "
                     f"{natural['flops']:11.3g} {reordered['L']:11d} {reordered['flops']:10.3g}  {name}")
    return "\n".join(lines)


# ---------------------------------------------------------------- the experiments


def growth_figure(sizes, dense_seconds, sparse_seconds, slopes):
    """Seconds per solve against the number of poses, log-log, dense and sparse, with the fitted slopes."""
    fig = plot.figure(6.0, 4.5)
    ax = fig.add_subplot()
    ax.loglog(sizes, dense_seconds, "o-", label=f"dense (dense_solve), slope {slopes[0]:.2f}")
    ax.loglog(sizes, sparse_seconds, "s-", label=f"sparse (SparseCholeskySolver), slope {slopes[1]:.2f}")
    ax.set_xlabel("poses N (manhattan:N)")
    ax.set_ylabel("seconds per solve")
    ax.set_title("one Gauss-Newton solve, dense against sparse")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize="small")
    return fig

