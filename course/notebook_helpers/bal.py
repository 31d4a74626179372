"""Helpers the chapter-4 notebook calls (``notebooks/chapter4_bundle_adjustment.py``): bundle adjustment.

Notation: C cameras, P points, K observations; the state is
``x = concat(cameras.ravel(), points.ravel())`` (n = 9C + 3P,), as in ``course.problems.bal.problem``;
the residual vector stacks the K residuals (2,) of ``course.problems.bal.dataset.residuals``, so J is
(2K, 9C + 3P) and ``H = J^T J`` is (n, n)::

    H = [ U    W ]     U = blockdiag(U_c) (9C, 9C),  V = blockdiag(V_p) (3P, 3P),
        [ W^T  V ]     W (9C, 3P) with one 9x3 block W_k per observation k at (c_k, p_k)

    S = U - W V^-1 W^T          the reduced camera system (9C, 9C)

Sections of the notebook and their helpers:

* sparsity: :func:`load`, :func:`jacobian_matrix`, :func:`reduced_camera_matrix`,
  :func:`sparsity_counts`, :func:`neighbours_only`, :func:`sparsity_figure`;
* cost per iteration and per second: :func:`kept_costs`, :func:`cost_figure`,
  :func:`time_to_reach`, :func:`minimum_reached`, :func:`per_iteration_table`;
* rank deficiency (dubrovnik-3-7): :func:`rank_report`, :func:`iteration_limit_table`,
  :func:`focal_length_table`;
* points behind the camera: :func:`mirror_points`, :func:`behind_camera_detail`;
* dense against Schur: :func:`dense_vs_schur`, :func:`dense_vs_schur_table`, :func:`dense_vs_schur_figure`;
* robust kernels: :func:`kernel_figure`;
* the parallel assembly: :data:`SOURCE_OPENMP`, :func:`openmp_table`;
* the gauge: :func:`gauge_report`, :func:`gauge_figure`.

``impl`` is an implementation's name or path (``course.core.impl.load``); a run is a
``course.backends.bal.common.BALRunResult`` (``course.app.compare.run_bal``).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from functools import partial
from typing import Any

import numpy as np
import scipy.linalg
import scipy.sparse as sp

from course.app import plot
from course.core import impl as impl_loader
from course.core.errors import DatasetError
from course.notebook_helpers.common import median_time, one_thread
from course.problems.bal.dataset import BALProblem, camera_frame_points, rotate
from course.problems.bal.problem import BlockLinearization, BundleAdjustmentProblem

# ---------------------------------------------------------------- every section


def load(name: str) -> BALProblem | None:
    """The BAL problem ``name`` (``course.problems.bal.dataset.load_bal``), or None (saying why) when its file is
    not on this machine (the data folder, or gtsam's ``Data/`` for dubrovnik-3-7)."""
    from course.problems.bal.dataset import load_bal

    try:
        return load_bal(name)
    except DatasetError as exc:
        print(f"{name}: skipped ({exc})")
        return None


# ---------------------------------------------------------------- sparsity of J, H and S


def jacobian_matrix(problem: BALProblem, impl: Any = "solutions") -> sp.csr_matrix:
    """J (2K, 9C + 3P) at the problem's start, from the implementation's Jacobian blocks.

    Rows ``2k, 2k + 1`` are observation k's residual (x, y); its nonzero columns are the 9 of
    camera ``c_k`` (``9 c_k + 0..8``: w, t, f, k1, k2) and the 3 of point ``p_k``
    (``9C + 3 p_k + 0..2``): 24 entries a row pair, whatever C and P.
    """
    ba = impl_loader.load(impl).module("bundle_adjustment")
    _, J_cam, J_point = ba.reprojection_residuals_and_jacobians(
        problem.cameras, problem.points, problem.camera_index, problem.point_index, problem.observations)
    K, C = problem.num_observations, problem.num_cameras
    columns = np.hstack([9 * problem.camera_index[:, None] + np.arange(9),
                         9 * C + 3 * problem.point_index[:, None] + np.arange(3)])  # (K, 12)
    rows = np.broadcast_to((2 * np.arange(K))[:, None, None] + np.arange(2)[None, :, None], (K, 2, 12))
    cols = np.broadcast_to(columns[:, None, :], (K, 2, 12))
    values = np.concatenate([np.asarray(J_cam), np.asarray(J_point)], axis=2)  # (K, 2, 12)
    shape = (2 * K, 9 * C + 3 * problem.num_points)
    return sp.csr_matrix((values.ravel(), (rows.ravel(), cols.ravel())), shape=shape)


def reduced_camera_matrix(lin: BlockLinearization) -> sp.csr_matrix:
    """``S = U - W V^-1 W^T`` (9C, 9C) from a linearization's blocks (no damping).

    ``W`` is assembled as a sparse (9C, 3P) matrix of the blocks W_k (9, 3) at block position
    (c_k, p_k), ``V^-1`` as the block diagonal of the inverted V_p (3, 3); the product has a
    nonzero 9x9 block (c, d) exactly when cameras c and d see a common point. Every V_p must be
    invertible (each point seen from two places at least).
    """
    C, P = len(lin.U), len(lin.V)
    ci, pi = np.asarray(lin.camera_index), np.asarray(lin.point_index)
    rows = np.broadcast_to((9 * ci)[:, None, None] + np.arange(9)[None, :, None], (len(ci), 9, 3))
    cols = np.broadcast_to((3 * pi)[:, None, None] + np.arange(3)[None, None, :], (len(ci), 9, 3))
    W = sp.csr_matrix((np.asarray(lin.W).ravel(), (rows.ravel(), cols.ravel())), shape=(9 * C, 3 * P))
    V_inv = sp.block_diag(list(np.linalg.inv(lin.V)), format="csr")
    U = sp.block_diag(list(lin.U), format="csr")
    return (U - W @ V_inv @ W.T).tocsr()


def _camera_pairs(problem: BALProblem) -> int:
    """The number of ordered camera pairs (c, d), c = d included, that see a common point."""
    seen = sp.csr_matrix((np.ones(problem.num_observations), (problem.camera_index, problem.point_index)),
                         shape=(problem.num_cameras, problem.num_points))
    return int((seen @ seen.T).nnz)


def sparsity_counts(problem: BALProblem) -> str:
    """A text table of the sizes and structural nonzeros of J, H and S of ``problem``.

    Counted from the observation indices alone (nothing is formed, so it runs on ladybug-49):
    ``nnz(J) = 2K * 12``; H has the C blocks U_c (9x9), the P blocks V_p (3x3) and the 2K'
    blocks W (9x3) of the K' distinct (camera, point) pairs; S has one 9x9 block per ordered
    pair of cameras that see a common point."""
    C, P, K = problem.num_cameras, problem.num_points, problem.num_observations
    n = 9 * C + 3 * P
    pairs = len(np.unique(problem.camera_index * P + problem.point_index))
    rows = [("J", 2 * K, n, 24 * K), ("H", n, n, 81 * C + 9 * P + 2 * 27 * pairs),
            ("S", 9 * C, 9 * C, 81 * _camera_pairs(problem))]
    lines = [f"{problem.name}: {C} cameras, {P} points, {K} observations",
             f"{'matrix':6} {'rows':>8} {'columns':>8} {'nonzeros':>11} {'density':>9} {'dense MB':>9}"]
    for name, m, k, nnz in rows:
        lines.append(f"{name:6} {m:8d} {k:8d} {nnz:11d} {100 * nnz / (m * k):8.3f}% {8 * m * k / 1e6:9.1f}")
    return "\n".join(lines)


def neighbours_only(problem: BALProblem, window: int = 1) -> BALProblem:
    """``problem`` (a ``course.problems.bal.dataset.synthetic`` one, where point p's first camera is ``p % C``) with
    only the observations of each point p by the cameras within ``window`` of ``p % C`` around the
    ring (``|c - p % C| <= window`` modulo C), and only the points left with two observations or
    more (renumbered): the covisibility of a camera moving along a path, where S is banded."""
    C = problem.num_cameras
    gap = np.abs(problem.camera_index - problem.point_index % C)
    keep = np.minimum(gap, C - gap) <= window
    counts = np.bincount(problem.point_index[keep], minlength=problem.num_points)
    points = np.flatnonzero(counts >= 2)
    keep &= counts[problem.point_index] >= 2
    renumber = np.full(problem.num_points, -1)
    renumber[points] = np.arange(len(points))
    truth = problem.ground_truth
    return BALProblem(problem.cameras.copy(), problem.points[points].copy(), problem.camera_index[keep],
                      renumber[problem.point_index[keep]], problem.observations[keep],
                      name=f"{problem.name}, neighbours {window}", source=problem.source,
                      ground_truth=None if truth is None else (truth[0], truth[1][points]))


def sparsity_figure(problems: Sequence[BALProblem], impl: Any = "solutions") -> Any:
    """One row of three spy plots per problem of ``problems``, at its start: J (2K, 9C + 3P),
    H = J^T J (n, n) and S (9C, 9C) (:func:`reduced_camera_matrix`).

    Dashed lines separate the camera columns (left/top) from the point columns. Each matrix is
    drawn as an image of its nonzero entries (small problems only), like matplotlib's ``spy``."""
    from matplotlib.colors import ListedColormap

    fig = plot.figure(13, 4.4 * len(problems))
    for row, problem in enumerate(problems):
        J = jacobian_matrix(problem, impl)
        H = (J.T @ J).tocsr()
        S = reduced_camera_matrix(BundleAdjustmentProblem(problem, impl).linearize(
            np.concatenate([problem.cameras.ravel(), problem.points.ravel()])))
        C = problem.num_cameras
        panels = [(J, f"J ({J.shape[0]} x {J.shape[1]}): {J.nnz} nonzeros"),
                  (H, f"H = J^T J ({H.shape[0]} x {H.shape[1]}): {H.nnz} nonzeros"),
                  (S, f"S = U - W V^-1 W^T ({S.shape[0]} x {S.shape[1]}): {S.nnz} nonzeros")]
        for col, (M, title) in enumerate(panels):
            ax = fig.add_subplot(len(problems), 3, 3 * row + col + 1)
            ax.imshow(M.toarray() != 0, cmap=ListedColormap(["white", "tab:blue"]), vmin=0, vmax=1,
                      interpolation="nearest", aspect="equal" if col else "auto")
            ax.set_title(title, fontsize=9)
            if col < 2:
                ax.axvline(9 * C - 0.5, color="k", linestyle="--", linewidth=0.7)
            if col == 1:
                ax.axhline(9 * C - 0.5, color="k", linestyle="--", linewidth=0.7)
            if col == 0:
                ax.set_ylabel(f"{problem.name}\n{C} cameras, {problem.num_points} points, "
                              f"{problem.num_observations} observations", fontsize=9)
            ax.tick_params(labelsize=7)
    fig.suptitle("nonzero entries (cameras' 9 columns each left of / above the dashed line, then points' 3 each)",
                 fontsize=10)
    return fig


# ---------------------------------------------------------------- cost per iteration and per second


def kept_costs(run: Any) -> np.ndarray:
    """The back end's own cost (``run.peer_costs``) of the point kept after each trace record:
    a rejected attempt keeps the previous cost. (K_trace,); empty without a trace."""
    costs = np.asarray(run.peer_costs, dtype=float)
    out, kept = np.empty(len(costs)), np.nan
    for k, (record, value) in enumerate(zip(run.trace, costs)):
        if record.iteration == 0 or record.accepted:
            kept = value
        out[k] = kept
    return out


def cost_figure(runs: Sequence[Any], title: str) -> Any:
    """Each run's own cost (the one it minimizes, ``kept_costs``) against the iteration (left)
    and the seconds since its solve started (right, log scale: the start at 0 is off the axis)."""
    fig = plot.figure(12, 4.6)
    by_iteration, by_time = fig.subplots(1, 2)
    values = []
    for run in runs:
        if run.not_run or not run.trace:
            continue
        kept = kept_costs(run)
        iterations = np.array([record.iteration for record in run.trace])
        seconds = np.array([record.seconds for record in run.trace])
        finite = np.isfinite(kept) & (kept > 0)
        label = f"{run.backend} {run.method}"
        by_iteration.plot(iterations[finite], kept[finite], marker=".", markersize=3, label=label)
        later = finite & (seconds > 0)
        by_time.plot(seconds[later], kept[later], marker=".", markersize=3,
                     label=f"{label} ({run.seconds:.2f} s)")
        values.append(kept[finite])
    for ax, xlabel in ((by_iteration, "iteration (step attempt)"), (by_time, "seconds since the solve started")):
        ax.set_yscale("log")
        ax.set_xlabel(xlabel)
        ax.set_ylabel("the back end's own cost 0.5 sum |r|^2")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize="x-small")
    by_time.set_xscale("log")
    if values:
        v = np.concatenate(values)
        by_iteration.set_ylim(v.min() / 1.5, v.max() * 1.5)
        by_time.set_ylim(v.min() / 1.5, v.max() * 1.5)
    fig.suptitle(title, fontsize=10)
    return fig


