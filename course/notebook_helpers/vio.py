"""Helpers the chapter-5 notebook calls (``notebooks/chapter5_vio.py``): a sliding-window VIO back end.

The runs come from ``course.problems.vio.window`` (ours: the window with the marginalisation prior, the
window that drops its oldest keyframe, the batch over all keyframes) and, where gtsam is
installed, from ``course.backends.vio.gtsam`` (GTSAM's batch Levenberg-Marquardt and its
fixed-lag smoother); each is a ``course.problems.vio.window.VioRun``. Layout of a window's H (n, n):
the frames first, 15 tangent coordinates each ``(dphi, dp, dv, db_g, db_a)``, then the
landmarks, 3 each.

Sections of the notebook and their helpers:

* the runs: :func:`run_estimators` (an :class:`Estimates`), :func:`runs_report`, :func:`not_run_note`;
* the fill-in of H: :func:`fill_in` (a :class:`FillIn`), :func:`fill_in_figure`, :func:`fill_in_report`;
* the window's cost and the prior's size: :func:`window_cost_figure`, :func:`prior_size_report`;
* the APE over time: :func:`ape_curves`, :func:`ape_figure`, :func:`ape_table`;
* EuRoC MH_05: :func:`mh05_table` (what ``python -m course ape euroc-mh05`` prints).

Every helper degrades to a note instead of a traceback: an implementation whose TODOs are not
written (``NotImplementedError``: a row ``not implemented: TODO module.function``), a tree
where ``course.problems.vio.window`` does not import, gtsam or ``course.backends.vio.gtsam`` missing,
the data folder without ``euroc_mh05/``.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from course.app import plot
from course.core import peers
from course.core.errors import DatasetError
from course.core.impl import not_implemented_reason

#: the tangent dimension of a keyframe and of a landmark in a window's H (``course.problems.vio.problem``)
FRAME_DOF, POINT_DOF = 15, 3
#: ours, in the order of the tables and the legends; then GTSAM's
OURS = ("prior", "drop", "batch")


# ---------------------------------------------------------------- the runs


@dataclass
class Estimates:
    """The estimates of one simulation ``name``: ``truth`` (a ``Trajectory`` at the IMU rate, or
    None when nothing ran), ``ours`` ``{"prior", "drop", "batch": VioRun or None}``, ``peers``
    (GTSAM's VioRuns that ran), ``notes`` (one line per run that did not), ``seconds`` (wall
    time of each run, by label) and ``window`` (keyframes in a full window)."""

    name: str
    truth: Any = None
    ours: dict = field(default_factory=dict)
    peers: list = field(default_factory=list)
    notes: list = field(default_factory=list)
    seconds: dict = field(default_factory=dict)
    window: int = 10

    @property
    def prior(self) -> Any:
        """The window with the marginalisation prior, or None."""
        return self.ours.get("prior")

    def runs(self) -> list:
        """Every VioRun that ran: ours (prior, drop, batch), then GTSAM's."""
        return [self.ours[k] for k in OURS if self.ours.get(k) is not None] + list(self.peers)


def _timed(call: Callable[[], Any], what: str, estimates: Estimates, log: Callable[[str], None] | None) -> Any:
    """``call()``, its wall time kept in ``estimates.seconds``; a ``NotImplementedError`` (an
    unwritten exercise) or a ``RuntimeError`` (GTSAM's indeterminate system) becomes a note (and None)."""
    start = time.perf_counter()
    try:
        run = call()
    except (NotImplementedError, RuntimeError) as exc:
        reason = not_implemented_reason(exc) if isinstance(exc, NotImplementedError) else (
            "failed: " + " ".join(str(exc).split())[:160])
        estimates.notes.append(f"{what}: {reason}")
        if log is not None:
            log(f"{what}: {reason}")
        return None
    seconds = time.perf_counter() - start
    estimates.seconds[run.label] = seconds
    if log is not None:
        log(f"{run.label}: {len(run.solve_seconds)} solves, {seconds:.1f} s")
    return run


