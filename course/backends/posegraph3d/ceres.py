"""3D pose graphs through Ceres (``pyceres``): a translation and a quaternion block per pose,
``EigenQuaternionManifold`` on the quaternion, and our edge error as a Python cost.

Each pose is two C-contiguous float64 parameter blocks, ``t`` (3,) and ``q`` (4,) in Eigen's
``(x, y, z, w)`` order; ``graph.fixed`` poses are constant blocks. One ``SE3EdgeCost`` residual
block per edge: ``r = U e`` (6,) with ``e`` our error (``course.geometry.se3``; translation first,
``Log`` rotation) and ``U`` the upper Cholesky factor of the edge's information, so Ceres minimises
exactly our chi2 (``2 * cost``); this is the one peer that does.

The Jacobians come from the implementation's ``pose_graph_3d.edge_errors_and_jacobians``, whose
``A``, ``B`` are for the right perturbation ``(R Exp(phi), t + R rho)``. Ceres moves ``t`` by
``t + dt`` (so ``rho = R^T dt``) and a quaternion by ``q_delta(d) * q`` with ``q_delta(d) =
(cos|d|, sin|d| d / |d|)``, a left rotation by ``2 d`` (so ``phi = 2 R^T d``), and wants the
Jacobian in the 4 ambient coordinates ``J_q`` with ``J_q P(q) = J_d`` for the manifold's plus
Jacobian ``P(q)`` (4, 3), whose columns are orthonormal: ``J_q = J_d P(q)^T``.

``impl`` names the implementation whose ``edge_errors_and_jacobians`` the cost calls (the
student's in the student tree: a TODO there makes this row a TODO). A Python cost is called
once per edge and evaluation (a few hundred microseconds here): expect this row to be slow; it
shows Ceres' iterations on our problem, not Ceres' speed.
"""

import time

import numpy as np
import pyceres

from course.backends import registry
from course.core import impl as impl_loader
from course.core.trace import IterationRecord, RunResult
from course.geometry import quaternion
from course.problems.posegraph3d.graph import PoseGraph3D
from course.problems.posegraph3d.problem import pack

METHODS = registry.peer_methods("posegraph3d", "ceres")


def plus_jacobian(q) -> np.ndarray:
    """``P(q)`` (4, 3): d(q_delta(d) * q)/dd at d = 0 for a unit quaternion ``(x, y, z, w)``."""
    v, w = np.asarray(q[:3], dtype=float), float(q[3])
    skew = np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])
    return np.vstack([w * np.eye(3) - skew, -v[None, :]])


class SE3EdgeCost(pyceres.CostFunction):
    """``r = U e(T_i, T_j)`` (6,) with parameter blocks ``t_i`` (3,), ``q_i`` (4,), ``t_j``, ``q_j``."""

    def __init__(self, t_z, R_z, sqrt_information, edges):
        pyceres.CostFunction.__init__(self)  # without it pyceres segfaults
        self.set_num_residuals(6)
        self.set_parameter_block_sizes([3, 4, 3, 4])
        self._t_z, self._R_z = np.asarray(t_z, dtype=float)[None], np.asarray(R_z, dtype=float)[None]
        self._u = np.asarray(sqrt_information, dtype=float)
        self._edges = edges  # the implementation's edge_errors_and_jacobians
        self._ij = (np.array([0]), np.array([1]))

    def Evaluate(self, parameters, residuals, jacobians):  # noqa: N802 (the pyceres name)
        t_i, q_i, t_j, q_j = (np.asarray(p, dtype=float) for p in parameters)
        R = quaternion.to_matrix(np.stack([q_i, q_j]))
        e, A, B = self._edges(np.stack([t_i, t_j]), R, *self._ij, self._t_z, self._R_z)
        residuals[:] = self._u @ e[0]
        if jacobians is None:
            return True
        for k, (J, R_k, q) in enumerate(((A[0], R[0], q_i), (B[0], R[1], q_j))):
            UJ = self._u @ J
            if jacobians[2 * k] is not None:
                jacobians[2 * k][:] = (UJ[:, :3] @ R_k.T).ravel()
            if jacobians[2 * k + 1] is not None:
                unit = q / np.linalg.norm(q)
                jacobians[2 * k + 1][:] = (2.0 * UJ[:, 3:] @ R_k.T @ plus_jacobian(unit).T).ravel()
        return True


class _Trace(pyceres.IterationCallback):
    def __init__(self):
        pyceres.IterationCallback.__init__(self)
        self.records: list = []
        self.start = time.perf_counter()

    def __call__(self, summary):
        self.records.append(IterationRecord(int(summary.iteration), 2.0 * summary.cost,
                                            accepted=bool(summary.step_is_successful),
                                            seconds=time.perf_counter() - self.start))
        return pyceres.CallbackReturnType.SOLVER_CONTINUE