def time_to_reach(run: Any, target_cost: float) -> tuple[int, float, float] | None:
    """``(iteration, seconds, cost)`` of the first accepted record of ``run`` whose own cost is at
    most ``target_cost``; None when it never gets there."""
    for record, value in zip(run.trace, run.peer_costs):
        if (record.iteration == 0 or record.accepted) and value <= target_cost:
            return record.iteration, record.seconds, float(value)
    return None


def minimum_reached(name: str, runs: Sequence[Any], method: str = "lm-type3") -> str:
    """Where our ``method`` among ``runs`` first comes within ``course.app.benchmark_bal.TOLERANCE``
    (relative) of the known all-observations minimum of ``name`` (``benchmark_bal.MINIMA``):
    one line, empty when the minimum of ``name`` is not known or ours did not run."""
    from course.app import benchmark_bal

    ours = next((r for r in runs if r.backend == "ours" and r.method == method and not r.not_run), None)
    if name not in benchmark_bal.MINIMA or ours is None:
        return ""
    minimum, tolerance = benchmark_bal.MINIMA[name], benchmark_bal.TOLERANCE
    hit = time_to_reach(ours, minimum * (1.0 + tolerance))
    where = (f"at iteration {hit[0]}, {hit[1]:.2f} s into the solve (cost {hit[2]:.6f})" if hit else
             f"not within {ours.iterations} iterations (cost {0.5 * ours.final_chi2:.6f})")
    return f"ours {method} within {tolerance:g} of the minimum {minimum} (all observations): {where}"


