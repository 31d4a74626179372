"""GTSAM's ``Marginals`` of a 2D pose graph at given poses, in our tangent.

The factor graph is ``course.backends.posegraph.gtsam``'s (``fix="eliminate"``: a fixed pose is no
variable, its edges become priors on their free poses), its values ours. GTSAM's ``Pose2`` moves by
``t + R v`` (the body frame), ours by ``(x, y, theta) + delta`` (the world's), so a covariance ports as
``A Sigma A^T`` with ``A = diag(R(theta), 1)``. A fixed pose's covariance is 0. GTSAM's between error is
``Logmap(z^-1 x_i^-1 x_j)``, ours the chapter-2 error: they agree to first order in the residual, so
the two H differ by the order of the residuals at the optimum.
"""

import time

import numpy as np

from course.backends.posegraph.gtsam import build_factor_graph
from course.problems.posegraph.graph import PoseGraph


def to_ours(covariance, theta) -> np.ndarray:
    """A ``Pose2`` covariance (3, 3) (body frame) at heading ``theta`` in our world-frame tangent."""
    c, s = np.cos(theta), np.sin(theta)
    A = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    return A @ covariance @ A.T


def marginals(graph: PoseGraph, poses) -> tuple[np.ndarray, float]:
    """``(covariances (N, 3, 3), seconds)`` of every pose at ``poses`` (N, 3): GTSAM's ``Marginals``
    (made, and ``marginalCovariance`` of every free pose) timed, the conversion not."""
    import gtsam

    poses = np.asarray(poses, dtype=float)
    factors, values, free = build_factor_graph(graph.with_poses(poses), fix="eliminate")
    start = time.perf_counter()
    marginal = gtsam.Marginals(factors, values)
    raw = [marginal.marginalCovariance(int(k)) for k in free.tolist()]
    seconds = time.perf_counter() - start
    out = np.zeros((graph.num_poses, 3, 3))
    for k, covariance in zip(free.tolist(), raw):
        out[k] = to_ours(np.asarray(covariance), poses[k, 2])
    return out, seconds
