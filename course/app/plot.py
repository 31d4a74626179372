"""Figures of runs and data, drawn with matplotlib's Agg canvas (no pyplot, no display).

Every function returns a ``matplotlib.figure.Figure`` and, given ``path``, also writes
it as a PNG (creating the folder). ``to_png(fig)`` gives the bytes, e.g. for
``IPython.display.Image`` in a notebook, whatever matplotlib backend the notebook uses.
"""

import io
from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure


def figure(width=7.0, height=4.5) -> Figure:
    """A constrained-layout figure of ``width`` x ``height`` inches on an Agg canvas (no pyplot)."""
    fig = Figure(figsize=(width, height), layout="constrained")
    FigureCanvasAgg(fig)
    return fig


def label(run) -> str:
    return f"{run.backend} {run.method}"


def save(fig: Figure, path) -> Path:
    """Write ``fig`` as a PNG at ``path`` (parents created); returns the path."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=120)
    return path


def to_png(fig: Figure) -> bytes:
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=100)
    return buffer.getvalue()


def kept_chi2(run) -> np.ndarray:
    """chi2 of the point kept after each record (a rejected attempt keeps the previous one)."""
    kept, out = np.nan, []
    for record in run.trace:
        if record.iteration == 0 or record.accepted:
            kept = record.chi2
        out.append(kept)
    return np.array(out, dtype=float)


def chi2_per_iteration(runs, path=None, title="chi2 per iteration") -> Figure:
    """chi2 (log scale) of the point kept, against the step attempt, one line per run.

    Rejected attempts are marked ``x`` at the chi2 they would have given. The axis stops
    at 1000 times the largest start chi2; a run that climbs higher (undamped
    Gauss-Newton from a far start) is named with its peak in the corner.
    """
    fig = figure()
    ax = fig.add_subplot()
    kept_all = []
    for run in runs:
        if not run.trace:
            continue
        iterations = np.array([r.iteration for r in run.trace])
        kept = kept_chi2(run)
        kept_all.append(kept[np.isfinite(kept) & (kept > 0)])
        (line,) = ax.plot(iterations, kept, marker=".", label=f"{label(run)} ({run.iterations})")
        rejected = [(r.iteration, r.chi2) for r in run.trace if r.iteration > 0 and not r.accepted]
        if rejected:
            it, chi2 = zip(*rejected)
            ax.plot(it, chi2, "x", color=line.get_color(), alpha=0.6, linestyle="none")
    ax.set_yscale("log")
    values = np.concatenate(kept_all) if kept_all else np.array([])
    if values.size:
        starts = [r.trace[0].chi2 for r in runs if r.trace and np.isfinite(r.trace[0].chi2)]
        top = min(values.max() * 5.0, max(starts) * 1e3) if starts else values.max() * 5.0
        ax.set_ylim(values.min() / 2.0, top)
        peaks = [f"{label(r)} peaks at {kept_chi2(r)[np.isfinite(kept_chi2(r))].max():.1e}"
                 for r in runs if r.trace and np.nanmax(kept_chi2(r)) > top]
        if peaks:
            ax.text(0.01, 0.99, "off the chart: " + "; ".join(peaks), transform=ax.transAxes,
                    va="top", fontsize="x-small")
    ax.set_xlabel("iteration (step attempt; x = rejected step)")
    ax.set_ylabel("chi2")
    ax.set_title(title)
    ax.grid(True, which="both", alpha=0.3)
    if ax.get_legend_handles_labels()[0]:  # no run ran (every row a TODO): no legend
        ax.legend(fontsize="small")
    if path is not None:
        save(fig, path)
    return fig


def damping_per_iteration(runs, path=None, title="lambda per iteration") -> Figure:
    """The damping (lambda; 1/radius for Ceres LM) used at each step attempt, log scale.

    Runs whose trace has no finite damping (Gauss-Newton, scipy) are left out.
    """
    fig = figure()
    ax = fig.add_subplot()
    for run in runs:
        points = [(r.iteration, r.damping) for r in run.trace if np.isfinite(r.damping) and r.damping > 0]
        if not points:
            continue
        it, lam = zip(*points)
        ax.plot(it, lam, marker=".", label=label(run))
    ax.set_yscale("log")
    ax.set_xlabel("iteration (step attempt)")
    ax.set_ylabel("lambda")
    ax.set_title(title)
    ax.grid(True, which="both", alpha=0.3)
    if ax.get_legend_handles_labels()[0]:
        ax.legend(fontsize="small")
    if path is not None:
        save(fig, path)
    return fig


def curve_fit(data, runs, path=None, title="data and fitted curves") -> Figure:
    """The samples, the true curve and each run's fitted curve ``exp(a x^2 + b x + c)``."""
    fig = figure()
    ax = fig.add_subplot()
    ax.plot(data.x, data.y, "o", markersize=3, color="0.6", label=f"data (sigma {data.sigma:g}, seed {data.seed})")
    xs = np.linspace(float(np.min(data.x)), float(np.max(data.x)), 200)

    def model(p):
        a, b, c = p
        return np.exp(a * xs**2 + b * xs + c)

    ax.plot(xs, model(data.truth), "k-", linewidth=2, label=f"truth {tuple(float(v) for v in data.truth)}")
    styles = ["-", "--", ":", "-."]
    for k, run in enumerate(runs):
        p = np.asarray(run.params, dtype=float)
        ax.plot(xs, model(p), styles[k % len(styles)], linewidth=1.2,
                label=f"{label(run)}: " + ", ".join(f"{v:.3f}" for v in p))
    ax.set_xlabel("x")
    ax.set_ylabel("y")
    ax.set_title(title)
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize="x-small")
    if path is not None:
        save(fig, path)
    return fig


def pose_graph_before_after(graph, result, path=None, title=None) -> Figure:
    """The graph's edges and poses at the start (grey) and after ``result`` (blue), side by side."""
    fig = figure(width=11.0, height=5.0)
    after = np.asarray(result.params).reshape(-1, 3)
    for k, (poses, colour, name) in enumerate(
        [(graph.poses, "0.55", f"start, chi2 {result.initial_chi2:.4g}"),
         (after, "tab:blue", f"{result.backend} {result.method}, chi2 {result.final_chi2:.4g}")]
    ):
        ax = fig.add_subplot(1, 2, k + 1)
        draw_graph(ax, graph, poses, colour)
        ax.set_title(name, fontsize=9)
    fig.suptitle(title or f"{graph.name}: {graph.num_poses} poses, {graph.num_edges} edges")
    if path is not None:
        save(fig, path)
    return fig


def draw_graph(ax, graph, poses, colour) -> None:
    """The edges (segments) and poses (dots) of ``graph`` at ``poses`` (N, 3) on ``ax``, equal aspect."""
    from matplotlib.collections import LineCollection

    segments = np.stack([poses[graph.edges_i, :2], poses[graph.edges_j, :2]], axis=1)
    ax.add_collection(LineCollection(list(segments), colors=colour, linewidths=0.3, alpha=0.5))
    ax.plot(poses[:, 0], poses[:, 1], ".", color=colour, markersize=1.5)
    ax.set_aspect("equal", adjustable="datalim")
    ax.autoscale()