def per_iteration_table(timings: Sequence[Any], title: str) -> str:
    """A text table of ``course.app.benchmark_bal.per_iteration``'s timings: milliseconds per
    iteration (scipy: per residual evaluation), the ratio to Ceres' LM and the cost (ours, all
    observations) after the timed iterations; a peer not installed here is a row saying so."""
    ceres = next((t.seconds_per_iteration for t in timings if t.backend == "ceres" and t.seconds_per_iteration),
                 None)
    lines = [title, f"{'back end':8} {'method':20} {'ms/iter':>9} {'/ ceres':>8} {'iters':>5} {'cost after':>14}"]
    for t in timings:
        if t.seconds_per_iteration is None:
            lines.append(f"{t.backend:8} {t.method:20} not run: {t.skipped}")
            continue
        ratio = f"{t.seconds_per_iteration / ceres:8.2f}" if ceres else f"{'-':>8}"
        lines.append(f"{t.backend:8} {t.method:20} {1e3 * t.seconds_per_iteration:9.2f} {ratio} "
                     f"{t.result.iterations:5d} {0.5 * t.result.final_chi2:14.4f}")
    return "\n".join(lines)


# ---------------------------------------------------------------- rank deficiency


def _rank(M: np.ndarray) -> tuple[int, np.ndarray]:
    """(numerical rank, singular values over the largest) of a dense matrix M (m, n)."""
    sigma = np.linalg.svd(M, compute_uv=False)
    tol = max(M.shape) * np.finfo(float).eps * sigma[0]
    return int(np.sum(sigma > tol)), sigma / sigma[0]


