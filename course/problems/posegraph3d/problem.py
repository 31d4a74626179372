"""Chapter 6 problem: a 3D pose graph as the loop sees it.

The point is ``x`` (12N,): per pose ``t`` (3) then ``R`` (9, row by row); the step ``h``
(6N,) is per pose ``(rho, phi)`` and moves it by the implementation's
``pose_graph_3d.retract``. Linearization is the implementation's
``pose_graph_3d.edge_errors_and_jacobians`` and ``pose_graph_3d_assembly.SparseAssembler3D``;
the step comes from its chapter-2 ``sparse_solve.SparseCholeskySolver`` (or scipy's SuperLU
where qdldl is not installed). ``chi2`` is always the framework's own
(``course.geometry.se3``), so a wrong exercise cannot fake a low cost.
"""

import numpy as np

from course.core import impl as impl_loader
from course.core import peers
from course.core.errors import SingularSystemError, check_array
from course.problems.posegraph3d.graph import PoseGraph3D
from course.solver.linearization import Linearization
from course.solver.superlu import SuperLUSolver


def pack(t, R) -> np.ndarray:
    """``x`` (12N,) of poses ``t`` (N, 3), ``R`` (N, 3, 3)."""
    return np.concatenate([np.reshape(t, (-1, 3)), np.reshape(R, (-1, 9))], axis=1).ravel()


def unpack(x):
    """``(t (N, 3), R (N, 3, 3))`` of ``x`` (12N,)."""
    x = np.asarray(x, dtype=float).reshape(-1, 12)
    return x[:, :3], x[:, 3:].reshape(-1, 3, 3)


class PoseGraph3DProblem:
    """``linearize`` / ``chi2`` / ``solve`` / ``retract`` for one 3D graph and implementation."""

    def __init__(self, graph: PoseGraph3D, impl="solutions", solver=None):
        """``solver``: an object with ``solve(H_upper, b) -> dx`` (default: the implementation's
        sparse Cholesky, or SuperLU without qdldl)."""
        self.graph = graph
        self.impl = impl_loader.load(impl)
        self.x0 = pack(graph.t, graph.R)
        self.num_poses = graph.num_poses
        self._edges = self.impl.module("pose_graph_3d")
        if solver is None:
            if peers.installed("qdldl"):
                solver = self.impl.module("sparse_solve").SparseCholeskySolver()
            else:
                peers.announce("qdldl")
                solver = SuperLUSolver()
        self._solver = solver
        self._assembler = self.impl.module("pose_graph_3d_assembly").SparseAssembler3D(
            graph.num_poses, graph.edges_i, graph.edges_j, graph.fixed)
        self._fixed_dof = (6 * graph.fixed[:, None] + np.arange(6)).ravel()

    def chi2(self, x) -> float:
        return self.graph.chi2(*unpack(x))

    def linearize(self, x) -> Linearization:
        g = self.graph
        t, R = unpack(x)
        e, A, B = self._edges.edge_errors_and_jacobians(t, R, g.edges_i, g.edges_j, g.t_z, g.R_z)
        where = "pose_graph_3d.edge_errors_and_jacobians"
        e = check_array(e, (g.num_edges, 6), where, "e")
        A = check_array(A, (g.num_edges, 6, 6), where, "A")
        B = check_array(B, (g.num_edges, 6, 6), where, "B")
        H, b, chi2 = self._assembler.assemble(e, A, B, g.information)
        return Linearization(H=H, b=check_array(b, (6 * g.num_poses,), "SparseAssembler3D.assemble", "b"),
                             chi2=float(chi2), upper=True,
                             diagonal_positions=getattr(self._assembler, "diagonal_positions", None))

    def solve(self, lin: Linearization, damping=None):
        """Step (6N,) of ``(H + diag(damping)) h = -b``."""
        h = np.asarray(self._solver.solve(lin.with_diagonal_added(damping), lin.b), dtype=float)
        if h.shape != lin.b.shape or not np.all(np.isfinite(h)) or (h @ lin.b > 0):
            raise SingularSystemError(
                f"{self.graph.name}: the sparse solve gave "
                + ("a non-finite step" if h.shape == lin.b.shape else f"shape {h.shape}")
                + " or an ascent direction: H is not positive definite (is a pose fixed?)")
        h[self._fixed_dof] = 0.0
        return h

    def retract(self, x, h):
        t, R = unpack(x)
        t_new, R_new = self._edges.retract(t, R, np.reshape(h, (-1, 6)))
        where = "pose_graph_3d.retract"
        return pack(check_array(t_new, t.shape, where, "t"), check_array(R_new, R.shape, where, "R"))
