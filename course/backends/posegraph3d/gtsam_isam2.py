"""GTSAM's ISAM2 fed a 3D pose graph one pose at a time (the online comparison, ``python -m course online``).

As the 2D driver (``course.backends.posegraph.gtsam_isam2``) with ``BetweenFactorPose3``, the information
matrices in GTSAM's tangent order (rotation first), and a ``PriorFactorPose3`` on pose 0.
"""

import time

import numpy as np

from course.backends.posegraph3d.gtsam import information_for_gtsam
from course.problems.posegraph3d.graph import PoseGraph3D


def run_online(graph: PoseGraph3D, prior_sigma: float = 1e-3, relinearize_threshold: float = 0.01) -> dict:
    """``{"seconds": (N,) per update, "relinearized": (N,), "reeliminated": (N,), "t": (N, 3), "R": (N, 3, 3)}``."""
    import gtsam

    params = gtsam.ISAM2Params()
    params.setRelinearizeThreshold(relinearize_threshold)
    params.relinearizeSkip = 1
    isam = gtsam.ISAM2(params)
    n = graph.num_poses
    info = information_for_gtsam(graph.information)
    later = np.maximum(graph.edges_i, graph.edges_j)
    arriving = np.argsort(later, kind="stable")
    bounds = np.searchsorted(later[arriving], np.arange(n + 1))
    seconds, relinearized, reeliminated = np.zeros(n), np.zeros(n, dtype=int), np.zeros(n, dtype=int)
    for k in range(n):
        factors = gtsam.NonlinearFactorGraph()
        values = gtsam.Values()
        initial = gtsam.Pose3(gtsam.Rot3(graph.R[k]), graph.t[k])
        if k == 0:
            factors.add(gtsam.PriorFactorPose3(0, initial, gtsam.noiseModel.Isotropic.Sigma(6, prior_sigma)))
        for e in arriving[bounds[k]:bounds[k + 1]].tolist():
            i, j = int(graph.edges_i[e]), int(graph.edges_j[e])
            z = gtsam.Pose3(gtsam.Rot3(graph.R_z[e]), graph.t_z[e])
            factors.add(gtsam.BetweenFactorPose3(i, j, z, gtsam.noiseModel.Gaussian.Information(info[e])))
            if (i, j) == (k - 1, k) and k > 0:
                initial = isam.calculateEstimatePose3(k - 1).compose(z)
            elif (i, j) == (k, k - 1) and k > 0:  # the odometry from k to k - 1 (intel's order)
                initial = isam.calculateEstimatePose3(k - 1).compose(z.inverse())
        values.insert(k, initial)
        start = time.perf_counter()
        result = isam.update(factors, values)
        seconds[k] = time.perf_counter() - start
        relinearized[k] = result.getVariablesRelinearized()
        reeliminated[k] = result.getVariablesReeliminated()
    estimate = isam.calculateEstimate()
    matrices = np.array([estimate.atPose3(k).matrix() for k in range(n)])
    return {"seconds": seconds, "relinearized": relinearized, "reeliminated": reeliminated,
            "t": matrices[:, :3, 3], "R": matrices[:, :3, :3]}
