"""Every method and back end in one place; compare, the demo, the benchmark, the notebooks
and the tests read them here.

Our methods are the minimizer's (:data:`course.solver.METHODS`). A peer is a module of
``course.backends`` with ``solve(problem_data, method, max_iterations, **options) ->
RunResult``; its library is imported only when it runs (:func:`peer_solver`), and where
that library is not installed the peer steps aside (``course.core.peers``). This module
imports nothing heavy, so that the command line can list names cheaply.
"""

import importlib

from course.core import peers
from course.core.backend_names import OURS

#: the curve's peers: backend -> (module, methods)
CURVE_PEERS: dict[str, tuple[str, tuple[str, ...]]] = {
    "ceres": ("course.backends.curve.ceres", ("levenberg-marquardt", "dogleg")),
    "scipy": ("course.backends.curve.scipy", ("lm", "trf")),
}
#: the pose graphs' peers: backend -> (module, methods)
POSE_GRAPH_PEERS: dict[str, tuple[str, tuple[str, ...]]] = {
    "g2o": ("course.backends.posegraph.g2o", ("gauss-newton", "levenberg", "dogleg")),
    "ceres": ("course.backends.posegraph.ceres", ("levenberg-marquardt", "dogleg")),
    "gtsam": ("course.backends.posegraph.gtsam", ("gauss-newton", "levenberg-marquardt", "dogleg")),
}
#: the 3D pose graphs' peers (chapter 6): backend -> (module, methods)
POSE_GRAPH_3D_PEERS: dict[str, tuple[str, tuple[str, ...]]] = {
    "g2o": ("course.backends.posegraph3d.g2o", ("gauss-newton", "levenberg")),
    "gtsam": ("course.backends.posegraph3d.gtsam", ("gauss-newton", "levenberg-marquardt")),
    "ceres": ("course.backends.posegraph3d.ceres", ("levenberg-marquardt",)),
}
#: bundle adjustment's peers (chapter 4, BAL problems): backend -> (module, methods)
BAL_PEERS: dict[str, tuple[str, tuple[str, ...]]] = {
    "ceres": ("course.backends.bal.colmap", ("levenberg-marquardt", "dogleg")),
    "gtsam": ("course.backends.bal.gtsam", ("levenberg-marquardt",)),
    "scipy": ("course.backends.bal.scipy", ("trf",)),
}
#: the library each peer back end needs (scipy is a core requirement)
LIBRARY = {"ceres": "pyceres", "g2o": "g2opy", "gtsam": "gtsam", "scipy": "scipy"}
#: where a kind's peer needs another library than ``LIBRARY`` says: Ceres' bundle adjustment
#: runs through pycolmap (a C++ cost), not pyceres
KIND_LIBRARY: dict[str, dict[str, str]] = {"bal": {"ceres": "pycolmap"}}
PEERS: dict[str, dict[str, tuple[str, tuple[str, ...]]]] = {
    "curve": CURVE_PEERS, "posegraph": POSE_GRAPH_PEERS, "posegraph3d": POSE_GRAPH_3D_PEERS,
    "bal": BAL_PEERS}


def pairs(kind: str) -> list:
    """Every ``(backend, method)`` of ``kind`` ("curve", "posegraph" or "bal"), ours first."""
    from course.solver import METHODS

    out = [(OURS, method) for method in METHODS]
    out += [(backend, method) for backend, (_, methods) in PEERS[kind].items() for method in methods]
    return out


def peer_methods(kind: str, backend: str) -> tuple:
    return PEERS[kind][backend][1]


def library(kind: str, backend: str) -> str:
    """The library the peer ``backend`` of ``kind`` needs (``pycolmap`` for Ceres on "bal")."""
    return KIND_LIBRARY.get(kind, {}).get(backend, LIBRARY[backend])


def peer_solver(kind: str, backend: str):
    """The ``solve`` function of a peer of ``kind``, importing its module (and library) now.

    Raises ``course.core.peers.PeerMissing`` (said once on stderr) when its library is not installed.
    """
    peers.require(library(kind, backend))
    module, _ = PEERS[kind][backend]
    return importlib.import_module(module).solve