def build_problem(graph: PoseGraph3D, edges, t=None, R=None):
    """``(problem, t_blocks, q_blocks, costs)``: the Ceres problem of ``graph`` at poses ``t`` (N, 3), ``R``
    (N, 3, 3) (default the graph's), one ``SE3EdgeCost`` per edge (``edges`` the implementation's
    ``edge_errors_and_jacobians``; an edge between two fixed poses left out), ``EigenQuaternionManifold`` on
    every quaternion, the fixed poses constant. Keep ``costs`` (the manifold too) alive as long as the
    problem."""
    t = graph.t if t is None else np.asarray(t, dtype=float)
    quats = quaternion.from_matrix(graph.R if R is None else np.asarray(R, dtype=float))
    t_blocks = [np.array(v, dtype=np.float64, order="C", copy=True) for v in t]
    q_blocks = [np.array(v, dtype=np.float64, order="C", copy=True) for v in quats]
    roots = np.swapaxes(np.linalg.cholesky(graph.information), 1, 2)  # U with U^T U = Omega
    problem = pyceres.Problem()
    costs = []
    fixed = set(graph.fixed.tolist())
    for i, j, t_z, R_z, u in zip(graph.edges_i.tolist(), graph.edges_j.tolist(), graph.t_z, graph.R_z, roots):
        if i in fixed and j in fixed:
            continue  # constant: pyceres segfaults on a block with only constant parameters
        cost = SE3EdgeCost(t_z, R_z, u, edges)
        costs.append(cost)
        problem.add_residual_block(cost, None, [t_blocks[i], q_blocks[i], t_blocks[j], q_blocks[j]])
    manifold = pyceres.EigenQuaternionManifold()
    for k in range(graph.num_poses):
        if problem.has_parameter_block(q_blocks[k]):
            problem.set_manifold(q_blocks[k], manifold)
            if k in fixed:
                problem.set_parameter_block_constant(t_blocks[k])
                problem.set_parameter_block_constant(q_blocks[k])
    costs.append(manifold)  # the problem holds it by pointer: alive as long as the costs
    return problem, t_blocks, q_blocks, costs


def solve(graph: PoseGraph3D, method: str, max_iterations: int = 100, *, impl="solutions",
          function_tolerance: float = 1e-12, parameter_tolerance: float = 1e-12,
          gradient_tolerance: float = 1e-14) -> RunResult:
    """Optimize ``graph`` from its poses with Ceres' ``levenberg-marquardt`` (``METHODS``),
    ``SPARSE_NORMAL_CHOLESKY``, one thread; the tolerances far below Ceres' own, as in 2D.

    ``params`` is ``pack(t, R)`` (12N,); ``seconds`` is ``pyceres.solve`` alone; ``iterations``
    the step attempts (Ceres' successful and unsuccessful steps, its iteration 0 not counted).
    """
    if method not in METHODS:
        raise ValueError(f"unknown Ceres method {method!r}; choose one of {METHODS}")
    edges = impl_loader.load(impl).module("pose_graph_3d").edge_errors_and_jacobians
    # once outside Ceres: a TODO (NotImplementedError) or a crash surfaces here, not in a callback
    edges(graph.t, graph.R, graph.edges_i[:1], graph.edges_j[:1], graph.t_z[:1], graph.R_z[:1])
    problem, t_blocks, q_blocks, costs = build_problem(graph, edges)
    options = pyceres.SolverOptions()
    options.linear_solver_type = pyceres.LinearSolverType.SPARSE_NORMAL_CHOLESKY
    options.trust_region_strategy_type = pyceres.TrustRegionStrategyType.LEVENBERG_MARQUARDT
    options.max_num_iterations = int(max_iterations)
    options.function_tolerance = function_tolerance
    options.parameter_tolerance = parameter_tolerance
    options.gradient_tolerance = gradient_tolerance
    options.num_threads = 1
    callback = _Trace()
    options.callbacks = [callback]
    summary = pyceres.SolverSummary()
    callback.start = start = time.perf_counter()
    pyceres.solve(options, problem, summary)
    seconds = time.perf_counter() - start
    t = np.array(t_blocks)
    R = quaternion.to_matrix(np.array(q_blocks))
    initial_chi2 = graph.chi2()
    trace = callback.records
    if trace:
        trace[0] = IterationRecord(0, initial_chi2, seconds=0.0)
    return RunResult(backend="ceres", method=method, params=pack(t, R), initial_chi2=initial_chi2,
                     final_chi2=graph.chi2(t, R), iterations=int(summary.num_successful_steps
                                                                  + summary.num_unsuccessful_steps - 1),
                     seconds=seconds, trace=trace, stop_reason=f"{summary.termination_type.name.lower()}: "
                                                                f"{summary.message}")
