"""Chapter 6's lesson (``notebooks/chapter6_pose_graphs_3d.py``): the figures of the theory, one edge
for the Jacobian checker, and a guard that turns an unwritten exercise into one line.

Conventions (``course.geometry.se3``): a pose is ``T = (t (3,), R (3, 3))``, ``x_world = R x_body + t``;
the course moves it on the right, ``T (+) (rho, phi) = (t + R rho, R Exp(phi))``; angles in radians
unless a name says degrees.

* ``todo_as_one_line``: a context in which an unwritten exercise (``NotImplementedError``) prints one line.
* ``perturbation_figure``: one pose moved on the left, ``Exp(delta) T``, and on the right, ``T (+) delta``.
* ``right_jacobian_figure``: how far ``phi + delta`` and ``phi + J_r^-1(phi) delta`` are from
  ``Log(Exp(phi) Exp(delta))``, against the angle ``|phi|``.
* ``random_edge``: one edge ``i -> j`` (poses and measurement) with a chosen residual rotation.
* ``block_pattern``, ``fill_in``, ``sparsity_figure``, ``fill_in_table``: H's 6x6-block pattern and its
  Cholesky factor's.
* ``chordal_distance``, ``chordal_figure``: the chordal distance against the angle; the singular values
  of the relaxation's matrices against the distance from the anchor.
* ``tls_surrogate``, ``gm_surrogate``, ``surrogate_figure``: GNC's surrogate costs ``rho_mu(s)``.
* ``gnc_weights_figure``, ``gnc_rounds_table``: each loop closure's GNC weight, round by round; what
  each run kept.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
from scipy.sparse import csgraph
from scipy.sparse.linalg import splu

from course.app import plot
from course.core.impl import not_implemented_reason
from course.geometry.so3 import exp_many, log_many, right_jacobian_inverse_many
from course.notebook_helpers.lesson import exercise, todo_as_one_line  # noqa: F401 (the cells call them here)

# ---------------------------------------------------------------- every cell that runs your code




# ---------------------------------------------------------------- section 1: perturbations


def _frame(ax, t, R, colour_x="tab:red", colour_y="tab:green", alpha=1.0, scale=0.6):
    """A pose's x and y axes, seen from above (the x-y plane)."""
    for axis, colour in ((0, colour_x), (1, colour_y)):
        ax.arrow(t[0], t[1], scale * R[0, axis], scale * R[1, axis], color=colour, alpha=alpha,
                 width=0.02, head_width=0.12, length_includes_head=True)


def perturbation_figure(angles_degrees=(-40.0, -20.0, 20.0, 40.0), shift=0.8):
    """Two panels, seen from above: a pose ``T`` (t = (3, 1, 0), yawed 30 degrees) moved by a rotation
    about z of each of ``angles_degrees`` and by a translation ``shift`` along x, on the left
    (``Exp(delta) T``: about the world's origin and axes) and on the right (``T (+) delta``: about the
    pose's own origin and axes)."""
    t = np.array([3.0, 1.0, 0.0])
    R = exp_many(np.array([[0.0, 0.0, np.radians(30.0)]]))[0]
    fig = plot.figure(10.0, 4.6)
    panels = fig.subplots(1, 2)
    for ax, side in zip(panels, ("left", "right")):
        ax.plot([0], [0], "k+", markersize=12)
        ax.annotate("world origin", (0, 0), textcoords="offset points", xytext=(6, -12), fontsize=8)
        for angle in angles_degrees:
            Rd = exp_many(np.array([[0.0, 0.0, np.radians(angle)]]))[0]
            if side == "left":  # Exp(delta) T = (R_d t, R_d R)
                t_new, R_new = Rd @ t, Rd @ R
            else:  # T (+) delta = (t, R Exp(phi))
                t_new, R_new = t, R @ Rd
            _frame(ax, t_new, R_new, "tab:red", "tab:green", alpha=0.35)
        for sign in (-1.0, 1.0):
            rho = np.array([sign * shift, 0.0, 0.0])
            t_new = t + rho if side == "left" else t + R @ rho
            _frame(ax, t_new, R, "tab:blue", "tab:cyan", alpha=0.5)
        _frame(ax, t, R)
        ax.set_aspect("equal")
        ax.set_xlim(-0.8, 4.4)
        ax.set_ylim(-0.6, 4.0)
        ax.grid(True, alpha=0.3)
        ax.set_xlabel("x (world)")
        ax.set_ylabel("y (world)")
    panels[0].set_title("on the left, Exp(delta) T: rotations turn the pose\nabout the world's origin; "
                        "shifts go along the world's x", fontsize=9)
    panels[1].set_title("on the right, T (+) delta: rotations turn the pose\nabout its own origin; "
                        "shifts go along its own x", fontsize=9)
    fig.suptitle(f"a pose (solid) moved by rotations of {', '.join(f'{a:g}' for a in angles_degrees)} degrees "
                 f"about z (red/green) and by {shift:g} along x (blue)", fontsize=10)
    return fig


