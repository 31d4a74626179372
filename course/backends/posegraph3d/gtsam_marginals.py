"""GTSAM's ``Marginals`` of a 3D pose graph at given poses, in our tangent.

The factor graph is ``course.backends.posegraph3d.gtsam``'s, its values ours. A fixed pose has a
``Constrained`` prior there, which ``Marginals`` (a Cholesky of the Hessian) cannot take: here a fixed
pose is no variable, each of its edges a ``PriorFactorPose3`` on the other pose (``x_i z`` or ``x_j
z^-1``, the information moved by the adjoint), as the 2D peer does. GTSAM's ``Pose3`` tangent is
``(omega, v)``, rotation first, moved on the right (``R Exp(omega)``, ``t + R v``): ours in the other
order, so a covariance ports by swapping its 3x3 blocks (``course.factorgraph.conventions``). Its
between error ``Logmap(z^-1 x_i^-1 x_j)`` agrees with ours to first order in the residual.
"""

import time

import numpy as np

from course.backends.posegraph3d.gtsam import information_for_gtsam
from course.factorgraph.conventions import from_gtsam_pose3
from course.problems.posegraph3d.graph import PoseGraph3D


def factor_graph(graph: PoseGraph3D, t, R):
    """``(factors, values, free)`` at poses ``t`` (N, 3), ``R`` (N, 3, 3), the fixed poses eliminated."""
    import gtsam

    fixed = np.zeros(graph.num_poses, dtype=bool)
    fixed[graph.fixed] = True
    pose = [gtsam.Pose3(gtsam.Rot3(R[k]), t[k]) for k in range(graph.num_poses)]
    info = information_for_gtsam(graph.information)
    factors = gtsam.NonlinearFactorGraph()
    for k, (i, j) in enumerate(zip(graph.edges_i.tolist(), graph.edges_j.tolist())):
        z = gtsam.Pose3(gtsam.Rot3(graph.R_z[k]), graph.t_z[k])
        if not fixed[i] and not fixed[j]:
            factors.add(gtsam.BetweenFactorPose3(i, j, z, gtsam.noiseModel.Gaussian.Information(info[k])))
        elif not fixed[j]:
            factors.add(gtsam.PriorFactorPose3(j, pose[i].compose(z), gtsam.noiseModel.Gaussian.Information(info[k])))
        elif not fixed[i]:
            adj = z.inverse().AdjointMap()
            factors.add(gtsam.PriorFactorPose3(i, pose[j].compose(z.inverse()),
                                               gtsam.noiseModel.Gaussian.Information(adj.T @ info[k] @ adj)))
    values = gtsam.Values()
    free = np.flatnonzero(~fixed)
    for k in free.tolist():
        values.insert(k, pose[k])
    return factors, values, free


def marginals(graph: PoseGraph3D, t, R) -> tuple[np.ndarray, float]:
    """``(covariances (N, 6, 6), seconds)`` of every pose at ``t``, ``R`` in our order (translation
    first): GTSAM's ``Marginals`` (made, and ``marginalCovariance`` of every free pose) timed."""
    import gtsam

    factors, values, free = factor_graph(graph, np.asarray(t, dtype=float), np.asarray(R, dtype=float))
    start = time.perf_counter()
    marginal = gtsam.Marginals(factors, values)
    raw = [marginal.marginalCovariance(int(k)) for k in free.tolist()]
    seconds = time.perf_counter() - start
    out = np.zeros((graph.num_poses, 6, 6))
    out[free] = from_gtsam_pose3(np.array(raw).reshape(-1, 6, 6))
    return out, seconds
