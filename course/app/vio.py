"""Chapter 5's comparison: our sliding window (with the marginalisation prior, and dropping old
frames), our batch, and GTSAM's fixed-lag smoother and batch on the same simulated data
(``python -m course vio``)."""

import numpy as np

from course.core.peers import installed
from course.problems.vio.ape import ape
from course.problems.vio.sim import load_vio_sim
from course.problems.vio.window import VARIANTS, batch, ground_truth, sliding_window


def compare(name="vio-sim:12:0", window=10, keyframe_every=5, method="dogleg", impl="solutions",
            peers=True) -> dict:
    """APE rmse (m, SE(3) alignment) and time per solve (s) of the window with the
    marginalisation prior, the window that drops old frames, the batch solution, and (``peers``,
    where gtsam is installed) GTSAM's batch and fixed-lag smoother on the same problem
    (``course.backends.vio.gtsam``).

    Returns ``{label: {"rmse", "max", "scale", "mean_solve_seconds", "solves", "mean_iterations"}}``
    (``scale``: the Sim(3) alignment's scale, the trajectory's scale error), or ``{label:
    {"failed": reason}}`` for a peer that raised (GTSAM's smoother can stop on an indeterminate
    system).
    """
    sim = load_vio_sim(name)
    truth = ground_truth(sim)
    runs = [sliding_window(sim, v, window, keyframe_every, method, impl) for v in VARIANTS]
    runs.append(batch(sim, runs[0], keyframe_every, method, impl))
    failed = {}
    if peers and installed("gtsam"):
        from course.backends.vio.gtsam import gtsam_batch, gtsam_window

        for label, call in ((f"GTSAM fixed-lag (window {window})", lambda: gtsam_window(sim, window, keyframe_every)),
                            ("GTSAM batch", lambda: gtsam_batch(sim, None, keyframe_every))):
            try:
                runs.append(call())
            except RuntimeError as exc:  # GTSAM's IndeterminateLinearSystemException and kin
                failed[label] = " ".join(str(exc).split())[:160]
    out: dict = {}
    for run in runs:
        stats = ape(truth, run.trajectory()).stats
        out[run.label] = {"rmse": stats["rmse"], "max": stats["max"],
                          "scale": ape(truth, run.trajectory(), align="sim3").alignment.scale,
                          "mean_solve_seconds": float(np.mean(run.solve_seconds)), "solves": len(run.solve_seconds),
                          "mean_iterations": float(np.mean(run.iterations))}
    out.update({label: {"failed": reason} for label, reason in failed.items()})
    return out


def format_comparison(results: dict) -> str:
    """A table of :func:`compare`'s figures."""
    lines = [f"{'estimator':<30} {'APE rmse (m)':>12} {'max (m)':>9} {'scale':>8} {'s/solve':>9} {'solves':>7} "
             f"{'iters':>6}"]
    for label, r in results.items():
        if "failed" in r:
            lines.append(f"{label:<30} failed: {r['failed']}")
            continue
        lines.append(f"{label:<30} {r['rmse']:>12.4f} {r['max']:>9.4f} {r['scale']:>8.4f} "
                     f"{r['mean_solve_seconds']:>9.3f} {r['solves']:>7d} {r['mean_iterations']:>6.1f}")
    return "\n".join(lines)


if __name__ == "__main__":  # pragma: no cover
    import sys

    print(format_comparison(compare(*(sys.argv[1:2] or ["vio-sim:12:0"]))))
