"""GTSAM's ``InitializePose3`` start of a 3D pose graph, as a peer of our chordal start
(``course.problems.posegraph3d.initialise``).

``gtsam.InitializePose3.initialize(graph)`` estimates the rotations by the chordal relaxation
(one linear least-squares problem in the nine entries of every R, projected to SO(3)), then the
poses given them. It reads the graph's ``BetweenFactorPose3`` and one ``PriorFactorPose3``,
which anchors the gauge: here a tight prior (sigma 1e-3) at the first fixed pose's file pose.
Our information matrices go in, reordered to GTSAM's tangent (rotation first).

The result is moved rigidly so that the anchor sits exactly at its file pose (a rigid motion
of every pose changes no edge error), and every fixed pose keeps its file pose.
"""

import time

import numpy as np

from course.backends.posegraph3d.gtsam import information_for_gtsam, poses_of
from course.problems.posegraph3d.graph import PoseGraph3D

#: the anchor prior's standard deviation (rotation in rad, translation in the graph's unit)
ANCHOR_SIGMA = 1e-3


def initialise(graph: PoseGraph3D) -> tuple[PoseGraph3D, float]:
    """``(graph with InitializePose3's poses, seconds of gtsam.InitializePose3.initialize)``."""
    import gtsam

    factors = gtsam.NonlinearFactorGraph()
    info = information_for_gtsam(graph.information)
    for k, (i, j) in enumerate(zip(graph.edges_i.tolist(), graph.edges_j.tolist())):
        factors.add(gtsam.BetweenFactorPose3(i, j, gtsam.Pose3(gtsam.Rot3(graph.R_z[k]), graph.t_z[k]),
                                             gtsam.noiseModel.Gaussian.Information(info[k])))
    anchor = int(graph.fixed[0])
    factors.add(gtsam.PriorFactorPose3(anchor, gtsam.Pose3(gtsam.Rot3(graph.R[anchor]), graph.t[anchor]),
                                       gtsam.noiseModel.Isotropic.Sigma(6, ANCHOR_SIGMA)))
    start = time.perf_counter()
    values = gtsam.InitializePose3.initialize(factors)
    seconds = time.perf_counter() - start
    t, R = poses_of(values, graph.num_poses)
    # the rigid motion that puts the anchor exactly at its file pose: T -> T_file T_anchor^-1 T
    turn = graph.R[anchor] @ R[anchor].T
    t = (t - t[anchor]) @ turn.T + graph.t[anchor]
    R = turn @ R
    t[graph.fixed], R[graph.fixed] = graph.t[graph.fixed], graph.R[graph.fixed]
    return graph.with_poses(t, np.asarray(R)), seconds
