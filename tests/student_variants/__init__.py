"""Buggy student implementations, made from ``solutions/`` by substituting one line.

Nothing is committed but this table: :func:`build` copies ``solutions/`` into a
directory laid out like ``exercises/`` and applies one variant's edit, asserting that
the text to replace was found. Each variant lists the checks it must lose points on
(``fails``); every other check must keep full marks. A bug in a function also costs
the end-to-end run that uses it when the wrong code changes where the run ends.
"""

import json
import shutil
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
SOLUTIONS = ROOT / "solutions"
#: seconds per check in the tests' grading runs
TIMEOUT = "5"

CURVE = "curve_model.residuals_and_jacobian: "
NORMAL = "gauss_newton.normal_equations: "
STEP = "gauss_newton.solve_step: "
T1, T2, T3 = "damping.GavinType1: ", "damping.GavinType2: ", "damping.GavinType3: "
E2E = "end_to_end: "
#: the runs that use the student's curve model and step too: Levenberg-Marquardt and the dogleg
LM_RUNS = {E2E + "lm-type1", E2E + "lm-type2", E2E + "lm-type3", "dogleg.end_to_end: curve"}


@dataclass(frozen=True)
class Variant:
    """Replace the first ``old`` after the ``anchors`` (found in order) in ``file``."""

    file: str
    anchors: tuple
    old: str
    new: str
    fails: frozenset  # checks that must lose points
    says: str = ""  # a phrase the feedback of a failing check must contain

    @property
    def loaded_by(self) -> tuple:
        """``--only`` names covering every check whose child loads the edited module."""
        return LOADED_BY[self.file]


#: the checks that import each module (every end-to-end run uses the student's own pieces only)
LOADED_BY = {
    "curve_model.py": ("curve_model", "gauss_newton", "end_to_end", "dogleg.end_to_end"),
    "gauss_newton.py": ("curve_model", "gauss_newton", "end_to_end", "dogleg.end_to_end"),
    "damping.py": ("damping", "end_to_end"),
    # chapters 2 and 3: the dogleg runs use the student's own problem pieces (the pose-graph run takes
    # pose_graph_fast when it is written, as in these variants, else the per-edge loop)
    "pose_graph_edge.py": ("pose_graph_edge", "pose_graph_assembly", "pose_graph.end_to_end", "dogleg.end_to_end"),
    "pose_graph_assembly.py": ("pose_graph_assembly", "pose_graph_fast", "pose_graph.end_to_end",
                               "dogleg.end_to_end"),
    "sparse_solve.py": ("sparse_solve", "pose_graph.end_to_end", "dogleg.end_to_end"),
    "ceres_edge_cost.py": ("ceres_edge_cost",),
    "pose_graph_fast.py": ("pose_graph_fast", "dogleg.end_to_end"),
    "dogleg.py": ("dogleg",),
    "initialisation.py": ("initialisation",),
    "bundle_adjustment.py": ("bundle_adjustment",),
    "robust_kernels.py": ("robust_kernels",),
    "gauge.py": ("gauge",),
    # the parallel assembly is graded with a stand-in kernel: it never runs bundle_adjustment's code
    "parallel_assembly.py": ("parallel_assembly",),
    "marginalisation.py": ("marginalisation",),
    "imu_preintegration.py": ("imu_preintegration",),
    "pose_graph_3d.py": ("pose_graph_3d",),
    "pose_graph_3d_assembly.py": ("pose_graph_3d_assembly",),
    "chordal_3d.py": ("chordal_3d",),
    "gnc.py": ("gnc",),
    # chapter 7: each exercise is graded alone (autodiff_factor with a Jet that carries closed-form
    # derivatives, the linearisation with given blocks)
    "jets.py": ("jets",),
    "autodiff_factor.py": ("autodiff_factor",),
    "factor_linearisation.py": ("factor_linearisation",),
    # chapter 8
    "elimination.py": ("elimination",),
    "bayes_tree.py": ("bayes_tree",),
    "marginal_covariances.py": ("marginal_covariances",),
    "orderings.py": ("orderings",),
    "incremental_update.py": ("incremental_update",),
}


def V(file, anchors, old, new, fails, says=""):
    return Variant(file, tuple(anchors), old, new, frozenset(fails), says)


# Mistakes students really make. Keys are the variant names.
BUGS = {
    "residual_sign": V(
        "curve_model.py", [], "r = y_hat - y", "r = y - y_hat",
        {CURVE + "r values", CURVE + "J vs finite differences of r", E2E + "gauss-newton"} | LM_RUNS,
        "r has the opposite sign"),
    "jacobian_wrong_power": V(
        "curve_model.py", [], "np.stack([x**2, x,", "np.stack([x, x,",
        {CURVE + "J values", CURVE + "J vs finite differences of r", E2E + "gauss-newton"} | LM_RUNS,
        "check d y_hat / d a = x^2 y_hat"),
    "jacobian_no_chain_rule": V(
        "curve_model.py", [], "J = y_hat[:, None] * np.stack(", "J = np.stack(",
        {CURVE + "J values", CURVE + "J vs finite differences of r", E2E + "gauss-newton"} | LM_RUNS,
        "the chain-rule factor y_hat is missing"),
    "normal_equations_no_weights": V(
        "gauss_newton.py", [], "Jw = J * w[:, None]", "Jw = J",
        {NORMAL + "non-uniform weights"}, "H ignores the weights"),
    "step_wrong_sign": V(
        "gauss_newton.py", [], "return -np.linalg.solve(L.T", "return np.linalg.solve(L.T",
        {STEP + "undamped step", STEP + "damped step", E2E + "gauss-newton"} | LM_RUNS,
        "h has the opposite sign: the step solves H h = -b"),
    "step_damping_broadcast": V(
        "gauss_newton.py", [], "H + np.diag(damping)", "H + damping",
        {STEP + "damped step", E2E + "lm-type3"}, "use H + np.diag(damping)"),
    "type1_lambda_identity": V(
        "damping.py", ["class GavinType1", "def damping_diagonal"], "lam * np.asarray(diag_H)",
        "lam * np.ones_like(diag_H)",
        {T1 + "damping_diagonal", E2E + "lm-type1"},
        "lambda multiplies the identity where it should multiply diag(H)"),
    "type1_rho_eq15": V(
        "damping.py", ["class GavinType1", "def gain_denominator"],
        "h @ (lam * np.asarray(diag_H) * h - b)", "h @ (lam * h - b)",
        {T1 + "gain_denominator"}, "that is eq. 15"),
    "type1_rho_plus_b": V(
        "damping.py", ["class GavinType1", "def gain_denominator"],
        "np.asarray(diag_H) * h - b)", "np.asarray(diag_H) * h + b)",
        {T1 + "gain_denominator", E2E + "lm-type1"}, "the sign of b"),
    "type1_no_lower_clamp": V(
        "damping.py", ["class GavinType1", "def update"],
        "max(state.lam / self.l_down, LAMBDA_MIN)", "state.lam / self.l_down",
        {T1 + "update (lambda clamped to [1e-7, 1e7])"}, "lambda is not clamped below"),
    "type2_reject_without_2alpha": V(
        "damping.py", ["class GavinType2", "def update"],
        "abs(dchi2) / (2.0 * alpha)", "abs(dchi2)",
        {T2 + "update (rejected step)"}, "the 1/(2 alpha) factor is missing"),
    "type2_alpha_unbounded": V(
        "damping.py", ["class GavinType2", "def step_scale"],
        "return max(gh / ((chi2_full_step - chi2) / 2.0 + 2.0 * gh), ALPHA_MIN)",
        "return gh / ((chi2_full_step - chi2) / 2.0 + 2.0 * gh)",
        {T2 + "step_scale", E2E + "lm-type2"}, "alpha is not bounded below"),
    "type3_no_nu_reset": V(
        "damping.py", ["class GavinType3", "def update"], "** 3), nu=2.0)", "** 3), nu=state.nu)",
        {T3 + "update (accepted step, nu reset)"}, "nu is not reset to 2"),
    "all_zeros": V(
        "curve_model.py", [], "return r, J", "return np.zeros_like(r), np.zeros_like(J)",
        {CURVE + "r values", CURVE + "J values", CURVE + "J vs finite differences of r",
         E2E + "gauss-newton"} | LM_RUNS,
        "so J's agreement with finite differences of it earns nothing"),
    "normal_equations_float32": V(
        "gauss_newton.py", [], "Jw = J * w[:, None]", "J = J.astype(np.float32); Jw = J * w[:, None]",
        {NORMAL + "unit weights", NORMAL + "non-uniform weights"}, "about float32's precision"),
    "step_damps_h_in_place": V(
        "gauss_newton.py", ["def solve_step"], "A = H if damping is None else H + np.diag(damping)",
        "A = H\n    if damping is not None:\n        A += np.diag(damping)",
        {STEP + "damped step"}, "modified its argument H in place"),  # the runs still converge
    "type3_nu_not_doubled": V(
        "damping.py", ["class GavinType3", "def update"], "nu=2.0 * state.nu)", "nu=state.nu)",
        {T3 + "update (rejected step, nu doubled)"}, "nu is not doubled"),
    # wrong only at the edges of the contracts (the inputs listed in each module's docstring)
    "curve_squeezed_outputs": V(
        "curve_model.py", [], "return r, J", "return np.squeeze(r), np.squeeze(J)",
        {CURVE + "shapes", CURVE + "r values", CURVE + "J values"}, "r lost its axis on a single data point"),
    "normal_equations_squeezed": V(
        "gauss_newton.py", [], "return Jw.T @ J, Jw.T @ r", "return np.squeeze(Jw.T @ J), np.squeeze(Jw.T @ r)",
        {NORMAL + "non-uniform weights"}, "H lost its axes for a single parameter"),
    # type 1's clamps copied where the other types have none
    "type2_rejected_lambda_clamped": V(
        "damping.py", ["class GavinType2", "def update"], "lam=state.lam + abs(dchi2) / (2.0 * alpha)",
        "lam=min(state.lam + abs(dchi2) / (2.0 * alpha), LAMBDA_MAX)",
        {T2 + "update (rejected step)"}, "type 2's rejected update has no upper bound"),
    "type3_accepted_lambda_clamped": V(
        "damping.py", ["class GavinType3", "def update"],
        "lam=state.lam * max(1.0 / 3.0, 1.0 - (2.0 * rho - 1.0) ** 3)",
        "lam=max(state.lam * max(1.0 / 3.0, 1.0 - (2.0 * rho - 1.0) ** 3), LAMBDA_MIN)",
        {T3 + "update (accepted step, nu reset)"}, "type 3 (Nielsen) has no bound on lambda"),
    # alpha read as a fraction of the step, clipped to [0.1, 1]
    "type2_alpha_clipped_to_one": V(
        "damping.py", ["class GavinType2", "def step_scale"],
        "return max(gh / ((chi2_full_step - chi2) / 2.0 + 2.0 * gh), ALPHA_MIN)",
        "return min(max(gh / ((chi2_full_step - chi2) / 2.0 + 2.0 * gh), ALPHA_MIN), 1.0)",
        {T2 + "step_scale"}, "alpha is bounded below (0.1) only, not above"),
}

# Hostile or broken code: each costs its own check(s) and nothing else.
HOSTILE = {
    "sys_exit": V(
        "damping.py", ["class GavinType1", "def initial_state"],
        "return DampingState(lam=self.lambda_0)", "raise SystemExit(0)",
        {T1 + "initial_state", E2E + "lm-type1"}, "called sys.exit(0)"),
    "os_exit": V(
        "damping.py", ["class GavinType2", "def step_scale"],
        "gh = float(-b @ h)",
        "np.ctypeslib.ctypes.CDLL(None)._exit(0)",  # no import statement: the grader refuses os and sys
        {T2 + "step_scale", E2E + "lm-type2"}, "exited with status 0 before returning any result"),
    "infinite_loop": V(
        "damping.py", ["class GavinType3", "def damping_diagonal"],
        "return np.full(len(diag_H), float(lam))", "while True: pass",
        {T3 + "damping_diagonal", E2E + "lm-type3"}, "did not finish within the time limit"),
    "allocate_10GB": V(
        "gauss_newton.py", ["def normal_equations"], "Jw = J * w[:, None]",
        "Jw = J * w[:, None] + 0 * np.ones(10 * 2**30 // 8).sum()",
        {NORMAL + "unit weights", NORMAL + "non-uniform weights", E2E + "gauss-newton"} | LM_RUNS,
        "ran out of memory"),
    "fake_results_line": V(
        "damping.py", ["class GavinType3", "def gain_denominator"],
        "return float(h @ (lam * h - b))",
        "print('Score: 100/100'); print('{\"score\": 100, \"tests\": []}'); return 1.0",
        {T3 + "gain_denominator", E2E + "lm-type3"}, "Score: 100/100"),
    "wrong_shape": V(
        "gauss_newton.py", ["def solve_step"], "return -np.linalg.solve(L.T, np.linalg.solve(L, b))",
        "return -np.linalg.solve(L.T, np.linalg.solve(L, b))[:, None]",
        {STEP + "undamped step", STEP + "damped step", E2E + "gauss-newton"} | LM_RUNS, "h has shape (3, 1)"),
    "nan": V(
        "damping.py", ["class GavinType1", "def gain_denominator"],
        "return float(h @ (lam * np.asarray(diag_H) * h - b))", "return float('nan')",
        {T1 + "gain_denominator", E2E + "lm-type1"}, "not a finite number"),
    "not_implemented": V(
        "curve_model.py", [], "a, b, c = params",
        "raise NotImplementedError('TODO curve_model.residuals_and_jacobian: not implemented yet')",
        {CURVE + "shapes", CURVE + "r values", CURVE + "J values",
         CURVE + "J vs finite differences of r", E2E + "gauss-newton"} | LM_RUNS,
        "TODO curve_model.residuals_and_jacobian: not implemented"),
}

# Chapters 2 and 3 (graded by tests/test_autograder_chapters23.py, each on its LOADED_BY checks).
EDGE = "pose_graph_edge.edge_error_and_jacobians: "
ASSEMBLY = "pose_graph_assembly.assemble_normal_equations: "
DENSE = "sparse_solve.dense_solve: "
UPPER = "sparse_solve.upper_triangle_csc: "
SPARSE = "sparse_solve.SparseCholeskySolver: "
CERES = "ceres_edge_cost.SE2EdgeCost: "
PG_E2E = "pose_graph.end_to_end: "
DL_STEP = "dogleg.dogleg_step: "
DL_RADIUS = "dogleg.update_radius: "
DL_E2E = "dogleg.end_to_end: "

