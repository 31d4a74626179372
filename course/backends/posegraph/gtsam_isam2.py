"""GTSAM's ISAM2 fed a 2D pose graph one pose at a time (the online comparison, ``python -m course online``).

Step k adds pose k (``BetweenFactorPose2`` per edge whose later pose is k, ``noiseModel.Gaussian.Information``
of the edge's information; step 0 a ``PriorFactorPose2`` on pose 0 of isotropic ``prior_sigma``) with its
initial value the odometry edge between k - 1 and k (either way round) composed onto ISAM2's current
estimate of pose k - 1 (the file's value where there is no such edge). ``ISAM2Params``: ``relinearizeThreshold`` and
``relinearizeSkip = 1``, the rest GTSAM's defaults. Only ``isam.update`` is timed.
"""

import time

import numpy as np

from course.problems.posegraph.graph import PoseGraph


def run_online(graph: PoseGraph, prior_sigma: float = 1e-3, relinearize_threshold: float = 0.01) -> dict:
    """``{"seconds": (N,) per update, "relinearized": (N,), "reeliminated": (N,), "poses": (N, 3)}``."""
    import gtsam

    params = gtsam.ISAM2Params()
    params.setRelinearizeThreshold(relinearize_threshold)
    params.relinearizeSkip = 1
    isam = gtsam.ISAM2(params)
    n = graph.num_poses
    later = np.maximum(graph.edges_i, graph.edges_j)
    arriving = np.argsort(later, kind="stable")
    bounds = np.searchsorted(later[arriving], np.arange(n + 1))
    seconds, relinearized, reeliminated = np.zeros(n), np.zeros(n, dtype=int), np.zeros(n, dtype=int)
    for k in range(n):
        factors = gtsam.NonlinearFactorGraph()
        values = gtsam.Values()
        initial = gtsam.Pose2(*graph.poses[k])
        if k == 0:
            factors.add(gtsam.PriorFactorPose2(0, initial, gtsam.noiseModel.Isotropic.Sigma(3, prior_sigma)))
        for e in arriving[bounds[k]:bounds[k + 1]].tolist():
            i, j = int(graph.edges_i[e]), int(graph.edges_j[e])
            z = gtsam.Pose2(*graph.measurements[e])
            factors.add(gtsam.BetweenFactorPose2(i, j, z, gtsam.noiseModel.Gaussian.Information(graph.information[e])))
            if (i, j) == (k - 1, k) and k > 0:
                initial = isam.calculateEstimatePose2(k - 1).compose(z)
            elif (i, j) == (k, k - 1) and k > 0:  # the odometry from k to k - 1 (intel's order)
                initial = isam.calculateEstimatePose2(k - 1).compose(z.inverse())
        values.insert(k, initial)
        start = time.perf_counter()
        result = isam.update(factors, values)
        seconds[k] = time.perf_counter() - start
        relinearized[k] = result.getVariablesRelinearized()
        reeliminated[k] = result.getVariablesReeliminated()
    estimate = isam.calculateEstimate()
    poses = np.array([[p.x(), p.y(), p.theta()] for p in (estimate.atPose2(k) for k in range(n))])
    return {"seconds": seconds, "relinearized": relinearized, "reeliminated": reeliminated, "poses": poses}