def rank_report(problem: BALProblem, impl: Any = "solutions") -> str:
    """Counts of ``problem``'s residuals and unknowns and the rank of J at its start, with the
    gauge free and fixed (the 7 unknowns ``BundleAdjustmentProblem(fix_gauge=True)`` holds).

    J (2K, n) has rank at most 2K: when 2K < n, at least n - 2K directions leave every residual
    unchanged to first order (7 of them the gauge: a similarity of the whole scene), so the
    minimum, where there is one, is not unique."""
    J = jacobian_matrix(problem, impl).toarray()
    fixed = BundleAdjustmentProblem(problem, impl, fix_gauge=True).fixed.ravel()
    free = np.concatenate([~fixed, np.ones(3 * problem.num_points, dtype=bool)])
    m, n = J.shape
    lines = [f"{problem.name}: {problem.num_cameras} cameras, {problem.num_points} points, "
             f"{problem.num_observations} observations: {m} residuals (2 per observation) for {n} unknowns "
             f"(9 per camera, 3 per point)"]
    for label, columns in (("gauge free", np.ones(n, dtype=bool)), ("gauge fixed", free)):
        rank, sigma = _rank(J[:, columns])
        k = int(columns.sum())
        lines.append(f"  {label:11}: {k} unknowns, rank J = {rank}, null space {k - rank} "
                     f"(at least {k} - {m} = {k - m}); the 3 smallest nonzero singular values over the largest: "
                     + ", ".join(f"{s:.2g}" for s in sigma[max(rank - 3, 0):rank]))
    return "\n".join(lines)