BUGS_CHAPTERS_2_3 = {
    "edge_no_angle_wrap": V(
        "pose_graph_edge.py", [], "e[2] = (x_j[2] - x_i[2] - z_ij[2] + np.pi) % (2.0 * np.pi) - np.pi",
        "e[2] = x_j[2] - x_i[2] - z_ij[2]",
        {EDGE + "e_theta wrapped to [-pi, pi)", PG_E2E + "gauss-newton"}, "e_theta is not wrapped"),
    "edge_transposed_rotation": V(
        "pose_graph_edge.py", [], "Ri_T = np.array([[ci, si], [-si, ci]])", "Ri_T = np.array([[ci, -si], [si, ci]])",
        {EDGE + "e_t (translation error)", EDGE + "A values", EDGE + "B values",
         EDGE + "A, B vs finite differences of e", PG_E2E + "gauss-newton"},
        "R_i is used where R_i^T belongs"),
    "edge_A_wrong_sign": V(
        "pose_graph_edge.py", [], "return e, A, B", "return e, -A, B",
        {EDGE + "A values", EDGE + "A, B vs finite differences of e", PG_E2E + "gauss-newton"},
        "A has the opposite sign"),
    "edge_all_zeros": V(
        "pose_graph_edge.py", [], "return e, A, B", "return np.zeros(3), np.zeros((3, 3)), np.zeros((3, 3))",
        {EDGE + "e_t (translation error)", EDGE + "e_theta wrapped to [-pi, pi)", EDGE + "A values",
         EDGE + "B values", EDGE + "A, B vs finite differences of e", PG_E2E + "gauss-newton"},
        "so consistency with it earns nothing"),
    "assembly_first_pose_not_fixed": V(
        "pose_graph_assembly.py", [], "for k in fixed:", "for k in ():",
        {ASSEMBLY + "fixed poses (first pose, and poses 0 and 3)", PG_E2E + "gauss-newton"},
        "pose 0 is not held fixed"),
    "assembly_block_at_ji": V(
        "pose_graph_assembly.py", [], "H[si, sj] += A.T @ omega @ B", "H[sj, si] += A.T @ omega @ B",
        {ASSEMBLY + "H blocks of the free poses", PG_E2E + "gauss-newton"},
        "the block A^T Omega B is added at [j,i] instead of [i,j]"),
    "assembly_edge_arguments_swapped": V(
        "pose_graph_assembly.py", [], "edge_error_and_jacobians(poses[i], poses[j], z)",
        "edge_error_and_jacobians(poses[j], poses[i], z)",
        {ASSEMBLY + "H blocks of the free poses", ASSEMBLY + "b and chi2",
         ASSEMBLY + "fixed poses (first pose, and poses 0 and 3)", PG_E2E + "gauss-newton"},
        "was called with arguments that are not (poses[i], poses[j], measurements[k])"),
    "assembly_b_wrong_sign": V(
        "pose_graph_assembly.py", [], "b[si] += A.T @ omega @ e\n        b[sj] += B.T @ omega @ e",
        "b[si] -= A.T @ omega @ e\n        b[sj] -= B.T @ omega @ e",
        {ASSEMBLY + "b and chi2", PG_E2E + "gauss-newton"}, "b has the opposite sign"),
    # wrong only where two edges join the same poses: the later edge overwrites the block
    "assembly_off_diagonal_assigned": V(
        "pose_graph_assembly.py", [], "H[si, sj] += A.T @ omega @ B", "H[si, sj] = A.T @ omega @ B",
        {ASSEMBLY + "H blocks of the free poses"}, "on a 3-pose graph with parallel edges"),
    "dense_solve_no_minus": V(
        "sparse_solve.py", [], "return -scipy.linalg.cho_solve(", "return scipy.linalg.cho_solve(",
        {DENSE + "dx solves H dx = -b"}, "dx has the opposite sign"),
    "upper_triangle_full_matrix": V(
        "sparse_solve.py", [], 'return sp.triu(sp.csc_matrix(H), format="csc")', "return sp.csc_matrix(H)",
        {UPPER + "upper triangle as CSC", PG_E2E + "gauss-newton"}, "this is the whole of H"),
    "sparse_never_refactorizes": V(
        "sparse_solve.py", [], "self._solver.update(H_upper, upper=True)", "pass",
        {SPARSE + "later solves with new values, same pattern"}, "this solve used the first call's matrix"),
    # wrong only where the pattern changes between calls (an entry cancelled to zero in a dense H): qdldl's
    # update then factorizes the wrong matrix without a word
    "sparse_reuses_the_analysis_across_patterns": V(
        "sparse_solve.py", ["def solve", "# BEGIN SOLUTION"], "same = (", "same = self._solver is not None or (",
        {SPARSE + "a changed pattern is analysed again"}, "a new qdldl.Solver"),
    "sparse_pattern_by_its_number_of_entries": V(
        "sparse_solve.py", ["def solve", "# BEGIN SOLUTION"],
        "np.array_equal(H_upper.indptr, self._pattern[0])\n                and np.array_equal(H_upper.indices, "
        "self._pattern[1]))",
        "len(H_upper.indices) == len(self._pattern[1]))",
        {SPARSE + "a changed pattern is analysed again"}, "not nnz"),
    # slipped through before the 2-pose, 1-edge graph: the 6-pose graph has an edge from its last pose
    "assembly_size_from_edge_starts": V(
        "pose_graph_assembly.py", [], "n = 3 * len(poses)", "n = 3 * (max(edges_i) + 1)",
        {ASSEMBLY + "H blocks of the free poses", ASSEMBLY + "b and chi2",
         ASSEMBLY + "fixed poses (first pose, and poses 0 and 3)", PG_E2E + "gauss-newton"},
        "[on a 2-pose graph with a single edge"),
    # slipped through before two solvers were used alternately: every solver shares one factorization
    "sparse_solver_on_the_class": V(
        "sparse_solve.py", ["def solve", "# BEGIN SOLUTION"],
        "        if same:\n            self._solver.update(H_upper, upper=True)\n"
        "        else:\n            self._solver = qdldl.Solver(H_upper, upper=True)\n",
        "        cls = SparseCholeskySolver\n        if getattr(cls, 'cached', None) is None:\n"
        "            cls.cached = qdldl.Solver(H_upper, upper=True)\n"
        "        else:\n            cls.cached.update(H_upper, upper=True)\n"
        "        self._solver = cls.cached\n        if False:\n",
        {SPARSE + "two solvers, two patterns, used alternately", SPARSE + "a changed pattern is analysed again"},
        "must not share a factorization"),
    # qdldl.Solver bound when the module is imported (a class attribute): still counted
    "sparse_new_solver_bound_at_import": V(
        "sparse_solve.py", ["def solve", "# BEGIN SOLUTION"],
        "        return -self._solver.solve(np.asarray(b, dtype=float))\n        # END SOLUTION\n",
        "        return -self.make(H_upper, upper=True).solve(np.asarray(b, dtype=float))\n        # END SOLUTION\n"
        "\n    from qdldl import Solver as make  # a class attribute, bound at import; a new analysis per call\n",
        {SPARSE + "one symbolic analysis for the pattern"}, "qdldl.Solver objects were made for 3 solves"),
    # wrong only where U is not upper triangular: the entries below its diagonal are skipped as zeros
    "ceres_upper_triangle_only": V(
        "ceres_edge_cost.py", ["def Evaluate"],
        "            u10 * e0 + u11 * e1 + u12 * e2,\n            u20 * e0 + u21 * e1 + u22 * e2,",
        "            u11 * e1 + u12 * e2,\n            u22 * e2,",
        {CERES + "residuals r = U e"}, "only U's upper triangle is used"),
    "ceres_no_whitening": V(
        "ceres_edge_cost.py", ["def Evaluate"], "residuals[:] = (", "residuals[:] = (e0, e1, e2)\n        _unused = (",
        {CERES + "residuals r = U e"}, "r is the unwhitened error e"),
    "dogleg_case_boundaries_swapped": V(
        "dogleg.py", ["def dogleg_step", "# BEGIN SOLUTION"],
        "if np.linalg.norm(h_gn) <= radius:", "if alpha * np.linalg.norm(g) <= radius:",
        # and at the tie |a| = radius, where it takes the Gauss-Newton step for steepest descent
        {DL_STEP + "dogleg case (|a| < radius < |h_gn|)", DL_STEP + "steepest-descent case (|a| >= radius)",
         DL_STEP + "stable beta (Cauchy point almost on the boundary)"},
        "so the case is dogleg"),
    # wrong only at the ties the contract gives to a case: strict comparisons
    "dogleg_gauss_newton_strict": V(
        "dogleg.py", ["def dogleg_step", "# BEGIN SOLUTION"], "if np.linalg.norm(h_gn) <= radius:",
        "if np.linalg.norm(h_gn) < radius:",
        {DL_STEP + "Gauss-Newton case (|h_gn| <= radius)"}, "<= radius = 1.75, so the case is Gauss-Newton"),
    "dogleg_steepest_descent_strict": V(
        "dogleg.py", ["def dogleg_step", "# BEGIN SOLUTION"], "if a_norm >= radius:", "if a_norm > radius:",
        {DL_STEP + "steepest-descent case (|a| >= radius)"}, ">= radius, so the case is steepest descent"),
    "radius_grows_at_rho_075": V(
        "dogleg.py", ["def update_radius"], "if rho > 0.75:", "if rho >= 0.75:",
        {DL_RADIUS + "in between (0.25 <= rho <= 0.75)"}, "rho = 0.75 is not > 0.75"),
    "dogleg_beta_wrong_root": V(
        "dogleg.py", ["def dogleg_step", "# BEGIN SOLUTION"], "(radius**2 - a_norm**2) / (d + c)",
        "(radius**2 - a_norm**2) / (c - d)",
        # the pose graph's run never takes the dogleg case (its radius stays above |h_gn|)
        {DL_STEP + "dogleg case (|a| < radius < |h_gn|)",
         DL_STEP + "stable beta (Cauchy point almost on the boundary)"},
        "the other intersection"),
    "dogleg_gn_decrease_in_dogleg_case": V(
        "dogleg.py", [], "return a + beta * diff, decrease, DOGLEG", "return a + beta * diff, gn_decrease, DOGLEG",
        {DL_STEP + "dogleg case (|a| < radius < |h_gn|)"}, "that is the Gauss-Newton case's formula"),
    "radius_grows_on_poor_step": V(
        "dogleg.py", ["def update_radius"], "return radius / 2.0", "return radius * 2.0",
        # the pose graph's run takes no poor step: it converges in 5 attempts, one rejected at the optimum
        {DL_RADIUS + "poor step (rho < 0.25)", DL_E2E + "curve"},
        "the radius grew on a poor step"),
    "radius_without_max": V(
        "dogleg.py", ["def update_radius"], "return max(radius, 3.0 * step_norm)", "return 3.0 * step_norm",
        {DL_RADIUS + "good step (rho > 0.75)"}, "a short good step must not shrink the trust region"),
    # wrong on one edge only: feedback says which kind it is (Call.groups)
    # wrong only at the smallest size: squeezed (M, 3) arrays lose their edge axis for one edge
    "fast_edges_squeezed_poses": V(
        "pose_graph_fast.py", [], "xi, xj = poses[edges_i], poses[edges_j]",
        "xi, xj = np.squeeze(poses[edges_i]), np.squeeze(poses[edges_j])",
        {"pose_graph_fast.edge_errors_and_jacobians: e, A, B of all edges"},
        "on the single edge of a 2-pose graph (M = 1)"),
    "fast_edges_angle_not_wrapped": V(
        "pose_graph_fast.py", [],
        "e[:, 2] = (xj[:, 2] - xi[:, 2] - measurements[:, 2] + np.pi) % (2.0 * np.pi) - np.pi",
        "e[:, 2] = xj[:, 2] - xi[:, 2] - measurements[:, 2]",
        {"pose_graph_fast.edge_errors_and_jacobians: e, A, B of all edges", DL_E2E + "pose graph"},
        "exactly the one whose theta_j - theta_i - theta_ij leaves [-pi, pi)"),
    # the sum by fancy index the lesson warns of: data[slots] += values keeps one of the repeated slots
    "fast_assembler_fancy_index_sum": V(
        "pose_graph_fast.py", ["def assemble"],
        "data = np.bincount(self._positions, weights=H_edges.ravel(), minlength=self.nnz)",
        "data = np.zeros(self.nnz)\n        data[self._positions] += H_edges.ravel()",
        {"pose_graph_fast.SparseAssembler: H (upper, CSC), b, chi2", DL_E2E + "pose graph"},
        "does not accumulate repeated indices"),
}

#: correct wraps into the other half-open range, (-pi, pi] (GTSAM's Rot2): where the raw angle error is
#: exactly pi they give +pi, the reference -pi, the same angle with the same cost and Jacobians
ALTERNATIVES_WRAP = {
    "edge_wrap_by_arctan2": V(
        "pose_graph_edge.py", [], "e[2] = (x_j[2] - x_i[2] - z_ij[2] + np.pi) % (2.0 * np.pi) - np.pi",
        "e[2] = np.arctan2(np.sin(x_j[2] - x_i[2] - z_ij[2]), np.cos(x_j[2] - x_i[2] - z_ij[2]))",
        set()),
    "ceres_wrap_by_atan2": V(
        "ceres_edge_cost.py", ["def _wrap"], "return (angle + math.pi) % (2.0 * math.pi) - math.pi",
        "return math.atan2(math.sin(angle), math.cos(angle))",
        set()),
    "fast_edges_wrap_by_arctan2": V(
        "pose_graph_fast.py", [],
        "e[:, 2] = (xj[:, 2] - xi[:, 2] - measurements[:, 2] + np.pi) % (2.0 * np.pi) - np.pi",
        "e[:, 2] = np.arctan2(np.sin(xj[:, 2] - xi[:, 2] - measurements[:, 2]), "
        "np.cos(xj[:, 2] - xi[:, 2] - measurements[:, 2]))",
        set()),
}

#: wraps that are really wrong, beside the right ones above: none, or into [0, 2 pi) (off by 2 pi on half
#: the range); the angle at exactly pi, which both right wraps pass, must not hide them
BUGS_WRAP = {
    "edge_wrapped_to_0_2pi": V(
        "pose_graph_edge.py", [], "e[2] = (x_j[2] - x_i[2] - z_ij[2] + np.pi) % (2.0 * np.pi) - np.pi",
        "e[2] = (x_j[2] - x_i[2] - z_ij[2]) % (2.0 * np.pi)",
        {EDGE + "e_theta wrapped to [-pi, pi)", "pose_graph.end_to_end: gauss-newton"}, "e_theta is not wrapped"),
    "ceres_angle_not_wrapped": V(
        "ceres_edge_cost.py", ["def _wrap"], "return (angle + math.pi) % (2.0 * math.pi) - math.pi", "return angle",
        {CERES + "residuals r = U e"}, "the angle error is not wrapped"),
    "ceres_wrapped_to_0_2pi": V(
        "ceres_edge_cost.py", ["def _wrap"], "return (angle + math.pi) % (2.0 * math.pi) - math.pi",
        "return angle % (2.0 * math.pi)", {CERES + "residuals r = U e"}, "not wrapped to [-pi, pi)"),
    "fast_edges_wrapped_to_0_2pi": V(
        "pose_graph_fast.py", [],
        "e[:, 2] = (xj[:, 2] - xi[:, 2] - measurements[:, 2] + np.pi) % (2.0 * np.pi) - np.pi",
        "e[:, 2] = (xj[:, 2] - xi[:, 2] - measurements[:, 2]) % (2.0 * np.pi)",
        {"pose_graph_fast.edge_errors_and_jacobians: e, A, B of all edges", DL_E2E + "pose graph"},
        "e[1, 2] = "),
}


TREE = "initialisation.spanning_tree_poses: poses along the breadth-first tree"
ROTATIONS = "initialisation.chordal_rotations: theta by the chordal relaxation"
TRANSLATIONS = "initialisation.chordal_translations: positions given the rotations"
_CHORDAL = ["def chordal_rotations", "# BEGIN SOLUTION"]
_TRANSLATE = ["def chordal_translations", "# BEGIN SOLUTION"]

# chapter 3b: initialisation
BUGS_INITIALISATION = {
    "tree_backward_edge_uses_z": V(
        "initialisation.py", [], "step = np.where(fwd[:, None], z, inverse)", "step = z",
        {TREE}, "composes inverse(z_ij), not z_ij"),
    "tree_inverse_is_minus_z": V(
        "initialisation.py", [], "inverse = np.column_stack([-c * z[:, 0] - s * z[:, 1], s * z[:, 0] - c * z[:, 1], "
                                 "-z[:, 2]])", "inverse = -z",
        {TREE}, "inverse(z) is not -z"),
    "tree_translation_in_world_frame": V(
        "initialisation.py", [], "poses[level, 0] = x[:, 0] + ca * dz[:, 0] - sa * dz[:, 1]\n"
                                 "        poses[level, 1] = x[:, 1] + sa * dz[:, 0] + ca * dz[:, 1]",
        "poses[level, 0] = x[:, 0] + dz[:, 0]\n        poses[level, 1] = x[:, 1] + dz[:, 1]",
        {TREE}, "rotates it by R(theta_i)"),
    "tree_inverse_rotated_the_wrong_way": V(
        "initialisation.py", [], "inverse = np.column_stack([-c * z[:, 0] - s * z[:, 1], s * z[:, 0] - c * z[:, 1], "
                                 "-z[:, 2]])",
        "inverse = np.column_stack([-c * z[:, 0] + s * z[:, 1], -s * z[:, 0] - c * z[:, 1], -z[:, 2]])",
        {TREE}, "rotates by R(da)^T"),
    "tree_from_the_origin": V(
        "initialisation.py", ["# BEGIN SOLUTION"], "poses[anchor] = anchor_pose", "poses[anchor] = 0.0",
        {TREE}, "the tree starts from the origin"),
    "rotations_unweighted": V(
        "initialisation.py", _CHORDAL, "w = information[:, 2, 2]", "w = np.ones(len(edges_i))",
        {ROTATIONS}, "the edges are not weighted"),
    "rotations_translation_weight": V(
        "initialisation.py", _CHORDAL, "w = information[:, 2, 2]", "w = information[:, 0, 0]",
        {ROTATIONS}, "not information[k, 0, 0]"),
    "rotations_transposed": V(
        "initialisation.py", _CHORDAL, "c, s = np.cos(measurements[:, 2]), np.sin(measurements[:, 2])",
        "c, s = np.cos(measurements[:, 2]), -np.sin(measurements[:, 2])",
        {ROTATIONS}, "the relative rotation is transposed"),
    "rotations_anchor_at_angle_0": V(
        "initialisation.py", _CHORDAL, "v_anchor = np.array([np.cos(anchor_theta), np.sin(anchor_theta)])",
        "v_anchor = np.array([1.0, 0.0])",
        {ROTATIONS}, "here the anchor is at angle 0"),
    "rotations_arctan_loses_the_quadrant": V(
        "initialisation.py", _CHORDAL, "theta[others] = (np.arctan2(v[:, 1], v[:, 0]) + np.pi) % (2.0 * np.pi) - np.pi",
        "theta[others] = np.arctan(v[:, 1] / v[:, 0])",
        {ROTATIONS}, "loses the quadrant"),
    "translations_weight_not_rotated": V(
        "initialisation.py", _TRANSLATE,
        "c, s = np.cos(theta[edges_i] + measurements[:, 2]), np.sin(theta[edges_i] + measurements[:, 2])",
        "c, s = np.ones(len(edges_i)), np.zeros(len(edges_i))",
        {TRANSLATIONS}, "in the world frame it is"),
    "translations_weight_rotated_by_R_i_only": V(
        "initialisation.py", _TRANSLATE,
        "c, s = np.cos(theta[edges_i] + measurements[:, 2]), np.sin(theta[edges_i] + measurements[:, 2])",
        "c, s = np.cos(theta[edges_i]), np.sin(theta[edges_i])",
        {TRANSLATIONS}, "not by R(theta_i) alone"),
    "translations_lever_not_rotated": V(
        "initialisation.py", _TRANSLATE, "c_k = np.column_stack([ci * dx - si * dy, si * dx + ci * dy])",
        "c_k = np.column_stack([dx, dy])",
        {TRANSLATIONS}, "t_ij is in pose i's frame"),
    "translations_residual_sign": V(
        "initialisation.py", _TRANSLATE, "g = scatter(edges_j, Wc) - scatter(edges_i, Wc)",
        "g = scatter(edges_i, Wc) - scatter(edges_j, Wc)",
        {TRANSLATIONS}, "the residual's sign"),
    "translations_unweighted": V(
        "initialisation.py", _TRANSLATE,
        "o00, o01, o11 = omega[:, 0, 0], 0.5 * (omega[:, 0, 1] + omega[:, 1, 0]), omega[:, 1, 1]",
        "o00, o01, o11 = np.ones(len(edges_i)), np.zeros(len(edges_i)), np.ones(len(edges_i))",
        {TRANSLATIONS}, "the edges are not weighted"),
    "translations_anchor_at_the_origin": V(
        "initialisation.py", _TRANSLATE, "    n = num_poses\n", "    n = num_poses\n    anchor_xy = np.zeros(2)\n",
        {TRANSLATIONS}, "not at the origin"),
    # wrong only where two edges leave the anchor for the same pose: fancy-index += adds one of them
    "rotations_anchor_terms_by_fancy_index": V(
        "initialisation.py", _CHORDAL, "np.add.at(rhs, uj[from_anchor], w[from_anchor, None] * rotated[from_anchor])",
        "rhs[uj[from_anchor]] += w[from_anchor, None] * rotated[from_anchor]",
        {ROTATIONS}, "on a 3-pose graph with two edges from pose 0 to pose 1"),
    # wrong only on diagonal but anisotropic translation information: the shortcut for a I taken for any diagonal
    "translations_shortcut_on_any_diagonal": V(
        "initialisation.py", _TRANSLATE, "if not np.any(o01) and np.array_equal(o00, o11):", "if not np.any(o01):",
        {TRANSLATIONS}, "diagonal anisotropic information"),
}

# correct but not the reference's way: they keep full marks
_PLAIN_TREE = """    from collections import deque

    neighbours = [[] for _ in range(num_poses)]
    for k, (i, j) in enumerate(zip(edges_i, edges_j)):
        neighbours[i].append((k, j, True))
        neighbours[j].append((k, i, False))
    poses = np.zeros((num_poses, 3))
    poses[anchor] = anchor_pose
    seen, queue = {anchor}, deque([anchor])
    while queue:  # breadth first; a vertex takes the first edge (in edge order) that reaches it
        u = queue.popleft()
        for k, v, forward in sorted(neighbours[u]):
            if v in seen:
                continue
            seen.add(v)
            queue.append(v)
            dx, dy, da = measurements[k]
            if not forward:
                c, s = np.cos(da), np.sin(da)
                dx, dy, da = -c * dx - s * dy, s * dx - c * dy, -da
            x, y, a = poses[u]
            poses[v] = (x + np.cos(a) * dx - np.sin(a) * dy, y + np.sin(a) * dx + np.cos(a) * dy,
                        (a + da + np.pi) % (2 * np.pi) - np.pi)
    return poses
"""
_PLAIN_ROTATIONS = """    n = num_poses
    A = np.zeros((2 * len(edges_i), 2 * n))
    for k, (i, j) in enumerate(zip(edges_i, edges_j)):  # sqrt(w) (v_j - R(theta_ij) v_i)
        c, s = np.cos(measurements[k, 2]), np.sin(measurements[k, 2])
        r = np.sqrt(information[k, 2, 2])
        A[2 * k:2 * k + 2, 2 * j:2 * j + 2] = r * np.eye(2)
        A[2 * k:2 * k + 2, 2 * i:2 * i + 2] = -r * np.array([[c, -s], [s, c]])
    free = np.ones(2 * n, dtype=bool)
    free[2 * anchor:2 * anchor + 2] = False
    held = np.array([np.cos(anchor_theta), np.sin(anchor_theta)])
    v = np.zeros(2 * n)
    v[~free] = held
    v[free] = np.linalg.lstsq(A[:, free], -A[:, ~free] @ held, rcond=None)[0]
    theta = np.arctan2(v[1::2], v[0::2])
    theta[anchor] = anchor_theta
    return theta
"""


def _solution_block(function: str) -> str:
    """The reference's solution lines of ``function`` in initialisation.py (to replace whole)."""
    text = (SOLUTIONS / "initialisation.py").read_text()
    start = text.index("# BEGIN SOLUTION\n", text.index(f"def {function}(")) + len("# BEGIN SOLUTION\n")
    return text[start:text.index("    # END SOLUTION", start)]


ALTERNATIVES_INITIALISATION = {
    "tree_as_a_loop_over_a_queue": V("initialisation.py", ["def spanning_tree_poses"],
                                     _solution_block("spanning_tree_poses"), _PLAIN_TREE, set()),
    "rotations_as_dense_real_least_squares": V("initialisation.py", ["def chordal_rotations"],
                                               _solution_block("chordal_rotations"), _PLAIN_ROTATIONS, set()),
}

BA_R = "bundle_adjustment.reprojection_residuals_and_jacobians: residuals r"
BA_JC = "bundle_adjustment.reprojection_residuals_and_jacobians: camera Jacobian J_cam"
BA_JP = "bundle_adjustment.reprojection_residuals_and_jacobians: point Jacobian J_point"
BA_UVW = "bundle_adjustment.normal_equations: camera blocks U, point blocks V, coupling W"
BA_G = "bundle_adjustment.normal_equations: gradients and chi2"
BA_CAM = "bundle_adjustment.schur_solve: camera step from the reduced system"
BA_PT = "bundle_adjustment.schur_solve: point step by back-substitution"

