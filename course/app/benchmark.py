"""Benchmarks: ratios against a peer measured in the same run, medians of several runs.

``python -m course benchmark`` prints, on w10000 and m3500, our Gauss-Newton time per
iteration over g2o's (g2opy), on every public 2D graph the time to solution of our chordal
start plus Gauss-Newton and of our Gauss-Newton from the file's poses over g2o's Gauss-Newton
from the file's poses (all stopped by the same rule), SuperLU over qdldl on w10000, on intel the
dense over the sparse solve of one Gauss-Newton system, the 3D graphs against g2o
(:mod:`course.app.benchmark_3d`, with and without CHOLMOD), on ladybug-49 our LM iteration over
Ceres' (pycolmap), GTSAM's and scipy's, and every back end's time to the minimum of
ladybug-49:front, the problem they all solve as it is, and how ours and Ceres' time per iteration
grow from 10k to 300k observations (:mod:`course.app.benchmark_bal`),
and the parallel assembly's speed-up (:mod:`course.app.parallel_speedup`). Nothing here is a test: the
machine is shared and noisy. A graph or peer missing here, or a piece of the implementation not
written yet (a TODO), is one line saying so, and the rest runs.
"""

import statistics
import time
from dataclasses import dataclass

import numpy as np

from course.backends import registry
from course.core import chapters
from course.core.errors import DatasetError
from course.core.peers import PeerMissing
from course.core.progress import Progress, quiet
from course.core.trace import RunResult
from course.problems.posegraph import dataset as datasets
from course.problems.posegraph.problem import PoseGraphProblem
from course.solver import SolverOptions, minimize
from course.solver.options import TIME_TO_SOLUTION_STOP as STOP
from course.solver.superlu import sparse_solver


def _median_seconds_per_iteration(run, repeats, progress, backend):
    values = []
    for _ in range(repeats):
        with progress.run(backend, "gauss-newton") as callback:
            result = run(callback)
        values.append(result.seconds / max(result.iterations, 1))
    return statistics.median(values), result


def gauss_newton_vs_g2o(name, repeats=5, impl="solutions", progress=None):
    """``(ours, g2o, ours_result, g2o_result)`` seconds per GN iteration, medians of ``repeats``.

    Raises ``PeerMissing`` without g2opy, ``DatasetError`` when ``name`` is not here."""
    progress = progress or quiet()
    g2o = registry.peer_solver("posegraph", "g2o")
    graph = datasets.load_dataset(name)
    ours, ours_result = _median_seconds_per_iteration(
        lambda callback: minimize(PoseGraphProblem(graph, impl), "gauss-newton", impl=impl, callback=callback),
        repeats, progress, "ours")
    theirs, g2o_result = _median_seconds_per_iteration(
        lambda callback: g2o(graph, "gauss-newton"), repeats, progress, "g2o")
    return ours, theirs, ours_result, g2o_result


@dataclass
class TimeToSolution:
    """Median seconds to solution on one graph, the runs interleaved: our chordal start plus
    Gauss-Newton (the start included), our Gauss-Newton from the file's poses, and g2o's from
    the file's poses; each with its last run (``RunResult``: iterations, final chi2 in our error)."""

    chordal: float
    file: float
    g2o: float
    chordal_run: RunResult
    file_run: RunResult
    g2o_run: RunResult


def time_to_solution(name, repeats=5, impl="solutions", progress=None) -> TimeToSolution:
    """:class:`TimeToSolution` of ``name``, every run stopped by the same rule as the 3D table's
    (:data:`course.solver.options.TIME_TO_SOLUTION_STOP`).
    ``PeerMissing`` without g2opy, ``DatasetError`` without the graph."""
    from course.app.starts import initialise

    progress = progress or quiet()
    g2o = registry.peer_solver("posegraph", "g2o")
    graph = datasets.load_dataset(name)
    options = SolverOptions(cost_tolerance=STOP)
    chordal, file, theirs = [], [], []
    for _ in range(repeats):
        with progress.run("ours", "chordal + gauss-newton") as callback:
            start, init_seconds = initialise(graph, "chordal", impl)
            run = minimize(PoseGraphProblem(start, impl), "gauss-newton", options=options, impl=impl,
                           callback=callback)
            run.init, run.init_seconds = "chordal", init_seconds
        chordal.append(run)
        with progress.run("ours", "gauss-newton from the file") as callback:
            file.append(minimize(PoseGraphProblem(graph, impl), "gauss-newton", options=options, impl=impl,
                                 callback=callback))
        with progress.run("g2o", "gauss-newton"):
            theirs.append(g2o(graph, "gauss-newton", gain_threshold=STOP))
    return TimeToSolution(statistics.median(r.total_seconds for r in chordal),
                          statistics.median(r.total_seconds for r in file),
                          statistics.median(r.seconds for r in theirs), chordal[-1], file[-1], theirs[-1])


