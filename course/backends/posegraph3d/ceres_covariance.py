"""Ceres' ``Covariance`` of a 3D pose graph at given poses (``pyceres``), in our tangent.

The problem is ``course.backends.posegraph3d.ceres``'s: blocks ``t`` (3,) and ``q`` (4,) per pose, our
error whitened (so its H is ours), at our values. Ceres moves ``t`` by ``t + dt`` and the quaternion by
``q_delta(d) * q``, a left rotation by ``2 d``; ours is ``(t + R rho, R Exp(phi))``, so ``rho = R^T dt``,
``phi = 2 R^T d`` and a pose's covariance is ``A C A^T``, ``A = diag(R^T, 2 R^T)``, ``C`` Ceres' joint
covariance of ``(dt, d)`` (its blocks ``tt``, ``tq``, ``qq`` in the manifold's tangent).
"""

import time

import numpy as np
import pyceres

from course.backends.posegraph3d.ceres import build_problem
from course.core import impl as impl_loader
from course.problems.posegraph3d.graph import PoseGraph3D


def options() -> "pyceres.CovarianceOptions":
    """Sparse QR, one thread (as every timed row here)."""
    chosen = pyceres.CovarianceOptions()
    chosen.algorithm_type = pyceres.CovarianceAlgorithmType.SPARSE_QR
    chosen.num_threads = 1
    return chosen


def marginals(graph: PoseGraph3D, t, R, impl="solutions") -> tuple[np.ndarray, float]:
    """``(covariances (N, 6, 6), seconds)`` of every pose at ``t`` (N, 3), ``R`` (N, 3, 3), translation
    first; a fixed pose's is 0; ``seconds``: ``Covariance.Compute`` and the blocks read."""
    R = np.asarray(R, dtype=float)
    edges = impl_loader.load(impl).module("pose_graph_3d").edge_errors_and_jacobians
    problem, t_blocks, q_blocks, costs = build_problem(graph, edges, t, R)
    free = np.setdiff1d(np.arange(graph.num_poses), graph.fixed).tolist()
    pairs = [pair for k in free for pair in ((t_blocks[k], t_blocks[k]), (t_blocks[k], q_blocks[k]),
                                              (q_blocks[k], q_blocks[k]))]
    start = time.perf_counter()
    covariance = pyceres.Covariance(options())
    if not covariance.compute(pairs, problem):
        raise ArithmeticError(f"{graph.name}: Ceres' Covariance.Compute failed (H rank-deficient?)")

    def block(a, b):
        return np.asarray(covariance.get_covariance_block_tangent_space(a, b, problem))

    raw = [(block(t_blocks[k], t_blocks[k]), block(t_blocks[k], q_blocks[k]), block(q_blocks[k], q_blocks[k]))
           for k in free]
    seconds = time.perf_counter() - start
    out = np.zeros((graph.num_poses, 6, 6))
    for k, (tt, tq, qq) in zip(free, raw):
        C = np.block([[tt, tq], [np.transpose(tq), qq]])
        A = np.zeros((6, 6))
        A[:3, :3], A[3:, 3:] = R[k].T, 2.0 * R[k].T
        out[k] = A @ C @ A.T
    del costs  # alive until here: the problem calls them
    return out, seconds
