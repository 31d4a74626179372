"""Helpers the chapter notebooks call (``notebooks/chapter*.py``), so their cells stay short.

Chapter 2: ``load``, ``one_thread``, ``outcome``, ``where``, ``median_time``, ``time_split``.
Chapter 3: ``use_eleven_colours``, ``rejected``, ``gauss_newton_minimum``, ``reached``,
``factorizations``, ``method_table``, ``chi2_against_time``, ``show_rejections``.
Chapter 3b: ``basin_figure``, ``lowest``, ``initialiser_table``, ``time_to_solution_table``.

A run is a ``course.core.trace.RunResult``.
"""

from __future__ import annotations

import contextlib
import statistics
import time
from collections.abc import Callable, Sequence
from typing import Any, TypeVar

import numpy as np

from course.app import plot
from course.core.errors import DatasetError
from course.core.trace import RunResult

T = TypeVar("T")

# ---------------------------------------------------------------- every chapter


def ran(runs: Sequence[RunResult]) -> list[RunResult]:
    """The runs that ran: a peer not installed here is a row of the table, not a curve."""
    return [r for r in runs if not r.not_run]


def not_run_note(runs: Sequence[RunResult]) -> str:
    """``"; not run here: ceres dogleg (pyceres is not installed here), ..."`` or ``""``."""
    skipped = [f"{r.backend} {r.method} ({r.not_run.removeprefix('not run: ')})" for r in runs if r.not_run]
    return "; not run here: " + ", ".join(skipped) if skipped else ""


# ---------------------------------------------------------------- chapter 2: pose graphs


def load(name: str) -> Any:
    """The named pose graph, or None (saying why) when its file is not on this machine."""
    from course.problems.posegraph import dataset as datasets  # chapter 2's: a chapter-1 tree has none

    try:
        return datasets.load_dataset(name)
    except DatasetError as exc:
        print(f"{name}: skipped ({exc})")
        return None


def one_thread() -> contextlib.AbstractContextManager:
    """A context in which BLAS runs on one thread (``threadpoolctl``); a no-op without it."""
    try:
        from threadpoolctl import threadpool_limits
    except ImportError:  # then BLAS keeps its own thread count
        return contextlib.nullcontext()
    return threadpool_limits(limits=1)


def outcome(r: RunResult) -> str:
    """'converged', 'limit' (max_iterations) or 'failed', from the stop reason."""
    if r.stop_reason.startswith("max_iterations"):
        return "limit"
    if r.stop_reason.startswith(("failed", "lambda_upper_bound", "solver_stopped")):
        return "failed"
    return "converged"


def where(r: RunResult, gn_min: float) -> str:
    """Where ``r`` ends against the Gauss-Newton minimum ``gn_min`` (1e-6 relative)."""
    rel = (r.final_chi2 - gn_min) / gn_min
    if abs(rel) <= 1e-6:
        return "the Gauss-Newton minimum"
    return "a lower minimum" if rel < 0 else "above the Gauss-Newton minimum"


def median_time(call: Callable[[], T], repeat: int) -> tuple[float, T]:
    """(median seconds, result) of ``repeat`` calls of ``call()`` (at least one)."""
    seconds: list[float] = []
    out = None
    for _ in range(max(repeat, 1)):
        start = time.perf_counter()
        out = call()
        seconds.append(time.perf_counter() - start)
    return statistics.median(seconds), out  # type: ignore[return-value]


def time_split(g: Any, repeat: int, impl: str) -> tuple[dict, dict, float]:
    """Seconds of each part of one Gauss-Newton iteration at the start of ``g``, with the
    pieces of implementation ``impl``: (per-iteration parts, one-off parts, chi2 of a trial point).

    Raises ``NotImplementedError`` when ``impl`` lacks ``pose_graph_fast`` or ``sparse_solve``."""
    from course.core import impl as impl_loader
    from course.problems.posegraph.problem import PoseGraphProblem
    from course.solver.superlu import sparse_solver

    pieces = impl_loader.load(impl)
    fast, sparse = pieces.module("pose_graph_fast"), pieces.module("sparse_solve")
    parts: dict[str, float] = {}
    once: dict[str, float] = {}
    parts["errors and Jacobians"], (e, A, B) = median_time(
        lambda: fast.edge_errors_and_jacobians(g.poses, g.edges_i, g.edges_j, g.measurements), repeat)
    once["sparsity pattern of H"], assembler = median_time(
        lambda: fast.SparseAssembler(g.num_poses, g.edges_i, g.edges_j, g.fixed), repeat)
    parts["assembly of H and b (and chi2)"], (H, b, _) = median_time(
        lambda: assembler.assemble(e, A, B, g.information), repeat)
    first, _ = median_time(lambda: sparse_solver(sparse).solve(H, b), repeat)
    solver = sparse_solver(sparse)  # SuperLU where qdldl is not installed
    solver.solve(H, b)
    parts["factorization and solve"], h = median_time(lambda: solver.solve(H, b), repeat)
    once["ordering and symbolic factorization"] = max(first - parts["factorization and solve"], 0.0)
    problem = PoseGraphProblem(g, impl)
    parts["pose update (retract)"], _ = median_time(lambda: problem.retract(problem.x0, h), repeat)
    trial, _ = median_time(lambda: g.chi2(), repeat)
    return parts, once, trial