def superlu_vs_qdldl(name="w10000", repeats=5, impl="solutions", progress=None):
    """``(superlu, qdldl, superlu_result, qdldl_result)``: median seconds of a whole
    Gauss-Newton solve of ``name`` with scipy's SuperLU (the stand-in where qdldl has no
    wheel) and with the implementation's qdldl solver. ``PeerMissing`` without qdldl."""
    from course.core import peers
    from course.solver.superlu import SuperLUSolver

    peers.require("qdldl")
    progress = progress or quiet()
    graph = datasets.load_dataset(name)
    out = []
    for label, solver in (("superlu", SuperLUSolver), ("qdldl", None)):
        runs = []
        for _ in range(repeats):
            with progress.run(label, "gauss-newton") as callback:
                problem = PoseGraphProblem(graph, impl, solver=solver() if solver else "ours")
                runs.append(minimize(problem, "gauss-newton", impl=impl, callback=callback))
        out.append((statistics.median(r.seconds for r in runs), runs[-1]))
    (superlu, superlu_run), (qdldl, qdldl_run) = out
    return superlu, qdldl, superlu_run, qdldl_run


def dense_vs_sparse(name="intel", repeats=5, impl="solutions"):
    """``(dense, sparse)`` median seconds to solve one Gauss-Newton system of ``name``."""
    from course.core import impl as impl_loader

    solve = impl_loader.load(impl).module("sparse_solve")
    problem = PoseGraphProblem(datasets.load_dataset(name), impl)
    lin = problem.linearize(problem.x0)
    full = lin.H.toarray()
    full = full + full.T - np.diag(full.diagonal())
    dense, sparse = [], []
    for _ in range(repeats):
        t0 = time.perf_counter()
        dx_dense = solve.dense_solve(full, lin.b)
        t1 = time.perf_counter()
        dx_sparse = sparse_solver(solve).solve(lin.H, lin.b)
        t2 = time.perf_counter()
        dense.append(t1 - t0)
        sparse.append(t2 - t1)
    np.testing.assert_allclose(dx_sparse, dx_dense, rtol=1e-6, atol=1e-9)
    return statistics.median(dense), statistics.median(sparse)


#: the public 2D graphs of the time-to-solution table (mit left out: no peer reaches its minimum from
#: the file's poses)
SOLUTION_GRAPHS = ("intel", "intel-g2o", "csail", "fr079", "m3500", "w10000")


