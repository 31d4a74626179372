"""Chapter 5's comparison: our sliding window (with the marginalisation prior, and dropping old
frames), our batch, and GTSAM's fixed-lag smoother and batch on the same simulated data
(``python -m course vio``)."""

import numpy as np

from course.core.peers import installed
from course.problems.vio.ape import ape
from course.problems.vio.sim import load_vio_sim
from course.problems.vio.window import (
    VARIANTS,
    Keyframes,
    batch,
    batch_problem,
    ground_truth,
    sliding_window,
    true_states,
)


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
    speed = speed_ratios(results)
    if speed:
        lines.append("ours over GTSAM, same run: " + ", ".join(f"{what} {ratio:.2f}x" for what, ratio in speed.items()))
    return "\n".join(lines)


def speed_ratios(results: dict) -> dict:
    """``{what: ours / GTSAM}`` from :func:`compare`'s figures where both ran: the window with the
    prior against the fixed-lag smoother in seconds per solve, and the batch against GTSAM's batch in
    seconds per iteration."""
    def first(test):
        return next((r for label, r in results.items() if test(label) and "failed" not in r), None)

    out = {}
    window = first(lambda label: label.startswith("window") and label.endswith("(with prior)"))
    smoother = first(lambda label: label.startswith("GTSAM fixed-lag"))
    ours, theirs = first(lambda label: label == "batch"), first(lambda label: label == "GTSAM batch")
    if window and smoother:
        out["window per solve"] = window["mean_solve_seconds"] / smoother["mean_solve_seconds"]
    if ours and theirs:
        out["batch per iteration"] = ((ours["mean_solve_seconds"] / ours["mean_iterations"])
                                      / (theirs["mean_solve_seconds"] / theirs["mean_iterations"]))
    return out


def consistency(sim="vio-sim:12:0", keyframe_every=5, impl="solutions") -> dict:
    """``{factor type: (chi2, dof)}`` of the batch problem at the truth of ``sim`` (a name or a
    ``VioSim``: true keyframe states and landmarks, the IMU preintegrated at the true biases):
    whether the factors' covariances model the simulator's noise (every ratio near 1; the
    priors, centred on the truth, below)."""
    sim = load_vio_sim(sim) if isinstance(sim, str) else sim
    kfs = Keyframes(sim, keyframe_every)
    seen = {int(lm) for f in range(len(kfs)) for lm in kfs.obs[f][0]}
    problem = batch_problem(sim, true_states(sim, keyframe_every), keyframe_every, impl, loss=None,
                            points={lm: sim.landmarks[lm] for lm in seen})
    return problem.chi2_by_factor(problem.x0)


def format_consistency(parts: dict) -> str:
    lines = [f"{'factor':<26} {'chi2':>10} {'dof':>6} {'chi2/dof':>9}"]
    lines += [f"{name:<26} {chi2:>10.1f} {dof:>6d} {chi2 / max(dof, 1):>9.3f}" for name, (chi2, dof) in parts.items()]
    return "\n".join(lines)


def seeds(count=20, seconds=12, window=10, keyframe_every=5, method="dogleg", impl="solutions") -> list:
    """APE rmse (m) and Sim(3) scale of the window with the prior and of the batch (from the
    window's estimate) on ``vio-sim:seconds:seed`` for seeds ``0 .. count - 1``: one dict a seed."""
    rows = []
    for seed in range(count):
        name = f"vio-sim:{seconds:g}:{seed}"
        sim = load_vio_sim(name)
        truth = ground_truth(sim)
        prior = sliding_window(sim, "prior", window, keyframe_every, method, impl)
        full = batch(sim, prior, keyframe_every, method, impl)
        row: dict = {"name": name}
        for label, run in (("window", prior), ("batch", full)):
            row[label] = ape(truth, run.trajectory()).stats["rmse"]
            row[label + " scale"] = ape(truth, run.trajectory(), align="sim3").alignment.scale
        rows.append(row)
    return rows


def format_seeds(rows: list) -> str:
    lines = [f"{'simulation':<16} {'window (m)':>10} {'batch (m)':>10} {'window scale':>12} {'batch scale':>11}"]
    lines += [f"{r['name']:<16} {r['window']:>10.4f} {r['batch']:>10.4f} {r['window scale']:>12.4f} "
              f"{r['batch scale']:>11.4f}" for r in rows]
    window, full = np.array([r["window"] for r in rows]), np.array([r["batch"] for r in rows])
    lines.append(f"{'mean':<16} {window.mean():>10.4f} {full.mean():>10.4f}")
    lines.append(f"{'median':<16} {np.median(window):>10.4f} {np.median(full):>10.4f}")
    lines.append(f"the batch is closer to the truth on {int(np.sum(full < window))} of {len(rows)}")
    return "\n".join(lines)


if __name__ == "__main__":  # pragma: no cover
    import sys

    print(format_comparison(compare(*(sys.argv[1:2] or ["vio-sim:12:0"]))))
