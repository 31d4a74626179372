"""GTSAM's LAGO initialisation of a 2D pose graph (``gtsam.lago.initialize``), as a peer of
our spanning-tree and chordal starts (``course.app.starts``).

LAGO (Carlone et al., "A fast and accurate approximation for planar pose graph
optimization", IJRR 2014) estimates the orientations by linear least squares on the
angles themselves, their 2 pi ambiguities resolved along a spanning tree of the odometry,
then the poses given them. GTSAM's implementation accepts only diagonal noise models
(``buildLinearOrientationGraph: invalid noise model``): graphs with full information
matrices (mit, intel-g2o) are refused, and :class:`LagoRefused` says which edge.

The result is moved rigidly so that the first fixed pose sits exactly at its file pose (a
rigid motion of every pose changes no edge error), and every fixed pose keeps its file pose.
"""

import time

import numpy as np

from course.core.errors import CourseError
from course.problems.posegraph.graph import PoseGraph


class LagoRefused(CourseError, ValueError):
    """GTSAM's LAGO does not accept this graph."""


def _diagonal_edges(information) -> np.ndarray:
    """(M,) whether each information matrix is diagonal."""
    off = information - np.einsum("kii->ki", information)[:, :, None] * np.eye(3)
    return ~np.any(off != 0.0, axis=(1, 2))


def initialise(graph: PoseGraph) -> tuple[PoseGraph, float]:
    """``(graph with LAGO's poses, seconds of gtsam.lago.initialize)``; ``LagoRefused`` when
    some edge's information matrix is not diagonal."""
    import gtsam

    diagonal = _diagonal_edges(graph.information)
    if not diagonal.all():
        k = int(np.flatnonzero(~diagonal)[0])
        raise LagoRefused(f"{graph.name}: GTSAM's LAGO accepts diagonal information matrices only, and "
                          f"{int((~diagonal).sum())} of {graph.num_edges} edges have a full one (edge {k}: "
                          f"{graph.information[k].round(3).tolist()})")
    factors = gtsam.NonlinearFactorGraph()
    for i, j, z, info in zip(graph.edges_i.tolist(), graph.edges_j.tolist(), graph.measurements.tolist(),
                             graph.information):
        factors.add(gtsam.BetweenFactorPose2(i, j, gtsam.Pose2(*z), gtsam.noiseModel.Diagonal.Precisions(
            np.diag(info))))
    anchor = int(graph.fixed[0])
    factors.add(gtsam.PriorFactorPose2(anchor, gtsam.Pose2(*graph.poses[anchor]),
                                       gtsam.noiseModel.Diagonal.Sigmas(np.full(3, 1e-3))))
    start = time.perf_counter()
    values = gtsam.lago.initialize(factors)
    seconds = time.perf_counter() - start
    poses = np.asarray(gtsam.utilities.extractPose2(values), dtype=float)  # rows in key order: 0..N-1
    if poses.shape != graph.poses.shape:
        raise LagoRefused(f"{graph.name}: LAGO returned {len(poses)} poses for {graph.num_poses}")
    return graph.with_poses(_moved_onto(poses, anchor, graph.poses[anchor], graph.fixed, graph.poses)), seconds


def _moved_onto(poses, anchor, target, fixed, file_poses):
    """``poses`` moved rigidly so that row ``anchor`` is ``target``; rows ``fixed`` from the file."""
    delta = target[2] - poses[anchor, 2]
    c, s = np.cos(delta), np.sin(delta)
    xy = (poses[:, :2] - poses[anchor, :2]) @ np.array([[c, s], [-s, c]]) + target[:2]
    theta = (poses[:, 2] + delta + np.pi) % (2.0 * np.pi) - np.pi
    out = np.column_stack([xy, theta])
    out[anchor] = target
    out[fixed] = file_poses[fixed]
    return out