def iteration_limit_table(problem: BALProblem, impl: Any, limits: Sequence[int], methods: Sequence[str],
                          backends: Sequence[str] | None = None) -> tuple[str, list]:
    """Every (back end, method) of ``methods`` on ``problem`` once per iteration limit of
    ``limits`` (``course.app.compare.run_bal``, the gauge fixed): a text table of the final cost (ours,
    0.5 sum |r|^2 over all observations) at each limit and the iterations used at the last, and
    the runs at the last limit."""
    from course.app import compare

    tables = [compare.run_bal(problem, impl=impl, methods=list(methods), backends=backends, max_iterations=limit)
              for limit in limits]
    head = f"{'backend':8} {'method':20}" + "".join(f" {f'cost @ {limit}':>13}" for limit in limits) + \
        f" {'iters used':>10}"
    lines = ["final cost 0.5 sum |r|^2 (ours, all observations) after at most N iterations", head,
             "-" * len(head)]
    for k, run in enumerate(tables[-1]):
        line = f"{run.backend:8} {run.method:20}"
        if run.not_run:
            lines.append(line + f" {run.not_run}")
            continue
        line += "".join(f" {0.5 * table[k].final_chi2:13.4g}" for table in tables)
        lines.append(line + f" {run.iterations:10d}")
    return "\n".join(lines), tables[-1]


def focal_length_table(problem: BALProblem, runs: Sequence[Any]) -> str:
    """Each run's final cost and its focal lengths f (one per camera, in pixels): a similarity of
    the scene (the gauge) leaves every f unchanged, so two zero-cost solutions with different f
    are two different minima, not one minimum seen in two gauges."""
    C = problem.num_cameras
    head = f"{'backend':8} {'method':20} {'final cost':>11}" + "".join(f" {f'f_{c}':>9}" for c in range(C))
    lines = [head, f"{'start':29} {0.5 * runs[0].initial_chi2 if runs else float('nan'):11.3g}"
             + "".join(f" {f:9.2f}" for f in problem.cameras[:, 6])]
    for run in runs:
        if run.not_run:
            continue
        f = np.asarray(run.params)[:9 * C].reshape(C, 9)[:, 6]
        lines.append(f"{run.backend:8} {run.method:20} {0.5 * run.final_chi2:11.3g}" + "".join(f" {v:9.2f}" for v in f))
    return "\n".join(lines)


# ---------------------------------------------------------------- points behind the camera


def mirror_points(problem: BALProblem, count: int, seed: int = 0) -> BALProblem:
    """``problem`` with ``count`` points (chosen at random) mirrored through the centre of the
    camera of their first observation, their new start behind that camera.

    With the camera's centre ``o = -R^T t``, the mirrored point is ``X' = 2 o - X``, so in that
    camera ``P' = R X' + t = -(R X + t) = -P``: the BAL projection ``-P[:2] / P[2]`` gives the same
    pixel, so the point's residual in that camera is unchanged, but ``P'_z = -P_z > 0``: behind.
    (Its other cameras see it elsewhere.) Cameras, observations and ground truth are unchanged."""
    rng = np.random.default_rng(seed)
    chosen = rng.choice(problem.num_points, size=min(count, problem.num_points), replace=False)
    first = np.array([problem.camera_index[np.flatnonzero(problem.point_index == p)[0]] for p in chosen])
    cam = problem.cameras[first]
    centres = -rotate(-cam[:, :3], cam[:, 3:6])  # o = -R^T t, with R(w)^T = R(-w)
    points = problem.points.copy()
    points[chosen] = 2.0 * centres - points[chosen]
    return BALProblem(problem.cameras.copy(), points, problem.camera_index, problem.point_index,
                      problem.observations, name=f"{problem.name} ({len(chosen)} points mirrored)",
                      source=problem.source, ground_truth=problem.ground_truth)


def behind_camera_detail(problem: BALProblem, cameras=None, points=None, limit: int = 12) -> str:
    """Which observations have their point behind (or on the plane of) their camera (``P_z >= 0``
    in the BAL convention, where a point in front has ``P_z < 0``): their count, the points that
    carry them and, per point (at most ``limit``), how many of its observations are behind."""
    cameras = problem.cameras if cameras is None else cameras
    points = problem.points if points is None else points
    P = camera_frame_points(cameras, points, problem.camera_index, problem.point_index)
    behind = P[:, 2] >= 0.0
    carriers = np.unique(problem.point_index[behind])
    total = np.bincount(problem.point_index, minlength=problem.num_points)
    count = np.bincount(problem.point_index[behind], minlength=problem.num_points)
    lines = [f"{problem.name}: {int(behind.sum())} of {problem.num_observations} observations have their point "
             f"behind the camera, on {len(carriers)} points ({int(np.sum(count[carriers] == total[carriers]))} of "
             "them behind every camera that sees them)"]
    for p in carriers[:limit]:
        depths = P[(problem.point_index == p) & behind, 2]
        lines.append(f"  point {p:5d}: {count[p]} of {total[p]} observations behind, P_z "
                     + ", ".join(f"{z:.3g}" for z in depths))
    if len(carriers) > limit:
        lines.append(f"  ... ({len(carriers) - limit} more points)")
    return "\n".join(lines)