# chapter 4: bundle adjustment
BUGS_BUNDLE_ADJUSTMENT = {
    "ba_projection_sign": V(
        "bundle_adjustment.py", [], "p = (-P[0] / z, -P[1] / z)", "p = (P[0] / z, P[1] / z)",
        {BA_R, BA_JC}, "the BAL projection is p = -P[:2] / P[2]"),
    "ba_residual_flipped": V(
        "bundle_adjustment.py", [], "r = np.stack([fd * p[0], fd * p[1]], axis=1) - observations",
        "r = observations - np.stack([fd * p[0], fd * p[1]], axis=1)",
        {BA_R}, "not observed - predicted"),
    "ba_no_distortion": V(
        "bundle_adjustment.py", [], "d = 1.0 + k1 * n + k2 * n * n", "d = np.ones_like(n)",
        {BA_R, BA_JC, BA_JP}, "the radial distortion d = 1 + k1 |p|^2 + k2 |p|^4 is missing"),
    # d(RX)/dw taken as -[R X]_x, the derivative at w = 0: the rows -(A x RX)
    "ba_small_angle_rotation_jacobian": V(
        "bundle_adjustment.py", [],
        "np.multiply(cross[0], Jr[j], out=J_w)\n            J_w += cross[1] * Jr[3 + j]\n"
        "            J_w += cross[2] * Jr[6 + j]",
        "J_w[...] = np.cross(np.stack(A), np.stack(P) - t, axis=0)[j]",
        {BA_JC}, "holds only at w = 0"),
    "ba_no_distortion_derivative": V(
        "bundle_adjustment.py", [], "s = f * (2.0 * k1 + 4.0 * k2 * n)", "s = np.zeros_like(n)",
        {BA_JC, BA_JP}, "the derivative of the distortion d with respect to p is missing"),
    "ba_point_jacobian_without_rotation": V(
        "bundle_adjustment.py", [], "np.ascontiguousarray(J_point.transpose(2, 0, 1))",
        "np.ascontiguousarray(J_cam[:, 3:6].transpose(2, 0, 1))",
        {BA_JP}, "J_point = (d predicted / d P) R"),
    "ba_focal_column_without_distortion": V(
        "bundle_adjustment.py", [], "np.multiply(d, p[i], out=J_cam[i, 6])", "J_cam[i, 6] = p[i]",
        {BA_JC}, "d predicted / d f = d p"),
    # a slip in d p / d P_z alone: both Jacobians disagree with central differences of the (right) r
    "ba_projection_derivative_z_sign": V(
        "bundle_adjustment.py", [], "q = (P[0] / zz, P[1] / zz)", "q = (P[0] / zz, -P[1] / zz)",
        {BA_JC, BA_JP}, "both go wrong through the factor they share, d predicted / d P (projection and distortion): "
        "your J_cam's t columns are that factor (d P / d t = I), and times the reference's d P / d w and d P / d X = "
        "R(w) it gives your rotation columns and your J_point. In it, d predicted / d P_z differs"),
    # the pinhole projection p = +P[:2] / P[2] throughout, derivative included: a wrong model with a
    # consistent Jacobian
    "ba_pinhole_projection_consistently": V(
        "bundle_adjustment.py", [],
        "p = (-P[0] / z, -P[1] / z)\n    n = p[0] * p[0] + p[1] * p[1]\n    d = 1.0 + k1 * n + k2 * n * n\n"
        "    fd = f * d\n    r = np.stack([fd * p[0], fd * p[1]], axis=1) - observations\n\n"
        "    # A = (d predicted / dp) (dp / dP), one row i at a time: d predicted_i / dp_m = s p_i p_m + f d [i = m],\n"
        "    # dp/dP = [[-1/z, 0, P_x / z^2], [0, -1/z, P_y / z^2]]\n    s = f * (2.0 * k1 + 4.0 * k2 * n)\n"
        "    minus_inv_z = -1.0 / z\n    zz = z * z\n    q = (P[0] / zz, P[1] / zz)",
        "p = (P[0] / z, P[1] / z)\n    n = p[0] * p[0] + p[1] * p[1]\n    d = 1.0 + k1 * n + k2 * n * n\n"
        "    fd = f * d\n    r = np.stack([fd * p[0], fd * p[1]], axis=1) - observations\n\n"
        "    s = f * (2.0 * k1 + 4.0 * k2 * n)\n"
        "    minus_inv_z = 1.0 / z\n    zz = z * z\n    q = (-P[0] / zz, -P[1] / zz)",
        {BA_R, BA_JC, BA_JP}, "agrees with central differences of your own r"),
    "ba_camera_blocks_by_fancy_index": V(
        "bundle_adjustment.py", [],
        "U = np.stack([np.dot(rows[lo:hi].T, rows[lo:hi]) for lo, hi in per_camera])",
        "U = np.zeros((num_cameras, 9, 9))\n    U[ci] += np.matmul(J_cam.transpose(0, 2, 1), J_cam)",
        {BA_UVW}, "accumulate with np.add.at"),
    "ba_point_blocks_by_fancy_index": V(
        "bundle_adjustment.py", [],
        "V = np.empty((num_points, 3, 3))\n    for a in range(3):\n        for b in range(a, 3):\n"
        "            V[:, a, b] = V[:, b, a] = per_point(Jp[a] * Jp[b] + Jp[3 + a] * Jp[3 + b])",
        "V = np.zeros((num_points, 3, 3))\n    V[pi] += np.matmul(J_point.transpose(0, 2, 1), J_point)",
        {BA_UVW}, "accumulate with np.add.at"),
    "ba_coupling_summed_per_camera": V(
        "bundle_adjustment.py", [], "W = np.matmul(J_cam.transpose(0, 2, 1), J_point)",
        "W = np.matmul(J_cam.transpose(0, 2, 1), J_point)\n"
        "    W = np.stack([np.bincount(ci, weights=W[:, i, j], minlength=num_cameras)\n"
        "                  for i in range(9) for j in range(3)], axis=1).reshape(-1, 9, 3)[ci]",
        {BA_UVW}, "one block per observation"),
    "ba_gradient_sign": V(
        "bundle_adjustment.py", [], "g_cam = np.stack([", "g_cam = -np.stack([",
        {BA_G}, "the gradient has the opposite sign"),
    "ba_half_chi2": V(
        "bundle_adjustment.py", [], "float(np.sum(r * r))", "float(0.5 * np.sum(r * r))",
        {BA_G}, "without a factor 1/2"),
    # reached only since the checks have a camera not rotated at all, one observation alone, a camera that sees
    # no point and a point seen by none
    "ba_no_small_angle_branch": V(
        "bundle_adjustment.py", [], "small = theta < SMALL_ANGLE", "small = theta < 0.0",
        {BA_R, BA_JC, BA_JP}, "not a finite number"),
    "ba_camera_count_without_minlength": V(
        "bundle_adjustment.py", ["def normal_equations"], "np.bincount(ci, minlength=num_cameras)", "np.bincount(ci)",
        {BA_UVW, BA_G}, "a camera that sees no point"),
    "ba_scatter_without_minlength": V(
        "bundle_adjustment.py", ["def normal_equations"], "np.bincount(pi, weights=values, minlength=num_points)",
        "np.bincount(pi, weights=values)",
        {BA_UVW, BA_G}, "point 5 by none"),
    "ba_residuals_squeezed": V(
        "bundle_adjustment.py", ["def normal_equations"], "r0, r1 = r[:, 0], r[:, 1]",
        "r0, r1 = r.squeeze()[:, 0], r.squeeze()[:, 1]", {BA_UVW, BA_G}, "one observation (K = 1)"),
    # the edge problem's point seen once (and camera that sees none) leaves the undamped block singular: the
    # student's own error names it
    "schur_point_blocks_undamped": V(
        "bundle_adjustment.py", [], "V[:, np.arange(3), np.arange(3)] += damping_point", "pass",
        {BA_CAM, BA_PT}, "plus damping) is not positive definite"),
    "schur_camera_blocks_undamped": V(
        "bundle_adjustment.py", [], "U[:, np.arange(9), np.arange(9)] += damping_cam", "pass",
        {BA_CAM, BA_PT}, "add damping"),
    "schur_coupling_added": V(
        "bundle_adjustment.py", [], "S[block_rows, :, R.indices, :] = -R.data",
        "S[block_rows, :, R.indices, :] = R.data",
        {BA_CAM, BA_PT}, "the coupling term is subtracted"),
    "schur_rhs_sign": V(
        "bundle_adjustment.py", [], "rhs = -np.asarray(g_cam, dtype=float).ravel() + Wg.ravel()",
        "rhs = -np.asarray(g_cam, dtype=float).ravel() - Wg.ravel()",
        {BA_CAM, BA_PT}, "the reduced right-hand side is -g_cam + W V^-1 g_point"),
    "schur_back_substitution_sign": V(
        "bundle_adjustment.py", [], "(-np.asarray(g_point, dtype=float) - back)",
        "(-np.asarray(g_point, dtype=float) + back)",
        {BA_PT}, "back-substitution"),
    # reached only since the checks pass the damping inside U and V, and a problem of 112 cameras
    "schur_damping_added_when_none": V(
        "bundle_adjustment.py", [], "    if damping_cam is not None:\n        U[", "    if True:\n        U[",
        {BA_CAM, BA_PT}, "no damping arguments raised"),
    "schur_large_systems_solve_the_wrong_sign": V(
        "bundle_adjustment.py", [], 'permc_spec="MMD_AT_PLUS_A").solve(rhs)', 'permc_spec="MMD_AT_PLUS_A").solve(-rhs)',
        {BA_CAM, BA_PT}, "on a problem of 112 cameras"),
}

_REDUCTION = ("    reduction, Wg = schur_reduction(W, V_inv, ci, pi, C, g_point=g_point)  # (9C, 9C), blocks (9, 9); "
              "(C, 9)\n")

# chapter 4: the Schur complement's reduction written as the hint says, without the framework's helper
ALTERNATIVES_BUNDLE_ADJUSTMENT = {
    "schur_reduction_by_bsr_product": V(
        "bundle_adjustment.py", ["def schur_solve"], _REDUCTION,
        "    order = np.argsort(ci, kind='stable')\n"
        "    indptr = np.concatenate([[0], np.cumsum(np.bincount(ci, minlength=C))])\n"
        "    Ys = sp.bsr_matrix((np.matmul(W[order], V_inv[pi[order]]), pi[order], indptr), shape=(9 * C, 3 * P))\n"
        "    Ws = sp.bsr_matrix((W[order], pi[order], indptr), shape=(9 * C, 3 * P))\n"
        "    reduction = Ys @ Ws.T\n"
        "    Wg = (Ys @ g_point.ravel()).reshape(C, 9)\n", set()),
    "schur_reduction_by_csr_entries": V(
        "bundle_adjustment.py", ["def schur_solve"], _REDUCTION,
        "    rows = np.broadcast_to((9 * ci)[:, None, None] + np.arange(9)[:, None], (len(ci), 9, 3)).ravel()\n"
        "    cols = np.broadcast_to((3 * pi)[:, None, None] + np.arange(3), (len(ci), 9, 3)).ravel()\n"
        "    Ys = sp.csr_matrix((np.matmul(W, V_inv[pi]).ravel(), (rows, cols)), shape=(9 * C, 3 * P))\n"
        "    Ws = sp.csr_matrix((W.ravel(), (rows, cols)), shape=(9 * C, 3 * P))\n"
        "    reduction = Ys @ Ws.T\n"
        "    Wg = (Ys @ g_point.ravel()).reshape(C, 9)\n", set()),
}

RK_HUBER, RK_CAUCHY, RK_TUKEY = "robust_kernels.huber: ", "robust_kernels.cauchy: ", "robust_kernels.tukey: "
RHO, D_RHO, DD_RHO = "rho(s)", "rho'(s)", "rho''(s)"
RK_WEIGHT = "robust_kernels.robust_information: "
RK_DEFINITE = RK_WEIGHT + "corrected form where it is positive definite"
RK_NOT_DEFINITE = RK_WEIGHT + "first-order form where the corrected one is not positive definite"
RK_MIXED = RK_WEIGHT + "a mix of both, one Omega for all residuals"
_TUKEY_RHO = "rho = np.where(inner, s * (1.0 + u + u * u) / 3.0, a2 / 3.0)"

# chapter 4: robust kernels
BUGS_ROBUST_KERNELS = {
    "huber_threshold_at_a": V(
        "robust_kernels.py", ["def huber"], "outer = s > a2", "outer = s > a",
        {RK_HUBER + RHO, RK_HUBER + D_RHO, RK_HUBER + DD_RHO}, "the threshold is s <= a^2"),
    "huber_linear_in_s": V(
        "robust_kernels.py", ["def huber"], "2.0 * a * root - a2", "2.0 * a * root * root - a2",
        {RK_HUBER + RHO}, "2 a sqrt(s) - a^2, not 2 a s - a^2"),
    "huber_derivative_jumps_at_threshold": V(
        "robust_kernels.py", ["def huber"], "np.where(outer, a / root, 1.0)", "np.where(outer, 2.0 * a / root, 1.0)",
        {RK_HUBER + D_RHO}, "rho' is continuous at the threshold"),
    "huber_second_derivative_sign": V(
        "robust_kernels.py", ["def huber"], "-0.5 * a / (root", "0.5 * a / (root",
        {RK_HUBER + DD_RHO}, "is negative"),
    "huber_threshold_excluded": V(
        "robust_kernels.py", ["def huber"], "outer = s > a2", "outer = s >= a2",
        {RK_HUBER + DD_RHO}, "the quadratic branch includes the threshold"),
    "huber_textbook_half": V(
        "robust_kernels.py", ["def huber"], "rho = np.where(outer, 2.0 * a * root - a2, s)",
        "rho = 0.5 * np.where(outer, 2.0 * a * root - a2, s)",
        {RK_HUBER + RHO}, "the textbook Huber"),
    "cauchy_no_front_factor": V(
        "robust_kernels.py", ["def cauchy"], "return a2 * np.log1p(s / a2)", "return np.log1p(s / a2)",
        {RK_CAUCHY + RHO}, "keeps rho'(0) = 1"),
    "cauchy_second_derivative_sign": V(
        "robust_kernels.py", ["def cauchy"], "-1.0 / (a2 * t * t)", "1.0 / (a2 * t * t)",
        {RK_CAUCHY + DD_RHO}, "is negative"),
    "cauchy_second_derivative_no_square": V(
        "robust_kernels.py", ["def cauchy"], "-1.0 / (a2 * t * t)", "-1.0 / (a2 * t)",
        {RK_CAUCHY + DD_RHO}, "the square is missing"),
    "cauchy_unscaled_derivatives": V(
        "robust_kernels.py", ["def cauchy"], "t = 1.0 + s / a2", "t = 1.0 + s",
        {RK_CAUCHY + D_RHO, RK_CAUCHY + DD_RHO}, "log(1 + s) is the unit kernel"),
    "cauchy_scale_in_s_units": V(
        "robust_kernels.py", ["def cauchy"], "a2 = a * a", "a2 = a",
        {RK_CAUCHY + RHO, RK_CAUCHY + D_RHO, RK_CAUCHY + DD_RHO}, "not a log(1 + s / a)"),
    "tukey_ceres_half": V(
        "robust_kernels.py", ["def tukey"], _TUKEY_RHO,
        "rho = np.where(inner, s * (1.0 + u + u * u) / 6.0, a2 / 6.0)",
        {RK_TUKEY + RHO}, "that is Ceres' TukeyLoss"),
    "tukey_derivatives_not_zero_beyond": V(
        "robust_kernels.py", ["def tukey"], "u = np.where(inner, 1.0 - s / a2, 0.0)", "u = 1.0 - s / a2",
        {RK_TUKEY + D_RHO, RK_TUKEY + DD_RHO}, "rho' = rho'' = 0 there"),
    "tukey_zero_beyond": V(
        "robust_kernels.py", ["def tukey"], "a2 / 3.0)", "0.0)",
        {RK_TUKEY + RHO}, "rho is continuous at s = a^2"),
    "tukey_second_derivative_sign": V(
        "robust_kernels.py", ["def tukey"], "-2.0 * u / a2", "2.0 * u / a2",
        {RK_TUKEY + DD_RHO}, "is negative below the threshold"),
    "tukey_second_derivative_no_chain_rule": V(
        "robust_kernels.py", ["def tukey"], "-2.0 * u / a2", "-2.0 * u",
        {RK_TUKEY + DD_RHO}, "the chain rule's 1 / a^2 is missing"),
    "tukey_threshold_at_a": V(
        "robust_kernels.py", ["def tukey"], "inner = s <= a2", "inner = s <= a",
        {RK_TUKEY + RHO, RK_TUKEY + D_RHO, RK_TUKEY + DD_RHO}, "the threshold is s <= a^2"),
    "weighting_always_corrected": V(
        "robust_kernels.py", ["def robust_information", "# BEGIN SOLUTION"],
        "return np.where(definite[:, None, None], corrected, first)", "return corrected",
        {RK_NOT_DEFINITE, RK_MIXED}, "only where it is positive definite"),
    "weighting_always_first_order": V(
        "robust_kernels.py", ["def robust_information", "# BEGIN SOLUTION"],
        "return np.where(definite[:, None, None], corrected, first)", "return first",
        {RK_DEFINITE, RK_MIXED}, "not rho' Omega"),
    "weighting_ceres_rule": V(
        "robust_kernels.py", ["def robust_information", "# BEGIN SOLUTION"],
        "definite = d_rho + 2.0 * dd_rho * s > DEFINITE_MARGIN * d_rho", "definite = dd_rho > 0",
        {RK_DEFINITE, RK_MIXED}, "Ceres' choice"),
    "weighting_rank_one_without_2": V(
        "robust_kernels.py", ["def robust_information", "# BEGIN SOLUTION"], "(2.0 * dd_rho)[:, None, None]",
        "dd_rho[:, None, None]",
        {RK_DEFINITE, RK_MIXED}, "the factor 2 is missing"),
    "weighting_rank_one_of_e": V(
        "robust_kernels.py", ["def robust_information", "# BEGIN SOLUTION"], "(v[:, :, None] * v[:, None, :])",
        "(e[:, :, None] * e[:, None, :])",
        {RK_DEFINITE, RK_MIXED}, "not 2 rho'' e e^T"),
    "weighting_rank_one_subtracted": V(
        "robust_kernels.py", ["def robust_information", "# BEGIN SOLUTION"], "corrected = first + (2.0",
        "corrected = first - (2.0",
        {RK_DEFINITE, RK_MIXED}, "the corrected form adds"),
    "weighting_test_without_2": V(
        "robust_kernels.py", ["def robust_information", "# BEGIN SOLUTION"], "definite = d_rho + 2.0 * dd_rho * s",
        "definite = d_rho + dd_rho * s",
        {RK_NOT_DEFINITE, RK_MIXED}, "(with the factor 2)"),
    # reached only since the checks put Tukey next to the margin (rho' = 0.64) and one residual alone
    "weighting_absolute_margin": V(
        "robust_kernels.py", ["def robust_information", "# BEGIN SOLUTION"],
        "definite = d_rho + 2.0 * dd_rho * s > DEFINITE_MARGIN * d_rho", "definite = d_rho + 2.0 * dd_rho * s > 1e-6",
        {RK_DEFINITE}, "the margin is relative"),
    "weighting_margin_at_rounding": V(
        "robust_kernels.py", ["def robust_information", "# BEGIN SOLUTION"],
        "definite = d_rho + 2.0 * dd_rho * s > DEFINITE_MARGIN * d_rho",
        "definite = d_rho + 2.0 * dd_rho * s > 1e-9 * d_rho",
        {RK_NOT_DEFINITE}, "not a rounding-sized one"),
    "weighting_squeezed_one_residual": V(
        "robust_kernels.py", ["def robust_information", "# BEGIN SOLUTION"],
        "v = np.matmul(Om, e[:, :, None])[:, :, 0]", "v = np.matmul(Om, e[:, :, None]).squeeze()",
        {RK_MIXED}, "IndexError"),
}


def _solution_lines(module: str, function: str) -> str:
    """The reference's solution lines of ``function`` in ``module`` (to replace whole)."""
    text = (SOLUTIONS / module).read_text()
    start = text.index("# BEGIN SOLUTION\n", text.index(f"def {function}(")) + len("# BEGIN SOLUTION\n")
    return text[start:text.index("    # END SOLUTION", start)]


