"""Where a 3D pose graph's solvers start: the file's poses or the chordal relaxation."""

import time

import numpy as np

from course.core import impl as impl_loader
from course.core.errors import check_array
from course.problems.posegraph3d.graph import PoseGraph3D

#: the starts a 3D graph knows
INITIALISERS_3D = ("file", "chordal")


def initialise(graph: PoseGraph3D, method: str = "file", impl="solutions") -> tuple[PoseGraph3D, float]:
    """``(graph with its poses replaced, seconds)``: ``file`` is the graph itself (0 s);
    ``chordal`` the implementation's ``chordal_3d.chordal_poses``, anchored at the first
    fixed pose's file pose (checked: (N, 3) and (N, 3, 3), finite)."""
    if method not in INITIALISERS_3D:
        raise ValueError(f"unknown start {method!r} for a 3D pose graph; choose one of {INITIALISERS_3D}")
    if method == "file":
        return graph, 0.0
    chordal = impl_loader.load(impl).module("chordal_3d")
    anchor = int(graph.fixed[0])
    start = time.perf_counter()
    t, R = chordal.chordal_poses(graph.num_poses, graph.edges_i, graph.edges_j, graph.t_z, graph.R_z,
                                 graph.information, graph.t[anchor].copy(), graph.R[anchor].copy(), anchor)
    seconds = time.perf_counter() - start
    where = "chordal_3d.chordal_poses"
    t = check_array(t, (graph.num_poses, 3), where, "t")
    R = check_array(R, (graph.num_poses, 3, 3), where, "R")
    if not np.all(np.isfinite(t)) or not np.all(np.isfinite(R)):
        raise ValueError(f"{where} returned non-finite poses")
    return graph.with_poses(t, R), seconds
