"""GTSAM's ISAM2 fed a 3D pose graph one pose at a time (the online comparison, ``python -m course online``).

The loop is ``course.backends.gtsam_isam2_feed``'s: ``BetweenFactorPose3`` per edge with the information
matrices in GTSAM's tangent order (rotation first), a ``PriorFactorPose3`` on pose 0 of isotropic
``prior_sigma``.
"""

import numpy as np

from course.backends.gtsam_isam2_feed import PoseFamily, feed
from course.backends.posegraph3d.gtsam import information_for_gtsam
from course.problems.posegraph3d.graph import PoseGraph3D


def run_online(graph: PoseGraph3D, prior_sigma: float = 1e-3, relinearize_threshold: float = 0.01) -> dict:
    """``{"seconds": (N,) per update, "relinearized": (N,), "reeliminated": (N,), "t": (N, 3), "R": (N, 3, 3)}``."""
    import gtsam

    info = information_for_gtsam(graph.information)
    family = PoseFamily(
        initial=lambda k: gtsam.Pose3(gtsam.Rot3(graph.R[k]), graph.t[k]),
        prior=lambda pose: gtsam.PriorFactorPose3(0, pose, gtsam.noiseModel.Isotropic.Sigma(6, prior_sigma)),
        measurement=lambda e: gtsam.Pose3(gtsam.Rot3(graph.R_z[e]), graph.t_z[e]),
        between=lambda e, z: gtsam.BetweenFactorPose3(int(graph.edges_i[e]), int(graph.edges_j[e]), z,
                                                      gtsam.noiseModel.Gaussian.Information(info[e])),
        estimate=lambda isam, k: isam.calculateEstimatePose3(k))
    isam, out = feed(graph.edges_i, graph.edges_j, graph.num_poses, family, relinearize_threshold)
    estimate = isam.calculateEstimate()
    matrices = np.array([estimate.atPose3(k).matrix() for k in range(graph.num_poses)])
    out["t"], out["R"] = matrices[:, :3, 3], matrices[:, :3, :3]
    return out
