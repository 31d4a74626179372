"""Chapter 6's benchmark: 3D pose graphs against g2o (g2opy), same run, medians.

For each graph: our Gauss-Newton seconds per iteration over g2o's, both from the file's
poses and both stopped after ``iterations`` (the cost of an iteration does not depend on
where it is); and time to solution: our chordal start plus Gauss-Newton (the start
included) over g2o's whole Gauss-Newton run from the file's poses, with each one's final
chi2 in our error (where g2o does not reach our minimum from the file, the ratio is against
where it stopped). GTSAM's Gauss-Newton per iteration is printed beside, as a row, not the bar.
"""

import statistics
from collections.abc import Callable
from functools import partial

from course.backends import registry
from course.core.errors import DatasetError
from course.core.peers import PeerMissing
from course.core.trace import RunResult
from course.problems.posegraph3d import dataset as datasets
from course.problems.posegraph3d.initialise import initialise
from course.problems.posegraph3d.problem import PoseGraph3DProblem
from course.solver import SolverOptions, minimize

GRAPHS = ("sphere2500", "torus3D", "parking-garage")


def per_iteration(name, repeats=3, iterations=8, impl="solutions") -> dict:
    """``{backend: median seconds per Gauss-Newton iteration}`` for ours, g2o and GTSAM (where
    installed) on ``name`` from the file's poses, each run capped at ``iterations``."""
    graph = datasets.load_dataset(name)
    options = SolverOptions(max_iterations=iterations)
    runs: dict[str, Callable[[], RunResult]] = {
        "ours": lambda: minimize(PoseGraph3DProblem(graph, impl), "gauss-newton", impl=impl, options=options)}
    for backend in ("g2o", "gtsam"):
        try:
            solve = registry.peer_solver("posegraph3d", backend)
        except PeerMissing:
            continue
        runs[backend] = partial(solve, graph, "gauss-newton", iterations)
    out = {}
    for backend, run in runs.items():
        values = []
        for _ in range(repeats):
            result = run()
            values.append(result.seconds / max(result.iterations, 1))
        out[backend] = statistics.median(values)
    return out


def time_to_solution(name, repeats=3, impl="solutions") -> tuple:
    """``(ours seconds, g2o seconds, ours result, g2o result)``, medians: chordal + GN against
    g2o's GN from the file's poses. ``PeerMissing`` without g2opy."""
    g2o = registry.peer_solver("posegraph3d", "g2o")
    graph = datasets.load_dataset(name)
    ours, theirs = [], []
    for _ in range(repeats):
        start, seconds = initialise(graph, "chordal", impl)
        run = minimize(PoseGraph3DProblem(start, impl), "gauss-newton", impl=impl)
        run.init, run.init_seconds = "chordal", seconds
        ours.append(run)
        theirs.append(g2o(graph, "gauss-newton"))
    return (statistics.median(r.total_seconds for r in ours), statistics.median(r.seconds for r in theirs),
            ours[-1], theirs[-1])


def main(graphs=GRAPHS, repeats=3, impl="solutions", out=print) -> None:
    """Print both tables; a graph or peer missing here is one line."""
    out(f"3D pose graphs: Gauss-Newton ms per iteration from the file's poses, median of {repeats}; impl {impl}:")
    out(f"{'graph':15} {'ours':>9} {'g2o':>9} {'ours/g2o':>9} {'gtsam':>9} {'ours/gtsam':>10}")
    for name in graphs:
        try:
            seconds = per_iteration(name, repeats, impl=impl)
        except DatasetError as exc:
            out(f"{name:15} skipped: {exc}")
            continue
        g2o, gtsam = seconds.get("g2o"), seconds.get("gtsam")
        out(f"{name:15} {seconds['ours'] * 1e3:9.1f} "
            + (f"{g2o * 1e3:9.1f} {seconds['ours'] / g2o:9.2f} " if g2o else f"{'-':>9} {'-':>9} ")
            + (f"{gtsam * 1e3:9.1f} {seconds['ours'] / gtsam:10.2f}" if gtsam else f"{'-':>9} {'-':>10}"))
    out(f"3D time to solution: ours (chordal start + Gauss-Newton, the start included) over g2o's Gauss-Newton "
        f"from the file's poses, median of {repeats}; final chi2 in our error:")
    out(f"{'graph':15} {'ours ms':>9} {'g2o ms':>9} {'ratio':>6} {'ours it':>8} {'g2o it':>7} {'ours chi2':>14} "
        f"{'g2o chi2':>14}")
    for name in graphs:
        try:
            ours, theirs, r_ours, r_g2o = time_to_solution(name, repeats, impl=impl)
        except (PeerMissing, DatasetError) as exc:
            out(f"{name:15} skipped: {exc}")
            continue
        out(f"{name:15} {ours * 1e3:9.1f} {theirs * 1e3:9.1f} {ours / theirs:6.2f} {r_ours.iterations:8d} "
            f"{r_g2o.iterations:7d} {r_ours.final_chi2:14.6f} {r_g2o.final_chi2:14.6f}")