# ---------------------------------------------------------------- dense against Schur


@dataclass
class StepTiming:
    """One damped step on a synthetic problem: P points, K observations, n = 9C + 3P unknowns,
    the seconds of the dense and the Schur solve and the relative difference of their steps."""

    num_points: int
    num_observations: int
    unknowns: int
    dense: float
    schur: float
    difference: float


def _dense_step(A: np.ndarray, b: np.ndarray) -> np.ndarray:
    """``h`` (n,) of ``A h = -b`` for A (n, n) symmetric positive definite, by a dense Cholesky factorization."""
    return scipy.linalg.cho_solve(scipy.linalg.cho_factor(A, check_finite=False), -b, check_finite=False)


def dense_vs_schur(num_cameras: int, point_counts: Sequence[int], impl: Any = "solutions", repeat: int = 1,
                   damping: float = 1e-3, seed: int = 0) -> list[StepTiming]:
    """Time one damped Gauss-Newton step ``(H + D) h = -b``, ``D = damping * diag(H)``, solved two
    ways on ``course.problems.bal.dataset.synthetic(num_cameras, P, seed)`` for each P of ``point_counts`` (gauge
    free: D makes the system definite), medians of ``repeat``, one BLAS thread:

    * dense: ``scipy.linalg.cho_factor`` and ``cho_solve`` of the (n, n) matrix, n = 9C + 3P
      (H formed beforehand by ``course.problems.bal.gauge.dense_hessian``, not timed): O(n^3);
    * Schur: the implementation's ``bundle_adjustment.schur_solve`` from the blocks U, V, W
      (``BundleAdjustmentProblem.solve``), which forms and factors S (9C, 9C): O(K) for the
      elimination plus O((9C)^3), so linear in P at fixed C.
    """
    from course.problems.bal.dataset import synthetic
    from course.problems.bal.gauge import dense_hessian

    out = []
    for P in point_counts:
        problem = synthetic(num_cameras, P, seed=seed)
        ba = BundleAdjustmentProblem(problem, impl)
        lin = ba.linearize(ba.x0)
        d = damping * lin.diagonal()
        H = dense_hessian(lin)
        H[np.diag_indices_from(H)] += d
        with one_thread():
            dense_s, h_dense = median_time(partial(_dense_step, H, lin.b), repeat)
            schur_s, h_schur = median_time(partial(ba.solve, lin, d), repeat)
        difference = float(np.linalg.norm(h_dense - h_schur) / np.linalg.norm(h_dense))
        out.append(StepTiming(P, problem.num_observations, len(H), dense_s, schur_s, difference))
    return out


def _slope(x: Sequence[float], y: Sequence[float]) -> float:
    """The least-squares slope of log y against log x."""
    return float(np.polyfit(np.log(x), np.log(y), 1)[0])


def dense_vs_schur_table(rows: Sequence[StepTiming], num_cameras: int) -> str:
    """A text table of :func:`dense_vs_schur`, and the growth exponents of both times in P
    (slope of log time against log P over the larger half of the sizes)."""
    lines = [f"one damped step, {num_cameras} cameras; dense = Cholesky of the (9C + 3P)^2 H, "
             "Schur = schur_solve (S is 9C x 9C)",
             f"{'points':>7} {'obs':>6} {'n':>6} {'dense ms':>10} {'Schur ms':>9} {'dense/Schur':>11} "
             f"{'|h_d - h_s| / |h_d|':>20}"]
    for r in rows:
        lines.append(f"{r.num_points:7d} {r.num_observations:6d} {r.unknowns:6d} {1e3 * r.dense:10.2f} "
                     f"{1e3 * r.schur:9.2f} {r.dense / r.schur:11.1f} {r.difference:20.2e}")
    if len(rows) >= 3:
        tail = rows[len(rows) // 2:]
        P = [r.num_points for r in tail]
        lines.append(f"growth exponent in P over P = {P[0]}..{P[-1]}: dense {_slope(P, [r.dense for r in tail]):.2f}, "
                     f"Schur {_slope(P, [r.schur for r in tail]):.2f}")
    return "\n".join(lines)


def dense_vs_schur_figure(rows: Sequence[StepTiming], num_cameras: int) -> Any:
    """The two times of :func:`dense_vs_schur` against the number of points, log-log."""
    fig = plot.figure(7, 4.5)
    ax = fig.add_subplot()
    P = [r.num_points for r in rows]
    ax.plot(P, [1e3 * r.dense for r in rows], "o-", label="dense Cholesky of H (9C + 3P unknowns)")
    ax.plot(P, [1e3 * r.schur for r in rows], "s-", label="Schur complement (S: 9C unknowns)")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("points P")
    ax.set_ylabel("milliseconds per damped step (one thread)")
    ax.set_title(f"one damped step, {num_cameras} cameras, synthetic problems")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize="small")
    return fig


