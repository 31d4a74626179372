"""Chapter 5's benchmark: our sliding window and batch against GTSAM's on the same simulated data,
same run, medians.

Each repeat runs, interleaved: our window with the marginalisation prior, GTSAM's
``BatchFixedLagSmoother`` on the same window (both timed per solve, the solver's call alone),
our batch from the window's estimate and GTSAM's batch LM (both timed per iteration). The
figures are the medians of the per-run means; the ratios are ours over GTSAM's, medians over
medians, with the range of the per-run ratios beside. Without gtsam it says so in one line.
"""

import statistics
from dataclasses import dataclass

import numpy as np

from course.core.peers import PeerMissing, installed
from course.problems.vio.sim import load_vio_sim
from course.problems.vio.window import batch, sliding_window

#: the rows: our window with the prior against GTSAM's fixed-lag smoother, our batch against GTSAM's
ROWS = ("window per solve", "batch per iteration")


@dataclass
class Speed:
    """One row: ``ours`` and ``theirs`` the per-run figures (s per solve or per iteration)."""

    what: str
    ours: list
    theirs: list

    @property
    def ratio(self) -> float:
        return statistics.median(self.ours) / statistics.median(self.theirs)

    @property
    def spread(self) -> tuple:
        ratios = [a / b for a, b in zip(self.ours, self.theirs)]
        return min(ratios), max(ratios)


def speed(name="vio-sim:12:0", repeats=5, window=10, keyframe_every=5, method="dogleg",
          impl="solutions") -> list:
    """``[Speed]`` for the window (per solve) and the batch (per iteration) of ``name``, ``repeats``
    interleaved runs of ours and GTSAM's; ``PeerMissing`` without gtsam."""
    if not installed("gtsam"):
        raise PeerMissing("gtsam")
    from course.backends.vio.gtsam import gtsam_batch, gtsam_window

    sim = load_vio_sim(name)
    rows = {what: Speed(what, [], []) for what in ROWS}
    for _ in range(repeats):
        ours = sliding_window(sim, "prior", window, keyframe_every, method, impl)
        theirs = gtsam_window(sim, window, keyframe_every)
        rows["window per solve"].ours.append(float(np.mean(ours.solve_seconds)))
        rows["window per solve"].theirs.append(float(np.mean(theirs.solve_seconds)))
        for run, side in ((batch(sim, ours, keyframe_every, method, impl), "ours"),
                          (gtsam_batch(sim, None, keyframe_every), "theirs")):
            getattr(rows["batch per iteration"], side).append(sum(run.solve_seconds) / max(sum(run.iterations), 1))
    return list(rows.values())


def format_speed(rows: list, name: str, repeats: int) -> str:
    """:func:`speed`'s table."""
    lines = [f"{name}: ours over GTSAM, same run, medians of {repeats} interleaved runs",
             f"{'':22} {'ours ms':>9} {'GTSAM ms':>9} {'ratio':>6}  per-run ratios"]
    for row in rows:
        low, high = row.spread
        ours, theirs = 1e3 * statistics.median(row.ours), 1e3 * statistics.median(row.theirs)
        lines.append(f"{row.what:22} {ours:9.2f} {theirs:9.2f} {row.ratio:6.2f}  {low:.2f} to {high:.2f}")
    return "\n".join(lines)


def main(names=("vio-sim:12:0",), repeats=5, impl="solutions", out=print) -> None:
    """Print :func:`format_speed` for each simulated run; without gtsam, or stopped at a TODO of
    ``impl``, one line saying so."""
    for name in names:
        try:
            rows = speed(name, repeats, impl=impl)
        except PeerMissing as exc:
            out(f"{name} sliding window against GTSAM skipped: {exc}")
            continue
        except NotImplementedError as exc:
            out(f"{name} sliding window against GTSAM not run: {exc}")
            continue
        out(format_speed(rows, name, repeats))