def first_order_errors(angles, step=1e-3, seed=0) -> tuple[np.ndarray, np.ndarray]:
    """For ``phi = angle u`` (a fixed random axis u) and a fixed random ``delta`` of length ``step``:
    ``(|Log(Exp(phi) Exp(delta)) - (phi + delta)|, |Log(Exp(phi) Exp(delta)) - (phi + J_r^-1(phi) delta)|)``
    divided by ``|delta|``, each (K,) for ``angles`` (K,) in radians (below pi)."""
    rng = np.random.default_rng(seed)
    u = rng.normal(size=3)
    u /= np.linalg.norm(u)
    delta = rng.normal(size=3)
    delta *= step / np.linalg.norm(delta)
    phi = np.asarray(angles, dtype=float)[:, None] * u
    exact = log_many(np.matmul(exp_many(phi), exp_many(np.tile(delta, (len(phi), 1)))))
    naive = np.linalg.norm(exact - (phi + delta), axis=1) / step
    with_jr = np.linalg.norm(exact - (phi + np.einsum("kab,b->ka", right_jacobian_inverse_many(phi), delta)),
                             axis=1) / step
    return naive, with_jr


def right_jacobian_figure(step=1e-3):
    """The relative error of the two first-order approximations of ``Log(Exp(phi) Exp(delta))``
    (:func:`first_order_errors`, ``|delta| = step``) against ``|phi|`` in degrees, log scale."""
    degrees = np.linspace(0.5, 170.0, 200)
    naive, with_jr = first_order_errors(np.radians(degrees), step)
    fig = plot.figure(6.6, 3.8)
    ax = fig.add_subplot()
    ax.semilogy(degrees, naive, label="phi + delta (J_r^-1 taken as I)")
    ax.semilogy(degrees, with_jr, label="phi + J_r^-1(phi) delta")
    ax.set_xlabel("|phi| (degrees)")
    ax.set_ylabel(f"error / |delta|  (|delta| = {step:g} rad)")
    ax.set_title("Log(Exp(phi) Exp(delta)) to first order in delta", fontsize=10)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    return fig


# ---------------------------------------------------------------- section 2: one edge


@dataclass
class Edge:
    """One edge ``i -> j``: the poses ``T_i``, ``T_j`` and the measurement ``Z``, each ``(t (3,), R (3, 3))``."""

    T_i: tuple
    T_j: tuple
    Z: tuple

    def arguments(self, T_i=None, T_j=None) -> tuple:
        """``(t (2, 3), R (2, 3, 3), edges_i [0], edges_j [1], t_z (1, 3), R_z (1, 3, 3))``: the arguments of
        ``edge_errors_and_jacobians`` for this edge, with ``T_i``, ``T_j`` in place of the edge's poses if given."""
        T_i, T_j = T_i or self.T_i, T_j or self.T_j
        return (np.stack([T_i[0], T_j[0]]), np.stack([T_i[1], T_j[1]]), np.array([0]), np.array([1]),
                self.Z[0][None], self.Z[1][None])

    @property
    def residual_angle(self) -> float:
        """``|Log(R_z^T R_i^T R_j)|`` (radians)."""
        return float(np.linalg.norm(log_many((self.Z[1].T @ self.T_i[1].T @ self.T_j[1])[None])[0]))


def random_edge(seed=0, residual_angle=0.5) -> Edge:
    """Random poses ``T_i``, ``T_j`` (rotations of any size, positions within a few units) and a
    measurement ``Z`` that differs from ``T_i^-1 T_j`` by a rotation of ``residual_angle`` radians
    about a random axis and a translation of about 0.3: a generic edge, away from the identity."""
    rng = np.random.default_rng(seed)
    R_i, R_j = exp_many(rng.normal(size=(2, 3)) * 1.2)
    t_i, t_j = rng.normal(size=(2, 3)) * 2.0
    axis = rng.normal(size=3)
    axis *= residual_angle / np.linalg.norm(axis)
    R_z = R_i.T @ R_j @ exp_many(axis[None])[0].T  # so that R_z^T R_i^T R_j = Exp(axis)
    t_z = R_i.T @ (t_j - t_i) + rng.normal(size=3) * 0.3
    return Edge((t_i, R_i), (t_j, R_j), (t_z, R_z))


