"""3D pose graphs through g2o (``g2opy``): ``VertexSE3`` and ``EdgeSE3``.

The graph goes to g2o as a temporary ``.g2o`` file (``course.problems.posegraph3d.dataset.
write_g2o``) read with ``SparseOptimizer.load``, solved by
``BlockSolverSE3(LinearSolverEigenSE3())`` (Eigen's sparse Cholesky).

g2o's error is ``[D_t; vec(q(D_R))]``, the rotation part about half of ours
(``sin(theta/2)`` against ``theta``), and its information is the file's, which is for
that error: the writer converts ours back (``course.geometry.se3.G2O_SCALE``), so g2o's
chi2 equals ours up to terms of order theta^3 in the edges' residual rotations. g2o
minimises its own chi2; ``final_chi2`` is ours, evaluated on g2o's solution. Stopping as
in 2D (``course.backends.posegraph.g2o``): a terminate action on the relative decrease.
"""

import os
import tempfile
import time

import numpy as np

from course.backends import registry
from course.core.trace import IterationRecord, RunResult
from course.problems.posegraph3d.graph import PoseGraph3D
from course.problems.posegraph3d.problem import pack

METHODS = registry.peer_methods("posegraph3d", "g2o")


def solve(graph: PoseGraph3D, method: str, max_iterations: int = 100, *, gain_threshold: float = 1e-10,
          verbose: bool = False) -> RunResult:
    """Optimize ``graph`` from its poses with g2o's ``method`` (``METHODS``).

    ``params`` is ``pack(t, R)`` (12N,) in our vertex order (``course.problems.posegraph3d.problem``); ``seconds`` the
    ``optimize()`` call alone; the trace is g2o's per-iteration chi2 (g2o's error) after
    a record 0 at our initial chi2.
    """
    import g2opy

    algorithms = {"gauss-newton": g2opy.OptimizationAlgorithmGaussNewton,
                  "levenberg": g2opy.OptimizationAlgorithmLevenberg,
                  "dogleg": g2opy.OptimizationAlgorithmDogleg}
    if method not in algorithms:
        raise ValueError(f"unknown g2o method {method!r}; choose one of {METHODS}")
    optimizer = g2opy.SparseOptimizer()
    optimizer.set_algorithm(algorithms[method](g2opy.BlockSolverSE3(g2opy.LinearSolverEigenSE3())))
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
    matrices = np.array([v.estimate().matrix() for v in vertices], dtype=float)
    t, R = matrices[:, :3, 3].copy(), matrices[:, :3, :3].copy()
    initial_chi2 = graph.chi2()
    trace = [IterationRecord(0, initial_chi2, seconds=0.0)]
    elapsed, factorizations = 0.0, 0
    for stats in optimizer.batch_statistics()[:iterations]:
        elapsed += stats.time_iteration
        factorizations += max(int(stats.levenberg_iterations), 1)
        trace.append(IterationRecord(int(stats.iteration) + 1, float(stats.chi2), seconds=elapsed,
                                     factorizations=factorizations))
    if optimizer.terminate():
        reason = f"gain_threshold: relative chi2 decrease below {gain_threshold:g}"
    elif iterations >= max_iterations:
        reason = f"max_iterations: {max_iterations} reached"
    else:
        reason = f"solver_stopped: g2o {method} stopped after {iterations} iterations"
    return RunResult(backend="g2o", method=method, params=pack(t, R), initial_chi2=initial_chi2,
                     final_chi2=graph.chi2(t, R), iterations=int(iterations), seconds=seconds, trace=trace,
                     stop_reason=reason, factorizations=factorizations)


def _load(optimizer, graph: PoseGraph3D) -> list:
    """``graph`` into ``optimizer`` through a temporary file, ``graph.fixed`` fixed; g2o's
    vertices in our order."""
    from course.problems.posegraph3d.dataset import write_g2o

    fd, path = tempfile.mkstemp(suffix=".g2o", prefix="course_g2o3d_")
    os.close(fd)
    try:
        write_g2o(graph, path)
        if not optimizer.load(path):
            raise RuntimeError(f"g2o could not load the graph written to {path}")
    finally:
        os.unlink(path)
    vertices = [optimizer.vertex(int(i)) for i in np.asarray(graph.ids)]
    if len(optimizer.vertices()) != graph.num_poses or len(optimizer.edges()) != graph.num_edges:
        raise RuntimeError(f"g2o loaded {len(optimizer.vertices())} vertices and {len(optimizer.edges())} edges, "
                           f"expected {graph.num_poses} and {graph.num_edges}")
    for k in graph.fixed:
        vertices[k].set_fixed(True)
    return vertices