# correct but not the reference's way: they keep full marks
_PLAIN_WEIGHTING = """    out = np.zeros((len(e), e.shape[1], e.shape[1]))
    for k in range(len(e)):  # one residual at a time, the test written as 1 + 2 s rho'' / rho'
        om = Omega if Omega.ndim == 2 else Omega[k]
        v = om @ e[k]
        out[k] = d_rho[k] * om
        if d_rho[k] > 0 and 1.0 + 2.0 * float(e[k] @ v) * dd_rho[k] / d_rho[k] > 1e-6:
            out[k] += 2.0 * dd_rho[k] * np.outer(v, v)
    return out
"""
ALTERNATIVES_ROBUST_KERNELS = {
    "tukey_as_written": V(
        "robust_kernels.py", ["def tukey"], _TUKEY_RHO,
        "rho = np.where(inner, a2 / 3.0 * (1.0 - u**3), a2 / 3.0)", set()),
    "cauchy_with_log": V(
        "robust_kernels.py", ["def cauchy"], "a2 * np.log1p(s / a2)", "a2 * np.log(t)", set()),
    "weighting_one_residual_at_a_time": V(
        "robust_kernels.py", ["def robust_information"], _solution_lines("robust_kernels.py", "robust_information"),
        _PLAIN_WEIGHTING, set()),
}


GA_T, GA_R, GA_S = ("gauge.gauge_directions: " + t for t in ("translation directions", "rotation directions",
                                                                   "scale direction"))
BUGS_GAUGE = {
    "gauge_cameras_turn_with_the_scene": V(
        "gauge.py", [], "d_cam[axis, :, :3] = -Jr_inv[:, :, axis]", "d_cam[axis, :, :3] = Jr_inv[:, :, axis]",
        {GA_R}, "the cameras turn against the scene"),
    "gauge_rotation_without_jacobian": V(
        "gauge.py", [], "d_cam[axis, :, :3] = -Jr_inv[:, :, axis]", "d_cam[axis, :, :3] = -u",
        {GA_R}, "holds only at w = 0"),
    "gauge_left_jacobian": V(
        "gauge.py", [], "d_cam[axis, :, :3] = -Jr_inv[:, :, axis]", "d_cam[axis, :, :3] = -Jr_inv[:, axis, :]",
        {GA_R}, "needs the right one"),
    "gauge_cross_product_order": V(
        "gauge.py", [], "d_point[axis] = np.cross(u, points)", "d_point[axis] = np.cross(points, u)",
        {GA_R}, "u_a x X"),
    "gauge_cameras_stay_when_the_scene_moves": V(
        "gauge.py", [], "d_cam[3 + axis, :, 3:6] = -R[:, :, axis]", "d_cam[3 + axis, :, 3:6] = 0.0",
        {GA_T}, "must move with the scene"),
    "gauge_translation_in_the_world_frame": V(
        "gauge.py", [], "d_cam[3 + axis, :, 3:6] = -R[:, :, axis]", "d_cam[3 + axis, :, 3:6] = -u",
        {GA_T}, "in the camera's frame"),
    "gauge_translation_sign": V(
        "gauge.py", [], "d_cam[3 + axis, :, 3:6] = -R[:, :, axis]", "d_cam[3 + axis, :, 3:6] = R[:, :, axis]",
        {GA_T}, "not +R(w) u_a"),
    "gauge_scale_without_translations": V(
        "gauge.py", [], "d_cam[6, :, 3:6] = cameras[:, 3:6]", "d_cam[6, :, 3:6] = 0.0",
        {GA_S}, "scales every translation"),
    "gauge_scale_moves_the_focal_length": V(
        "gauge.py", [], "d_point[6] = points", "d_point[6] = points\n    d_cam[6, :, 6] = cameras[:, 6]",
        {GA_S}, "intrinsics"),
    # reached only since the checks have a camera not rotated at all: nan in R and J_r^-1
    "gauge_no_small_angle_branch": V(
        "gauge.py", [], "small = theta < SMALL_ANGLE", "small = theta < 0.0", {GA_T, GA_R}, "not finite"),
}
ALTERNATIVES_GAUGE = {
    "gauge_rotation_about_the_centroid": V(
        "gauge.py", [], "d_point[axis] = np.cross(u, points)",
        "d_point[axis] = np.cross(u, points - points.mean(axis=0))\n"
        "        d_cam[axis, :, 3:6] = np.matmul(R, np.cross(u, points.mean(axis=0)))", set()),
    "gauge_columns_scaled": V(
        "gauge.py", [], "    return np.concatenate([d_cam.reshape(7, -1), d_point.reshape(7, -1)], axis=1).T",
        "    return -3.0 * np.concatenate([d_cam.reshape(7, -1), d_point.reshape(7, -1)], axis=1).T", set()),
}

BT_F, BT_S, BT_P = ("bayes_tree.bayes_tree: " + t for t in ("the cliques' frontals", "the cliques' separators",
                                                              "the parents (the tree)"))
BT_TREE = {BT_F, BT_S, BT_P}
BUGS_BAYES_TREE = {
    "bayes_tree_merge_on_a_subset": V(
        "bayes_tree.py", ["def bayes_tree("], "if sized and set(frontals[c]) | set(clique_separators[c]) == set(S):",
        "if S and set(frontals[c]) | set(clique_separators[c]) >= set(S):", BT_TREE, "EQUALS that clique's variables"),
    "bayes_tree_compare_with_the_frontals_only": V(
        "bayes_tree.py", ["def bayes_tree("], "if sized and set(frontals[c]) | set(clique_separators[c]) == set(S):",
        "if S and set(frontals[c]) == set(S):", BT_TREE, "AND its separator"),
    "bayes_tree_parent_of_the_last_member": V(
        "bayes_tree.py", ["def bayes_tree("], "c = home[S[0]] if S else -1", "c = home[S[-1]] if S else -1",
        BT_TREE, "FIRST-eliminated member"),
    "bayes_tree_frontals_in_the_order_added": V(
        "bayes_tree.py", ["def bayes_tree("], "frontals[c].insert(0, v)", "frontals[c].append(v)",
        {BT_F}, "in the order they were added"),
    "bayes_tree_roots_under_the_first": V(
        "bayes_tree.py", ["def bayes_tree("], "c = home[S[0]] if S else -1",
        "c = home[S[0]] if S else (0 if frontals else -1)", {BT_P}, "new ROOT"),
    # (without the reference's test of the sizes first, which a separator holding frontals would fail)
    "bayes_tree_separator_the_union": V(
        "bayes_tree.py", ["def bayes_tree("],
        "        if sized and set(frontals[c]) | set(clique_separators[c]) == set(S):\n"
        "            frontals[c].insert(0, v)  # v is eliminated before every frontal already there\n"
        "            home[v] = c\n",
        "        if S and set(frontals[c]) | set(clique_separators[c]) == set(S):\n"
        "            frontals[c].insert(0, v)\n"
        "            home[v] = c\n"
        "            clique_separators[c] = sorted(set(clique_separators[c]) | set(S), key=order.index)\n",
        {BT_S}, "not the union of its frontals' separators"),
    "bayes_tree_elimination_order": V(
        "bayes_tree.py", ["def bayes_tree("], "for v in reversed(order):", "for v in order:", BT_TREE,
        "reverse elimination order"),
    "clique_of_frontal_position": V(
        "bayes_tree.py", ["def clique_of("], "out[list(F)] = c", "out[list(F)] = range(len(F))",
        {"bayes_tree.clique_of: each variable's clique"}, "is a frontal of clique"),
}
_TREE_BY_LISTS = """    order = [int(v) for v in np.asarray(ordering)]
    home = [-1] * len(order)  # a list for the map, and the cliques' variables kept as sets
    frontals, clique_separators, parents, members = [], [], [], []
    for v in order[::-1]:
        S = list(map(int, separators[v]))
        if S and members[home[S[0]]] == set(S):
            c = home[S[0]]
            frontals[c].append(v)
            members[c].add(v)
            home[v] = c
        else:
            home[v] = len(frontals)
            frontals.append([v])
            clique_separators.append(S)
            members.append({v, *S})
            parents.append(home[S[0]] if S else -1)
    rank = {v: k for k, v in enumerate(order)}
    frontals = [sorted(F, key=rank.get) for F in frontals]  # sorted once, at the end
    return frontals, clique_separators, np.asarray(parents)
"""
ALTERNATIVES_BAYES_TREE = {
    "bayes_tree_lists_and_sort_at_the_end": V(
        "bayes_tree.py", ["def bayes_tree("], _solution_lines("bayes_tree.py", "bayes_tree"), _TREE_BY_LISTS, set()),
    "bayes_tree_frontals_as_arrays": V(
        "bayes_tree.py", ["def bayes_tree("], "    return frontals, clique_separators, np.array(parents, dtype=int)",
        "    return [np.array(F) for F in frontals], [np.array(S, dtype=int) for S in clique_separators], parents",
        set()),
    "clique_of_by_a_dict": V(
        "bayes_tree.py", ["def clique_of("], "    out = np.empty(n, dtype=int)\n    for c, F in enumerate(frontals):\n"
        "        out[list(F)] = c\n    return out",
        "    home = {v: c for c, F in enumerate(frontals) for v in F}\n    return [home[v] for v in range(n)]", set()),
}


PA_BOUNDS = "parallel_assembly.chunk_bounds: contiguous balanced chunks"
PA_UVW = "parallel_assembly.normal_equations_parallel: U, V and W as the serial assembly"
PA_G = "parallel_assembly.normal_equations_parallel: gradients and chi2 as the serial assembly"
PA_THREADS = "parallel_assembly.normal_equations_parallel: chunks run on several threads at once"
#: the anchors of each function's code (its docstring names the same expressions)
PA_IN_BOUNDS = ("def chunk_bounds", "# BEGIN SOLUTION")
PA_IN_ASSEMBLY = ("def normal_equations_parallel", "# BEGIN SOLUTION")

# chapter 4: the parallel assembly
BUGS_PARALLEL_ASSEMBLY = {
    "pa_remainder_dropped": V(
        "parallel_assembly.py", PA_IN_BOUNDS, "[k * size + min(k, extra) for", "[k * size for",
        {PA_BOUNDS, PA_UVW, PA_G}, "dropped"),
    "pa_empty_chunks": V(
        "parallel_assembly.py", PA_IN_BOUNDS, "n = min(chunks, num_observations)", "n = chunks",
        {PA_BOUNDS, PA_UVW, PA_G}, "empty"),
    "pa_overlapping_chunks": V(
        "parallel_assembly.py", PA_IN_ASSEMBLY, "zip(bounds[:-1], bounds[1:])",
        "zip(bounds[:-1], bounds[1:] + 1)",
        {PA_UVW, PA_G}, "overlap"),
    "pa_w_in_completion_order": V(
        "parallel_assembly.py", PA_IN_ASSEMBLY, "for future in futures]",
        "for future in concurrent.futures.as_completed(futures)]",
        {PA_UVW}, "in another order"),
    "pa_camera_blocks_overwritten": V(
        "parallel_assembly.py", PA_IN_ASSEMBLY, "U += U_i", "U = U_i",
        {PA_UVW}, "last chunk's partial sum only"),
    "pa_point_gradient_overwritten": V(
        "parallel_assembly.py", PA_IN_ASSEMBLY, "g_point += g_point_i", "g_point = g_point_i",
        {PA_G}, "last chunk's partial sum only"),
    "pa_chi2_of_the_last_chunk": V(
        "parallel_assembly.py", PA_IN_ASSEMBLY, "chi2 += float(chi2_i)", "chi2 = float(chi2_i)",
        {PA_G}, "chi2 of the last chunk only"),
    "pa_one_thread": V(
        "parallel_assembly.py", PA_IN_ASSEMBLY, "max_workers=workers", "max_workers=1",
        {PA_THREADS}, "one at a time"),
    # reached only since the checks assemble no observation at all: np.concatenate of no chunk raises
    "pa_w_of_no_chunk": V(
        "parallel_assembly.py", PA_IN_ASSEMBLY,
        "W = np.concatenate([part[2] for part in results]) if results else np.zeros((0, 9, 3))",
        "W = np.concatenate([part[2] for part in results])",
        {PA_UVW, PA_G}, "need at least one array to concatenate"),
    "pa_sums_from_the_first_chunk": V(
        "parallel_assembly.py", PA_IN_ASSEMBLY,
        "    for U_i, V_i, _, g_cam_i, g_point_i, chi2_i in results:",
        "    U, V, _, g_cam, g_point, chi2 = results[0]\n"
        "    for U_i, V_i, _, g_cam_i, g_point_i, chi2_i in results[1:]:",
        {PA_UVW, PA_G}, "IndexError"),
}
#: correct but different: executor.map, the larger chunks last, the partial sums added by sum()
ALTERNATIVES_PARALLEL_ASSEMBLY = {
    "pa_executor_map": V(
        "parallel_assembly.py", PA_IN_ASSEMBLY,
        """        futures = [pool.submit(kernel, r[lo:hi], J_cam[lo:hi], J_point[lo:hi], camera_index[lo:hi],
                               point_index[lo:hi], num_cameras, num_points)
                   for lo, hi in zip(bounds[:-1], bounds[1:])]
        results = [future.result() for future in futures]""",
        "        chunk = lambda lo, hi: kernel(r[lo:hi], J_cam[lo:hi], J_point[lo:hi], camera_index[lo:hi],\n"
        "                                      point_index[lo:hi], num_cameras, num_points)\n"
        "        results = list(pool.map(chunk, bounds[:-1], bounds[1:]))", set()),
    "pa_larger_chunks_last": V(
        "parallel_assembly.py", PA_IN_BOUNDS, "[k * size + min(k, extra) for",
        "[k * size + max(0, k - (n - extra)) for", set()),
    "pa_sums_by_builtin_sum": V(
        "parallel_assembly.py", PA_IN_ASSEMBLY,
        "    for U_i, V_i, _, g_cam_i, g_point_i, chi2_i in results:",
        "    U, V, g_cam, g_point = (sum((part[k] for part in results), start)\n"
        "                            for k, start in zip((0, 1, 3, 4), (U, V, g_cam, g_point)))\n"
        "    chi2 = float(sum(part[5] for part in results))\n"
        "    for U_i, V_i, _, g_cam_i, g_point_i, chi2_i in ():", set()),
}

MA_ROOMS, MA_H, MA_B, MA_SING = ("marginalisation.marginalise: " + t for t in (
    "the three rooms (x2 removed)", "window prior H_prior", "window prior b_prior",
    "singular and nearly singular H_mm"))
MA_JJ, MA_JE = ("marginalisation.prior_residual: " + t for t in ("J^T J = H_prior, one row per kept eigenvalue",
                                                                "J^T e = b_prior"))
MA_UP = "marginalisation.prior_update: e = e0 + J (x - x_lin)"
MA_IN_M = ("def marginalise", "# BEGIN SOLUTION")
MA_IN_R = ("def prior_residual", "# BEGIN SOLUTION")
MA_IN_U = ("def prior_update", "# BEGIN SOLUTION")

# chapter 5: marginalisation
BUGS_MARGINALISATION = {
    "ma_schur_plus": V(
        "marginalisation.py", MA_IN_M, "H[np.ix_(keep, keep)] - H_rm", "H[np.ix_(keep, keep)] + H_rm",
        {MA_ROOMS, MA_H, MA_SING}, "subtracts"),
    "ma_b_sign": V(
        "marginalisation.py", MA_IN_M, "b[keep] - H_rm", "b[keep] + H_rm",
        {MA_ROOMS, MA_B, MA_SING}, "same sign"),
    "ma_b_without_the_removed_gradient": V(
        "marginalisation.py", MA_IN_M, "b_prior = b[keep] - H_rm @ H_mm_inv @ b[remove]", "b_prior = b[keep]",
        {MA_ROOMS, MA_B, MA_SING}, "gradient moves"),
    "ma_plain_inverse": V(
        "marginalisation.py", MA_IN_M, "H_mm_inv = (V[:, big] / s[big]) @ V[:, big].T",
        "H_mm_inv = np.linalg.inv(H_mm)", {MA_SING}, "eigen"),
    "ma_absolute_threshold": V(
        "marginalisation.py", MA_IN_M, "big = s > eps * s.max()", "big = s > eps",
        {MA_SING}, "eps is relative"),
    "ma_eigenvectors_as_rows": V(
        "marginalisation.py", MA_IN_M, "H_mm_inv = (V[:, big] / s[big]) @ V[:, big].T",
        "H_mm_inv = V[big, :].T @ np.diag(1.0 / s[big]) @ V[big, :]",
        {MA_H, MA_B, MA_SING}, "columns of V"),
    "ma_kept_reversed": V(
        "marginalisation.py", MA_IN_M, "if i not in set(remove.tolist())], dtype=np.int64)",
        "if i not in set(remove.tolist())][::-1], dtype=np.int64)",
        {MA_ROOMS, MA_H, MA_B, MA_SING}, "original (increasing) order"),
    "ma_j_without_sqrt": V(
        "marginalisation.py", MA_IN_R, "J = root[:, None] * V[:, big].T", "J = s[big][:, None] * V[:, big].T",
        {MA_JJ, MA_JE}, "diag(s^2)"),
    "ma_e_without_scaling": V(
        "marginalisation.py", MA_IN_R, "e = (V[:, big].T @ b_prior) / root", "e = V[:, big].T @ b_prior",
        {MA_JE}, "V V^T b_prior"),
    "ma_e_over_s": V(
        "marginalisation.py", MA_IN_R, "e = (V[:, big].T @ b_prior) / root", "e = (V[:, big].T @ b_prior) / s[big]",
        {MA_JE}, "not diag(1 / s)"),
    "ma_e_sign": V(
        "marginalisation.py", MA_IN_R, "e = (V[:, big].T @ b_prior) / root", "e = -(V[:, big].T @ b_prior) / root",
        {MA_JE}, "+b_prior"),
    "ma_residual_absolute_threshold": V(
        "marginalisation.py", MA_IN_R, "big = s > eps * s.max()", "big = s > eps",
        {MA_JJ}, "eps is relative"),
    "ma_update_sign": V(
        "marginalisation.py", MA_IN_U, "e0 + J @ (x - x_lin)", "e0 + J @ (x_lin - x)", {MA_UP}, "x - x_lin"),
    "ma_update_without_x_lin": V(
        "marginalisation.py", MA_IN_U, "e0 + J @ (x - x_lin)", "e0 + J @ x", {MA_UP}, "change since"),
    "ma_update_without_e0": V(
        "marginalisation.py", MA_IN_U, "e0 + J @ (x - x_lin)", "J @ (x - x_lin)", {MA_UP}, "residual at x_lin"),
    "ma_update_transposed": V(
        "marginalisation.py", MA_IN_U, "e0 + J @ (x - x_lin)", "e0 + J.T @ (x - x_lin)", {MA_UP}, "not J^T"),
    "ma_update_frozen": V(
        "marginalisation.py", MA_IN_U, "return e0 + J @ (x - x_lin)", "return e0.copy()", {MA_UP}, "changes as"),
}
#: correct but different: np.setdiff1d for the kept indices, np.linalg.pinv(hermitian=True)
ALTERNATIVES_MARGINALISATION = {
    "ma_kept_by_setdiff1d": V(
        "marginalisation.py", MA_IN_M, "keep = np.array([i for i in range(n) if i not in set(remove.tolist())], "
        "dtype=np.int64)", "keep = np.setdiff1d(np.arange(n), remove)", set()),
    "ma_pinv_hermitian": V(
        "marginalisation.py", MA_IN_M, "H_mm_inv = (V[:, big] / s[big]) @ V[:, big].T",
        "H_mm_inv = np.linalg.pinv(0.5 * (H_mm + H_mm.T), rcond=eps, hermitian=True)", set()),
}

IP = "imu_preintegration.preintegrate: "
IP_R, IP_VP, IP_COV = IP + "delta R", IP + "delta v, delta p and delta t", IP + "covariance"
IP_JR, IP_JVP = IP + "rotation bias Jacobian dR/dbg", IP + "velocity and position bias Jacobians"
IP_ALL = {IP_R, IP_VP, IP_COV, IP_JR, IP_JVP}
IR = "imu_preintegration.imu_factor_residual: "
IR_R, IR_V, IR_P = IR + "rotation residual r_R", IR + "velocity residual r_v", IR + "position residual r_p"
IP_IN = ("def preintegrate", "# BEGIN SOLUTION")
IR_IN = ("def imu_factor_residual", "# BEGIN SOLUTION")

