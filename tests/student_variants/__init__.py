"""Buggy student implementations, made from ``solutions/`` by substituting one line.

Nothing is committed but this table: :func:`build` copies ``solutions/`` into a
directory laid out like ``exercises/`` and applies one variant's edit, asserting that
the text to replace was found. Each variant lists the checks it must lose points on
(``fails``); every other check must keep full marks. A bug in a function also costs
the end-to-end run that uses it when the wrong code changes where the run ends.
"""

import shutil
from dataclasses import dataclass
from pathlib import Path

SOLUTIONS = Path(__file__).resolve().parents[2] / "solutions"

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
}

# Hostile or broken code: each costs its own check(s) and nothing else.
HOSTILE = {
    "sys_exit": V(
        "damping.py", ["class GavinType1", "def initial_state"],
        "return DampingState(lam=self.lambda_0)", "import sys; sys.exit(0)",
        {T1 + "initial_state", E2E + "lm-type1"}, "called sys.exit(0)"),
    "os_exit": V(
        "damping.py", ["class GavinType2", "def step_scale"],
        "gh = float(-b @ h)", "import os; os._exit(0)",
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
    "dense_solve_no_minus": V(
        "sparse_solve.py", [], "return -scipy.linalg.cho_solve(", "return scipy.linalg.cho_solve(",
        {DENSE + "dx solves H dx = -b"}, "dx has the opposite sign"),
    "upper_triangle_full_matrix": V(
        "sparse_solve.py", [], 'return sp.triu(sp.csc_matrix(H), format="csc")', "return sp.csc_matrix(H)",
        {UPPER + "upper triangle as CSC", PG_E2E + "gauss-newton"}, "this is the whole of H"),
    "sparse_never_refactorizes": V(
        "sparse_solve.py", [], "self._solver.update(H_upper, upper=True)", "pass",
        {SPARSE + "later solves with new values, same pattern"},
        "this solve used the first call's matrix"),
    # slipped through before the 2-pose, 1-edge graph: the 6-pose graph has an edge from its last pose
    "assembly_size_from_edge_starts": V(
        "pose_graph_assembly.py", [], "n = 3 * len(poses)", "n = 3 * (max(edges_i) + 1)",
        {ASSEMBLY + "H blocks of the free poses", ASSEMBLY + "b and chi2",
         ASSEMBLY + "fixed poses (first pose, and poses 0 and 3)", PG_E2E + "gauss-newton"},
        "[on a 2-pose graph with a single edge"),
    # slipped through before two solvers were used alternately: every solver shares one factorization
    "sparse_solver_on_the_class": V(
        "sparse_solve.py", ["def solve", "# BEGIN SOLUTION"],
        "        if self._solver is None:\n            self._solver = qdldl.Solver(H_upper, upper=True)\n"
        "        else:\n            self._solver.update(H_upper, upper=True)\n"
        "        return -self._solver.solve(",
        "        cls = SparseCholeskySolver\n        if getattr(cls, 'cached', None) is None:\n"
        "            cls.cached = qdldl.Solver(H_upper, upper=True)\n"
        "        else:\n            cls.cached.update(H_upper, upper=True)\n"
        "        return -cls.cached.solve(",
        {SPARSE + "two solvers, two patterns, used alternately"}, "must not share a factorization"),
    # qdldl.Solver bound when the module is imported (a class attribute): still counted
    "sparse_new_solver_bound_at_import": V(
        "sparse_solve.py", ["def solve", "# BEGIN SOLUTION"],
        "        if self._solver is None:\n            self._solver = qdldl.Solver(H_upper, upper=True)\n"
        "        else:\n            self._solver.update(H_upper, upper=True)\n"
        "        return -self._solver.solve(np.asarray(b, dtype=float))\n        # END SOLUTION\n",
        "        return -self.make(H_upper, upper=True).solve(np.asarray(b, dtype=float))\n        # END SOLUTION\n"
        "\n    from qdldl import Solver as make  # a class attribute, bound at import; a new analysis per call\n",
        {SPARSE + "one symbolic analysis for the pattern"}, "3 qdldl.Solver objects were made for 3 solves"),
    "ceres_no_whitening": V(
        "ceres_edge_cost.py", ["def Evaluate"], "residuals[:] = (", "residuals[:] = (e0, e1, e2)\n        _unused = (",
        {CERES + "residuals r = U e"}, "r is the unwhitened error e"),
    "dogleg_case_boundaries_swapped": V(
        "dogleg.py", ["def dogleg_step", "# BEGIN SOLUTION"],
        "if np.linalg.norm(h_gn) <= radius:", "if alpha * np.linalg.norm(g) <= radius:",
        {DL_STEP + "dogleg case (|a| < radius < |h_gn|)",
         DL_STEP + "stable beta (Cauchy point almost on the boundary)"},
        "so the case is dogleg"),
    "dogleg_beta_wrong_root": V(
        "dogleg.py", ["def dogleg_step", "# BEGIN SOLUTION"], "(radius**2 - a_norm**2) / (d + c)",
        "(radius**2 - a_norm**2) / (c - d)",
        {DL_STEP + "dogleg case (|a| < radius < |h_gn|)",
         DL_STEP + "stable beta (Cauchy point almost on the boundary)", DL_E2E + "pose graph"},
        "the other intersection"),
    "dogleg_gn_decrease_in_dogleg_case": V(
        "dogleg.py", [], "return a + beta * diff, decrease, DOGLEG", "return a + beta * diff, gn_decrease, DOGLEG",
        {DL_STEP + "dogleg case (|a| < radius < |h_gn|)"}, "that is the Gauss-Newton case's formula"),
    "radius_grows_on_poor_step": V(
        "dogleg.py", ["def update_radius"], "return radius / 2.0", "return radius * 2.0",
        {DL_RADIUS + "poor step (rho < 0.25)", DL_E2E + "curve", DL_E2E + "pose graph"},
        "the radius grew on a poor step"),
    "radius_without_max": V(
        "dogleg.py", ["def update_radius"], "return max(radius, 3.0 * step_norm)", "return 3.0 * step_norm",
        {DL_RADIUS + "good step (rho > 0.75)"}, "a short good step must not shrink the trust region"),
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
        "initialisation.py", _CHORDAL, "a = np.exp(1j * measurements[:, 2])", "a = np.exp(-1j * measurements[:, 2])",
        {ROTATIONS}, "the relative rotation is transposed"),
    "rotations_anchor_at_angle_0": V(
        "initialisation.py", _CHORDAL, "z_anchor = np.exp(1j * anchor_theta)", "z_anchor = 1.0",
        {ROTATIONS}, "here the anchor is at angle 0"),
    "rotations_arctan_loses_the_quadrant": V(
        "initialisation.py", _CHORDAL, "theta[others] = (np.angle(z) + np.pi) % (2.0 * np.pi) - np.pi",
        "theta[others] = np.arctan(z.imag / z.real)",
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
        "bundle_adjustment.py", [], "p = -P[:, :2] / z[:, None]", "p = P[:, :2] / z[:, None]",
        {BA_R, BA_JC}, "the BAL projection is p = -P[:2] / P[2]"),
    "ba_residual_flipped": V(
        "bundle_adjustment.py", [], "r = (f * d)[:, None] * p - observations",
        "r = observations - (f * d)[:, None] * p",
        {BA_R}, "not observed - predicted"),
    "ba_no_distortion": V(
        "bundle_adjustment.py", [], "d = 1.0 + k1 * n + k2 * n * n", "d = np.ones_like(n)",
        {BA_R, BA_JC, BA_JP}, "the radial distortion d = 1 + k1 |p|^2 + k2 |p|^4 is missing"),
    "ba_small_angle_rotation_jacobian": V(
        "bundle_adjustment.py", [], "dRX_dw = -np.matmul(R, np.matmul(_skew(X), Jr))",
        "dRX_dw = -_skew(np.matmul(R, X[:, :, None])[:, :, 0])",
        {BA_JC}, "holds only at w = 0"),
    "ba_no_distortion_derivative": V(
        "bundle_adjustment.py", [], "dpred_dp = (f * (2.0 * k1 + 4.0 * k2 * n))[:, None, None] * "
                                    "(p[:, :, None] * p[:, None, :])", "dpred_dp = np.zeros((K, 2, 2))",
        {BA_JC, BA_JP}, "the derivative of the distortion d with respect to p is missing"),
    "ba_point_jacobian_without_rotation": V(
        "bundle_adjustment.py", [], "J_point = np.matmul(A, R)", "J_point = A",
        {BA_JP}, "J_point = (d predicted / d P) R"),
    "ba_focal_column_without_distortion": V(
        "bundle_adjustment.py", [], "J_cam[:, :, 6] = d[:, None] * p", "J_cam[:, :, 6] = p",
        {BA_JC}, "d predicted / d f = d p"),
    "ba_camera_blocks_by_fancy_index": V(
        "bundle_adjustment.py", [], "U = scatter(ci, np.matmul(Jc_t, J_cam), num_cameras)",
        "U = np.zeros((num_cameras, 9, 9))\n    U[ci] += np.matmul(Jc_t, J_cam)",
        {BA_UVW}, "accumulate with np.add.at"),
    "ba_point_blocks_by_fancy_index": V(
        "bundle_adjustment.py", [], "V = scatter(pi, np.matmul(Jp_t, J_point), num_points)",
        "V = np.zeros((num_points, 3, 3))\n    V[pi] += np.matmul(Jp_t, J_point)",
        {BA_UVW}, "accumulate with np.add.at"),
    "ba_coupling_summed_per_camera": V(
        "bundle_adjustment.py", [], "W = np.matmul(Jc_t, J_point)",
        "W = scatter(ci, np.matmul(Jc_t, J_point), num_cameras)[ci]",
        {BA_UVW}, "one block per observation"),
    "ba_gradient_sign": V(
        "bundle_adjustment.py", [], "g_cam = scatter(ci,", "g_cam = -scatter(ci,",
        {BA_G}, "the gradient has the opposite sign"),
    "ba_half_chi2": V(
        "bundle_adjustment.py", [], "float(np.sum(r * r))", "float(0.5 * np.sum(r * r))",
        {BA_G}, "without a factor 1/2"),
    "schur_point_blocks_undamped": V(
        "bundle_adjustment.py", [], "V[:, np.arange(3), np.arange(3)] += damping_point", "pass",
        {BA_CAM, BA_PT}, "the damping is added to V as well as U"),
    "schur_camera_blocks_undamped": V(
        "bundle_adjustment.py", [], "U[:, np.arange(9), np.arange(9)] += damping_cam", "pass",
        {BA_CAM, BA_PT}, "the damping D_c is missing"),
    "schur_coupling_added": V(
        "bundle_adjustment.py", [], "S = scipy.linalg.block_diag(*U) - reduction.toarray()",
        "S = scipy.linalg.block_diag(*U) + reduction.toarray()",
        {BA_CAM, BA_PT}, "the coupling term is subtracted"),
    "schur_rhs_sign": V(
        "bundle_adjustment.py", [], "rhs = -np.asarray(g_cam, dtype=float).ravel() + Ys @",
        "rhs = -np.asarray(g_cam, dtype=float).ravel() - Ys @",
        {BA_CAM, BA_PT}, "the reduced right-hand side is -g_cam + W V^-1 g_point"),
    "schur_back_substitution_sign": V(
        "bundle_adjustment.py", [], "(-np.asarray(g_point, dtype=float) - back)",
        "(-np.asarray(g_point, dtype=float) + back)",
        {BA_PT}, "back-substitution"),
}

VARIANTS = {**BUGS, **HOSTILE, **BUGS_CHAPTERS_2_3, **BUGS_INITIALISATION, **ALTERNATIVES_INITIALISATION,
            **BUGS_BUNDLE_ADJUSTMENT}


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
