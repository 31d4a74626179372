"""Chapter 2 problem: a 2D pose graph as the loop sees it.

The unknown is the flat vector ``x = poses.ravel()`` (3N,). Linearization uses the
implementation's vectorized ``pose_graph_fast`` when it is written and falls back to
its per-edge loop ``pose_graph_assembly`` (dense H) otherwise; the step comes from the sparse solve
``course.solver.choice`` picks on the upper triangle of H (``auto``: CHOLMOD on a large graph, else its
``sparse_solve.SparseCholeskySolver``, or, where qdldl is not installed, scipy's SuperLU, said once).
"""

import numpy as np

from course.core import impl as impl_loader
from course.core.errors import SingularSystemError, check_array
from course.geometry.se2 import wrap_angle
from course.problems.posegraph.chi2 import prepare as prepare_chi2
from course.problems.posegraph.graph import PoseGraph
from course.solver.choice import choose
from course.solver.held_still import check_held_still
from course.solver.linearization import Linearization
from course.solver.superlu import checked_step

#: the per-edge loop assembles a dense (3N, 3N) H: refuse beyond this many poses
MAX_DENSE_POSES = 4000


class PoseGraphProblem:
    """``linearize`` / ``chi2`` / ``solve`` / ``retract`` for one pose graph and implementation."""

    def __init__(self, graph: PoseGraph, impl="solutions", vectorized=None, solver=None):
        """``solver``: a name of ``course.solver.choice.SOLVES`` (default ``auto``) or an object with
        ``solve(H_upper, b) -> dx``; ``linear_solve`` names the one that runs."""
        self.graph = graph
        self.impl = impl_loader.load(impl)
        self.x0 = graph.poses.ravel().copy()
        self.num_poses = graph.num_poses
        self._sparse = self.impl.module("sparse_solve")
        self._solver, self.linear_solve = choose(solver, self._sparse, 3 * graph.num_poses)
        self._fixed_dof = (3 * graph.fixed[:, None] + np.arange(3)).ravel()
        self._assembler = None
        self._held_checked = False
        prepare_chi2()  # the trial chi2's compiled pass, compiled here and not in the first solve's clock
        if vectorized is not False:
            fast = self.impl.module("pose_graph_fast")
            try:
                self._assembler = fast.SparseAssembler(
                    graph.num_poses, graph.edges_i, graph.edges_j, graph.fixed
                )
                self._fast = fast
            except NotImplementedError:
                if vectorized:
                    raise
        if self._assembler is None and graph.num_poses > MAX_DENSE_POSES:
            raise ValueError(
                f"{graph.name}: {graph.num_poses} poses is too many for the per-edge loop "
                f"(a dense {3 * graph.num_poses}^2 H); implement pose_graph_fast first"
            )

    def poses(self, x):
        return np.asarray(x).reshape(-1, 3)

    def chi2(self, x) -> float:
        return self.graph.chi2(self.poses(x))

    def linearize(self, x) -> Linearization:
        g = self.graph
        n = 3 * g.num_poses
        if self._assembler is not None:
            e, A, B = self._fast.edge_errors_and_jacobians(
                self.poses(x), g.edges_i, g.edges_j, g.measurements
            )
            H, b, chi2 = self._assembler.assemble(e, A, B, g.information)
            b = check_array(b, (n,), "SparseAssembler.assemble", "b")
            self._check_held_still(H, b, "pose_graph_fast.SparseAssembler.assemble")
            return Linearization(H=H, b=b, chi2=float(chi2), upper=True,
                                 diagonal_positions=getattr(self._assembler, "diagonal_positions", None))
        H, b, chi2 = self.impl.module("pose_graph_assembly").assemble_normal_equations(
            self.poses(x), g.edges_i, g.edges_j, g.measurements, g.information, g.fixed
        )
        where = "pose_graph_assembly.assemble_normal_equations"
        H = check_array(H, (n, n), where, "H")
        b = check_array(b, (n,), where, "b")
        self._check_held_still(H, b, where)
        upper = self._sparse.upper_triangle_csc(H)
        return Linearization(H=upper, b=b,
                             chi2=float(chi2), upper=True)

    def _check_held_still(self, H, b, where):
        """The first system assembled must hold the fixed poses still (``course.solver.held_still``):
        the assembly's structure does not change between iterations, so once is enough."""
        if not self._held_checked:
            check_held_still(H, b, self._fixed_dof, where, 3)
            self._held_checked = True

    def solve(self, lin: Linearization, damping=None):
        """Step (3N,) of ``(H + diag(damping)) h = -b`` by the sparse solver.

        With no pose fixed and no damping, H is singular (the whole graph can move: 3 gauge
        freedoms) and ``SingularSystemError`` says so; a sparse LDL^T need not notice, as
        rounding leaves tiny pivots where H has zero ones."""
        if not len(self.graph.fixed) and (damping is None or not np.any(damping)):
            raise SingularSystemError(f"{self.graph.name}: H is not positive definite: no pose is fixed, so the "
                                      "whole graph can move (3 gauge freedoms); fix one pose")
        H = lin.with_diagonal_added(damping)
        return checked_step(self._solver, H, lin.b, self._fixed_dof, self.graph.name)

    def retract(self, x, h):
        """SE(2) update as in the source: add, then wrap the angles."""
        poses = self.poses(x) + self.poses(h)
        poses[:, 2] = wrap_angle(poses[:, 2])
        return poses.ravel()