def size_sweep_figure(rows: Sequence[Any]) -> Any:
    """Ours and Ceres' seconds per LM iteration against the observations (log-log, left), and
    their ratio (right), from ``course.app.benchmark_bal.size_sweep``'s rows."""
    fig = plot.figure(10, 4)
    left, right = fig.add_subplot(1, 2, 1), fig.add_subplot(1, 2, 2)
    K = [r.observations for r in rows]
    left.plot(K, [1e3 * r.ours for r in rows], "o-", label="ours (Schur complement, numpy and scipy)")
    measured = [r for r in rows if r.ceres is not None]
    if measured:
        left.plot([r.observations for r in measured], [1e3 * r.ceres for r in measured], "s-",
                  label="Ceres (pycolmap, one thread)")
        right.plot([r.observations for r in measured], [r.ratio for r in measured], "o-")
    right.axhline(1.0, color="grey", lw=0.8)
    for ax in (left, right):
        ax.set_xscale("log")
        ax.set_xlabel("observations")
        ax.grid(True, which="both", alpha=0.3)
    left.set_yscale("log")
    left.set_ylabel("milliseconds per LM iteration")
    left.legend(fontsize="small")
    right.set_ylabel("ours / Ceres")
    right.set_ylim(bottom=0)
    fig.suptitle("bal-synthetic: how the cost of an iteration grows")
    return fig


# ---------------------------------------------------------------- robust kernels


def kernel_figure(losses: Sequence[Any], impl: Any = "solutions", reach: float = 4.0) -> Any:
    """The kernels of ``losses`` (``(kernel, scale)`` pairs, e.g. ``course.problems.bal.outliers.DEFAULT_LOSSES``'s)
    from the implementation's ``robust_kernels``, against the residual's norm |r| = sqrt(s) from 0
    to ``reach`` times the largest scale: left, the cost rho(s) of one residual (least squares:
    s); right, the weight rho'(s) (solid, the first-order information ``rho' I``) and the
    eigenvalue ``rho' + 2 rho'' s`` of the corrected information along r (dashed; where it is not
    positive, ``robust_information`` falls back to the first-order weight)."""
    from course.solver.robust import RobustLoss

    kernels = impl_loader.load(impl).module("robust_kernels")
    chosen = [RobustLoss.of(loss) for loss in losses if loss is not None and not isinstance(loss, list)]
    unique = list(dict.fromkeys(chosen))
    top = reach * max(loss.scale for loss in unique if loss is not None)
    norm = np.linspace(0.0, top, 400)
    s = norm * norm
    fig = plot.figure(12, 4.5)
    cost_ax, weight_ax = fig.subplots(1, 2)
    cost_ax.plot(norm, s, color="k", linestyle=":", label="least squares: s")
    weight_ax.axhline(1.0, color="k", linestyle=":", label="least squares: 1")
    for loss, colour in zip(unique, ("tab:blue", "tab:orange", "tab:green", "tab:red")):
        assert loss is not None
        rho, d_rho, dd_rho = getattr(kernels, loss.kernel)(s, loss.scale)
        cost_ax.plot(norm, rho, color=colour, label=str(loss))
        weight_ax.plot(norm, d_rho, color=colour, label=f"{loss}: rho'")
        weight_ax.plot(norm, d_rho + 2.0 * dd_rho * s, color=colour, linestyle="--", linewidth=1,
                       label=f"{loss}: rho' + 2 rho'' s")
        for ax in (cost_ax, weight_ax):
            ax.axvline(loss.scale, color=colour, linestyle=":", linewidth=0.8)
    cost_ax.set_ylim(0, 3 * max(loss.scale for loss in unique if loss is not None) ** 2)
    cost_ax.set_ylabel("rho(s), s = |r|^2")
    weight_ax.set_ylabel("weight")
    weight_ax.set_ylim(-1.05, 1.1)
    for ax in (cost_ax, weight_ax):
        ax.set_xlabel("|r| (pixels); dotted vertical lines: each kernel's scale a")
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize="x-small")
    fig.suptitle("robust kernels: the cost of one residual and its weight", fontsize=10)
    return fig


