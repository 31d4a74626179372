"""Every method and back end in one place; compare, the demo, the benchmark, the notebooks
and the tests read them here.

Our methods are the minimizer's strategies (:data:`course.core.method_names.OUR_METHODS`, each
described there; a comparison runs :data:`~course.core.method_names.DEFAULT_METHODS` unless told
otherwise), the peers' are listed here with a line each. A peer is a module of
``course.backends`` with ``solve(problem_data, method, max_iterations, **options) ->
RunResult``; its library is imported only when it runs (:func:`peer_solver`), and where
that library is not installed the peer steps aside (``course.core.peers``). This module
imports nothing heavy, so that the command line can list names cheaply.
"""

import importlib

from course.core import peers
from course.core.backend_names import FACTOR_GRAPH_BACKENDS, GTSAM_CUSTOM, JAX, OURS
from course.core.method_names import DEFAULT_METHODS, OUR_METHODS

#: the curve's peers: backend -> (module, {method: what it is})
CURVE_PEERS: dict[str, tuple[str, dict[str, str]]] = {
    "ceres": ("course.backends.curve.ceres", {
        "levenberg-marquardt": "Ceres' Levenberg-Marquardt (pyceres): (J^T J + D^2 / radius) h = -J^T r, D^2 the "
                               "squared column norms of J, Nielsen's update of the radius",
        "dogleg": "Ceres' traditional dogleg (pyceres), in the variables scaled by D"}),
    "scipy": ("course.backends.curve.scipy", {
        "lm": "scipy.optimize.least_squares(method='lm'): MINPACK's Levenberg-Marquardt",
        "trf": "scipy.optimize.least_squares(method='trf'): the trust region reflective method"}),
}
#: the pose graphs' peers: backend -> (module, {method: what it is})
POSE_GRAPH_PEERS: dict[str, tuple[str, dict[str, str]]] = {
    "g2o": ("course.backends.posegraph.g2o", {
        "gauss-newton": "g2o's Gauss-Newton (g2opy)",
        "levenberg": "g2o's Levenberg: H + lambda I, lambda_0 = 1e-5 max H_ii, a Nielsen-like update of lambda",
        "dogleg": "g2o's Powell dogleg"}),
    "ceres": ("course.backends.posegraph.ceres", {
        "levenberg-marquardt": "Ceres' Levenberg-Marquardt (pyceres; the implementation's edge cost in Python)",
        "dogleg": "Ceres' traditional dogleg (pyceres; the implementation's edge cost in Python)"}),
    "gtsam": ("course.backends.posegraph.gtsam", {
        "gauss-newton": "GTSAM's GaussNewtonOptimizer (BetweenFactorPose2)",
        "levenberg-marquardt": "GTSAM's LevenbergMarquardtOptimizer (BetweenFactorPose2)",
        "dogleg": "GTSAM's DoglegOptimizer, Powell's dogleg (BetweenFactorPose2)"}),
}
#: the 3D pose graphs' peers (chapter 6): backend -> (module, {method: what it is})
POSE_GRAPH_3D_PEERS: dict[str, tuple[str, dict[str, str]]] = {
    "g2o": ("course.backends.posegraph3d.g2o", {
        "gauss-newton": "g2o's Gauss-Newton on EdgeSE3 (its own error, rotation part vec(q))",
        "levenberg": "g2o's Levenberg on EdgeSE3: H + lambda I, a Nielsen-like update of lambda"}),
    "gtsam": ("course.backends.posegraph3d.gtsam", {
        "gauss-newton": "GTSAM's GaussNewtonOptimizer (BetweenFactorPose3, its Logmap error)",
        "levenberg-marquardt": "GTSAM's LevenbergMarquardtOptimizer (BetweenFactorPose3, its Logmap error)"}),
    "ceres": ("course.backends.posegraph3d.ceres", {
        "levenberg-marquardt": "Ceres' Levenberg-Marquardt (pyceres; the implementation's edge error in Python)"}),
}
#: bundle adjustment's peers (chapter 4, BAL problems): backend -> (module, {method: what it is})
BAL_PEERS: dict[str, tuple[str, dict[str, str]]] = {
    "ceres": ("course.backends.bal.colmap", {
        "levenberg-marquardt": "Ceres' Levenberg-Marquardt through pycolmap.bundle_adjustment (C++ cost, Schur "
                               "complement)",
        "dogleg": "Ceres' dogleg through pycolmap.bundle_adjustment (C++ cost, Schur complement)"}),
    "gtsam": ("course.backends.bal.gtsam", {
        "levenberg-marquardt": "GTSAM's LevenbergMarquardtOptimizer (GeneralSFMFactorCal3Bundler)"}),
    "scipy": ("course.backends.bal.scipy", {
        "trf": "scipy.optimize.least_squares(method='trf'), sparse Jacobian, x_scale='jac'"}),
}
#: the factor graphs' peers (chapter 7), offered on ``FACTOR_GRAPH_KINDS`` and run when named: each solves the
#: problem's factor graph (``course.factorgraph.FactorGraph``), ``solve(graph, method, max_iterations, impl=...)``
FACTOR_GRAPH_PEERS: dict[str, tuple[str, dict[str, str]]] = {
    GTSAM_CUSTOM: ("course.backends.factorgraph.gtsam_custom", {
        "levenberg-marquardt": "GTSAM's LevenbergMarquardtOptimizer on gtsam.CustomFactor: our residual, its "
                               "Jacobians by our Jets, one Python callback per factor"}),
}
#: the library each peer back end needs (scipy is a core requirement)
LIBRARY = {"ceres": "pyceres", "g2o": "g2opy", "gtsam": "gtsam", GTSAM_CUSTOM: "gtsam", JAX: "jax", "scipy": "scipy"}
#: where a kind's peer needs another library than ``LIBRARY`` says: Ceres' bundle adjustment
#: runs through pycolmap (a C++ cost), not pyceres
KIND_LIBRARY: dict[str, dict[str, str]] = {"bal": {"ceres": "pycolmap"}}
PEERS: dict[str, dict[str, tuple[str, dict[str, str]]]] = {
    "curve": CURVE_PEERS, "posegraph": POSE_GRAPH_PEERS, "posegraph3d": POSE_GRAPH_3D_PEERS,
    "bal": BAL_PEERS}