# ---------------------------------------------------------------- chapter 3: the dogleg


def use_eleven_colours() -> None:
    """Matplotlib's colour cycle: tab10 and black (eleven runs per pose graph)."""
    import matplotlib
    from cycler import cycler

    tab10 = matplotlib.colormaps["tab10"].colors  # type: ignore[attr-defined]  # a ListedColormap
    matplotlib.rcParams["axes.prop_cycle"] = cycler(color=[*tab10, "black"])


def rejected(r: RunResult) -> list[int]:
    """Indices of the rejected step attempts in ``r.trace``.

    When the LM loop stops on a tiny step it records that step (no trial point, rho NaN):
    not an attempt that was rejected."""
    last = len(r.trace)
    if r.stop_reason == "step_tolerance" and not np.isfinite(r.trace[-1].rho):
        last -= 1
    return [k for k in range(1, last) if not r.trace[k].accepted]


def gauss_newton_minimum(runs: Sequence[RunResult]) -> float:
    """The final chi2 of our Gauss-Newton among ``runs`` (NaN when it did not run: a TODO)."""
    return next((r.final_chi2 for r in runs if r.backend == "ours" and r.method == "gauss-newton"
                 and not r.not_run), float("nan"))


def reached(r: RunResult, runs: Sequence[RunResult]) -> str:
    """'yes' when ``r`` ends at the Gauss-Newton minimum (1e-6 relative), else 'no' or 'lower';
    '?' when our Gauss-Newton did not run."""
    gn = gauss_newton_minimum(runs)
    if not np.isfinite(gn):
        return "?"
    rel = (r.final_chi2 - gn) / gn
    return "yes" if abs(rel) <= 1e-6 else ("lower" if rel < 0 else "no")


def factorizations(r: RunResult) -> str:
    """The factorization count of ``r``: exact for ours, ``*`` where a peer reports it, else n/a."""
    if r.backend == "ours":
        return str(r.factorizations)
    if (r.backend == "ceres" and r.factorizations > 0) or (r.backend == "g2o" and r.method == "levenberg"):
        return f"{r.factorizations}*"
    return "n/a"


def method_table(runs: Sequence[RunResult], title: str) -> str:
    """A text table of ``runs``: iterations, factorizations, time, final chi2, at GN minimum."""
    head = (f"{'backend':8} {'method':20} {'iters':>5} {'factorizations':>14} {'time ms':>9} "
            f"{'final chi2':>17}  at GN minimum")
    lines = [title, head, "-" * len(head)]
    for r in runs:
        lines.append(f"{r.backend:8} {r.method:20} {r.iterations:5d} {factorizations(r):>14} "
                     f"{1e3 * r.seconds:9.2f} {r.final_chi2:17.10g}  {reached(r, runs)}")
    return "\n".join(lines)