# ---------------------------------------------------------------- the parallel assembly

#: the source's table: milliseconds per solve on EuRoC MH_05, without and with OpenMP
SOURCE_OPENMP = {"Levenberg-Marquardt": (218.77, 148.73), "dogleg": (61.42, 83.40)}


def openmp_table() -> str:
    """The source's OpenMP table (:data:`SOURCE_OPENMP`) with each speed-up (serial / OpenMP)."""
    lines = ["the source's table: one solve on EuRoC MH_05 (C++, OpenMP threads in the assembly)",
             f"{'method':20} {'serial ms':>10} {'OpenMP ms':>10} {'speed-up':>9}"]
    for method, (serial, openmp) in SOURCE_OPENMP.items():
        lines.append(f"{method:20} {serial:10.2f} {openmp:10.2f} {serial / openmp:8.2f}x")
    return "\n".join(lines)


# ---------------------------------------------------------------- the gauge


def _hessian(problem: BALProblem, impl: Any, fix_gauge: bool) -> tuple[np.ndarray, BundleAdjustmentProblem]:
    from course.problems.bal.gauge import dense_hessian

    ba = BundleAdjustmentProblem(problem, impl, fix_gauge=fix_gauge)
    return dense_hessian(ba.linearize(ba.x0)), ba


def gauge_report(problem: BALProblem, impl: Any = "solutions") -> str:
    """The gauge of ``problem`` at its start, checked three ways (H formed densely: small problems):

    * the eigenvalues of H (n, n) over the largest: how many are zero (below
      ``course.problems.bal.gauge.ZERO``) with the gauge free and fixed, and the 8 smallest;
    * the implementation's ``gauge.gauge_directions`` N (n, 7): ``|J N| / (|J| |N|)`` (Frobenius
      norms), zero up to rounding when every column is a direction the residuals do not see;
    * the largest principal angle between span(N) and the eigenvectors of H's 7 smallest
      eigenvalues (0: the same subspace)."""
    from course.problems.bal.gauge import ZERO

    gauge = impl_loader.load(impl).module("gauge")
    lines = []
    for fix in (False, True):
        H, _ = _hessian(problem, impl, fix)
        values = np.linalg.eigvalsh(H) / np.linalg.eigvalsh(H)[-1]
        label = "gauge fixed" if fix else "gauge free"
        lines.append(f"{label:11}: {int(np.sum(np.abs(values) < ZERO))} of {len(values)} eigenvalues of H below "
                     f"{ZERO:g} (relative); the 8 smallest: " + ", ".join(f"{v:.1e}" for v in values[:8]))
    H, _ = _hessian(problem, impl, False)
    N = np.asarray(gauge.gauge_directions(problem.cameras, problem.points), dtype=float)
    J = jacobian_matrix(problem, impl)
    seen = np.linalg.norm(J @ N) / (sp.linalg.norm(J) * np.linalg.norm(N))
    _, vectors = np.linalg.eigh(H)
    angle = float(np.max(scipy.linalg.subspace_angles(N, vectors[:, :7])))
    lines.append(f"gauge_directions N ({N.shape[0]} x {N.shape[1]}): |J N| / (|J| |N|) = {seen:.1e}; largest "
                 f"principal angle between span(N) and H's 7 lowest eigenvectors: {np.degrees(angle):.2g} degrees")
    return "\n".join(lines)


def gauge_figure(problem: BALProblem, impl: Any = "solutions") -> Any:
    """The eigenvalues of H at the start of ``problem``, ascending, over the largest (|value|,
    log scale), with the gauge free and fixed; the dotted line is ``course.problems.bal.gauge.ZERO``."""
    from course.problems.bal.gauge import ZERO

    fig = plot.figure(7, 4.5)
    ax = fig.add_subplot()
    for fix, marker in ((False, "o"), (True, "s")):
        H, _ = _hessian(problem, impl, fix)
        values = np.linalg.eigvalsh(H)
        values = np.abs(values / values[-1])
        shown = min(40, len(values))
        ax.semilogy(np.arange(shown), np.maximum(values[:shown], 1e-20), marker, markersize=4, linestyle="-",
                    linewidth=0.6, label="gauge fixed (7 unknowns held)" if fix else "gauge free")
    ax.axhline(ZERO, color="k", linestyle=":", linewidth=1, label=f"zero: {ZERO:g} relative")
    ax.set_xlabel("eigenvalue index (ascending; the smallest 40)")
    ax.set_ylabel("|eigenvalue| / largest")
    ax.set_title(f"{problem.name}: the spectrum of H = J^T J at the start")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize="small")
    return fig