def run_estimators(name: str, impl: Any = "solutions", keep_hessians_at: int | None = None, window: int = 10,
                   with_peers: bool = True, log: Callable[[str], None] | None = None) -> Estimates:
    """Run on the simulation ``name`` (``course.problems.vio.sim.load_vio_sim``), with implementation ``impl``:

    * ``sliding_window(sim, "prior", window, keep_hessians_at=...)``: the window with the
      marginalisation prior (its ``hessians`` hold the H of solve ``keep_hessians_at``);
    * ``sliding_window(sim, "drop", window)``: the window that forgets its oldest keyframe;
    * ``batch(sim, prior)``: all keyframes at once, started from the first;
    * with ``with_peers``, where gtsam and ``course.backends.vio.gtsam`` import: GTSAM's batch
      (``gtsam_batch(sim)``, from its own IMU propagation: it needs none of ours) and its
      fixed-lag smoother holding the same window (``gtsam_window(sim, window)``).

    ``log``, when given, is called with one line per run (its label, solves and wall time) or note."""
    estimates = Estimates(name, window=window)

    def note(line: str) -> None:
        estimates.notes.append(line)
        if log is not None:
            log(line)

    try:
        from course.problems.vio import window as vio_window
        from course.problems.vio.sim import load_vio_sim
    except ImportError as exc:
        note(f"course.problems.vio.window does not import here ({exc}): no run of ours or GTSAM's")
        return estimates
    sim = load_vio_sim(name)
    estimates.truth = vio_window.ground_truth(sim)
    prior = _timed(lambda: vio_window.sliding_window(sim, "prior", window, impl=impl,
                                                     keep_hessians_at=keep_hessians_at),
                   f"window {window} (with prior)", estimates, log)
    drop = _timed(lambda: vio_window.sliding_window(sim, "drop", window, impl=impl),
                  f"window {window} (without prior)", estimates, log)
    batch = None
    if prior is not None:
        batch = _timed(lambda: vio_window.batch(sim, prior, impl=impl), "batch", estimates, log)
    else:
        note("batch: not run (it starts from the window with the prior)")
    estimates.ours = {"prior": prior, "drop": drop, "batch": batch}
    if not with_peers:
        return estimates
    if not peers.installed("gtsam"):
        note(f"GTSAM: not run ({peers.missing_message('gtsam')})")
        return estimates
    try:
        from course.backends.vio.gtsam import gtsam_batch, gtsam_window
    except ImportError as exc:
        note(f"GTSAM: not run (course.backends.vio.gtsam does not import here: {exc})")
        return estimates
    for call, what in ((lambda: gtsam_batch(sim), "GTSAM batch"),
                       (lambda: gtsam_window(sim, window), f"GTSAM fixed-lag (window {window})")):
        run = _timed(call, what, estimates, log)
        if run is not None:
            estimates.peers.append(run)
    return estimates


def not_run_note(estimates: Estimates, what: str) -> str:
    """The line to print in place of a section that needs ``what`` (e.g. "the window with the
    prior"), which did not run: why, from ``estimates.notes``."""
    return f"{estimates.name}: {what} did not run here, so this section is skipped:\n" + "\n".join(
        f"  {line}" for line in estimates.notes)


def runs_report(estimates: Estimates) -> str:
    """One line per run: its label, keyframes, solves, iterations per solve and wall time; then
    the notes of the runs that did not run."""
    lines = [f"{estimates.name}: " + (f"{len(estimates.truth.timestamps)} IMU samples of ground truth"
                                      if estimates.truth is not None else "no ground truth (nothing ran)")]
    for run in estimates.runs():
        seconds = estimates.seconds.get(run.label, np.nan)
        lines.append(f"  {run.label:<32} {len(run.times):4d} keyframes {len(run.solve_seconds):4d} solves "
                     f"{np.mean(run.iterations):5.1f} iterations/solve {seconds:7.1f} s")
    lines += [f"  {line}" for line in estimates.notes]
    return "\n".join(lines)


# ---------------------------------------------------------------- the fill-in of H