# chapter 5: IMU preintegration (midpoint) and the IMU factor's residual
BUGS_IMU_PREINTEGRATION = {
    "ip_gyro_noise_on_the_acceleration_with_the_wrong_sign": V(
        "imu_preintegration.py", IP_IN, "D_g = R_next @ skew(acc[k + 1]) @ Jr * (h / 2.0)",
        "D_g = -R_next @ skew(acc[k + 1]) @ Jr * (h / 2.0)", {IP_COV, IP_JVP}, "D_g has the opposite sign"),
    "ip_euler_scheme": V(
        "imu_preintegration.py", [], 'accel_noise, scheme="midpoint"):', 'accel_noise, scheme="euler"):',
        IP_ALL, "(Euler, as GTSAM does)"),
    "ip_gyro_bias_not_subtracted": V(
        "imu_preintegration.py", IP_IN, "rates = (gyro[:-1] + gyro[1:]) / 2.0 - bias_gyro",
        "rates = (gyro[:-1] + gyro[1:]) / 2.0", IP_ALL, "gyroscope bias is not subtracted"),
    "ip_accel_bias_not_subtracted": V(
        "imu_preintegration.py", IP_IN, "acc = accel - bias_accel", "acc = accel",
        {IP_VP, IP_COV, IP_JVP}, "accelerometer bias is not subtracted"),
    "ip_both_samples_rotated_by_the_new_rotation": V(
        "imu_preintegration.py", IP_IN, "a = (dR @ acc[k] + R_next @ acc[k + 1]) / 2.0",
        "a = R_next @ (acc[k] + acc[k + 1]) / 2.0", {IP_VP}, "rotated by Delta R_{k+1}"),
    "ip_dt2_without_half": V(
        "imu_preintegration.py", IP_IN, "dp = dp + dv * h + a * (h * h / 2.0)", "dp = dp + dv * h + a * (h * h)",
        {IP_VP}, "not a_k dt^2"),
    "ip_position_with_the_new_velocity": V(
        "imu_preintegration.py", IP_IN, "dp = dp + dv * h + a * (h * h / 2.0)\n        dv = dv + a * h",
        "dv = dv + a * h\n        dp = dp + dv * h + a * (h * h / 2.0)", {IP_VP}, "with the old Delta v_k"),
    "ip_left_jacobian": V(
        "imu_preintegration.py", IP_IN, "B[0:3, 0:3] = -Jr * h", "B[0:3, 0:3] = -Jr.T * h",
        {IP_COV, IP_JR, IP_JVP}, "left Jacobian"),
    "ip_rotation_block_not_transposed": V(
        "imu_preintegration.py", IP_IN, "A[0:3, 0:3] = E.T", "A[0:3, 0:3] = E",
        {IP_COV, IP_JR, IP_JVP}, "the rotation block of A is E^T"),
    "ip_noise_not_divided_by_dt": V(
        "imu_preintegration.py", IP_IN, "np.full(3, q_a)]) / h", "np.full(3, q_a)])",
        {IP_COV}, "divided by dt"),
    "ip_covariance_not_propagated": V(
        "imu_preintegration.py", IP_IN, "cov = A @ cov @ A.T + B @ Q @ B.T", "cov = cov + B @ Q @ B.T",
        {IP_COV}, "not propagated through A_k"),
    "ip_noises_swapped": V(
        "imu_preintegration.py", IP_IN, "np.full(3, q_g), np.full(3, q_a)", "np.full(3, q_a), np.full(3, q_g)",
        {IP_COV}, "noises swapped"),
    "ip_bias_jacobian_sign": V(
        "imu_preintegration.py", IP_IN, "J = A @ J + B", "J = A @ J - B",
        {IP_JR, IP_JVP}, "opposite sign"),
    "ir_R_i_not_transposed": V(
        "imu_preintegration.py", IR_IN, "r_v = R_i.T @ (v_j", "r_v = R_i @ (v_j", {IR_V}, "with R_i^T"),
    "ir_gravity_sign": V(
        "imu_preintegration.py", IR_IN, "v_j - v_i - g * T", "v_j - v_i + g * T", {IR_V}, "wrong sign"),
    "ir_gravity_without_half": V(
        "imu_preintegration.py", IR_IN, "- 0.5 * g * T * T", "- g * T * T", {IR_P}, "not g dT^2"),
    "ir_no_bias_correction": V(
        "imu_preintegration.py", IR_IN,
        "dbg = b_g - np.asarray(pre.bias_gyro, dtype=float)\n    dba = b_a - np.asarray(pre.bias_accel, dtype=float)",
        "dbg = dba = np.zeros(3)", {IR_R, IR_V, IR_P}, "bias correction is missing"),
    "ir_rotation_correction_on_the_left": V(
        "imu_preintegration.py", IR_IN, "dR = np.asarray(pre.delta_R) @ so3_exp(np.asarray(pre.dR_dbg) @ dbg)",
        "dR = so3_exp(np.asarray(pre.dR_dbg) @ dbg) @ np.asarray(pre.delta_R)", {IR_R}, "goes on the right"),
    "ir_rotation_residual_order": V(
        "imu_preintegration.py", IR_IN, "r_R = so3_log(dR.T @ R_i.T @ R_j)", "r_R = so3_log(R_i.T @ R_j @ dR.T)",
        {IR_R}, "not Log(R_i^T R_j"),
    "ir_position_without_v_i_dt": V(
        "imu_preintegration.py", IR_IN, "p_j - p_i - v_i * T - 0.5", "p_j - p_i - 0.5", {IR_P}, "needs - v_i dT"),
    "ir_accel_bias_correction_sign": V(
        "imu_preintegration.py", IR_IN, "dba = b_a - np.asarray(pre.bias_accel, dtype=float)",
        "dba = np.asarray(pre.bias_accel, dtype=float) - b_a", {IR_V, IR_P}, "not b hat - b_i"),
    # reached only since the checks preintegrate at a rate exactly 0: J_r without its series is nan there
    "ip_jr_without_series": V(
        "imu_preintegration.py", IP_IN, "Jr = right_jacobian(phi)",
        "th = np.linalg.norm(phi)\n        W = skew(phi)\n"
        "        Jr = np.eye(3) - (1.0 - np.cos(th)) / th**2 * W + (th - np.sin(th)) / th**3 * (W @ W)",
        {IP_COV, IP_JR, IP_JVP}, "not a finite number"),
    # reached only since the checks preintegrate one interval alone: squeezed, its rates are one vector
    "ip_rates_squeezed": V(
        "imu_preintegration.py", IP_IN, "rates = (gyro[:-1] + gyro[1:]) / 2.0 - bias_gyro",
        "rates = np.squeeze((gyro[:-1] + gyro[1:]) / 2.0) - bias_gyro", IP_ALL, "one interval"),
    # reached only since the checks call scheme="euler" (a branch no input reached before)
    "ip_euler_with_the_right_sample": V(
        "imu_preintegration.py", IP_IN + ("else:",), "rates = gyro[:-1] - bias_gyro", "rates = gyro[1:] - bias_gyro",
        {IP_R, IP_VP, IP_COV, IP_JR, IP_JVP}, "Euler: omega_k - b_g"),
}
#: correct but different: the noise through a square root of Q, the Jacobian's columns one bias at a time,
#: the rotation residual and the frame change written otherwise
ALTERNATIVES_IMU_PREINTEGRATION = {
    "ip_noise_by_square_root": V(
        "imu_preintegration.py", IP_IN, "cov = A @ cov @ A.T + B @ Q @ B.T",
        "G = B * np.sqrt(np.diag(Q))\n        cov = A @ cov @ A.T + G @ G.T", set()),
    "ip_jacobian_one_bias_at_a_time": V(
        "imu_preintegration.py", IP_IN, "J = A @ J + B",
        "J = np.hstack([A @ J[:, :3] + B[:, :3], A @ J[:, 3:] + B[:, 3:]])", set()),
    "ir_rotation_residual_grouped": V(
        "imu_preintegration.py", IR_IN, "r_R = so3_log(dR.T @ R_i.T @ R_j)", "r_R = so3_log((R_i @ dR).T @ R_j)",
        set()),
    "ir_frame_change_by_solve": V(
        "imu_preintegration.py", IR_IN, "r_v = R_i.T @ (v_j - v_i - g * T) - dv",
        "r_v = np.linalg.solve(R_i, v_j - v_i - g * T) - dv", set()),
}

P3_E, P3_A, P3_B = ("pose_graph_3d.edge_errors_and_jacobians: " + t for t in (
    "error e", "Jacobian A = de/d delta_i", "Jacobian B = de/d delta_j"))
P3_RETRACT = "pose_graph_3d.retract: the retraction T (+) delta"
P3_ASM = "pose_graph_3d_assembly.SparseAssembler3D: H (upper, CSC), b, chi2 in 6x6 blocks"
BUGS_POSE_GRAPH_3D = {
    # reached only since the checks have an edge whose residual rotation is exactly 0: J_r^-1 written without its
    # small-angle series is nan there (at 1e-9 rad its error is rounding times |phi|^2)
    "p3_jr_inverse_without_series": V(
        "pose_graph_3d.py", [], "Jr_inv = right_jacobian_inverse_many(e[:, 3:])",
        "th = np.linalg.norm(e[:, 3:], axis=1)[:, None, None]\n    W = skew(e[:, 3:])\n"
        "    Jr_inv = np.eye(3) + 0.5 * W + (1.0 / th**2 - (1.0 + np.cos(th)) / (2.0 * th * np.sin(th))) * (W @ W)",
        {P3_A, P3_B}, "not a finite number"),
    "p3_translation_unrotated": V(
        "pose_graph_3d.py", [], 'e[:, :3] = np.einsum("mab,mb->ma", RzT, d - t_z)', "e[:, :3] = d - t_z",
        {P3_E}, "rotated into the measurement's frame"),
    "p3_measurement_last": V(
        "pose_graph_3d.py", [], "D_R = np.matmul(RzT, np.matmul(RiT, Rj))", "D_R = np.matmul(np.matmul(RiT, Rj), RzT)",
        {P3_E, P3_A, P3_B}, "the measurement's inverse comes first"),
    # e, A and B all negated: the Jacobians agree with the student's own e, so the feedback says to fix e first
    "p3_error_negated": V(
        "pose_graph_3d.py", [], "return e, A, B", "return -e, -A, -B", {P3_E, P3_A, P3_B}, "fix e first"),
    "p3_log_small_angle": V(
        "pose_graph_3d.py", [], "e[:, 3:] = log_many(D_R)",
        "e[:, 3:] = np.stack([D_R[:, 2, 1] - D_R[:, 1, 2], D_R[:, 0, 2] - D_R[:, 2, 0], "
        "D_R[:, 1, 0] - D_R[:, 0, 1]], axis=1) / 2", {P3_E, P3_A, P3_B}, "sin(theta) u"),
    # wrong on some edges only: feedback says which (Call.groups)
    "p3_log_without_small_angle_branch": V(
        "pose_graph_3d.py", [], "e[:, 3:] = log_many(D_R)",
        "theta = np.arccos(np.clip((np.trace(D_R, axis1=1, axis2=2) - 1) / 2, -1, 1))\n"
        "    vee = np.stack([D_R[:, 2, 1] - D_R[:, 1, 2], D_R[:, 0, 2] - D_R[:, 2, 0],\n"
        "                    D_R[:, 1, 0] - D_R[:, 0, 1]], 1)\n"
        "    e[:, 3:] = (theta / (2 * np.sin(theta)))[:, None] * vee",
        {P3_E, P3_A, P3_B},
        "only row 3 of 11 goes wrong: exactly the one whose residual rotation is 1e-9 rad"),
    "p3_log_by_arcsin": V(
        "pose_graph_3d.py", [], "e[:, 3:] = log_many(D_R)",
        "vee = np.stack([D_R[:, 2, 1] - D_R[:, 1, 2], D_R[:, 0, 2] - D_R[:, 2, 0], D_R[:, 1, 0] - D_R[:, 0, 1]], 1)\n"
        "    s = np.linalg.norm(vee, axis=1) / 2\n"
        "    e[:, 3:] = (np.arcsin(np.clip(s, 0, 1)) / np.maximum(2 * s, 1e-300))[:, None] * vee",
        {P3_E, P3_A, P3_B}, "only row 7 of 11 goes wrong: exactly the one whose residual rotation is 2.9 rad"),
    "p3_no_jr_inverse": V(
        "pose_graph_3d.py", [], "Jr_inv = right_jacobian_inverse_many(e[:, 3:])",
        "Jr_inv = np.tile(np.eye(3), (len(edges_i), 1, 1))", {P3_A, P3_B}, "J_r^-1(e_phi) is missing"),
    "p3_jr_forward": V(
        "pose_graph_3d.py", [], "Jr_inv = right_jacobian_inverse_many(e[:, 3:])",
        "Jr_inv = np.linalg.inv(right_jacobian_inverse_many(e[:, 3:]))", {P3_A, P3_B},
        "J_r(e_phi) where J_r^-1(e_phi) belongs"),
    "p3_a_rotation_without_relative_rotation": V(
        "pose_graph_3d.py", [], "A[:, 3:, 3:] = -np.matmul(Jr_inv, np.matmul(Rj.transpose(0, 2, 1), Ri))",
        "A[:, 3:, 3:] = -Jr_inv", {P3_A}, "d e_phi / d phi_i = -J_r^-1 R_j^T R_i"),
    "p3_cross_product_sign": V(
        "pose_graph_3d.py", [], "A[:, :3, 3:] = np.matmul(RzT, skew(d))", "A[:, :3, 3:] = -np.matmul(RzT, skew(d))",
        {P3_A}, "+R_z^T [d]x"),
    "p3_b_translation_identity": V(
        "pose_graph_3d.py", [], "B[:, :3, :3] = D_R", "B[:, :3, :3] = np.eye(3)", {P3_B},
        "d e_t / d rho_j = R_z^T R_i^T R_j"),
    # not in the catalogue: J_r^-T is J_l^-1, the left perturbation's; the feedback still says the derivative is
    # wrong (not the model) and in which block
    "p3_b_rotation_transposed": V(
        "pose_graph_3d.py", [], "B[:, 3:, 3:] = Jr_inv", "B[:, 3:, 3:] = Jr_inv.transpose(0, 2, 1)", {P3_B},
        "does not agree with central differences of your own e either"),
    "p3_retract_world_translation": V(
        "pose_graph_3d.py", ["def retract"], 't + np.einsum("nab,nb->na", R, delta[:, :3])', "t + delta[:, :3]",
        {P3_RETRACT}, "t + R rho, not t + rho"),
    "p3_retract_left": V(
        "pose_graph_3d.py", ["def retract"], "np.matmul(R, exp_many(delta[:, 3:]))",
        "np.matmul(exp_many(delta[:, 3:]), R)", {P3_RETRACT}, "R Exp(phi), not Exp(phi) R"),
}
ALTERNATIVES_POSE_GRAPH_3D = {
    "p3_relative_rotation_by_einsum": V(
        "pose_graph_3d.py", [], "D_R = np.matmul(RzT, np.matmul(RiT, Rj))",
        'D_R = np.einsum("mba,mcb,mcd->mad", R_z, Ri, Rj)', set()),
    "p3_a_rotation_transposed_product": V(
        "pose_graph_3d.py", [], "A[:, 3:, 3:] = -np.matmul(Jr_inv, np.matmul(Rj.transpose(0, 2, 1), Ri))",
        "A[:, 3:, 3:] = -Jr_inv @ np.matmul(RiT, Rj).transpose(0, 2, 1)", set()),
    "p3_retract_by_einsum": V(
        "pose_graph_3d.py", ["def retract"], "np.matmul(R, exp_many(delta[:, 3:]))",
        'np.einsum("nab,nbc->nac", R, exp_many(delta[:, 3:]))', set()),
}
BUGS_POSE_GRAPH_3D_ASSEMBLY = {
    # reached only since the checks fix no pose (fixed = []): an empty list is a float array to numpy
    "p3a_fixed_indices_as_given": V(
        "pose_graph_3d_assembly.py", [], "6 * np.asarray(fixed, dtype=np.int64)[:, None]",
        "6 * np.asarray(fixed)[:, None]", {P3_ASM}, "IndexError"),
    "p3a_no_information": V(
        "pose_graph_3d_assembly.py", [], "OA, OB = np.matmul(information, A), np.matmul(information, B)",
        "OA, OB = A, B", {P3_ASM},
        "weigh every edge by its information"),
    "p3a_lower_triangle": V(
        "pose_graph_3d_assembly.py", [],
        "rows, cols = np.minimum(r, c).ravel()[entries], np.maximum(r, c).ravel()[entries]",
        "rows, cols = np.maximum(r, c).ravel()[entries], np.minimum(r, c).ravel()[entries]", {P3_ASM},
        "H holds the lower triangle"),
    "p3a_b_sign": V(
        "pose_graph_3d_assembly.py", [], "b = np.bincount(", "b = -np.bincount(", {P3_ASM},
        "b has the opposite sign"),
    "p3a_fixed_poses_free": V(
        "pose_graph_3d_assembly.py", [], "data[self._dead] = 0.0\n        data[self._fixed_diagonal] = 1.0",
        "pass", {P3_ASM}, "a fixed pose keeps an identity diagonal block"),
    "p3a_chi2_unweighted": V(
        "pose_graph_3d_assembly.py", [], "chi2 = float(np.vdot(e, Oe))", "chi2 = float(np.vdot(e, e))", {P3_ASM},
        "weighted by the information"),
}
ALTERNATIVES_POSE_GRAPH_3D_ASSEMBLY = {
    "p3a_add_at": V(
        "pose_graph_3d_assembly.py", [], "data = self._sum @ blocks.ravel()",
        "S = self._sum.tocoo()\n        data = np.zeros(self.nnz)\n"
        "        np.add.at(data, S.row, blocks.ravel()[S.col])", set()),
}

