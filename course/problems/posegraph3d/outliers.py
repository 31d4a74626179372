"""Wrong loop closures (perceptual aliasing) for the outlier experiment of chapter 6.

``with_wrong_loop_closures(graph, share, seed)`` replaces ``share`` of a graph's loop closures
(the edges that do not join consecutive poses) by wrong ones, seeded: each joins two random
poses that are not consecutive, measures a rotation drawn uniformly from SO(3) and a
translation drawn from a normal distribution as wide as the graph's positions, and keeps the
replaced edge's information (so it claims the same confidence). ``outliers`` (M,) says which
edges are wrong; the odometry is never touched.
"""

import numpy as np

from course.geometry import quaternion
from course.problems.posegraph3d.graph import PoseGraph3D


def odometry(graph: PoseGraph3D) -> np.ndarray:
    """(M,) bool: the edges between consecutive poses (the known inliers)."""
    return np.abs(graph.edges_i - graph.edges_j) == 1


def with_wrong_loop_closures(graph: PoseGraph3D, share: float, seed: int = 0) -> PoseGraph3D:
    """A copy of ``graph`` with ``round(share * closures)`` loop closures replaced (see above)."""
    if not 0.0 <= share <= 1.0:
        raise ValueError(f"share must lie in [0, 1], got {share}")
    rng = np.random.default_rng(seed)
    closures = np.flatnonzero(~odometry(graph))
    wrong = np.sort(rng.choice(closures, size=int(round(share * len(closures))), replace=False))
    ei, ej = graph.edges_i.copy(), graph.edges_j.copy()
    t_z, R_z = graph.t_z.copy(), graph.R_z.copy()
    n = graph.num_poses
    for k in wrong:
        while True:
            a, b = (int(v) for v in rng.choice(n, size=2, replace=False))
            if abs(a - b) > 1:
                break
        ei[k], ej[k] = a, b
    q = rng.normal(size=(len(wrong), 4))
    R_z[wrong] = quaternion.to_matrix(q)  # a normalised Gaussian quaternion is uniform on SO(3)
    t_z[wrong] = rng.normal(0.0, float(np.std(graph.t, axis=0).mean()), (len(wrong), 3))
    outliers = np.zeros(graph.num_edges, dtype=bool)
    outliers[wrong] = True
    return PoseGraph3D(graph.t, graph.R, ei, ej, t_z, R_z, graph.information, graph.fixed, graph.ids,
                       f"{graph.name}+{share:.0%} wrong", graph.source, graph.ground_truth, outliers, graph.repaired,
                       graph.information_repair)
