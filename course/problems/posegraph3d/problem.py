"""Chapter 6 problem: a 3D pose graph as the loop sees it.

The point is ``x`` (12N,): per pose ``t`` (3) then ``R`` (9, row by row); the step ``h``
(6N,) is per pose ``(rho, phi)`` and moves it by the implementation's
``pose_graph_3d.retract``. Linearization is the implementation's
``pose_graph_3d.edge_errors_and_jacobians`` and ``pose_graph_3d_assembly.SparseAssembler3D``;
the step comes from the sparse solve ``course.solver.choice`` picks (``auto``: CHOLMOD on a large
graph, else its chapter-2 ``sparse_solve.SparseCholeskySolver``, or scipy's SuperLU where qdldl is
not installed; CHOLMOD analyses H's pattern when the problem is made). ``chi2`` is always the framework's own
(``course.geometry.se3``), so a wrong exercise cannot fake a low cost.

Robust variants: ``weights`` (M,) scale every edge's information (GNC's inner problems,
``course.problems.posegraph3d.robust``); a ``loss`` (chapter 4's ``course.solver.robust``,
the implementation's ``robust_kernels``) replaces each edge's ``s_k = e_k^T Omega_k e_k`` by
``rho(s_k)``: the edge is whitened by the Cholesky factor of its information (``r_k = L_k^T
e_k``, ``Omega_k = L_k L_k^T``), reweighted, and handed to the assembler with unit information.
"""

import numpy as np

from course.core import impl as impl_loader
from course.core.errors import check_array
from course.geometry import se3
from course.problems.posegraph3d.graph import PoseGraph3D
from course.solver import robust
from course.solver.choice import choose
from course.solver.cholmod import analyse_ahead
from course.solver.held_still import check_held_still
from course.solver.linearization import Linearization
from course.solver.superlu import checked_step


def pack(t, R) -> np.ndarray:
    """``x`` (12N,) of poses ``t`` (N, 3), ``R`` (N, 3, 3)."""
    return np.concatenate([np.reshape(t, (-1, 3)), np.reshape(R, (-1, 9))], axis=1).ravel()


def unpack(x):
    """``(t (N, 3), R (N, 3, 3))`` of ``x`` (12N,)."""
    x = np.asarray(x, dtype=float).reshape(-1, 12)
    return x[:, :3], x[:, 3:].reshape(-1, 3, 3)


class PoseGraph3DProblem:
    """``linearize`` / ``chi2`` / ``solve`` / ``retract`` for one 3D graph and implementation."""

    def __init__(self, graph: PoseGraph3D, impl="solutions", solver=None, weights=None, loss=None):
        """``solver``: a name of ``course.solver.choice.SOLVES`` (default ``auto``: CHOLMOD on a large
        graph where cvxopt is installed, else the implementation's sparse Cholesky, or SuperLU without
        qdldl) or an object with ``solve(H_upper, b) -> dx``; ``linear_solve`` names the one that runs;
        ``weights`` (M,) >= 0 and ``loss``
        (``(kernel, scale)``, scale in units of sqrt(s)) as in the module docstring."""
        self.graph = graph
        self.impl = impl_loader.load(impl)
        self.information = graph.information
        if weights is not None:
            weights = np.asarray(weights, dtype=float)
            if weights.shape != (graph.num_edges,) or not np.all(np.isfinite(weights)) or np.any(weights < 0):
                raise ValueError(f"weights must be {graph.num_edges} finite numbers >= 0")
            self.information = graph.information * weights[:, None, None]
        self.loss = robust.RobustLoss.of(loss)
        if self.loss is not None:
            self.kernels = self.impl.module("robust_kernels")
            self._root = np.linalg.cholesky(self.information)  # L with Omega = L L^T (M, 6, 6)
            self._unit = np.broadcast_to(np.eye(6), self.information.shape)
        self.x0 = pack(graph.t, graph.R)
        self.num_poses = graph.num_poses
        self._edges = self.impl.module("pose_graph_3d")
        self._solver, self.linear_solve = choose(solver, self.impl.module("sparse_solve"), 6 * graph.num_poses)
        self._assembler = self.impl.module("pose_graph_3d_assembly").SparseAssembler3D(
            graph.num_poses, graph.edges_i, graph.edges_j, graph.fixed)
        self._fixed_dof = (6 * graph.fixed[:, None] + np.arange(6)).ravel()
        self._held_checked = False
        analyse_ahead(self._solver, self._pattern)  # H's pattern is fixed: its ordering found now, not in a run

    def _pattern(self):
        """An H of the assembler's pattern (upper triangle, CSC), from zero Jacobians."""
        zero = np.zeros((self.graph.num_edges, 6, 6))
        return self._assembler.assemble(zero[:, 0], zero, zero, self.information)[0]

    def squared_residuals(self, x) -> np.ndarray:
        """``s_k = e_k^T Omega_k e_k`` (M,) at x, with the graph's own information (no weights)."""
        return self.graph.squared_errors(*unpack(x))

    def chi2(self, x) -> float:
        e = self.graph.errors(*unpack(x))
        if self.loss is None:
            return se3.weighted_chi2(e, self.information)
        return robust.robust_chi2(self.kernels, self.loss, np.einsum("mba,mb->ma", self._root, e))

    def linearize(self, x) -> Linearization:
        g = self.graph
        t, R = unpack(x)
        e, A, B = self._edges.edge_errors_and_jacobians(t, R, g.edges_i, g.edges_j, g.t_z, g.R_z)
        where = "pose_graph_3d.edge_errors_and_jacobians"
        e = check_array(e, (g.num_edges, 6), where, "e")
        A = check_array(A, (g.num_edges, 6, 6), where, "A")
        B = check_array(B, (g.num_edges, 6, 6), where, "B")
        information, robust_chi2 = self.information, None
        if self.loss is not None:  # whitened, then reweighted: unit information from here on
            LT = self._root.transpose(0, 2, 1)
            e, (A, B), robust_chi2 = robust.reweight(self.kernels, self.loss, np.einsum("mab,mb->ma", LT, e),
                                                     (np.matmul(LT, A), np.matmul(LT, B)))
            information = self._unit
        H, b, chi2 = self._assembler.assemble(e, A, B, information)
        chi2 = chi2 if robust_chi2 is None else robust_chi2
        b = check_array(b, (6 * g.num_poses,), "SparseAssembler3D.assemble", "b")
        if not self._held_checked:  # the structure does not change between iterations: once is enough
            check_held_still(H, b, self._fixed_dof, "pose_graph_3d_assembly.SparseAssembler3D.assemble", 6)
            self._held_checked = True
        return Linearization(H=H, b=b,
                             chi2=float(chi2), upper=True,
                             diagonal_positions=getattr(self._assembler, "diagonal_positions", None))

    def solve(self, lin: Linearization, damping=None):
        """Step (6N,) of ``(H + diag(damping)) h = -b``."""
        return checked_step(self._solver, lin.with_diagonal_added(damping), lin.b, self._fixed_dof,
                            self.graph.name)

    def retract(self, x, h):
        t, R = unpack(x)
        t_new, R_new = self._edges.retract(t, R, np.reshape(h, (-1, 6)))
        where = "pose_graph_3d.retract"
        return pack(check_array(t_new, t.shape, where, "t"), check_array(R_new, R.shape, where, "R"))
