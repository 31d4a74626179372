"""Robust 3D pose-graph solves for chapter 6: least squares, a robust kernel, and GNC around
the one minimizer, each from the chordal start, and how they score against the truth.

GNC (the implementation's ``gnc.gnc``) sees the problem through ``solve(weights) -> s``:
every call minimises ``sum_k w_k s_k`` with Gauss-Newton, warm-started from the previous
call's solution (the first from the chordal start of the weighted graph), and returns the
squared residuals ``s_k = e_k^T Omega_k e_k`` of every edge there. The odometry edges are
known inliers. An edge whose weight is below ``DROP`` is left out of the inner problem (its
share of the cost, ``w s``, is below ``DROP s``): random wrong closures join far-apart poses, and
leaving them in keeps the fill-in they cause in the sparse Cholesky factor (on sphere2500 with
20% of them, 3.8 million nonzeros in L against 1.5 million, 13x the factorization time).
``c2`` is the threshold on s: the 0.99 quantile of chi-square with 6 degrees
of freedom by default (16.81), what an inlier's s exceeds once in a hundred.
"""

from dataclasses import dataclass, field

import numpy as np

from course.core import impl as impl_loader
from course.core import peers
from course.geometry.so3 import log_many
from course.problems.posegraph3d.graph import PoseGraph3D
from course.problems.posegraph3d.initialise import initialise
from course.problems.posegraph3d.outliers import odometry
from course.problems.posegraph3d.problem import PoseGraph3DProblem, unpack
from course.solver import SolverOptions, minimize
from course.solver.cholmod import CholmodSolver

#: chi-square with 6 degrees of freedom, 0.99 quantile
C2_6DOF_99 = 16.811893829770927
#: weights below this leave their edge out of GNC's inner problem (TLS gives exact zeros)
DROP = 1e-12
#: each inner solve: Gauss-Newton, at most 30 iterations, stopped at a relative decrease of 1e-8 (the
#: weights change after it anyway; the last solve's weights are binary or final)
INNER = SolverOptions(max_iterations=30, cost_tolerance=1e-8)


@dataclass
class RobustRun:
    """One robust solve: the poses, which edges it kept (weight > 0.5), the outer iterations
    (GNC's mu values), inner Gauss-Newton iterations, seconds; for GNC, ``extra`` holds ``mus`` and
    ``weights``, the weights (M,) of each solve, the first least squares' ones included."""

    method: str
    t: np.ndarray
    R: np.ndarray
    kept: np.ndarray
    outer: int = 0
    inner: int = 0
    seconds: float = 0.0
    extra: dict = field(default_factory=dict)


def _weighted(graph: PoseGraph3D, weights) -> PoseGraph3D:
    return PoseGraph3D(graph.t, graph.R, graph.edges_i, graph.edges_j, graph.t_z, graph.R_z,
                       graph.information * np.asarray(weights)[:, None, None], graph.fixed, graph.ids, graph.name)


def factorizer():
    """CHOLMOD where cvxopt is installed, else None (the implementation's sparse solve): random wrong
    closures fill the factor in, where a supernodal Cholesky keeps its speed and qdldl does not."""
    if peers.installed("cvxopt"):
        return CholmodSolver()
    peers.announce("cvxopt")
    return None


def least_squares(graph: PoseGraph3D, impl="solutions", loss=None, max_iterations=100) -> RobustRun:
    """Gauss-Newton (with ``loss``: ``(kernel, scale)``, e.g. ``("cauchy", sqrt(c2))``) from the
    chordal start, at most ``max_iterations``; an edge is kept when its s is below ``C2_6DOF_99``."""
    start, init_seconds = initialise(graph, "chordal", impl)
    problem = PoseGraph3DProblem(start, impl, loss=loss, solver=factorizer())
    run = minimize(problem, "gauss-newton", impl=impl, options=SolverOptions(max_iterations=max_iterations))
    t, R = unpack(run.params)
    method = "least squares" if loss is None else f"{loss[0]} kernel"
    return RobustRun(method, t, R, problem.squared_residuals(run.params) < C2_6DOF_99, 1, run.iterations,
                     init_seconds + run.seconds)


def gnc(graph: PoseGraph3D, surrogate="tls", impl="solutions", c2=C2_6DOF_99) -> RobustRun:
    """GNC with the implementation's ``gnc`` module; the edges kept are those of weight > 0.5."""
    module = impl_loader.load(impl).module("gnc")
    state: dict = {"x": None, "inner": 0, "seconds": 0.0, "weights": []}
    solver = factorizer()

    def solve(weights):
        weights = np.asarray(weights, dtype=float)
        state["weights"].append(weights.copy())
        keep = weights >= DROP
        weighted = _weighted(graph.with_edges(keep), weights[keep])
        if state["x"] is None:
            weighted, seconds = initialise(weighted, "chordal", impl)
            state["seconds"] += seconds
        else:
            weighted = weighted.with_poses(*unpack(state["x"]))
        problem = PoseGraph3DProblem(weighted, impl, solver=solver)
        run = minimize(problem, "gauss-newton", impl=impl, options=INNER)
        state["x"], state["inner"] = run.params, state["inner"] + run.iterations
        state["seconds"] += run.seconds
        return graph.squared_errors(*unpack(run.params))

    weights, mus = module.gnc(solve, graph.num_edges, c2, surrogate, known_inliers=odometry(graph))
    t, R = unpack(state["x"])
    return RobustRun(f"GNC {surrogate.upper()}", t, R, np.asarray(weights) > 0.5, len(mus), state["inner"],
                     state["seconds"], {"mus": list(mus), "weights": state["weights"]})


def errors_against(t, R, t_true, R_true) -> tuple:
    """``(translation rmse, rotation rmse in rad)`` of poses against the truth after moving the
    solution so that its pose 0 is the truth's (the gauge: a peer may let the fixed pose drift)."""
    A_R = R_true[0] @ R[0].T  # T_align = T_true0 T_0^-1
    R = np.matmul(A_R, R)
    t = np.einsum("ab,nb->na", A_R, t - t[0]) + t_true[0]
    dt = np.linalg.norm(t - t_true, axis=1)
    dR = np.linalg.norm(log_many(np.matmul(np.swapaxes(R_true, 1, 2), R)), axis=1)
    return float(np.sqrt(np.mean(dt**2))), float(np.sqrt(np.mean(dR**2)))


def precision_recall(kept, outliers) -> tuple:
    """``(precision, recall)`` of the rejected edges as a detector of the wrong ones (1.0 when
    there is nothing to detect or nothing was rejected wrongly)."""
    rejected = ~np.asarray(kept)
    outliers = np.asarray(outliers)
    hits = int(np.sum(rejected & outliers))
    precision = hits / max(int(rejected.sum()), 1) if rejected.any() else 1.0
    recall = hits / int(outliers.sum()) if outliers.any() else 1.0
    return precision, recall