# ---------------------------------------------------------------- section 3: assembly and sparsity


def block_pattern(num_poses: int, edges_i, edges_j) -> sp.csc_matrix:
    """H's pattern in 6x6 blocks (N, N), both triangles: block (i, j) is stored when i = j or an edge
    joins i and j. Its values make it positive definite (the pose graph's Laplacian plus I), so that a
    numerical factorization of it has the pattern any H of the graph has."""
    i, j = np.asarray(edges_i), np.asarray(edges_j)
    adjacency = sp.coo_matrix((np.ones(len(i)), (i, j)), shape=(num_poses, num_poses))
    adjacency = ((adjacency + adjacency.T) > 0).astype(float)
    degree = np.asarray(adjacency.sum(axis=1)).ravel()
    return sp.csc_matrix(sp.diags(degree + 1.0) - adjacency)


def fill_in(num_poses: int, edges_i, edges_j, ordering="MMD_AT_PLUS_A") -> dict:
    """The 6x6 blocks of H's upper triangle and of its Cholesky factor ``L`` (lower, diagonal included)
    under ``ordering`` (SuperLU's ``permc_spec``: ``"NATURAL"``, the poses in file order, or
    ``"MMD_AT_PLUS_A"``, minimum degree): ``{"H": int, "L": int, "L_pattern": csc (N, N), "order": (N,)}``."""
    H = block_pattern(num_poses, edges_i, edges_j)
    factor = splu(H, permc_spec=ordering, diag_pivot_thresh=0.0, options={"SymmetricMode": True})
    L = sp.csc_matrix(factor.L)
    return {"H": int(sp.triu(H).nnz), "L": int(L.nnz), "L_pattern": L, "order": factor.perm_c}


def sparsity_figure(graph, title=""):
    """Three panels, in 6x6 blocks: H's pattern (poses in file order), the Cholesky factor L in that
    order, and L with the poses reordered by minimum degree; each titled with its block count."""
    n, i, j = graph.num_poses, graph.edges_i, graph.edges_j
    H = block_pattern(n, i, j)
    natural, ordered = fill_in(n, i, j, "NATURAL"), fill_in(n, i, j)
    fig = plot.figure(11.0, 4.0)
    panels = fig.subplots(1, 3)
    panels[0].spy(sp.triu(H), markersize=1.2)
    panels[0].set_title(f"H, upper triangle: {natural['H']} blocks", fontsize=9)
    panels[1].spy(natural["L_pattern"], markersize=1.2)
    panels[1].set_title(f"L, poses in file order: {natural['L']} blocks", fontsize=9)
    panels[2].spy(ordered["L_pattern"], markersize=1.2)
    panels[2].set_title(f"L, minimum-degree order: {ordered['L']} blocks", fontsize=9)
    for ax in panels:
        ax.tick_params(labelsize=7)
    fig.suptitle(title or f"{graph.name}: {n} poses, {graph.num_edges} edges (one dot: a 6x6 block)", fontsize=10)
    return fig


def fill_in_table(graphs) -> str:
    """A text table, one row per graph of ``graphs``: poses, edges, the 6x6 blocks of H's upper
    triangle and of its Cholesky factor L with the poses in file order and in minimum-degree order
    (:func:`fill_in`)."""
    head = f"{'graph':26} {'poses':>5} {'edges':>5} {'H blocks':>8} {'L, file order':>13} {'L, min. degree':>14}"
    lines = [head, "-" * len(head)]
    for g in graphs:
        natural = fill_in(g.num_poses, g.edges_i, g.edges_j, "NATURAL")
        ordered = fill_in(g.num_poses, g.edges_i, g.edges_j)
        lines.append(f"{g.name:26} {g.num_poses:5d} {g.num_edges:5d} {natural['H']:8d} {natural['L']:13d} "
                     f"{ordered['L']:14d}")
    return "\n".join(lines)


# ---------------------------------------------------------------- section 4: the chordal relaxation


def chordal_distance(angle):
    """``|R_a - R_b|_F^2 = 8 sin^2(theta / 2)`` for rotations ``theta`` apart (radians, any shape)."""
    return 8.0 * np.sin(np.asarray(angle, dtype=float) / 2.0) ** 2


def hops_from(num_poses: int, edges_i, edges_j, anchor=0) -> np.ndarray:
    """Each pose's number of edges from ``anchor`` on the shortest path (N,) (-1 if not reached)."""
    adjacency = sp.coo_matrix((np.ones(len(edges_i)), (edges_i, edges_j)), shape=(num_poses, num_poses))
    hops = csgraph.shortest_path(adjacency, directed=False, unweighted=True, indices=anchor)
    return np.where(np.isfinite(hops), hops, -1).astype(int)


