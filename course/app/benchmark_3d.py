"""Chapter 6's benchmark: 3D pose graphs against g2o (g2opy), same run, medians.

For each graph: our Gauss-Newton seconds per iteration over g2o's, both from the file's
poses and both stopped after ``iterations`` (the cost of an iteration does not depend on
where it is); and time to solution: our chordal start plus Gauss-Newton (the start
included) over g2o's whole Gauss-Newton run from the file's poses, with each one's final
chi2 in our error (where g2o does not reach our minimum from the file, the ratio is against
where it stopped). GTSAM's Gauss-Newton per iteration is printed beside, as a row, not the bar.

"ours" solves each step with the implementation's sparse Cholesky (chapter 2: qdldl, a
simplicial LDL^T); "ours+CHOLMOD" with the framework's supernodal CHOLMOD
(:mod:`course.solver.cholmod`, where cvxopt is installed), the factorization g2o and GTSAM are
built on: the graphs with many loop closures fill the factor in, and there it pays.
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
from course.solver.cholmod import CholmodSolver
from course.solver.options import TIME_TO_SOLUTION_STOP as STOP

GRAPHS = ("sphere2500", "torus3D", "parking-garage")


def our_solvers() -> dict:
    """``{label: solver factory}``: the implementation's sparse solve (``"ours"``, whatever the size),
    and CHOLMOD where cvxopt is installed."""
    from course.core import peers

    solvers: dict = {"ours": lambda: "ours"}
    if peers.installed("cvxopt"):
        solvers["ours+CHOLMOD"] = CholmodSolver
    return solvers


def per_iteration(name, repeats=3, iterations=8, impl="solutions") -> dict:
    """``{backend: median seconds per Gauss-Newton iteration}`` for ours (each of :func:`our_solvers`),
    g2o and GTSAM (where installed) on ``name`` from the file's poses, each run capped at ``iterations``."""
    graph = datasets.load_dataset(name)
    options = SolverOptions(max_iterations=iterations)
    def ours(make) -> RunResult:
        return minimize(PoseGraph3DProblem(graph, impl, solver=make()), "gauss-newton", impl=impl, options=options)

    runs: dict[str, Callable[[], RunResult]] = {label: partial(ours, make) for label, make in our_solvers().items()}
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
    """``(ours, g2o seconds, g2o result)``, medians: chordal + GN with each of :func:`our_solvers`
    (``ours``: ``{label: (seconds, last result)}``) against g2o's GN from the file's poses, the runs
    interleaved, each stopped by the same rule (:data:`STOP`). ``PeerMissing`` without g2opy."""
    g2o = registry.peer_solver("posegraph3d", "g2o")
    graph = datasets.load_dataset(name)
    solvers = our_solvers()
    ours: dict = {label: [] for label in solvers}
    theirs = []
    for _ in range(repeats):
        for label, make in solvers.items():
            start, seconds = initialise(graph, "chordal", impl)
            run = minimize(PoseGraph3DProblem(start, impl, solver=make()), "gauss-newton", impl=impl,
                           options=SolverOptions(cost_tolerance=STOP))
            run.init, run.init_seconds = "chordal", seconds
            ours[label].append(run)
        theirs.append(g2o(graph, "gauss-newton", gain_threshold=STOP))
    return ({label: (statistics.median(r.total_seconds for r in runs), runs[-1]) for label, runs in ours.items()},
            statistics.median(r.seconds for r in theirs), theirs[-1])


def main(graphs=GRAPHS, repeats=3, impl="solutions", out=print) -> None:
    """Print both tables; a graph or peer missing here is one line."""
    out(f"3D pose graphs: Gauss-Newton ms per iteration from the file's poses, median of {repeats}; impl {impl}:")
    labels = list(our_solvers())
    out(f"{'graph':15} " + " ".join(f"{label:>12} {'/g2o':>5}" for label in labels) + f" {'g2o':>9} {'gtsam':>9}")
    for name in graphs:
        try:
            seconds = per_iteration(name, repeats, impl=impl)
        except (DatasetError, NotImplementedError) as exc:
            out(f"{name:15} skipped: {exc}")
            continue
        g2o, gtsam = seconds.get("g2o"), seconds.get("gtsam")
        ours = " ".join(f"{seconds[label] * 1e3:12.1f} " + (f"{seconds[label] / g2o:5.2f}" if g2o else f"{'-':>5}")
                        for label in labels)
        out(f"{name:15} {ours} " + (f"{g2o * 1e3:9.1f}" if g2o else f"{'-':>9}")
            + (f" {gtsam * 1e3:9.1f}" if gtsam else f" {'-':>9}"))
    out(f"3D time to solution: ours (chordal start + Gauss-Newton, the start included) over g2o's Gauss-Newton "
        f"from the file's poses, median of {repeats}, every run stopped at a relative chi2 decrease below {STOP:g}; "
        "final chi2 in our error:")
    out(f"{'graph':15} {'ours':12} {'ours ms':>9} {'g2o ms':>9} {'ratio':>6} {'ours it':>8} {'g2o it':>7} "
        f"{'ours chi2':>14} {'g2o chi2':>14}")
    for name in graphs:
        try:
            ours, theirs, r_g2o = time_to_solution(name, repeats, impl=impl)
        except (PeerMissing, DatasetError, NotImplementedError) as exc:
            out(f"{name:15} skipped: {exc}")
            continue
        for label, (seconds, r_ours) in ours.items():
            out(f"{name:15} {label:12} {seconds * 1e3:9.1f} {theirs * 1e3:9.1f} {seconds / theirs:6.2f} "
                f"{r_ours.iterations:8d} {r_g2o.iterations:7d} {r_ours.final_chi2:14.6f} {r_g2o.final_chi2:14.6f}")