#: the kinds whose problems are also factor graphs (chapter 7: ``ours-autodiff``, ``ours-numeric``)
FACTOR_GRAPH_KINDS = ("posegraph", "posegraph3d", "bal")

#: what each kind is, for ``--help``
KINDS = {"curve": "the curve (curve)", "posegraph": "2D pose graphs", "posegraph3d": "3D pose graphs",
         "bal": "bundle adjustment (BAL problems)"}


def pairs(kind: str, every: bool = False) -> list:
    """The ``(backend, method)`` pairs of ``kind`` ("curve", "posegraph", "posegraph3d" or "bal"), ours
    first: a comparison's default (our :data:`~course.core.method_names.DEFAULT_METHODS`), or with
    ``every`` all it offers (every strategy of the minimizer, :data:`~course.core.method_names.OUR_METHODS`);
    every peer method either way."""
    out = [(OURS, method) for method in (OUR_METHODS if every else DEFAULT_METHODS)]
    if every and kind in FACTOR_GRAPH_KINDS:  # offered, run when named: the same minimizer on the factor graph
        out += [(backend, method) for backend in FACTOR_GRAPH_BACKENDS for method in DEFAULT_METHODS]
    out += [(backend, method) for backend, (_, methods) in PEERS[kind].items() for method in methods]
    if every and kind in FACTOR_GRAPH_KINDS:  # GTSAM on our residual, beside GTSAM's native factors
        after = max((k + 1 for k, (backend, _) in enumerate(out) if backend == "gtsam"), default=len(out))
        out[after:after] = [(backend, method) for backend, (_, methods) in FACTOR_GRAPH_PEERS.items()
                            for method in methods]
    return out


def describe(kind: str, backend: str, method: str) -> str:
    """What ``method`` of ``backend`` is (one line), on problems of ``kind``."""
    if backend == OURS:
        return OUR_METHODS[method]
    if backend in FACTOR_GRAPH_BACKENDS:
        how = {"autodiff": "Jets (chapter 7)", "numeric": "central differences",
               "jax": "JAX (jax.jacfwd under vmap and jit, the residual in jax.numpy)"}[FACTOR_GRAPH_BACKENDS[backend]]
        return f"{OUR_METHODS[method]}, on the problem as a factor graph, its Jacobians by {how}"
    if backend in FACTOR_GRAPH_PEERS:
        return FACTOR_GRAPH_PEERS[backend][1][method]
    return PEERS[kind][backend][1][method]


def factor_graph_peer_solver(backend: str):
    """The ``solve`` function of a factor graphs' peer (``FACTOR_GRAPH_PEERS``), importing it now;
    ``course.core.peers.PeerMissing`` when its library is not installed."""
    peers.require(LIBRARY[backend])
    module, _ = FACTOR_GRAPH_PEERS[backend]
    return importlib.import_module(module).solve


def peer_methods(kind: str, backend: str) -> tuple:
    return tuple(PEERS[kind][backend][1])


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