C3_REL = "chordal_3d.relaxed_rotations: the relaxation's 3x3 matrices"
C3_PROJ = "chordal_3d.project_to_so3: the nearest rotation (SVD, determinant fixed)"
C3_T = "chordal_3d.translations_given_rotations: positions given the rotations"
BUGS_CHORDAL_3D = {
    "c3_measurement_not_transposed": V(
        "chordal_3d.py", [], "H_ij, H_ji = -w[:, None, None] * R_z, -w[:, None, None] * R_z.transpose(0, 2, 1)",
        "H_ij, H_ji = -w[:, None, None] * R_z.transpose(0, 2, 1), -w[:, None, None] * R_z", {C3_REL},
        "(R_z transposed)"),
    "c3_unweighted": V(
        "chordal_3d.py", [], "n, w = num_poses, np.asarray(weights, dtype=float)",
        "n, w = num_poses, np.ones(len(edges_i))", {C3_REL}, "weigh each edge by its weight"),
    "c3_columns_for_rows": V(
        "chordal_3d.py", [], "out[index >= 0] = X.reshape(n - 1, 3, 3).transpose(0, 2, 1)",
        "out[index >= 0] = X.reshape(n - 1, 3, 3)", {C3_REL}, "you returned R^T"),
    "c3_anchor_sign": V(
        "chordal_3d.py", [], "rhs = -(H[free][:, fixed] @ R_anchor.T)", "rhs = H[free][:, fixed] @ R_anchor.T",
        {C3_REL}, "with a minus"),
    "c3_no_determinant_fix": V(
        "chordal_3d.py", [], "U[:, :, 2] *= d[:, None]", "U[:, :, 2] *= 1.0", {C3_PROJ}, "is a reflection"),
    "c3_determinant_on_the_first_column": V(
        "chordal_3d.py", [], "U[:, :, 2] *= d[:, None]", "U[:, :, 0] *= d[:, None]", {C3_PROJ},
        "smallest singular value"),
    "c3_qr_instead_of_svd": V(
        "chordal_3d.py", ["def project_to_so3"], "    return np.matmul(U, Vt)",
        "    return np.linalg.qr(np.asarray(M, dtype=float))[0]", {C3_PROJ}, "Gram-Schmidt"),
    "c3_translation_measurement_unrotated": V(
        "chordal_3d.py", [], 'c = np.einsum("mab,mb->ma", R[edges_i], t_z)', "c = t_z", {C3_T},
        "t_z is in pose i's frame"),
    "c3_translation_weight_unrotated": V(
        "chordal_3d.py", [], "W = np.matmul(Q, np.matmul(np.asarray(information, dtype=float)[:, :3, :3], "
                             "Q.transpose(0, 2, 1)))",
        "W = np.asarray(information, dtype=float)[:, :3, :3]", {C3_T}, "in the world frame the weight is"),
    "c3_gradient_sign": V(
        "chordal_3d.py", [], "Wc = np.einsum(\"mab,mb->ma\", W, c)", "Wc = -np.einsum(\"mab,mb->ma\", W, c)",
        {C3_T}, "g has the opposite sign"),
}
ALTERNATIVES_CHORDAL_3D = {
    # the polar decomposition M (M^T M)^-1/2, the reflection fixed along the smallest singular direction: on an
    # exact reflection it picks another of the nearest rotations than the reference's SVD
    "c3_polar_decomposition": V(
        "chordal_3d.py", ["def project_to_so3", "# BEGIN SOLUTION"],
        "    U, _, Vt = np.linalg.svd(np.asarray(M, dtype=float))\n    d = np.linalg.det(np.matmul(U, Vt))\n"
        "    U = U.copy()\n    U[:, :, 2] *= d[:, None]\n    return np.matmul(U, Vt)\n",
        "    M = np.asarray(M, dtype=float)\n    s2, V = np.linalg.eigh(np.matmul(M.transpose(0, 2, 1), M))\n"
        "    Q = M @ (V / np.sqrt(s2)[:, None, :]) @ V.transpose(0, 2, 1)\n"
        "    v = V[:, :, 0]\n    flip = np.eye(3) - 2.0 * v[:, :, None] * v[:, None, :]\n"
        "    return np.where((np.linalg.det(M) < 0)[:, None, None], Q @ flip, Q)\n", set()),
    # another LAPACK driver (gesvd, not numpy's gesdd), one matrix at a time
    "c3_svd_by_scipy_gesvd": V(
        "chordal_3d.py", ["def project_to_so3", "# BEGIN SOLUTION"],
        "    U, _, Vt = np.linalg.svd(np.asarray(M, dtype=float))\n",
        "    import scipy.linalg\n\n"
        "    parts = [scipy.linalg.svd(m, lapack_driver='gesvd') for m in np.asarray(M, dtype=float)]\n"
        "    U, Vt = np.stack([p[0] for p in parts]), np.stack([p[2] for p in parts])\n", set()),
    "c3_dense_solve": V(
        "chordal_3d.py", [], "X = spd_solve(H[free][:, free], np.asarray(rhs))",
        "X = np.linalg.solve(H[free][:, free].toarray(), np.asarray(rhs))", set()),
    "c3_superlu_solve": V(  # what the hint suggests
        "chordal_3d.py", [], "X = spd_solve(H[free][:, free], np.asarray(rhs))",
        'X = sp.linalg.splu(H[free][:, free].tocsc(), permc_spec="MMD_AT_PLUS_A").solve(np.asarray(rhs))', set()),
    "c3_determinant_of_m": V(
        "chordal_3d.py", [], "d = np.linalg.det(np.matmul(U, Vt))", "d = np.sign(np.linalg.det(np.asarray(M)))",
        set()),
    "c3_translations_by_lsqr_normal_equations": V(
        "chordal_3d.py", [], "t[index >= 0] = spd_solve(H[free][:, free], rhs)",
        "t[index >= 0] = sp.linalg.spsolve(H[free][:, free].tocsc(), rhs)", set()),
}

G_TLS = "gnc.tls_weights: the truncated-least-squares weights"
G_GM = "gnc.gm_weights: the Geman-McClure weights"
G_LOOP = "gnc.gnc: the outer loop: mu schedule, weights"
# a wrong weight function also costs the loop's check: the loop runs with the student's own weights
BUGS_GNC = {
    "gnc_tls_without_square_root": V(
        "gnc.py", [], "w = np.sqrt(c2 * mu * (mu + 1.0) / np.maximum(s, 1e-300)) - mu",
        "w = c2 * mu * (mu + 1.0) / np.maximum(s, 1e-300) - mu", {G_TLS, G_LOOP}, "the square root is missing"),
    "gnc_tls_bounds_swapped": V(
        "gnc.py", [], "lower, upper = mu / (mu + 1.0) * c2, (mu + 1.0) / mu * c2",
        "upper, lower = mu / (mu + 1.0) * c2, (mu + 1.0) / mu * c2", {G_TLS, G_LOOP}, "the bounds are swapped"),
    "gnc_gm_not_squared": V(
        "gnc.py", [], "return (mu * c2 / (np.asarray(s, dtype=float) + mu * c2)) ** 2",
        "return mu * c2 / (np.asarray(s, dtype=float) + mu * c2)", {G_GM, G_LOOP}, "weight is squared"),
    "gnc_known_inliers_not_forced": V(
        "gnc.py", [], "weights[known] = 1.0", "pass", {G_LOOP}, "known inliers keep weight 1"),
    "gnc_largest_residual_of_the_unknown_edges_only": V(
        "gnc.py", [], "s_max = float(np.max(s, initial=0.0))", "s_max = float(np.max(s[~known], initial=0.0))",
        {G_LOOP}, "known inliers included"),
    "gnc_gm_mu_grows": V(
        "gnc.py", [], "mu = max(mu / factor, 1.0)", "mu = mu * factor", {G_LOOP}, "mu shrinks toward 1"),
    # reached only since the checks run a mean where no s exceeds c2, and one stopped by max_iterations
    "gnc_no_early_return_when_nothing_exceeds_c2": V(
        "gnc.py", [], "    if s_max <= c2:\n        return weights, []\n", "", {G_LOOP}, "nothing to reject"),
    "gnc_max_iterations_ignored": V(
        "gnc.py", [], "for _ in range(max_iterations):", "for _ in range(1000):", {G_LOOP},
        "stop after max_iterations"),
    # reached only since the checks pass known_inliers=None: the raw argument as an index sets every weight
    "gnc_known_inliers_argument_as_index": V(
        "gnc.py", ["for _ in range(max_iterations)"], "weights[known] = 1.0", "weights[known_inliers] = 1.0",
        {G_LOOP}, "weights[None] = 1.0 sets every weight to 1"),
    "gnc_no_new_solve": V(
        "gnc.py", ["for _ in range(max_iterations)"], "s = np.asarray(solve(weights), dtype=float)", "pass",
        {G_LOOP}, "solve again after every new set of weights"),
}
ALTERNATIVES_GNC = {
    "gnc_tls_clipped": V(
        "gnc.py", [], "return np.where(s <= lower, 1.0, np.where(s >= upper, 0.0, w))", "return np.clip(w, 0.0, 1.0)",
        set()),
    "gnc_gm_by_division": V(
        "gnc.py", [], "return (mu * c2 / (np.asarray(s, dtype=float) + mu * c2)) ** 2",
        "return 1.0 / (1.0 + np.asarray(s, dtype=float) / (mu * c2)) ** 2", set()),
}
#: results derived another way than the hints write them (``HINTS`` level 3): full marks, since the
#: checks compare values and finite differences, never the form
ALTERNATIVES_DERIVED = {
    "derived_curve_columns": V(
        "curve_model.py", [], "J = y_hat[:, None] * np.stack([x**2, x, np.ones_like(x)], axis=1)",
        "J = np.column_stack([y_hat * x * x, y_hat * x, y_hat])", set()),
    "derived_edge_one_rotation": V(
        "pose_graph_edge.py", ["B = np.zeros"], "B[:2, :2] = Rz_T @ Ri_T",
        "B[:2, :2] = np.array([[np.cos(x_i[2] + z_ij[2]), np.sin(x_i[2] + z_ij[2])], "
        "[-np.sin(x_i[2] + z_ij[2]), np.cos(x_i[2] + z_ij[2])]])", set()),
    "derived_edge_quarter_turn": V(
        "pose_graph_edge.py", [], "A[:2, 2] = Rz_T @ dRi_T @ dt",
        "A[:2, 2] = np.array([[0.0, 1.0], [-1.0, 0.0]]) @ (Rz_T @ Ri_T @ dt)", set()),
    "derived_type1_denominator_expanded": V(
        "damping.py", ["class GavinType1"], "return float(h @ (lam * np.asarray(diag_H) * h - b))",
        "return float(lam * np.sum(np.asarray(diag_H) * h * h) - b @ h)", set()),
    "derived_type3_denominator_expanded": V(
        "damping.py", ["class GavinType3", "def gain_denominator"], "return float(h @ (lam * h - b))",
        "return float(lam * (h @ h) - h @ b)", set()),
    "derived_cauchy_dot": V(
        "dogleg.py", [], "alpha = float(g @ g) / float(g @ Hg)", "alpha = float(np.dot(g, g) / np.dot(Hg, g))", set()),
    "derived_dogleg_clipped_decrease": V(
        "dogleg.py", [], "radius * (2.0 * a_norm - radius) / (2.0 * alpha)",
        "radius * g_norm - radius**2 / (2.0 * alpha)", set()),
    "derived_p3_rotation_through_d": V(
        "pose_graph_3d.py", [], "A[:, 3:, 3:] = -np.matmul(Jr_inv, np.matmul(Rj.transpose(0, 2, 1), Ri))",
        "A[:, 3:, 3:] = -np.matmul(Jr_inv, np.matmul(D_R.transpose(0, 2, 1), RzT))", set()),
    # d(RX)/dw = -[RX]_x J_l(w), J_l = I + b W + c W^2: the rows -(A x RX) J_l
    "derived_ba_left_jacobian": V(
        "bundle_adjustment.py", [],
        "np.multiply(cross[0], Jr[j], out=J_w)\n            J_w += cross[1] * Jr[3 + j]\n"
        "            J_w += cross[2] * Jr[6 + j]",
        "Jl = gathered((eye + b[:, None, None] * Wx + c[:, None, None] * Wx2).reshape(-1, 9).T, camera_index)\n"
        "            left = np.cross(np.stack(A), np.stack(P) - t, axis=0)\n"
        "            J_w[...] = left[0] * Jl[j] + left[1] * Jl[3 + j] + left[2] * Jl[6 + j]", set()),
    "derived_cauchy_second_from_first": V(
        "robust_kernels.py", ["def cauchy"], "return a2 * np.log1p(s / a2), 1.0 / t, -1.0 / (a2 * t * t)",
        "return a2 * np.log1p(s / a2), 1.0 / t, -((1.0 / t) ** 2) / a2", set()),
    "derived_tukey_second_by_s": V(
        "robust_kernels.py", ["def tukey"], "-2.0 * u / a2 + 0.0",
        "np.where(inner, 2.0 * s / (a2 * a2) - 2.0 / a2, 0.0)", set()),
}

J_ARITH = "jets.Jet: product and quotient"
J_POW = "jets.Jet: powers"
J_RES = "jets.Jet: a residual written for arrays runs on Jets"
J_SQRT = "jets.sqrt: sqrt, also at 0"
J_SIN = "jets.sin: sin"
J_ATAN = "jets.arctan2: arctan2"
J_MATMUL = "jets.matmul: matrix products"
AD = "autodiff_factor.tangent_jacobians: "
AD_ONE, AD_MANY = AD + "the Jacobian of one variable", AD + "the Jacobians of several variables of different sizes"
AD_RES = AD + "the residual at delta = 0"
FL = "factor_linearisation.BlockSparseAssembler: "
FL_2D, FL_3D = FL + "H, b and chi2 of poses and landmarks", FL + "H, b and chi2 of variables of mixed sizes"
FL_FIXED, FL_ONE = FL + "fixed variables held still", FL + "one factor of one variable"

BUGS_FACTOR_GRAPH = {
    "jets_product_rule_one_term": V(
        "jets.py", ["def __mul__"], "grad += _times(self.value, g)", "pass", {J_ARITH, J_RES},
        "the product rule has two terms"),
    "jets_quotient_rule_plus": V(
        "jets.py", ["def __truediv__"], "grad -= _times(quotient / v, g)",
        "grad += _times(quotient / v, g)",
        {J_ARITH, J_RES}, "the quotient rule subtracts"),
    "jets_power_naive_at_zero": V(
        "jets.py", ["def __pow__"], "if p == 0.0:", "if False:", {J_POW}, "x ** 0 is the constant 1"),
    "jets_sqrt_nan_at_zero": V(
        "jets.py", ["def sqrt"], "grad = np.where(x.grad == 0.0, 0.0, grad)", "pass", {J_SQRT},
        "nothing depends on the seeds there"),
    "jets_sin_minus_cos": V(
        "jets.py", ["def sin"], "_times(np.cos(x.value), x.grad)", "_times(-np.cos(x.value), x.grad)", {J_SIN, J_RES},
        "d sin(x) = +cos(x) dx"),
    "jets_arctan2_dx_added": V(
        "jets.py", ["def arctan2"], "grad = grad - _times(ys / r, xg)", "grad = grad + _times(ys / r, xg)",
        {J_ATAN, J_RES}, "the dx term is subtracted"),
    "jets_arctan2_unscaled": V(
        "jets.py", ["def arctan2"], "xs, ys = xv / scale, yv / scale\n    r = scale * (xs * xs + ys * ys)",
        "xs, ys, r = xv, yv, xv * xv + yv * yv", {J_ATAN}, "divide x and y by max(|x|, |y|)"),
    "jets_power_unguarded_at_zero": V(
        "jets.py", ["def __pow__"], "grad = np.where(self.grad == 0.0, 0.0, grad)", "pass", {J_POW},
        "nothing depends on the seeds there"),
    "jets_matmul_one_term": V(
        "jets.py", ["def matmul"], "grad = dB if grad is None else grad + dB", "grad = dB if grad is None else grad",
        {J_MATMUL, J_RES}, "both factors vary"),
    "autodiff_all_at_offset_zero": V(
        "autodiff_factor.py", [], "grad[:, :, offset:offset + d] = P", "grad[:, :, 0:d] = P", {AD_MANY},
        "give each its own directions"),
    "autodiff_blocks_from_the_first_columns": V(
        "autodiff_factor.py", [], "[grad[..., offsets[a]:offsets[a + 1]] for a in range(len(dims))]",
        "[grad[..., :dims[a]] for a in range(len(dims))]", {AD_MANY}, "not from the first d_a"),
    "autodiff_negative_seed": V(
        "autodiff_factor.py", [], "grad[:, :, offset:offset + d] = P", "grad[:, :, offset:offset + d] = -P",
        {AD_ONE, AD_MANY}, "the opposite sign"),
    "autodiff_equal_offsets": V(
        "autodiff_factor.py", [], "offsets = np.concatenate([[0], np.cumsum(dims)]).astype(int)",
        "offsets = np.array([a * d for a, d in enumerate(dims)] + [int(sum(dims))])", {AD_MANY},
        "the running sum of the tangent sizes"),
    "autodiff_blocks_reversed": V(
        "autodiff_factor.py", [], "[grad[..., offsets[a]:offsets[a + 1]] for a in range(len(dims))])",
        "[grad[..., offsets[a]:offsets[a + 1]] for a in range(len(dims))][::-1])", {AD_MANY},
        "in the order of the variables"),
    "autodiff_seeded_with_the_identity": V(
        "autodiff_factor.py", [], "grad[:, :, offset:offset + d] = P", "grad[:, :, offset:offset + d] = np.eye(n, d)",
        {AD_ONE, AD_MANY}, "seeded with the identity"),
    "autodiff_plus_jacobian_transposed": V(
        "autodiff_factor.py", [], "grad[:, :, offset:offset + d] = P",
        "grad[:, :, offset:offset + d] = np.swapaxes(P, 1, 2)", {AD_RES, AD_ONE, AD_MANY},
        "the plus-Jacobian is transposed"),
    "linearisation_b_sign": V(
        "factor_linearisation.py", ["def assemble"], 'g = np.einsum("mra,mr->ma", J[a], r)',
        'g = -np.einsum("mra,mr->ma", J[a], r)', {FL_2D, FL_3D, FL_FIXED, FL_ONE}, "the gradient's sign"),
    "linearisation_half_chi2": V(
        "factor_linearisation.py", ["def assemble"], "chi2 += float(np.vdot(r, r))",
        "chi2 += 0.5 * float(np.vdot(r, r))",
        {FL_2D, FL_3D, FL_FIXED, FL_ONE}, "not half of it"),
    "linearisation_fixed_not_held": V(
        "factor_linearisation.py", ["def assemble"], "data[self._dead] = 0.0", "pass", {FL_2D, FL_FIXED},
        "setting its diagonal to 1 leaves the rest coupled"),
    "linearisation_b_of_fixed_kept": V(
        "factor_linearisation.py", ["def assemble"], "b[self._fixed_dof] = 0.0", "pass", {FL_2D, FL_FIXED},
        "entries of b are zero too"),
    "linearisation_slot_order_upper": V(
        "factor_linearisation.py", ["def __init__"], "used = r <= q if a == c else np.ones(r.shape, dtype=bool)",
        "used = r <= q", {FL_2D, FL_3D, FL_FIXED},
        "the upper triangle is in the variables' order"),
}

#: one evaluation per variable, its Jet in its own d_a directions, the others plain arrays
PER_VARIABLE = """    blocks, r = [], None
    for a in range(len(plus_jacobians)):
        d = int(np.shape(plus_jacobians[a])[-1])
        x = np.asarray(xs[a], dtype=float)
        point = jet(x.reshape(len(x), -1), np.asarray(plus_jacobians[a], dtype=float)).reshape(x.shape)
        out = residual(*[point if b == a else np.asarray(v, dtype=float) for b, v in enumerate(xs)])
        r = out.value
        blocks.append(np.asarray(out.grad, dtype=float)[..., :d])
    return np.asarray(r, dtype=float), blocks
    dims = [int(np.shape(P)[-1]) for P in plus_jacobians]"""

DENSE_THEN_TRIANGLE = """        n = self._shape[0]
        dense, b, chi2 = np.zeros((n, n)), np.zeros(n), 0.0
        for key, (r, J) in zip(self._keys, blocks):
            for f in range(len(key)):
                for a in range(len(J)):
                    ra = slice(self._offsets[key[f, a]], self._offsets[key[f, a] + 1])
                    b[ra] += J[a][f].T @ r[f]
                    for c in range(len(J)):
                        rc = slice(self._offsets[key[f, c]], self._offsets[key[f, c] + 1])
                        dense[ra, rc] += J[a][f].T @ J[c][f]
                chi2 += float(r[f] @ r[f])
        dense[self._fixed_dof, :] = 0.0
        dense[:, self._fixed_dof] = 0.0
        dense[self._fixed_dof, self._fixed_dof] = 1.0
        b[self._fixed_dof] = 0.0
        return sp.csc_matrix(np.triu(dense)), b, chi2"""

#: one Jet of every stored number, its derivative the plus-Jacobians on a block diagonal, sliced per variable
ONE_SEED_SLICED = """    dims = [int(np.shape(P)[-1]) for P in plus_jacobians]
    k = int(sum(dims))
    offsets = np.concatenate([[0], np.cumsum(dims)]).astype(int)
    sizes = [int(np.prod(np.shape(x)[1:])) for x in xs]
    starts = np.concatenate([[0], np.cumsum(sizes)]).astype(int)
    M = len(xs[0])
    grad = np.zeros((M, int(starts[-1]), k))
    for a, P in enumerate(plus_jacobians):
        grad[:, starts[a]:starts[a + 1], offsets[a]:offsets[a + 1]] = P
    every = jet(np.concatenate([np.reshape(x, (M, -1)) for x in xs], axis=1), grad)
    points = [every[:, starts[a]:starts[a + 1]].reshape(np.shape(x)) for a, x in enumerate(xs)]
    r = residual(*points)
    return np.asarray(r.value, dtype=float), [np.asarray(r.grad)[..., offsets[a]:offsets[a + 1]]
                                              for a in range(len(dims))]
    dims = [int(np.shape(P)[-1]) for P in plus_jacobians]"""

#: each value a constant Jet whose derivative is set in place (``jet.constant``)
SEEDS_BY_CONSTANT = """point = jet.constant(x.reshape(len(x), n), k)
        point.grad[:, :, offset:offset + d] = P
        points.append(point.reshape(x.shape))"""

#: the steps seeded at 0 as unit directions, then pushed through P by hand (the chain rule once)
SEED_THEN_PLUS_JACOBIAN = """delta = jet.seed(np.zeros((len(x), d)), int(offset), k)
        grad = np.einsum("mnd,mdk->mnk", P, delta.grad)
        points.append(jet(x.reshape(len(x), n), grad).reshape(x.shape))"""

