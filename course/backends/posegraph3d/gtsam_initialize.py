"""GTSAM's ``InitializePose3`` start of a 3D pose graph, as a peer of our chordal start
(``course.problems.posegraph3d.initialise``).

``gtsam.InitializePose3.initialize(graph)`` estimates the rotations by the chordal relaxation
(one linear least-squares problem in the nine entries of every R, projected to SO(3)), then the
poses given them. It reads the graph's ``BetweenFactorPose3`` and ``PriorFactorPose3``: the
factor graph of :func:`course.backends.posegraph3d.gtsam.build_factor_graph` (our information
reordered to GTSAM's tangent), with soft priors at the fixed poses (a ``Constrained`` one
cannot be whitened there).

The result is moved rigidly so that the anchor sits exactly at its file pose (a rigid motion
of every pose changes no edge error), and every fixed pose keeps its file pose.
"""

import time

import numpy as np

from course.backends.posegraph3d.gtsam import build_factor_graph, poses_of
from course.problems.posegraph3d.graph import PoseGraph3D


def initialise(graph: PoseGraph3D) -> tuple[PoseGraph3D, float]:
    """``(graph with InitializePose3's poses, seconds of gtsam.InitializePose3.initialize)``."""
    import gtsam

    factors, _ = build_factor_graph(graph, hard_priors=False)
    anchor = int(graph.fixed[0])
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