def chi2_against_time(runs: Sequence[RunResult], title: str) -> Any:
    """A figure of the chi2 of the point kept against the time since the solve started, log-log."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=(7, 4.5), layout="constrained")
    ax = fig.add_subplot()
    values, starts = [], []
    for r in runs:
        t = np.array([record.seconds for record in r.trace])
        kept = plot.kept_chi2(r)
        keep = (t > 0) & np.isfinite(kept) & (kept > 0)
        if not keep.any():
            continue
        ax.plot(1e3 * t[keep], kept[keep], marker=".", label=f"{plot.label(r)} ({1e3 * r.seconds:.1f} ms)")
        values.append(kept[keep])
        starts.append(r.trace[0].chi2)
    if np.isfinite(gauss_newton_minimum(runs)):
        ax.axhline(gauss_newton_minimum(runs), color="k", linestyle=":", linewidth=1, label="Gauss-Newton minimum")
    ax.set_xscale("log")
    ax.set_yscale("log")
    if values:
        v = np.concatenate(values)
        ax.set_ylim(v.min() / 2, min(v.max() * 5, max(starts) * 1e3))
    ax.set_xlabel("milliseconds since the solve started (the start, at 0, is off the axis)")
    ax.set_ylabel("chi2")
    ax.set_title(title)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize="x-small")
    return fig


def show_rejections(run: RunResult, limit: int, name: str) -> list[int]:
    """Print the trace rows of ``run`` (on dataset ``name``) around each rejection, at most
    ``limit`` rows; return the new factorizations before each retry."""
    trace, rejections = run.trace, rejected(run)
    rows = sorted({j for k in rejections for j in (k - 1, k, k + 1) if 0 <= j < len(trace)})
    print(f"{name}, ours {run.method}: {run.iterations} attempts, {len(rejections)} rejected, "
          f"{run.factorizations} factorizations ({run.stop_reason})")
    print(f"{'iter':>5} {'chi2':>15} {'radius/lambda':>13} {'rho':>10} {'accepted':>8} "
          f"{'factorizations':>14} {'new':>4}")
    previous = None
    for j in rows[:limit]:
        if previous is not None and j != previous + 1:
            print(f"{'...':>5}")
        r = trace[j]
        new = r.factorizations - trace[j - 1].factorizations if j > 0 else r.factorizations
        print(f"{r.iteration:5d} {r.chi2:15.8g} {r.damping:13.4g} {r.rho:10.3g} {str(r.accepted):>8} "
              f"{r.factorizations:14d} {new:4d}")
        previous = j
    if len(rows) > limit:
        print(f"{'...':>5} ({len(rows) - limit} more rows)")
    return [trace[k + 1].factorizations - trace[k].factorizations for k in rejections if k + 1 < len(trace)]


# ---------------------------------------------------------------- chapter 3b: initialisation


def basin_figure(starts: dict[str, tuple[Any, RunResult]], title: str) -> Any:
    """One row per start: its poses (grey, left) and where the run from it ends (blue, right).

    ``starts`` maps a start's name (``file``, ``chordal``, ...) to (the graph holding the
    start poses, the ``RunResult`` of the solve from them)."""
    from matplotlib.figure import Figure

    fig = Figure(figsize=(11, 4.5 * len(starts)), layout="constrained")
    for row, (name, (graph, run)) in enumerate(starts.items()):
        panels = [(graph.poses, "0.55", f"start: {name}, chi2 {run.initial_chi2:.4g}"),
                  (np.asarray(run.params).reshape(-1, 3), "tab:blue",
                   f"{run.backend} {run.method} from {name}: chi2 {run.final_chi2:.6g} "
                   f"({run.iterations} iterations)")]
        for col, (poses, colour, label) in enumerate(panels):
            ax = fig.add_subplot(len(starts), 2, 2 * row + col + 1)
            plot.draw_graph(ax, graph, poses, colour)
            ax.set_title(label, fontsize=9)
    fig.suptitle(title)
    return fig


def lowest(runs: Sequence[RunResult]) -> float:
    """The lowest final chi2 among the runs that ran (NaN when none did)."""
    return min((r.final_chi2 for r in runs if not r.not_run), default=float("nan"))


def initialiser_table(tables: dict[str, list[RunResult]], methods: Sequence[str]) -> str:
    """A text table, one row per (graph, start): the start's chi2, the initialisation's
    milliseconds, and per method of ``methods`` the iterations, the final chi2 and
    ``lowest`` (yes: within 1e-6 relative of the lowest final chi2 of any run on that graph).

    ``tables`` maps a graph's name to our runs on it, every start and method (``RunResult.init``
    names the start); a pair missing from the runs is ``-``, a start that did not run (a TODO) one
    line naming it."""
    group = 5 + 1 + 14 + 1 + 6
    left = f"{'graph':13} {'start':8} {'start chi2':>11} {'init ms':>8}"
    head = [(" " * len(left) + "".join(f" | {m:^{group}}" for m in methods)).rstrip(),
            left + "".join(f" | {'iters':>5} {'final chi2':>14} {'lowest':>6}" for _ in methods)]
    lines = head + ["-" * len(head[1])]
    for name, runs in tables.items():
        best = lowest(runs)
        for init in dict.fromkeys(r.init for r in runs):
            row = [r for r in runs if r.init == init and not r.not_run]
            if not row:  # a TODO: one line naming it
                reason = next(r.not_run for r in runs if r.init == init)
                lines.append(f"{name:13} {init:8} {reason}")
                continue
            line = f"{name:13} {init:8} {row[0].initial_chi2:11.4g} {1e3 * row[0].init_seconds:8.2f}"
            for m in methods:
                r = next((r for r in row if r.method == m), None)
                if r is None:
                    line += f" | {'-':>{group}}"
                    continue
                at = "yes" if abs(r.final_chi2 - best) <= 1e-6 * abs(best) else "no"
                line += f" | {r.iterations:5d} {r.final_chi2:14.8g} {at:>6}"
            lines.append(line)
    lines.append("lowest final chi2: " + ", ".join(
        f"{name} {lowest(runs):.8g}" if np.isfinite(lowest(runs)) else f"{name} - (no run)"
        for name, runs in tables.items()))
    return "\n".join(lines)


def time_to_solution_table(runs: Sequence[RunResult], title: str) -> str:
    """A text table of ``runs``: start, iterations, initialisation, solve and total
    milliseconds (the time to solution, ``RunResult.total_seconds``), final chi2; a run
    that did not run (a peer not installed here) is a row with its reason."""
    head = (f"{'backend':8} {'method':13} {'start':8} {'iters':>5} {'init ms':>9} {'solve ms':>9} "
            f"{'total ms':>9} {'final chi2':>14}")
    lines = [title, head, "-" * len(head)]
    for r in runs:
        if r.not_run:
            lines.append(f"{r.backend:8} {r.method:13} {r.init:8} {r.not_run}")
            continue
        lines.append(f"{r.backend:8} {r.method:13} {r.init:8} {r.iterations:5d} {1e3 * r.init_seconds:9.2f} "
                     f"{1e3 * r.seconds:9.2f} {1e3 * r.total_seconds:9.2f} {r.final_chi2:14.8g}")
    return "\n".join(lines)