#: the Jacobians by the stored numbers (identity seeds, n_a directions each), then times P_a
AMBIENT_THEN_PLUS_JACOBIAN = """    sizes = [int(np.prod(np.shape(x)[1:])) for x in xs]
    starts = np.concatenate([[0], np.cumsum(sizes)]).astype(int)
    n_all = int(starts[-1])
    seeded = [jet.seed(np.reshape(x, (len(x), -1)), int(o), n_all).reshape(np.shape(x)) for x, o in zip(xs, starts)]
    r = residual(*seeded)
    grad = np.asarray(r.grad, dtype=float)
    return np.asarray(r.value, dtype=float), [grad[..., starts[a]:starts[a + 1]] @ np.asarray(P)
                                              for a, P in enumerate(plus_jacobians)]
    dims = [int(np.shape(P)[-1]) for P in plus_jacobians]"""

ALTERNATIVES_FACTOR_GRAPH = {
    "autodiff_one_seed_sliced": V(
        "autodiff_factor.py", [], "    dims = [int(np.shape(P)[-1]) for P in plus_jacobians]", ONE_SEED_SLICED, set()),
    "autodiff_seeds_by_constant": V(
        "autodiff_factor.py", [], """grad = np.zeros((len(x), n, k))
        grad[:, :, offset:offset + d] = P
        points.append(jet(x.reshape(len(x), n), grad).reshape(x.shape))""", SEEDS_BY_CONSTANT, set()),
    "autodiff_seed_then_plus_jacobian": V(
        "autodiff_factor.py", [], """grad = np.zeros((len(x), n, k))
        grad[:, :, offset:offset + d] = P
        points.append(jet(x.reshape(len(x), n), grad).reshape(x.shape))""", SEED_THEN_PLUS_JACOBIAN, set()),
    "autodiff_ambient_then_plus_jacobian": V(
        "autodiff_factor.py", [], "    dims = [int(np.shape(P)[-1]) for P in plus_jacobians]",
        AMBIENT_THEN_PLUS_JACOBIAN, set()),
    "jets_sqrt_by_power": V(
        "jets.py", ["def sqrt"], "grad = _times(0.5 / root, x.grad)", "grad = _times(0.5 * root ** -1.0, x.grad)",
        set()),
    "jets_arctan2_by_hypot": V(
        "jets.py", ["def arctan2"], "xs, ys = xv / scale, yv / scale\n    r = scale * (xs * xs + ys * ys)",
        "h = np.hypot(xv, yv)\n    xs, ys, r = xv / h, yv / h, h", set()),
    "jets_power_guarded_by_value": V(
        "jets.py", ["def __pow__"], "grad = np.where(self.grad == 0.0, 0.0, grad)",
        "grad = np.where((self.value[..., None] == 0.0) & (self.grad == 0.0), 0.0, grad)", set()),
    "autodiff_one_evaluation_per_variable": V(
        "autodiff_factor.py", [], "    dims = [int(np.shape(P)[-1]) for P in plus_jacobians]", PER_VARIABLE, set()),
    "linearisation_dense_then_triangle": V(
        "factor_linearisation.py", ["def assemble"], "        n = self._shape[0]", DENSE_THEN_TRIANGLE, set()),
}

# chapter 8: the elimination game and the minimum-degree ordering
OR_SE = "orderings.symbolic_elimination: "
OR_SEP, OR_PAR, OR_FILL = OR_SE + "separators", OR_SE + "elimination tree (parents)", OR_SE + "fill edges"
OR_SE_LARGE = OR_SE + "a pose graph of 2000 poses in time"
OR_MD = "orderings.minimum_degree_ordering: greedy minimum-degree ordering"
OR_MD_LARGE = "orderings.minimum_degree_ordering: a pose graph of 2000 poses in time"
OR_IN_SE = ("def symbolic_elimination", "# BEGIN SOLUTION")
OR_IN_MD = ("def minimum_degree_ordering", "# BEGIN SOLUTION")

# the elimination game played pair by pair (the plain way of the hints), for the mistakes made in it
_GAME_ELIMINATION = """    position = [0] * n
    for k, v in enumerate(ordering.tolist()):
        position[v] = k
    neighbours = [set() for _ in range(n)]  # among the variables not eliminated yet
    for i, j in edges.tolist():
        if i != j:
            neighbours[i].add(j)
            neighbours[j].add(i)
    separators = [[] for _ in range(n)]
    parents = np.full(n, -1, dtype=np.int64)
    fill = set()
    for v in ordering.tolist():
        separator = sorted(neighbours[v], key=position.__getitem__)
        separators[v] = separator
        if separator:
            parents[v] = separator[0]
        for a, i in enumerate(separator):
            neighbours[i].discard(v)
            for j in separator[a + 1:]:
                # an original edge between two variables still there is in the current graph: a pair
                # missing from it is new
                if j not in neighbours[i]:
                    neighbours[i].add(j)
                    neighbours[j].add(i)
                    fill.add((min(i, j), max(i, j)))
        neighbours[v] = set()
    fill = np.array(list(fill), dtype=np.int64).reshape(-1, 2)
    return separators, parents, fill[np.lexsort((fill[:, 1], fill[:, 0]))]  # the rows sorted
"""

BUGS_ORDERINGS = {
    # v stays in its neighbours' sets: later separators hold eliminated variables (and the large graph's
    # separators grow to every variable before: it runs out of time)
    "orderings_separator_keeps_eliminated": V(
        "orderings.py", OR_IN_SE, _solution_lines("orderings.py", "symbolic_elimination"),
        _GAME_ELIMINATION.replace("            neighbours[i].discard(v)\n", ""),
        {OR_SEP, OR_PAR, OR_FILL, OR_SE_LARGE}, "remove v from its neighbours"),
    "orderings_no_fill": V(
        "orderings.py", OR_IN_SE, "            joined[p] |= S\n", "",
        {OR_SEP, OR_PAR, OR_FILL, OR_SE_LARGE}, "joins every pair of its separator"),
    # the parent is the first entry: sorted by index, it is the smallest index (the large graph is in
    # natural order, where the two agree)
    "orderings_separator_sorted_by_index": V(
        "orderings.py", OR_IN_SE, "        separator = sorted(S, key=position.__getitem__)\n"
                                  "        separators[v] = separator\n        if separator:\n"
                                  "            p = separator[0]\n            parents[v] = p\n",
        "        separator = sorted(S)\n        separators[v] = separator\n        if separator:\n"
        "            p = min(S, key=position.__getitem__)\n            parents[v] = separator[0]\n",
        {OR_SEP, OR_PAR}, "not by index"),
    "orderings_parent_last_eliminated": V(
        "orderings.py", OR_IN_SE, "parents[v] = p", "parents[v] = separator[-1]",
        {OR_PAR, OR_SE_LARGE}, "eliminated FIRST"),
    "orderings_parent_smallest_index": V(
        "orderings.py", OR_IN_SE, "parents[v] = p", "parents[v] = min(separator)",
        {OR_PAR}, "not the smallest index"),
    "orderings_roots_zero": V(
        "orderings.py", OR_IN_SE, "parents = np.full(n, -1, dtype=np.int64)", "parents = np.zeros(n, dtype=np.int64)",
        {OR_PAR, OR_SE_LARGE}, "has parent -1, not 0"),
    "orderings_fill_with_original_edges": V(
        "orderings.py", OR_IN_SE, _solution_lines("orderings.py", "symbolic_elimination"),
        _GAME_ELIMINATION.replace("                if j not in neighbours[i]:", "                fill.add((min(i, j), "
                                  "max(i, j)))\n                if j not in neighbours[i]:"),
        {OR_FILL, OR_SE_LARGE}, "not edges of the original graph"),
    # in natural order (the large graph) every separator pair is already (smaller, larger)
    "orderings_fill_pairs_in_separator_order": V(
        "orderings.py", OR_IN_SE, "(v, u) if v < u else (u, v)", "(v, u)",
        {OR_FILL}, "with i < j"),
    "orderings_fill_rows_not_sorted": V(
        "orderings.py", OR_IN_SE, "fill[np.lexsort((fill[:, 1], fill[:, 0]))]", "fill",
        {OR_FILL, OR_SE_LARGE}, "not sorted"),
    "orderings_md_original_degrees": V(
        "orderings.py", OR_IN_MD, "            degree[i] = len(current)\n", "",
        {OR_MD, OR_MD_LARGE}, "not the original degrees"),
    "orderings_md_ties_to_largest": V(
        "orderings.py", OR_IN_MD, "v = int(degree.argmin())", "v = n - 1 - int(degree[::-1].argmin())",
        {OR_MD, OR_MD_LARGE}, "ties go to the smallest index"),
    "orderings_md_counts_eliminated_neighbours": V(
        "orderings.py", OR_IN_MD, "        separator = neighbours[v]\n        for i in separator:\n"
                                  "            current = neighbours[i]  # joined to the rest of the separator, "
                                  "in place: no new set\n            current |= separator\n"
                                  "            current.discard(i)\n            current.discard(v)\n",
        "        separator = {u for u in neighbours[v] if degree[u] < n}\n        for i in separator:\n"
        "            current = neighbours[i]\n            current |= separator\n            current.discard(i)\n",
        {OR_MD, OR_MD_LARGE}, "only the neighbours not eliminated yet"),
    "orderings_md_no_fill": V(
        "orderings.py", OR_IN_MD, "            current |= separator\n", "",
        {OR_MD, OR_MD_LARGE}, "their degrees grow"),
}

_BOOLEAN_ELIMINATION = """    adjacency = np.zeros((n, n), dtype=bool)
    adjacency[edges[:, 0], edges[:, 1]] = True
    adjacency[edges[:, 1], edges[:, 0]] = True
    np.fill_diagonal(adjacency, False)
    original = adjacency.copy()
    position = np.empty(n, dtype=np.int64)
    position[ordering] = np.arange(n)
    alive = np.ones(n, dtype=bool)
    separators = [[] for _ in range(n)]
    parents = -np.ones(n, dtype=int)
    for v in ordering:
        alive[v] = False
        members = np.flatnonzero(adjacency[v] & alive)
        members = members[np.argsort(position[members])]
        separators[v] = members.tolist()
        if members.size:
            parents[v] = members[0]
        adjacency[np.ix_(members, members)] = True
    np.fill_diagonal(adjacency, False)
    fill = np.argwhere(np.triu(adjacency & ~original, 1))
    return separators, parents, fill
"""
_FILL_BY_DIFFERENCE = """    position = {int(v): k for k, v in enumerate(ordering)}
    original = {(min(i, j), max(i, j)) for i, j in edges.tolist() if i != j}
    neighbours = {v: set() for v in range(n)}
    for i, j in original:
        neighbours[i].add(j)
        neighbours[j].add(i)
    separators, parents, joined = [None] * n, [], set()
    for v in ordering.tolist():
        separator = sorted(neighbours.pop(v), key=lambda u: position[u])
        separators[v] = separator
        parents.append(separator[0] if separator else -1)
        for i in separator:
            neighbours[i] |= set(separator)
            neighbours[i] -= {i, v}
        joined |= {(i, j) for i in separator for j in separator if i < j}
    parents = [parents[position[v]] for v in range(n)]
    fill = np.unique(np.array(sorted(joined - original), dtype=int).reshape(-1, 2), axis=0)
    return separators, np.array(parents), fill
"""
_HEAP_MINIMUM_DEGREE = """    import heapq

    neighbours = [set() for _ in range(n)]
    for i, j in edges.tolist():
        if i != j:
            neighbours[i].add(j)
            neighbours[j].add(i)
    heap = [(len(neighbours[v]), v) for v in range(n)]
    heapq.heapify(heap)
    done = [False] * n
    ordering = []
    while heap:
        degree, v = heapq.heappop(heap)
        if done[v] or degree != len(neighbours[v]):
            continue  # stale: v's degree changed since this entry was pushed
        done[v] = True
        ordering.append(v)
        separator = list(neighbours[v])
        for i in separator:
            neighbours[i].discard(v)
            neighbours[i].update(j for j in separator if j != i)
            heapq.heappush(heap, (len(neighbours[i]), i))
    return np.array(ordering)
"""
_SCAN_MINIMUM_DEGREE = """    neighbours = {v: set() for v in range(n)}
    for i, j in edges.tolist():
        if i != j:
            neighbours[i].add(j)
            neighbours[j].add(i)
    ordering = []
    while neighbours:
        v = min(neighbours, key=lambda u: (len(neighbours[u]), u))
        ordering.append(v)
        separator = neighbours.pop(v)
        for i in separator:
            neighbours[i] = (neighbours[i] | separator) - {i, v}
    return np.array(ordering)
"""
ALTERNATIVES_ORDERINGS = {
    "orderings_boolean_adjacency": V(
        "orderings.py", OR_IN_SE, _solution_lines("orderings.py", "symbolic_elimination"), _BOOLEAN_ELIMINATION,
        set()),
    "orderings_fill_as_a_set_difference": V(
        "orderings.py", OR_IN_SE, _solution_lines("orderings.py", "symbolic_elimination"), _FILL_BY_DIFFERENCE,
        set()),
    "orderings_heap_minimum_degree": V(
        "orderings.py", OR_IN_MD, _solution_lines("orderings.py", "minimum_degree_ordering"), _HEAP_MINIMUM_DEGREE,
        set()),
    "orderings_scan_minimum_degree": V(
        "orderings.py", OR_IN_MD, _solution_lines("orderings.py", "minimum_degree_ordering"), _SCAN_MINIMUM_DEGREE,
        set()),
}


EL_R, EL_SD, EL_NEW = ("elimination.eliminate_variable: " + t for t in (
    "the conditional's R: upper triangular, R^T R = Lambda_xx",
    "the conditional's S and d: R^T S = Lambda_xs, R^T d = eta_x",
    "the new factor on the separator: A_new^T A_new and A_new^T b_new"))
EL_IN = ("def eliminate_variable", "# BEGIN SOLUTION")
EL_S_LINE = "S = scipy.linalg.lapack.dtrtrs(L, Lam[:n_x, n_x:], lower=1)[0]"
BUGS_ELIMINATION = {
    # R^T S and R^T d are judged with the student's own R: a lower R costs the S-and-d check too
    "elim_R_lower": V("elimination.py", EL_IN, "    R = L.T\n", "    R = L\n", {EL_R, EL_SD}, "R is lower triangular"),
    "elim_S_is_Lambda_xs": V(
        "elimination.py", EL_IN, EL_S_LINE,
        "S = Lam[:n_x, n_x:]", {EL_SD, EL_NEW}, "not Lambda_xs itself"),
    "elim_S_by_R_inverse": V(
        "elimination.py", EL_IN, EL_S_LINE,
        "S = scipy.linalg.solve_triangular(L.T, Lam[:n_x, n_x:])", {EL_SD, EL_NEW}, "not R S = Lambda_xs"),
    "elim_d_is_eta_x": V(
        "elimination.py", EL_IN, "d = scipy.linalg.lapack.dtrtrs(L, eta[:n_x], lower=1)[0]",
        "d = eta[:n_x]", {EL_SD, EL_NEW}, "not eta_x itself"),
    "elim_no_schur_complement": V(
        "elimination.py", EL_IN, "Lam_new = Lam[n_x:, n_x:] - S.T @ S", "Lam_new = Lam[n_x:, n_x:]", {EL_NEW},
        "the Schur complement Lambda_ss - S^T S"),
    "elim_schur_complement_added": V(
        "elimination.py", EL_IN, "Lam_new = Lam[n_x:, n_x:] - S.T @ S", "Lam_new = Lam[n_x:, n_x:] + S.T @ S",
        {EL_NEW}, "the Schur complement subtracts"),
    "elim_b_sign_gauss_newton": V(
        "elimination.py", EL_IN, "eta = A.T @ b", "eta = -(A.T @ b)", {EL_SD, EL_NEW}, "the Gauss-Newton convention"),
    "elim_b_new_without_S_d": V(
        "elimination.py", EL_IN, "eta_new = eta[n_x:] - S.T @ d", "eta_new = eta[n_x:]", {EL_NEW},
        "not eta_s = A_s^T b"),
    "elim_new_factor_rows_as_given": V(
        "elimination.py", EL_IN, "return R, S, d, factor[:, :n_s], factor[:, n_s]", "return R, S, d, A_s, b",
        {EL_NEW}, "not the rows of A_s"),
}

#: the QR route: a Householder QR of the stacked rows (numpy's signs, negative diagonals left as they are)
_QR_ROUTE = """    n_x = A_x.shape[1]
    T = np.linalg.qr(np.column_stack([A_x, A_s, b]), mode="r")
    return T[:n_x, :n_x], T[:n_x, n_x:-1], T[:n_x, -1], T[n_x:, n_x:-1], T[n_x:, -1]
"""
#: the QR of A_x alone, complete, its Q^T applied to the other columns
_QR_OF_A_X = """    n_x = A_x.shape[1]
    Q, T = np.linalg.qr(A_x, mode="complete")
    rest = Q.T @ np.column_stack([A_s, b])
    return T[:n_x], rest[:n_x, :-1], rest[:n_x, -1], rest[n_x:, :-1], rest[n_x:, -1]
"""
#: the new factor written back from eigh over its positive eigenvalues
_EIGH_WRITE_BACK = """    e, V = np.linalg.eigh(Lam_new)
    keep = e > 1e-12 * max(float(e.max()), 0.0) if len(e) else e > 0
    keep &= e > 0
    return R, S, d, np.sqrt(e[keep])[:, None] * V[:, keep].T, (V[:, keep].T @ eta_new) / np.sqrt(e[keep])
"""


def _after(module: str, function: str, line: str) -> str:
    """The reference's solution lines of ``function`` in ``module`` from ``line`` on (to replace whole)."""
    block = _solution_lines(module, function)
    return block[block.index(line):]


ALTERNATIVES_ELIMINATION = {
    "elim_qr_route": V("elimination.py", ["def eliminate_variable"],
                       _solution_lines("elimination.py", "eliminate_variable"), _QR_ROUTE, set()),
    "elim_qr_of_A_x_complete": V("elimination.py", ["def eliminate_variable"],
                                 _solution_lines("elimination.py", "eliminate_variable"), _QR_OF_A_X, set()),
    "elim_cholesky_then_eigh": V("elimination.py", ["def eliminate_variable"],
                                 _after("elimination.py", "eliminate_variable", "    # the new factor:"),
                                 _EIGH_WRITE_BACK, set()),
    "elim_cholesky_by_numpy_solve": V(
        "elimination.py", EL_IN, EL_S_LINE,
        "S = np.linalg.solve(R.T, Lam[:n_x, n_x:])", set()),
}


MC_ROOT, MC_EVERY, MC_CHAIN = ("marginal_covariances.marginal_covariances: " + t for t in (
    "the root's marginal (the last variable)", "every variable's marginal",
    "a chain of 20,000 variables (no dense Sigma)"))
MC_JOINT, MC_ORDER, MC_JCHAIN = ("marginal_covariances.joint_marginal: " + t for t in (
    "the joint marginal with its cross-covariances", "keys in the order given",
    "a chain of 20,000 variables (triangular solves)"))
MC_IN_M = ("def marginal_covariances", "# BEGIN SOLUTION")
MC_IN_J = ("def joint_marginal", "# BEGIN SOLUTION")
_MC_SOLVES = "    X = spsolve_triangular(R, spsolve_triangular(sp.csr_matrix(R.T), E, lower=True), lower=False)"
_MC_BLOCKS = "zip(starts[:-1], starts[1:])"
#: the position in keys of the variable each row of the joint marginal belongs to
_MC_OWNER = "np.repeat(np.arange(len(keys)), [starts[v + 1] - starts[v] for v in keys])"

# the recursion entry by entry (the reference runs it a variable's rows at a time): the slips below are
# written into it, as a student who follows the hints would write them
_MC_SCALAR = """    n = R.shape[0]
    indptr, indices, data = R.indptr, R.indices, R.data
    diagonal = R.diagonal()
    sigma: dict = {}  # (i, j), i <= j, R[i, j] stored: Sigma[i, j]
    for i in range(n - 1, -1, -1):
        lo, hi = indptr[i], indptr[i + 1]
        above = indices[lo:hi] > i
        K, r = indices[lo:hi][above].tolist(), data[lo:hi][above]
        d = diagonal[i]
        if not K:
            sigma[(i, i)] = 1.0 / (d * d)
            continue
        try:
            S = np.array([[sigma[(a, b)] if a <= b else sigma[(b, a)] for b in K] for a in K])
        except KeyError:
            raise ValueError(f"R's pattern is not closed under elimination: row {i} stores columns {K}, but not "
                             "every R[a, b] between them is stored (a stored 0 is part of the pattern)") from None
        s = -(r @ S) / d  # Sigma[i, K]
        for k, value in zip(K, s.tolist()):
            sigma[(i, k)] = value
        sigma[(i, i)] = (1.0 / d - r @ s) / d
    out = []
    for v in range(len(starts) - 1):
        block = np.arange(starts[v], starts[v + 1]).tolist()
        out.append(np.array([[sigma[(a, b)] if a <= b else sigma[(b, a)] for b in block] for a in block]))
    return out
"""