def relaxed_singular_values(graph, impl="solutions") -> np.ndarray:
    """The singular values (N, 3), largest first, of the matrices ``impl``'s ``relaxed_rotations``
    gives on ``graph`` (weights ``trace(Omega_rot) / 3``, pose 0 the anchor at its file rotation)."""
    chordal = exercise("chordal_3d", impl)
    weights = np.trace(graph.information[:, 3:, 3:], axis1=1, axis2=2) / 3.0
    M = chordal.relaxed_rotations(graph.num_poses, graph.edges_i, graph.edges_j, graph.R_z, weights, graph.R[0], 0)
    return np.linalg.svd(np.asarray(M, dtype=float), compute_uv=False)


def chordal_figure(graph=None, impl="solutions"):
    """(left) the chordal distance ``8 sin^2(theta/2)`` and its small-angle form ``2 theta^2`` against
    theta; (right, when ``graph`` is given) the singular values of the relaxation's matrices on it
    (:func:`relaxed_singular_values`) against the number of edges from the anchor, mean and range
    per distance; a TODO there is written in the panel."""
    fig = plot.figure(11.0 if graph is not None else 5.5, 4.0)
    axes = fig.subplots(1, 2 if graph is not None else 1)
    left = axes[0] if graph is not None else axes
    theta = np.linspace(0.0, np.pi, 200)
    left.plot(np.degrees(theta), chordal_distance(theta), label="|R_a - R_b|_F^2 = 8 sin^2(theta/2)")
    left.plot(np.degrees(theta), 2.0 * theta**2, "--", label="2 theta^2 (twice the squared angle)")
    left.set_ylim(0, 12)
    left.set_xlabel("theta, the angle between R_a and R_b (degrees)")
    left.set_ylabel("squared distance")
    left.set_title("the chordal distance saturates", fontsize=9)
    left.grid(True, alpha=0.3)
    left.legend(fontsize=8)
    if graph is None:
        return fig
    right = axes[1]
    try:
        s = relaxed_singular_values(graph, impl)
    except NotImplementedError as exc:
        right.text(0.5, 0.5, f"{not_implemented_reason(exc)}\n(write it, then run this cell again)",
                   ha="center", va="center", fontsize=9, wrap=True, transform=right.transAxes)
        right.set_axis_off()
        return fig
    hops = hops_from(graph.num_poses, graph.edges_i, graph.edges_j)
    levels = np.unique(hops[hops >= 0])
    for k, name in enumerate(("largest", "middle", "smallest")):
        mean = np.array([s[hops == h, k].mean() for h in levels])
        low = np.array([s[hops == h, k].min() for h in levels])
        high = np.array([s[hops == h, k].max() for h in levels])
        right.plot(levels, mean, marker=".", label=f"{name} singular value (mean)")
        right.fill_between(levels, low, high, alpha=0.15)
    right.axhline(1.0, color="k", linewidth=0.6)
    right.set_xlabel("edges from the anchor (pose 0)")
    right.set_ylabel("singular value of the relaxed 3x3 matrix")
    right.set_title(f"{graph.name}: the relaxation's matrices are not rotations (a rotation's are 1, 1, 1)",
                    fontsize=9)
    right.grid(True, alpha=0.3)
    right.legend(fontsize=8)
    return fig


# ---------------------------------------------------------------- section 5: robust costs and GNC


def tls_surrogate(s, mu, c2):
    """GNC's surrogate of truncated least squares ``min(s, c2)`` at control ``mu`` > 0 (Yang et al.
    2020, written in ``s = r^2``): ``s`` up to ``mu / (mu + 1) c2``; ``2 sqrt(c2 mu (mu + 1) s) - mu (c2 + s)``
    up to ``(mu + 1) / mu c2``; ``c2`` beyond. (M,) for s (M,)."""
    s = np.asarray(s, dtype=float)
    lower, upper = mu / (mu + 1.0) * c2, (mu + 1.0) / mu * c2
    middle = 2.0 * np.sqrt(c2 * mu * (mu + 1.0) * s) - mu * (c2 + s)
    return np.where(s <= lower, s, np.where(s >= upper, c2, middle))


def gm_surrogate(s, mu, c2):
    """GNC's surrogate of Geman-McClure at control ``mu`` >= 1: ``mu c2 s / (mu c2 + s)``; mu = 1 is
    Geman-McClure ``c2 s / (c2 + s)``, large mu nearly least squares. (M,) for s (M,)."""
    s = np.asarray(s, dtype=float)
    return mu * c2 * s / (mu * c2 + s)