@dataclass
class FillIn:
    """The structure of one marginalisation (``VioRun.hessians``), as boolean masks of nonzeros:

    * ``before`` (n, n): the window's H at its solution; ``removed`` its marginalised indices
      (the oldest frame and the landmarks no other frame sees); ``frames`` its frame count;
    * ``schur`` (k, k), k = n - len(removed): the pattern of the Schur complement
      ``H_kk - H_km H_mm^-1 H_mk`` on the kept indices (in their order in ``before``): ``H_kk``'s
      nonzeros and the fill-in ``fill`` (k, k), the entries that are zero in ``H_kk`` and couple
      two kept indices linked to the removed ones (structurally: both next to one connected
      group of removed indices, whose block of ``H_mm^-1`` is full);
    * ``coupled`` (k,): the kept indices linked to the removed ones (the block that fills in);
    * ``after`` (n', n'): the next window's H at its start, the new prior included;
      ``after_frames`` its frame count;
    * ``before_values``, ``after_values``: the two matrices themselves.
    """

    before: np.ndarray
    removed: np.ndarray
    frames: int
    schur: np.ndarray
    fill: np.ndarray
    coupled: np.ndarray
    after: np.ndarray | None
    after_frames: int
    before_values: np.ndarray | None = None
    after_values: np.ndarray | None = None

    @property
    def kept(self) -> np.ndarray:
        return np.setdiff1d(np.arange(len(self.before)), self.removed)

    def coupled_blocks(self) -> tuple[list, int]:
        """(the kept frames linked to the removed indices, as positions among the kept frames
        counted from 0, i.e. the next window's frames; the number of kept landmarks linked)."""
        idx, split = self.kept[self.coupled], FRAME_DOF * self.frames
        frames = sorted({int(i) // FRAME_DOF - 1 for i in idx if i < split})
        landmarks = {(int(i) - split) // POINT_DOF for i in idx if i >= split}
        return frames, len(landmarks)

    def information_ratio(self) -> tuple[list, float] | None:
        """(the kept frames no removed index is linked to, as the next window's positions; the
        median over their 15 diagonal entries of ``diag(H_after) / diag(H_before)``), or None
        without ``after`` or such frames. Marginalisation adds nothing to those frames: the
        ratio is about 1 (a little more where the new keyframe adds observations)."""
        if self.before_values is None or self.after_values is None:
            return None
        linked, _ = self.coupled_blocks()
        apart = [f for f in range(self.frames - 1) if f not in linked]
        if not apart:
            return None
        before = np.concatenate([np.diag(self.before_values)[FRAME_DOF * (f + 1):FRAME_DOF * (f + 2)] for f in apart])
        after = np.concatenate([np.diag(self.after_values)[FRAME_DOF * f:FRAME_DOF * (f + 1)] for f in apart])
        return apart, float(np.median(after / before))


def fill_in(hessians: dict) -> FillIn:
    """The :class:`FillIn` of ``hessians`` (``VioRun.hessians``: ``before``, ``removed``,
    ``before_frames``, ``after``, ``after_frames``); nonzero means exactly nonzero."""
    from scipy.sparse import csr_matrix
    from scipy.sparse.csgraph import connected_components

    nz = np.asarray(hessians["before"]) != 0
    removed = np.unique(np.asarray(hessians["removed"], dtype=np.int64))
    kept = np.setdiff1d(np.arange(len(nz)), removed)
    kk, km, mm = nz[np.ix_(kept, kept)], nz[np.ix_(kept, removed)], nz[np.ix_(removed, removed)]
    groups, label = connected_components(csr_matrix(mm), directed=False)
    member = np.zeros((len(removed), groups), dtype=np.int64)
    member[np.arange(len(removed)), label] = 1
    touches = (km.astype(np.int64) @ member) > 0  # (k, groups): kept index next to a group
    reach = (touches.astype(np.int64) @ touches.T.astype(np.int64)) > 0
    schur = kk | reach
    after = hessians.get("after")
    return FillIn(nz, removed, int(hessians["before_frames"]), schur, schur & ~kk, touches.any(axis=1),
                  None if after is None else np.asarray(after) != 0, int(hessians.get("after_frames", 0)),
                  np.asarray(hessians["before"]), None if after is None else np.asarray(after))


def _nnz(mask: np.ndarray) -> str:
    return f"{int(mask.sum())} nonzeros ({100.0 * mask.mean():.1f}%)"


def _spy(ax: Any, mask: np.ndarray, frames: int, title: str, red_rows=None, orange=None) -> None:
    """``mask`` (n, n) as a picture: nonzeros black, ``red_rows`` (indices) red in their rows and
    columns, ``orange`` (n, n) orange; the frame/landmark boundary as dashed blue lines."""
    image = np.ones(mask.shape + (3,))
    image[mask] = 0.0
    if red_rows is not None and len(red_rows):
        lines = np.zeros(mask.shape, dtype=bool)
        lines[red_rows, :] = True
        lines[:, red_rows] = True
        image[mask & lines] = (0.85, 0.1, 0.1)
    if orange is not None:
        image[orange] = (1.0, 0.55, 0.0)
    ax.imshow(image, interpolation="nearest")
    edge = FRAME_DOF * frames - 0.5
    ax.axhline(edge, color="tab:blue", linestyle="--", linewidth=0.8)
    ax.axvline(edge, color="tab:blue", linestyle="--", linewidth=0.8)
    ax.set_title(title, fontsize=9)
    ax.set_xlabel(f"frames (15 each) | landmarks (3 each); n = {len(mask)}", fontsize=8)
    ax.tick_params(labelsize=7)


def fill_in_figure(fill: FillIn) -> Any:
    """Three spy plots side by side: the window's H before the marginalisation (the removed
    rows and columns red), the Schur complement on the kept indices (the fill-in orange), and
    the next window's H at its start (its new frame and landmarks, the prior included)."""
    panels = 3 if fill.after is not None else 2
    fig = plot.figure(5.0 * panels, 5.4)
    axes = fig.subplots(1, panels)
    _spy(axes[0], fill.before, fill.frames,
         f"H of the full window ({fill.frames} frames) at its solution\n{_nnz(fill.before)}; "
         f"red: the {len(fill.removed)} indices marginalised", red_rows=fill.removed)
    _spy(axes[1], fill.schur, fill.frames - 1,
         f"H_kk - H_km H_mm^-1 H_mk on the kept indices\n{_nnz(fill.schur)}; "
         f"orange: fill-in, {int(fill.fill.sum())} entries", orange=fill.fill)
    if fill.after is not None:
        _spy(axes[2], fill.after, fill.after_frames,
             f"H of the next window ({fill.after_frames} frames) at its start\n{_nnz(fill.after)}, prior included")
    return fig


def fill_in_report(fill: FillIn) -> str:
    """The nonzero counts before and after, and the block that fills in."""
    n, k = len(fill.before), len(fill.kept)
    removed_landmarks = int(np.sum(fill.removed >= FRAME_DOF * fill.frames)) // POINT_DOF
    kept_nz = fill.schur & ~fill.fill
    frames, landmarks = fill.coupled_blocks()
    size = int(fill.coupled.sum())
    lines = [f"before: n = {n} ({fill.frames} frames, {(n - FRAME_DOF * fill.frames) // POINT_DOF} landmarks), "
             f"{_nnz(fill.before)}",
             f"removed: the oldest frame and {removed_landmarks} landmarks seen by no other frame "
             f"({len(fill.removed)} indices)",
             f"kept: k = {k}; H_kk has {int(kept_nz.sum())} nonzeros, the Schur complement {int(fill.schur.sum())}: "
             f"fill-in {int(fill.fill.sum())} entries",
             f"the block that fills in: the {size} kept indices linked to the removed ones, i.e. next window's "
             f"frame{'s' if len(frames) != 1 else ''} {', '.join(str(f) for f in frames)} and {landmarks} landmarks "
             f"(those the removed frame saw) - {size} x {size} = {size * size} entries, of which "
             f"{int(fill.schur[np.ix_(fill.coupled, fill.coupled)].sum())} are now nonzero"]
    if fill.after is not None:
        lines.append(f"after: the next window at its start, n = {len(fill.after)} ({fill.after_frames} frames, "
                     f"{(len(fill.after) - FRAME_DOF * fill.after_frames) // POINT_DOF} landmarks), {_nnz(fill.after)}")
    ratio = fill.information_ratio()
    if ratio is not None:
        apart, median = ratio
        lines.append(f"the information on the kept frames no removed index is linked to (next window's frames "
                     f"{', '.join(str(f) for f in apart)}): diag(H) of the next window over this one's, median "
                     f"{median:.2f}")
    return "\n".join(lines)


# ---------------------------------------------------------------- the window's cost and the prior's size


def _window_dof(step: dict) -> int:
    return FRAME_DOF * int(step["frames"]) + POINT_DOF * int(step["landmarks"])


def window_cost_figure(run: Any, window: int = 10) -> Any:
    """Per solve of ``run`` (a window's VioRun, ``run.steps``), against the newest keyframe's time:
    top, the window's chi2 at its solution (robust; the prior's term included); bottom, the
    prior's size (the tangent dimension of the variables it touches, and its rows, its rank)
    beside the window's dimension (15 frames + 3 landmarks). The dotted line: the first solve
    with a full window (``window`` keyframes)."""
    steps = run.steps
    t = np.array([s["time"] for s in steps])
    fig = plot.figure(9, 6.5)
    cost_ax, size_ax = fig.subplots(2, 1, sharex=True)
    cost_ax.plot(t, [s["chi2"] for s in steps], "o-", markersize=3, label="chi2 at the window's solution")
    cost_ax.set_yscale("log")
    cost_ax.set_ylabel("chi2 (robust, prior included)")
    size_ax.plot(t, [_window_dof(s) for s in steps], "-", color="0.5", label="the window: 15 frames + 3 landmarks")
    size_ax.plot(t, [s["prior_dof"] for s in steps], "o-", markersize=3, label="prior: variables it touches (dof)")
    size_ax.plot(t, [s["prior_rank"] for s in steps], "s--", markersize=3, label="prior: rows (rank)")
    size_ax.set_ylabel("tangent dimension")
    size_ax.set_xlabel("time of the window's newest keyframe (s)")
    full = next((s["time"] for s in steps if s["frames"] >= window), None)
    for ax in (cost_ax, size_ax):
        if full is not None:
            ax.axvline(full, color="k", linestyle=":", linewidth=0.8, label=f"first full window ({window} keyframes)")
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize="small")
    fig.suptitle(f"{run.label}: one point per solve", fontsize=10)
    return fig


def prior_size_report(run: Any, window: int = 10) -> str:
    """The prior's size over the solves with a full window: first, last, smallest and largest dof,
    dof minus rank, against the window's dimension; and the chi2 over the same solves."""
    full = [s for s in run.steps if s["frames"] >= window and s["prior_dof"] > 0]
    if not full:
        return f"{run.label}: no solve with a prior ({len(run.steps)} solves)"
    dof = np.array([s["prior_dof"] for s in full])
    rank = np.array([s["prior_rank"] for s in full])
    share = dof / np.array([_window_dof(s) for s in full])
    chi2 = np.array([s["chi2"] for s in full])
    gap = sorted(set((dof - rank).tolist()))
    return "\n".join([
        f"{run.label}: {len(full)} solves with a prior, from t = {full[0]['time']:.2f} s to {full[-1]['time']:.2f} s",
        f"  prior dof: first {dof[0]}, last {dof[-1]}, between {dof.min()} and {dof.max()} "
        f"({100 * share.min():.0f}% to {100 * share.max():.0f}% of the window's dimension); "
        f"dof - rank: {', '.join(str(g) for g in gap)}",
        f"  chi2 at the solution: first {chi2[0]:.4g}, last {chi2[-1]:.4g}, between {chi2.min():.4g} and "
        f"{chi2.max():.4g}"])


# ---------------------------------------------------------------- APE over time


@dataclass
class ApeCurve:
    """One run's APE: ``label``, keyframe ``times`` (K,), position ``errors`` (K,) in metres after
    SE(3) alignment on the whole run and their ``stats`` (``course.problems.vio.ape.statistics``);
    ``unaligned`` (K,) the errors without alignment (every estimate starts from the true first
    keyframe: the drift from the start); ``sim3_scale``, ``sim3_rmse`` the scale and rmse of a
    Sim(3) alignment (a scale error shows as a scale away from 1)."""

    label: str
    times: np.ndarray
    errors: np.ndarray
    stats: dict
    unaligned: np.ndarray
    sim3_scale: float
    sim3_rmse: float


def ape_curves(estimates: Estimates) -> list[ApeCurve]:
    """The APE (``course.problems.vio.ape.ape``: SE(3), none and Sim(3)) of every run of ``estimates`` against
    its ground truth."""
    from course.problems.vio.ape import ape

    out = []
    for run in estimates.runs():
        estimate = run.trajectory()
        result = ape(estimates.truth, estimate)
        unaligned = ape(estimates.truth, estimate, align="none")
        sim3 = ape(estimates.truth, estimate, align="sim3")
        out.append(ApeCurve(run.label, np.asarray(run.times)[result.est_indices], result.errors, result.stats,
                            unaligned.errors, sim3.alignment.scale, sim3.stats["rmse"]))
    return out


def ape_figure(curves: Sequence[ApeCurve], title: str) -> Any:
    """Each run's per-keyframe position error against time: left, after SE(3) alignment on the
    whole run (the APE); right, without alignment (the drift from the true start)."""
    fig = plot.figure(13, 4.8)
    aligned_ax, raw_ax = fig.subplots(1, 2, sharex=True)
    for curve in curves:
        style = "--" if curve.label.startswith("GTSAM") else "-"
        aligned_ax.plot(curve.times, curve.errors, style, marker="o", markersize=2.5,
                        label=f"{curve.label} (rmse {curve.stats['rmse']:.3f} m)")
        raw_ax.plot(curve.times, curve.unaligned, style, marker="o", markersize=2.5,
                    label=f"{curve.label} (last {curve.unaligned[-1]:.3f} m)")
    aligned_ax.set_ylabel("position error after SE(3) alignment (m)")
    aligned_ax.set_title(title, fontsize=10)
    raw_ax.set_ylabel("position error without alignment (m)")
    raw_ax.set_title("the same estimates without alignment: each starts at the true first keyframe", fontsize=10)
    for ax in (aligned_ax, raw_ax):
        ax.set_xlabel("keyframe time (s)")
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize="small")
    return fig


def ape_table(estimates: Estimates, curves: Sequence[ApeCurve]) -> str:
    """``course.app.vio.format_comparison``'s table (APE rmse and max, seconds per solve,
    solves, iterations per solve) for every run that ran; each run's Sim(3) scale and rmse and
    its last error without alignment; then the notes of the runs that did not run."""
    from course.app.vio import format_comparison

    by_label = {c.label: c for c in curves}
    results = {}
    for run in estimates.runs():
        stats = by_label[run.label].stats
        results[run.label] = {"rmse": stats["rmse"], "max": stats["max"], "scale": by_label[run.label].sim3_scale,
                              "mean_solve_seconds": float(np.mean(run.solve_seconds)),
                              "solves": len(run.solve_seconds), "mean_iterations": float(np.mean(run.iterations))}
    lines = [format_comparison(results)] if results else ["no run to compare"]
    if curves:
        lines += ["", f"{'estimator':<28} {'Sim(3) scale':>12} {'Sim(3) rmse':>12} {'last, unaligned':>16}"]
        lines += [f"{c.label:<28} {c.sim3_scale:>12.4f} {c.sim3_rmse:>12.4f} {c.unaligned[-1]:>16.4f}" for c in curves]
    if estimates.notes:
        lines += ["", "did not run here:"] + [f"  {line}" for line in estimates.notes]
    return "\n".join(lines)


# ---------------------------------------------------------------- EuRoC MH_05


def mh05_table(folder: Any = None) -> str:
    """What ``python -m course ape euroc-mh05`` prints: the APE (SE(3)) of the source's own estimate
    on EuRoC MH_05 against the ground truth, both shipped in the data folder
    (``course.problems.vio.ape.euroc_mh05_files``; ``COURSE_DATA`` or ``../shared/data``), with evo's row and
    the source's LM row beside it; a note when the files are not there."""
    from course.problems.vio import ape
    from course.problems.vio.trajectory_io import read_trajectory

    try:
        gt_path, est_path = ape.euroc_mh05_files(folder)
    except DatasetError as exc:
        return f"EuRoC MH_05: skipped ({exc})"
    stats = ape.ape(read_trajectory(gt_path), read_trajectory(est_path)).stats
    return "\n".join([
        f"APE, translation part (m); alignment se3; pairs within {ape.MAX_DIFF:g} s",
        f"  GT  {gt_path}", f"  EST {est_path}",
        ape.format_header(),
        ape.format_row("ours", stats),
        ape.format_row("evo 1.38.1 (-a)", ape.EVO_SE3_ROW),
        ape.format_row("source's LM run", ape.SOURCE_LM_ROW),
        "",
        ape.compare_to_source(stats)])
