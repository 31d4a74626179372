"""Where a pose-graph solve starts: the file's poses, a spanning tree, the chordal relaxation,
or GTSAM's LAGO (a peer: ``course.backends.posegraph.gtsam_lago``, where gtsam is installed and the
information matrices are diagonal); in 3D (:func:`initialise_3d`), the file's poses, our chordal
relaxation or GTSAM's ``InitializePose3`` (``course.backends.posegraph3d.gtsam_initialize``).

``initialise(graph, method, impl) -> (graph with new poses, seconds)`` runs the
implementation's ``initialisation`` module (chapter 3b's exercise: the reference's or a
student's), so a student's initialiser goes through every comparison. The first fixed pose
``graph.fixed[0]`` anchors the gauge at its file pose; every fixed pose keeps its file pose
(the solvers hold them there). ``seconds`` is the initialisation alone, for time-to-solution
(``RunResult.init_seconds``). Cheap to import (the command line reads ``INITIALISERS``).
"""

import time
from typing import TYPE_CHECKING

from course.core import impl as impl_loader
from course.core.errors import check_array

if TYPE_CHECKING:
    from course.problems.posegraph.graph import PoseGraph

#: our starts for a pose-graph solve, ``file`` (the file's poses) first
INITIALISERS = ("file", "tree", "chordal")
#: a peer's start: GTSAM's LAGO (2D), GTSAM's InitializePose3 (3D)
PEER_INITIALISERS = ("lago", "initializepose3")
#: the starts of a 3D pose graph
INITIALISERS_3D = ("file", "chordal", "initializepose3")

#: the implementation function behind each method but ``file``
FUNCTIONS = {"tree": "spanning_tree_poses", "chordal": "chordal_poses"}


def check_method(method: str) -> str:
    """``method`` if it is one of ``INITIALISERS`` or ``PEER_INITIALISERS``, else ``ValueError``."""
    if method not in INITIALISERS + PEER_INITIALISERS:
        raise ValueError(f"unknown initialisation {method!r}; choose one of "
                         f"{', '.join(INITIALISERS + PEER_INITIALISERS)}")
    return method


def initialise(graph: "PoseGraph", method: str = "file", impl="solutions") -> tuple["PoseGraph", float]:
    """``(graph with its poses replaced, seconds)`` for ``method`` (one of ``INITIALISERS``).

    ``file`` returns ``graph`` itself and 0.0; ``lago`` is GTSAM's (``PeerMissing`` without
    gtsam, ``LagoRefused`` on full information matrices). ``tree`` and ``chordal`` call
    ``spanning_tree_poses`` and ``chordal_poses`` of ``impl``'s ``initialisation`` module
    (``solutions``, ``exercises`` or a path), anchored at ``graph.fixed[0]`` at its file
    pose; the returned poses are checked ((N, 3), finite). A stub raises
    ``NotImplementedError`` naming its TODO; a disconnected graph ``ValueError``.
    """
    import numpy as np

    check_method(method)
    if method == "file":
        return graph, 0.0
    if method not in INITIALISERS + ("lago",):
        raise ValueError(f"--init {method} starts 3D pose graphs only; a 2D graph starts from one of "
                         f"{', '.join(INITIALISERS + ('lago',))}")
    if method == "lago":
        from course.core import peers

        peers.require("gtsam")
        from course.backends.posegraph import gtsam_lago

        return gtsam_lago.initialise(graph)
    module = impl_loader.load(impl).module("initialisation")
    function = getattr(module, FUNCTIONS[method])
    anchor = int(graph.fixed[0])
    args = [graph.num_poses, graph.edges_i, graph.edges_j, graph.measurements]
    if method == "chordal":
        args.append(graph.information)
    start = time.perf_counter()
    poses = function(*args, graph.poses[anchor].copy(), anchor=anchor)
    seconds = time.perf_counter() - start
    poses = np.array(check_array(poses, (graph.num_poses, 3), f"initialisation.{FUNCTIONS[method]}", "poses"))
    poses[graph.fixed] = graph.poses[graph.fixed]
    return graph.with_poses(poses), seconds


def initialise_3d(graph, method: str = "file", impl="solutions") -> tuple:
    """``(3D graph with its poses replaced, seconds)`` for ``method`` in :data:`INITIALISERS_3D`:
    ``file`` and ``chordal`` as ``course.problems.posegraph3d.initialise.initialise`` (the
    implementation's ``chordal_3d``), ``initializepose3`` GTSAM's (``PeerMissing`` without gtsam)."""
    if method not in INITIALISERS_3D:
        raise ValueError(f"--init {method}: a 3D pose graph starts from one of {', '.join(INITIALISERS_3D)}")
    if method == "initializepose3":
        from course.core import peers

        peers.require("gtsam")
        from course.backends.posegraph3d import gtsam_initialize

        return gtsam_initialize.initialise(graph)
    from course.problems.posegraph3d.initialise import initialise as ours

    return ours(graph, method, impl)