def main(repeats=5, graphs=("w10000", "m3500"), impl="solutions", out=print, bal=("ladybug-49",), solvers=True,
         parallel=True, graphs3d=("sphere2500", "torus3D", "parking-garage"), vio=("vio-sim:12:0",),
         solution_graphs=SOLUTION_GRAPHS):
    """Print the benchmarks of ``impl``; what cannot run here (a graph, g2opy) is one line.

    ``bal``: the bundle-adjustment problems of :mod:`course.app.benchmark_bal` (and, when there are
    any, its size sweep on ``bal-synthetic``); ``solvers``: the
    sparse and dense solves (SuperLU against qdldl on w10000, dense against sparse on intel);
    ``parallel``: the parallel assembly against the serial one; ``graphs3d``: chapter 6's 3D graphs
    (:mod:`course.app.benchmark_3d`, medians of ``min(repeats, 3)``: g2o takes minutes on torus3D);
    ``vio``: chapter 5's window and batch against GTSAM's (:mod:`course.app.benchmark_vio`);
    ``solution_graphs``: the 2D graphs of the time-to-solution table (every public one by default)."""
    out(f"Gauss-Newton seconds per iteration, ours over g2o (g2opy), median of {repeats}; impl {impl}:")
    out(f"{'graph':10} {'ours ms/it':>11} {'g2o ms/it':>10} {'ratio':>6} {'ours chi2':>14} {'g2o chi2':>14}")
    for name in graphs:
        progress = Progress(2 * repeats, label=name)  # on a terminal only
        try:
            ours, theirs, r_ours, r_g2o = gauss_newton_vs_g2o(name, repeats, impl=impl, progress=progress)
        except (PeerMissing, DatasetError, NotImplementedError) as exc:
            out(f"{name:10} skipped: {exc}")
            continue
        finally:
            progress.close()
        out(f"{name:10} {ours * 1e3:11.2f} {theirs * 1e3:10.2f} {ours / theirs:6.2f} "
            f"{r_ours.final_chi2:14.6f} {r_g2o.final_chi2:14.6f}")
    out(f"Time to solution on the 2D graphs, median of {repeats}, every run stopped at a relative chi2 decrease "
        f"below {STOP:g} (g2o's gain threshold): ours from the chordal start (the start included) and from the "
        "file's poses, over g2o's Gauss-Newton from the file's poses; iterations in brackets:")
    out(f"{'graph':10} {'chordal ms':>15} {'file ms':>13} {'g2o ms':>14} {'chordal/g2o':>11} {'file/g2o':>8} "
        f"{'chi2 chordal':>13} {'chi2 file':>13} {'chi2 g2o':>13}")
    for name in solution_graphs:
        progress = Progress(3 * repeats, label=f"{name} time to solution")
        try:
            t = time_to_solution(name, repeats, impl=impl, progress=progress)
        except (PeerMissing, DatasetError, NotImplementedError) as exc:
            out(f"{name:10} skipped: {exc}")
            continue
        finally:
            progress.close()
        out(f"{name:10} {t.chordal * 1e3:10.1f} ({t.chordal_run.iterations:2d}) {t.file * 1e3:8.1f} "
            f"({t.file_run.iterations:2d}) {t.g2o * 1e3:9.1f} ({t.g2o_run.iterations:2d}) {t.chordal / t.g2o:11.2f} "
            f"{t.file / t.g2o:8.2f} {t.chordal_run.final_chi2:13.6f} {t.file_run.final_chi2:13.6f} "
            f"{t.g2o_run.final_chi2:13.6f}")
    if solvers:
        _solvers(repeats, impl, out)
    if graphs3d and _handed_out("ch6", out):
        from course.app import benchmark_3d

        benchmark_3d.main(graphs3d, repeats=min(repeats, 3), impl=impl, out=out)
    # chapter 4: one LM iteration of bundle adjustment against the peers', and our time to solution
    if _handed_out("ch4", out):
        from course.app import benchmark_bal

        benchmark_bal.main(names=bal, repeats=repeats, impl=impl, out=out, sweep=benchmark_bal.SWEEP if bal else ())
    if vio and _handed_out("ch5", out):  # chapter 5: the sliding window and the batch against GTSAM's
        from course.app import benchmark_vio

        benchmark_vio.main(vio, repeats=repeats, impl=impl, out=out)
    # chapter 4: the parallel assembly against the serial one, alone and in whole LM / dogleg iterations
    if parallel and chapters.handed_out("ch4"):
        from course.app import parallel_speedup

        parallel_speedup.section(repeats=2 * repeats - 1, impl=impl, out=out,
                                 iteration_repeats=max(1, (repeats + 1) // 2))


def _handed_out(name: str, out) -> bool:
    """Whether this tree holds chapter ``name``; where it does not (an assignment's tree), one line saying so."""
    if chapters.handed_out(name):
        return True
    out(f"chapter {name[2:]} ({chapters.chapter(name).title}) is not handed out yet in this tree: skipped")
    return False


def _solvers(repeats, impl, out) -> None:
    """SuperLU against qdldl on w10000 and dense against sparse on intel, one line each."""
    progress = Progress(2 * repeats, label="w10000 sparse solvers")
    try:
        superlu, qdldl, r_superlu, r_qdldl = superlu_vs_qdldl("w10000", repeats, impl=impl, progress=progress)
    except (PeerMissing, DatasetError, NotImplementedError) as exc:
        out(f"w10000 SuperLU vs qdldl skipped: {exc}")
    else:
        out(f"w10000 Gauss-Newton solve: SuperLU {superlu:.2f} s ({r_superlu.iterations} it, chi2 "
            f"{r_superlu.final_chi2:.6f}), qdldl {qdldl:.2f} s ({r_qdldl.iterations} it, chi2 "
            f"{r_qdldl.final_chi2:.6f}), SuperLU/qdldl = {superlu / qdldl:.2f} (median of {repeats})")
    finally:
        progress.close()
    try:
        dense, sparse = dense_vs_sparse("intel", repeats, impl=impl)
    except (DatasetError, NotImplementedError) as exc:
        out(f"intel dense vs sparse skipped: {exc}")
    else:
        out(f"intel: dense solve {dense * 1e3:.1f} ms, sparse {sparse * 1e3:.2f} ms, "
            f"dense/sparse = {dense / sparse:.0f}x (median of {repeats})")