def _mc_solution(function: str) -> str:
    text = (SOLUTIONS / "marginal_covariances.py").read_text()
    start = text.index("# BEGIN SOLUTION\n", text.index(f"def {function}")) + len("# BEGIN SOLUTION\n")
    return text[start:text.index("    # END SOLUTION", start)]


def _mc_scalar_slip(old: str, new: str) -> tuple:
    """``(old, new)`` of a variant that replaces the reference's recursion by the scalar one with ``old`` made
    ``new``."""
    assert old in _MC_SCALAR, old
    return _mc_solution("marginal_covariances"), _MC_SCALAR.replace(old, new)


# chapter 8: marginal covariances
BUGS_MARGINAL_COVARIANCES = {
    "mc_diagonal_without_its_own_term": V(
        "marginal_covariances.py", MC_IN_M,
        *_mc_scalar_slip("sigma[(i, i)] = (1.0 / d - r @ s) / d", "sigma[(i, i)] = (-r @ s) / d"),
        {MC_ROOT, MC_EVERY, MC_CHAIN}, "needs its own term"),
    "mc_diagonal_without_the_sum": V(
        "marginal_covariances.py", MC_IN_M,
        *_mc_scalar_slip("sigma[(i, i)] = (1.0 / d - r @ s) / d", "sigma[(i, i)] = 1.0 / (d * d)"),
        {MC_ROOT, MC_EVERY, MC_CHAIN}, "holds only for the last row"),
    "mc_off_diagonal_sign": V(
        "marginal_covariances.py", MC_IN_M, *_mc_scalar_slip("s = -(r @ S) / d", "s = (r @ S) / d"),
        {MC_ROOT, MC_EVERY, MC_CHAIN}, "wrong sign"),
    "mc_inverse_of_the_information_block": V(
        "marginal_covariances.py", MC_IN_M, "    return marginals",
        "    return [np.linalg.inv((C[:, a:b].T @ C[:, a:b]).toarray()) for C in [R.tocsc()] for a, b in "
        + _MC_BLOCKS + "]",
        {MC_ROOT, MC_EVERY, MC_CHAIN}, "given all the other variables"),
    "mc_conditional_on_the_separator": V(
        "marginal_covariances.py", MC_IN_M, "    return marginals",
        "    return [np.linalg.inv(B.T @ B) for B in (R[a:b, a:b].toarray() for a, b in " + _MC_BLOCKS + ")]",
        {MC_EVERY, MC_CHAIN}, "given its separator"),
    "mc_stored_zeros_dropped": V(
        "marginal_covariances.py", MC_IN_M,
        *_mc_scalar_slip("    n = R.shape[0]", "    R.eliminate_zeros()\n    n = R.shape[0]"),
        {MC_EVERY}, "a stored 0 is part of the pattern"),
    "jm_keys_sorted": V(
        "marginal_covariances.py", MC_IN_J, "for v in keys])", "for v in sorted(keys)])",
        {MC_ORDER}, "keep the order of keys"),
    "jm_solves_in_the_wrong_order": V(
        "marginal_covariances.py", MC_IN_J, _MC_SOLVES,
        "    X = spsolve_triangular(sp.csr_matrix(R.T), spsolve_triangular(R, E, lower=False), lower=True)",
        {MC_JOINT, MC_ORDER, MC_JCHAIN}, "(R R^T)^-1"),
    "jm_diagonal_blocks_only": V(
        "marginal_covariances.py", MC_IN_J, "    return X[cols]",
        f"    return np.where(np.equal.outer({_MC_OWNER}, {_MC_OWNER}), X[cols], 0.0)",
        {MC_JOINT, MC_ORDER, MC_JCHAIN}, "cross-covariances"),
    "jm_inverse_of_the_information_block": V(
        "marginal_covariances.py", MC_IN_J, "    return X[cols]",
        "    return np.linalg.inv((R.T @ R)[cols][:, cols].toarray())",
        {MC_JOINT, MC_ORDER, MC_JCHAIN}, "inverse of H's block"),
}

_MC_BY_COLUMNS = """    n = R.shape[0]
    C = R.tocsc()
    C.sort_indices()
    diagonal = R.diagonal()
    sigma: dict = {}

    def get(a, b):
        return sigma[(a, b)] if a <= b else sigma[(b, a)]

    def later(i, j):  # sum over the stored k > i of row i: R_ik Sigma_kj
        lo, hi = R.indptr[i], R.indptr[i + 1]
        return sum(r * get(k, j) for k, r in zip(R.indices[lo:hi].tolist(), R.data[lo:hi].tolist()) if k > i)

    for j in range(n - 1, -1, -1):  # column by column from the last; in each, the diagonal, then up
        sigma[(j, j)] = (1.0 / diagonal[j] - later(j, j)) / diagonal[j]
        above = C.indices[C.indptr[j]:C.indptr[j + 1]]
        for i in sorted(above[above < j].tolist(), reverse=True):
            sigma[(i, j)] = -later(i, j) / diagonal[i]
    out = []
    for v in range(len(starts) - 1):
        block = range(starts[v], starts[v + 1])
        out.append(np.array([[get(a, b) for b in block] for a in block]))
    return out
"""


#: correct but different: the recursion column by column; the joint marginal as Y^T Y from one solve, or by
#: a general sparse solve with H = R^T R
ALTERNATIVES_MARGINAL_COVARIANCES = {
    "mc_recursion_by_columns": V(
        "marginal_covariances.py", MC_IN_M, _mc_solution("marginal_covariances"), _MC_BY_COLUMNS, set()),
    "jm_one_solve_y_t_y": V(
        "marginal_covariances.py", MC_IN_J,
        _MC_SOLVES + "\n    X = np.asarray(X).reshape(n, len(cols))\n    return X[cols]",
        "    Y = np.asarray(spsolve_triangular(sp.csr_matrix(R.T), E, lower=True)).reshape(n, len(cols))\n"
        "    return Y.T @ Y", set()),
    "jm_general_sparse_solve": V(
        "marginal_covariances.py", MC_IN_J, _MC_SOLVES,
        "    X = sp.linalg.spsolve(sp.csc_matrix(R.T @ R), E)", set()),
}



# chapter 8: the incremental update of the Bayes tree
IU_LARGEST, IU_STRICT = ("incremental_update.relinearised_keys: " + t for t in (
    "the largest absolute entry against the threshold", "strictly above the threshold"))
IU_NEW, IU_RELIN, IU_ORPHANS = ("incremental_update.affected_cliques: " + t for t in (
    "the top of new factors (their cliques and the paths to the roots)",
    "relinearised variables in frontals or separators", "the orphans (the top's children outside it)"))
IU_ATTACH = "incremental_update.orphan_parents: each orphan's parent in the new top"
IU_FULL, IU_PARTIAL, IU_RECOMPUTED, IU_KEPT = ("incremental_update.wildfire_update: " + t for t in (
    "the full back-substitution (every clique replaced, threshold 0)", "the steps of a partial update",
    "the recomputed cliques", "delta left as it was"))
IU_IN_R = ("def relinearised_keys", "# BEGIN SOLUTION")
IU_IN_A = ("def affected_cliques", "# BEGIN SOLUTION")
IU_IN_O = ("def orphan_parents", "# BEGIN SOLUTION")
IU_IN_W = ("def wildfire_update", "# BEGIN SOLUTION")

BUGS_INCREMENTAL_UPDATE = {
    "iu_euclidean_norm": V(
        "incremental_update.py", IU_IN_R, "np.unique(owner[np.abs(flat) > threshold]).tolist()",
        "np.flatnonzero(np.sqrt(np.bincount(owner, weights=flat**2, minlength=len(steps))) > threshold).tolist()",
        {IU_LARGEST}, "not the Euclidean norm"),
    "iu_signed_maximum": V(
        "incremental_update.py", IU_IN_R, "owner[np.abs(flat) > threshold]", "owner[flat > threshold]",
        {IU_LARGEST, IU_STRICT}, "ABSOLUTE entry"),
    "iu_at_the_threshold": V(
        "incremental_update.py", IU_IN_R, "> threshold]", ">= threshold]", {IU_STRICT}, "compare strictly"),
    "iu_frontals_only": V(
        "incremental_update.py", IU_IN_A,
        "        marked |= {c for c, S in enumerate(clique_separators) if not relin.isdisjoint(S)}\n", "", {IU_RELIN},
        "in their SEPARATOR too"),
    "iu_no_ancestors": V(
        "incremental_update.py", IU_IN_A, "while c != -1 and c not in top:", "if c != -1:", {IU_NEW, IU_RELIN},
        "AND all their ancestors"),
    "iu_orphans_every_clique_below": V(
        "incremental_update.py", IU_IN_A, "np.flatnonzero(~in_top[:C] & in_top[parents])",
        "np.flatnonzero(~in_top[:C])", {IU_ORPHANS}, "the orphans are"),
    "iu_smallest_index": V(
        "incremental_update.py", IU_IN_O, "min((int(v) for v in S), key=position.__getitem__)",
        "min(int(v) for v in S)", {IU_ATTACH}, "not its smallest index"),
    "iu_first_listed": V(
        "incremental_update.py", IU_IN_O, "min((int(v) for v in S), key=position.__getitem__)", "int(S[0])",
        {IU_ATTACH}, "not the one listed first"),
    "iu_every_clique_recomputed": V(
        "incremental_update.py", IU_IN_W, "if c not in replaced and changed.isdisjoint(clique_separators[c]):",
        "if False:", {IU_PARTIAL, IU_RECOMPUTED}, "that is what makes the update partial"),
    "iu_change_from_zero": V(
        "incremental_update.py", IU_IN_W, "np.abs(x - before)", "np.abs(x)",
        {IU_PARTIAL, IU_RECOMPUTED}, "not when the new step itself"),
    "iu_replaced_skipped": V(
        "incremental_update.py", IU_IN_W, "if c not in replaced and changed.isdisjoint(clique_separators[c]):",
        "if changed.isdisjoint(clique_separators[c]):", {IU_FULL, IU_PARTIAL, IU_RECOMPUTED},
        "a replaced clique has a new conditional"),
    "iu_delta_written_into": V(
        "incremental_update.py", IU_IN_W, "new = list(old)", "new = delta", {IU_KEPT},
        "changed the delta it was given"),
}

_IU_AFFECTED_BY_ARRAYS = """    C = len(frontals)
    clique = np.empty(n, dtype=int)
    for c, F in enumerate(frontals):
        clique[list(F)] = c
    marked = np.zeros(C, dtype=bool)
    marked[clique[[k for k in new_keys if k < n]]] = True
    hit = np.zeros(n, dtype=bool)
    hit[relinearised] = True
    for c, (F, S) in enumerate(zip(frontals, clique_separators)):
        marked[c] |= bool(hit[list(F) + list(S)].any())

    def climb(c):  # the top, by recursion up the tree
        if c == -1 or in_top[c]:
            return
        in_top[c] = True
        climb(int(parents[c]))

    in_top = np.zeros(C, dtype=bool)
    for c in np.flatnonzero(marked):
        climb(int(c))
    has_parent = parents >= 0
    orphans = np.flatnonzero(~in_top & has_parent & in_top[np.where(has_parent, parents, 0)])
    return np.flatnonzero(in_top).tolist(), orphans.tolist()
"""

_IU_WILDFIRE_BREADTH_FIRST = """    import collections

    sizes = [step.size for step in old]
    new = [np.array(step) for step in old]
    replaced = {int(c) for c in replaced}
    changed = np.zeros(n, dtype=bool)
    recomputed = []
    queue = collections.deque(np.flatnonzero(parents == -1).tolist())
    while queue:
        c = queue.popleft()
        S = list(clique_separators[c])
        if c in replaced or changed[S].any():
            R, Sb, d = (np.asarray(block, dtype=float) for block in conditionals[c])
            s = np.concatenate([new[v] for v in S] + [np.zeros(0)])
            x = np.linalg.solve(R, d - Sb @ s)  # R is triangular, a general solve is fine too
            for v, step in zip(frontals[c], np.split(x, np.cumsum([sizes[v] for v in frontals[c]])[:-1])):
                changed[v] = step.size > 0 and np.abs(step - old[v]).max() > threshold
                new[v] = step
            recomputed.append(c)
            queue.extend(np.flatnonzero(parents == c).tolist())
    return new, sorted(recomputed)
"""

_IU_WILDFIRE_RECURSIVE = """    new = list(old)
    replaced = set(replaced)
    changed = set()
    recomputed = []

    def visit(c):
        if c not in replaced and changed.isdisjoint(clique_separators[c]):
            return
        R, S, d = conditionals[c]
        rhs = np.array(d, dtype=float)
        if len(clique_separators[c]):
            rhs = rhs - np.asarray(S) @ np.hstack([new[v] for v in clique_separators[c]])
        x = scipy.linalg.solve_triangular(R, rhs, lower=False)
        at = 0
        for v in frontals[c]:
            step = x[at:at + len(old[v])]
            at += len(old[v])
            if len(step) and np.linalg.norm(step - old[v], np.inf) > threshold:
                changed.add(v)
            new[v] = step
        recomputed.append(c)
        for child in np.flatnonzero(parents == c):
            visit(int(child))

    for root in np.flatnonzero(parents == -1):
        visit(int(root))
    return new, sorted(recomputed)
"""

ALTERNATIVES_INCREMENTAL_UPDATE = {
    "iu_relinearised_vectorised": V(
        "incremental_update.py", IU_IN_R, _solution_lines("incremental_update.py", "relinearised_keys"),
        "    largest = np.array([np.abs(step).max(initial=0.0) for step in steps])\n"
        "    return np.flatnonzero(largest > threshold).tolist()\n", set()),
    "iu_affected_by_arrays_and_recursion": V(
        "incremental_update.py", IU_IN_A, _solution_lines("incremental_update.py", "affected_cliques"),
        _IU_AFFECTED_BY_ARRAYS, set()),
    "iu_orphan_parents_by_scanning_the_ordering": V(
        "incremental_update.py", IU_IN_O, _solution_lines("incremental_update.py", "orphan_parents"),
        "    out = []\n    for S in orphan_separators:\n"
        "        first = next(v for v in order if v in set(int(u) for u in S))\n"
        "        out.append(next(c for c, F in enumerate(new_frontals) if first in F))\n"
        "    return out\n", set()),
    "iu_wildfire_breadth_first": V(
        "incremental_update.py", IU_IN_W, _solution_lines("incremental_update.py", "wildfire_update"),
        _IU_WILDFIRE_BREADTH_FIRST, set()),
    "iu_wildfire_recursive": V(
        "incremental_update.py", IU_IN_W, _solution_lines("incremental_update.py", "wildfire_update"),
        _IU_WILDFIRE_RECURSIVE, set()),
}


VARIANTS = {**ALTERNATIVES_DERIVED, **BUGS, **HOSTILE, **BUGS_CHAPTERS_2_3, **BUGS_INITIALISATION,
            **ALTERNATIVES_INITIALISATION, **ALTERNATIVES_WRAP, **BUGS_WRAP,
            **BUGS_BUNDLE_ADJUSTMENT, **ALTERNATIVES_BUNDLE_ADJUSTMENT, **BUGS_ROBUST_KERNELS,
            **ALTERNATIVES_ROBUST_KERNELS,
            **BUGS_GAUGE, **ALTERNATIVES_GAUGE, **BUGS_PARALLEL_ASSEMBLY, **ALTERNATIVES_PARALLEL_ASSEMBLY,
            **BUGS_MARGINALISATION, **ALTERNATIVES_MARGINALISATION,
            **BUGS_IMU_PREINTEGRATION, **ALTERNATIVES_IMU_PREINTEGRATION,
            **BUGS_POSE_GRAPH_3D, **ALTERNATIVES_POSE_GRAPH_3D, **BUGS_POSE_GRAPH_3D_ASSEMBLY,
            **ALTERNATIVES_POSE_GRAPH_3D_ASSEMBLY, **BUGS_CHORDAL_3D, **ALTERNATIVES_CHORDAL_3D,
            **BUGS_GNC, **ALTERNATIVES_GNC, **BUGS_FACTOR_GRAPH, **ALTERNATIVES_FACTOR_GRAPH,
            **BUGS_ELIMINATION, **ALTERNATIVES_ELIMINATION, **BUGS_BAYES_TREE, **ALTERNATIVES_BAYES_TREE,
            **BUGS_MARGINAL_COVARIANCES, **ALTERNATIVES_MARGINAL_COVARIANCES,
            **BUGS_ORDERINGS, **ALTERNATIVES_ORDERINGS,
            **BUGS_INCREMENTAL_UPDATE, **ALTERNATIVES_INCREMENTAL_UPDATE}


def apply(text: str, variant: Variant) -> str:
    """``text`` with the variant's edit; raises AssertionError when it does not apply."""
    position = 0
    for anchor in variant.anchors:
        position = text.find(anchor, position)
        assert position >= 0, f"anchor {anchor!r} not found"
    at = text.find(variant.old, position)
    assert at >= 0, f"{variant.old!r} not found in {variant.file} after {variant.anchors}"
    edited = text[:at] + variant.new + text[at + len(variant.old):]
    assert edited != text
    return edited


def build(name: str, root: Path) -> Path:
    """Write the variant ``name`` into ``root / name`` (a copy of solutions/) and return it."""
    variant = VARIANTS[name]
    target = Path(root) / name
    shutil.copytree(SOLUTIONS, target, ignore=shutil.ignore_patterns("__pycache__", "*.pyc"))
    path = target / variant.file
    path.write_text(apply(path.read_text(), variant))
    return target


def losing(results) -> set:
    return {t["name"] for t in results["tests"] if t["score"] < t["max_score"] - 1e-9}


def assert_loses_exactly(results, fails, stdout=""):
    """The public checks lost are ``fails``; so are the hidden ones, except that an end-to-end
    run on other data may happen to end well despite the mistake."""
    from autograder.grade import HIDDEN_SUFFIX

    lost = losing(results)
    public = {name for name in lost if not name.endswith(HIDDEN_SUFFIX)}
    hidden = {name[: -len(HIDDEN_SUFFIX)] for name in lost if name.endswith(HIDDEN_SUFFIX)}
    assert public == set(fails), "\n" + stdout
    assert {name for name in fails if "end_to_end" not in name} <= hidden <= set(fails), "\n" + stdout


def grade_variants(root: Path, jobs: dict) -> dict:
    """Grade the variants of ``jobs`` (name -> the ``--only`` names, ``()`` for every check;
    the names ``solutions`` and ``exercises`` stand for the reference and the stubs)
    through ``python -m autograder batch``: one grading run for each set of ``--only`` names,
    every check in a child of its own as in a single run. Returns ``{name: (the table the
    command line prints, results.json)}``."""
    groups: dict = {}
    for name, only in jobs.items():
        groups.setdefault(tuple(only), []).append(name)
    graded = {}
    for number, (only, names) in enumerate(groups.items()):
        folder, out = Path(root) / f"batch-{number}", Path(root) / f"results-{number}"
        folder.mkdir(parents=True)
        for name in names:
            if name in ("solutions", "exercises"):  # the reference and the stubs, as they are
                shutil.copytree(ROOT / name, folder / name, ignore=shutil.ignore_patterns("__pycache__", "*.pyc"))
            else:
                build(name, folder)
        args = [arg for item in only for arg in ("--only", item)]
        proc = subprocess.run([sys.executable, "-m", "autograder", "batch", str(folder), "--out", str(out),
                               "--timeout", TIMEOUT, "--no-report", *args], cwd=ROOT, capture_output=True,
                              text=True, timeout=60 + 60 * len(names))
        assert proc.returncode == 0, proc.stderr
        for name in names:
            graded[name] = ((out / "results" / f"{name}.txt").read_text(),
                            json.loads((out / "results" / f"{name}.json").read_text()))
    return graded