def surrogate_figure(c2=1.0):
    """Two panels against the residual ``r = sqrt(s)`` (in units of ``sqrt(c2)``): the TLS surrogate
    for growing mu beside ``min(s, c2)``, the GM surrogate for shrinking mu beside least squares."""
    r = np.linspace(-3.0, 3.0, 601) * np.sqrt(c2)
    s = r**2
    fig = plot.figure(11.0, 4.0)
    tls, gm = fig.subplots(1, 2)
    tls.plot(r, np.minimum(s, 10 * c2), "k:", label="least squares, r^2")
    for mu in (0.02, 0.1, 0.5, 2.0, 20.0):
        tls.plot(r, tls_surrogate(s, mu, c2), label=f"mu = {mu:g}")
    tls.plot(r, np.minimum(s, c2), "k", linewidth=2, label="TLS, min(r^2, c2)")
    tls.set_title("TLS surrogate: mu grows from near 0 (nearly convex) to infinity (TLS)", fontsize=9)
    gm.plot(r, np.minimum(s, 10 * c2), "k:", label="least squares, r^2")
    for mu in (50.0, 10.0, 3.0, 1.0):
        gm.plot(r, gm_surrogate(s, mu, c2), label=f"mu = {mu:g}" + (" (Geman-McClure)" if mu == 1 else ""))
    gm.set_title("GM surrogate: mu shrinks from large (nearly least squares) to 1", fontsize=9)
    for ax in (tls, gm):
        ax.set_ylim(0, 4.2 * c2)
        ax.set_xlabel("r / sqrt(c2)")
        ax.set_ylabel("rho_mu(r^2) / c2" if c2 == 1 else "rho_mu(r^2)")
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=7, loc="lower right")
    return fig


def gnc_weights_figure(runs, outliers, odometry):
    """One panel per GNC run of ``runs`` (``RobustRun`` with ``extra["weights"]``, the weights of each
    round): every loop closure's weight against the round, wrong closures (``outliers`` (M,) bool) in
    red, right ones in blue; the odometry (``odometry`` (M,) bool, weight 1 throughout) is left out."""
    fig = plot.figure(5.5 * len(runs), 4.0)
    axes = np.atleast_1d(fig.subplots(1, len(runs)))
    closures = ~np.asarray(odometry, dtype=bool)
    outliers = np.asarray(outliers, dtype=bool)
    for ax, run in zip(axes, runs):
        W = np.array(run.extra["weights"])  # (rounds, M)
        rounds = np.arange(len(W))
        for k in np.flatnonzero(closures & ~outliers):
            ax.plot(rounds, W[:, k], color="tab:blue", alpha=0.25, linewidth=0.8)
        for k in np.flatnonzero(outliers):
            ax.plot(rounds, W[:, k], color="tab:red", alpha=0.5, linewidth=0.8)
        ax.plot([], [], color="tab:blue", label=f"right loop closures ({int((closures & ~outliers).sum())})")
        ax.plot([], [], color="tab:red", label=f"wrong loop closures ({int(outliers.sum())})")
        ax.set_xlabel("GNC round (0: least squares)")
        ax.set_ylabel("weight")
        ax.set_ylim(-0.05, 1.05)
        ax.set_title(f"{run.method}: {len(W) - 1} rounds", fontsize=9)
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=8)
    return fig



def gnc_rounds_table(runs, outliers, odometry) -> str:
    """One line per GNC run of ``runs`` (``RobustRun``, ``extra["mus"]`` and ``extra["weights"]``): its
    rounds, the first and last mu, and at the end how many wrong closures (``outliers`` (M,) bool) it
    kept (weight > 0.5) and how many right ones (neither ``outliers`` nor ``odometry``) it rejected."""
    outliers = np.asarray(outliers, dtype=bool)
    right = ~outliers & ~np.asarray(odometry, dtype=bool)
    lines = []
    for run in runs:
        mus = run.extra["mus"]
        mu = f"mu {mus[0]:.4g} to {mus[-1]:.4g}" if mus else "no mu (every edge an inlier)"
        lines.append(f"ours {run.method}: {len(mus)} rounds after least squares ({mu}); kept "
                     f"{int(np.sum(run.kept & outliers))} of {int(outliers.sum())} wrong closures, rejected "
                     f"{int(np.sum(~run.kept & right))} of {int(right.sum())} right ones")
    return "\n".join(lines)
