"""Ceres' ``Covariance`` of a 2D pose graph at given poses (``pyceres``), in our tangent.

The problem is ``course.backends.posegraph.ceres``'s (a ``(3,)`` block per pose, moved by plain addition
as ours, the fixed poses constant blocks, the implementation's ``SE2EdgeCost``), at our values; Ceres
evaluates the Jacobian once and computes the covariance blocks of every free pose by its sparse QR
(``SPARSE_QR``). Its residual is our error whitened, so its H is ours.
"""

import time

import numpy as np
import pyceres

from course.backends.posegraph.ceres import build_problem
from course.problems.posegraph.graph import PoseGraph


def options() -> "pyceres.CovarianceOptions":
    """Sparse QR, one thread (as every timed row here)."""
    chosen = pyceres.CovarianceOptions()
    chosen.algorithm_type = pyceres.CovarianceAlgorithmType.SPARSE_QR
    chosen.num_threads = 1
    return chosen


def marginals(graph: PoseGraph, poses, impl="solutions") -> tuple[np.ndarray, float]:
    """``(covariances (N, 3, 3), seconds)`` of every pose at ``poses`` (N, 3); a fixed pose's is 0;
    ``seconds``: ``Covariance.Compute`` and the blocks read."""
    problem, blocks, costs, _ = build_problem(graph, poses=np.asarray(poses, dtype=float), impl=impl)
    free = np.setdiff1d(np.arange(graph.num_poses), graph.fixed)
    pairs = [(blocks[k], blocks[k]) for k in free.tolist()]
    start = time.perf_counter()
    covariance = pyceres.Covariance(options())
    if not covariance.compute(pairs, problem):
        raise ArithmeticError(f"{graph.name}: Ceres' Covariance.Compute failed (H rank-deficient?)")
    raw = [covariance.get_covariance_block(blocks[k], blocks[k]) for k in free.tolist()]
    seconds = time.perf_counter() - start
    out = np.zeros((graph.num_poses, 3, 3))
    out[free] = np.array(raw).reshape(-1, 3, 3)
    del costs  # alive until here: the problem calls them
    return out, seconds
