"""GTSAM's ISAM2 fed a 2D pose graph one pose at a time (the online comparison, ``python -m course online``).

The loop is ``course.backends.gtsam_isam2_feed``'s: ``BetweenFactorPose2`` per edge with
``noiseModel.Gaussian.Information`` of the edge's information, a ``PriorFactorPose2`` on pose 0 of isotropic
``prior_sigma``.
"""

import numpy as np

from course.backends.gtsam_isam2_feed import PoseFamily, feed
from course.problems.posegraph.graph import PoseGraph


def run_online(graph: PoseGraph, prior_sigma: float = 1e-3, relinearize_threshold: float = 0.01) -> dict:
    """``{"seconds": (N,) per update, "relinearized": (N,), "reeliminated": (N,), "poses": (N, 3)}``."""
    import gtsam

    family = PoseFamily(
        initial=lambda k: gtsam.Pose2(*graph.poses[k]),
        prior=lambda pose: gtsam.PriorFactorPose2(0, pose, gtsam.noiseModel.Isotropic.Sigma(3, prior_sigma)),
        measurement=lambda e: gtsam.Pose2(*graph.measurements[e]),
        between=lambda e, z: gtsam.BetweenFactorPose2(int(graph.edges_i[e]), int(graph.edges_j[e]), z,
                                                      gtsam.noiseModel.Gaussian.Information(graph.information[e])),
        estimate=lambda isam, k: isam.calculateEstimatePose2(k))
    isam, out = feed(graph.edges_i, graph.edges_j, graph.num_poses, family, relinearize_threshold)
    estimate = isam.calculateEstimate()
    out["poses"] = np.array([[p.x(), p.y(), p.theta()] for p in (estimate.atPose2(k) for k in range(graph.num_poses))])
    return out
