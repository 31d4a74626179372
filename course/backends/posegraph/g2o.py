"""2D pose graphs through g2o (the ``g2opy`` bindings by the g2o authors).

The graph goes to g2o as a temporary ``.g2o`` file written by
``course.problems.posegraph.dataset.write_g2o`` and read with ``SparseOptimizer.load`` (adding 64k edges
one by one through the bindings is quadratic: ~20 s on w10000, against ~0.2 s for the
file). Vertices keep the file ids, the ``FIX`` lines fix ``graph.fixed``, and the
solver is ``BlockSolverSE2(LinearSolverEigenSE2())`` (sparse Cholesky, Eigen).

g2o's ``EdgeSE2`` error is ``(z^-1 (x_i^-1 x_j)).toVector()``, the same error as ours
(``course.geometry.se2.edge_errors``), so g2o's chi2 is our chi2.

Stopping: every method gets a ``SparseOptimizerTerminateAction`` that stops after an
iteration whose relative chi2 decrease ``(chi2_prev - chi2) / chi2`` lies in
``[0, gain_threshold)``. Without it Gauss-Newton runs all ``max_iterations``; with it,
the last (tiny) step is still taken. Levenberg also stops by itself when 10 damping
attempts in one iteration fail to lower chi2.
"""

import os
import tempfile
import time

import numpy as np

from course.backends import registry
from course.core.trace import IterationRecord, RunResult
from course.problems.posegraph.graph import PoseGraph

METHODS = registry.peer_methods("posegraph", "g2o")


def solve(
    graph: PoseGraph,
    method: str,
    max_iterations: int = 100,
    *,
    gain_threshold: float = 1e-10,
    verbose: bool = False,
) -> RunResult:
    """Optimize ``graph`` from ``graph.poses`` with g2o's ``method`` (one of ``METHODS``).

    Returns a ``RunResult`` with ``params`` the (N, 3) final poses in our vertex order,
    ``final_chi2 = graph.chi2(params)``, ``iterations`` as returned by
    ``SparseOptimizer.optimize`` (outer iterations: the damping attempts inside one
    Levenberg iteration count once; ``factorizations`` counts them, from g2o's
    ``levenberg_iterations``, and is one per iteration for the other methods), and
    ``seconds`` the ``optimize()`` call alone (no file writing, loading or
    ``initialize_optimization``).

    The trace: record 0 is the start (our chi2); record k is g2o's batch statistics of
    iteration k-1 (chi2 after that iteration, cumulative iteration time). ``damping``,
    ``rho`` and ``step_norm`` are not exposed by the bindings (NaN).

    ``stop_reason`` starts with ``gain_threshold``, ``max_iterations`` or
    ``solver_stopped`` (the algorithm returned Terminate or Fail; for Levenberg: no
    damping attempt lowered chi2), followed by ``: `` and details.
    ``verbose=True`` prints g2o's per-iteration lines (to C++ stderr).
    """
    import g2opy

    algorithms = {
        "gauss-newton": g2opy.OptimizationAlgorithmGaussNewton,
        "levenberg": g2opy.OptimizationAlgorithmLevenberg,
        "dogleg": g2opy.OptimizationAlgorithmDogleg,
    }
    if method not in algorithms:
        raise ValueError(f"unknown g2o method {method!r}; choose one of {METHODS}")
    if max_iterations < 1:
        raise ValueError(f"max_iterations must be >= 1, got {max_iterations}")
    optimizer = g2opy.SparseOptimizer()
    optimizer.set_algorithm(algorithms[method](g2opy.BlockSolverSE2(g2opy.LinearSolverEigenSE2())))
    optimizer.set_verbose(verbose)
    vertices = _load(optimizer, graph)
    terminate = g2opy.SparseOptimizerTerminateAction()
    terminate.set_gain_threshold(gain_threshold)
    optimizer.add_post_iteration_action(terminate)
    optimizer.set_compute_batch_statistics(True)
    if not optimizer.initialize_optimization():
        raise RuntimeError("g2o initialize_optimization() failed")

    start = time.perf_counter()
    iterations = optimizer.optimize(max_iterations)
    seconds = time.perf_counter() - start
    if iterations < 0:
        raise RuntimeError(f"g2o optimize() returned {iterations}")

    initial_chi2 = graph.chi2()
    trace, factorizations = _trace(optimizer, iterations, initial_chi2)
    poses = np.array([v.estimate().vector() for v in vertices], dtype=float).reshape(-1, 3)
    if optimizer.terminate():
        reason = f"gain_threshold: relative chi2 decrease below {gain_threshold:g}"
    elif iterations >= max_iterations:
        reason = f"max_iterations: {max_iterations} reached"
    else:
        reason = f"solver_stopped: g2o {method} stopped after {iterations} iterations"
        if method == "levenberg":
            reason += " (no damping attempt lowered chi2)"
    return RunResult(
        backend="g2o",
        method=method,
        params=poses,
        initial_chi2=initial_chi2,
        final_chi2=graph.chi2(poses),
        iterations=int(iterations),
        seconds=seconds,
        trace=trace,
        stop_reason=reason,
        factorizations=factorizations,
    )


def _load(optimizer, graph: PoseGraph) -> list:
    """Put ``graph`` into ``optimizer`` through a temporary ``.g2o`` file (see the module
    docstring) and fix ``graph.fixed``; returns g2o's vertices in our vertex order."""
    from course.problems.posegraph.dataset import write_g2o

    fd, path = tempfile.mkstemp(suffix=".g2o", prefix="course_g2o_")
    os.close(fd)
    try:
        write_g2o(graph, path)
        if not optimizer.load(path):
            raise RuntimeError(f"g2o could not load the graph written to {path}")
    finally:
        os.unlink(path)
    ids = [int(i) for i in np.asarray(graph.ids)]
    vertices = [optimizer.vertex(i) for i in ids]
    if len(optimizer.vertices()) != graph.num_poses or len(optimizer.edges()) != graph.num_edges:
        raise RuntimeError(
            f"g2o loaded {len(optimizer.vertices())} vertices and {len(optimizer.edges())} "
            f"edges, expected {graph.num_poses} and {graph.num_edges}"
        )
    for k in graph.fixed:
        vertices[k].set_fixed(True)
    return vertices


def _trace(optimizer, iterations: int, initial_chi2: float) -> tuple[list, int]:
    """``(trace, factorizations)`` from g2o's batch statistics of the first ``iterations``
    iterations, after a record 0 at ``initial_chi2`` (see ``solve``)."""
    trace = [IterationRecord(0, initial_chi2, seconds=0.0)]
    elapsed, factorizations = 0.0, 0
    for stats in optimizer.batch_statistics()[:iterations]:
        elapsed += stats.time_iteration
        factorizations += max(int(stats.levenberg_iterations), 1)
        trace.append(
            IterationRecord(
                iteration=int(stats.iteration) + 1,
                chi2=float(stats.chi2),
                seconds=elapsed,
                factorizations=factorizations,
            )
        )
    return trace, factorizations
