"""Feedback on mistakes nobody foresaw: the known mistakes graded with their catalogue stripped.

For every variant whose feedback comes from the catalogue (its ``says`` is a known mistake's text),
its checks are judged again as if no mistake were known (``Expected.without_catalogue``): does
the feedback still point at the right function, and, where ``LOCATES`` names one, at the right
factor or block? The variants run in the grader's sandbox, as a student's code does.
"""

import ast
from dataclasses import dataclass
from pathlib import Path

from . import SOLUTIONS, VARIANTS, apply, build

#: per variant, what the feedback must say to name the factor or block that goes wrong, where the
#: exercise has factors (projection, distortion and rotation in BA) or blocks (the Jacobian's columns)
LOCATES = {
    # bundle adjustment: the factor of the chain rule
    "ba_no_distortion_derivative": "both go wrong through the factor they share, d predicted / d P",
    "ba_small_angle_rotation_jacobian": "is right; d P / d w (J_cam's rotation columns",
    "ba_point_jacobian_without_rotation": "is right; d P / d X = R(w) (J_point",
    "ba_focal_column_without_distortion": "is right; d predicted / d (f, k1, k2)",
    # the SE(3) edge: the block of A or B
    "p3_no_jr_inverse": "(d e_phi / d phi (rotation rows, rotation columns) differ",
    "p3_jr_forward": "(d e_phi / d phi (rotation rows, rotation columns) differ",
    "p3_a_rotation_without_relative_rotation": "(d e_phi / d phi (rotation rows, rotation columns) differ",
    "p3_cross_product_sign": "(d e_t / d phi (translation rows, rotation columns) differ",
    "p3_b_translation_identity": "(d e_t / d rho (translation rows, translation columns) differ",
    # the SE(2) edge: the entry or column of e, A, B
    "edge_no_angle_wrap": "e[2] = ",
    "edge_A_wrong_sign": "A[:, 0] disagrees with finite differences",
    # the IMU factor: which of r_R, r_v, r_p
    "ir_R_i_not_transposed": "r_v[",
    "ir_gravity_sign": "r_v[",
    "ir_gravity_without_half": "r_p[",
    "ir_rotation_correction_on_the_left": "r_R[",
    "ir_rotation_residual_order": "r_R[",
    "ir_position_without_v_i_dt": "r_p[",
}


@dataclass
class HeldOut:
    """One variant judged without the catalogue."""

    name: str
    function: str  # the qualified name of the function the variant edits: "damping.GavinType1.update"
    lost: list  # the checks that lost points
    feedback: str  # their messages
    names_function: bool
    locates: bool | None  # None when LOCATES says nothing of this variant

    @property
    def ok(self) -> bool:
        return self.names_function and self.locates is not False


def edited_function(name: str) -> str:
    """``module.Class.function``: the innermost definition around the variant's edit."""
    variant = VARIANTS[name]
    text = (SOLUTIONS / variant.file).read_text()
    edited = apply(text, variant)
    line = next(k for k, (a, b) in enumerate(zip(text.splitlines(), edited.splitlines()), 1) if a != b)
    best, best_span = variant.file[:-3], None
    stack = [(node, variant.file[:-3]) for node in ast.parse(text).body]
    while stack:
        node, prefix = stack.pop()
        if isinstance(node, (ast.FunctionDef, ast.ClassDef)):
            qualified = f"{prefix}.{node.name}"
            if node.lineno <= line <= (node.end_lineno or node.lineno):
                span = (node.end_lineno or node.lineno) - node.lineno
                if best_span is None or span < best_span:
                    best, best_span = qualified, span
            stack += [(child, qualified) for child in node.body]
    return best


def catalogued(names, expected_by_check) -> list:
    """The variants of ``names`` whose ``says`` is the text of a known mistake of one of their checks."""
    kept = []
    for name in names:
        variant = VARIANTS[name]
        whys = {why for check in variant.fails if check in expected_by_check
                for per_call in expected_by_check[check].mistakes for pairs in per_call.values() for _, why in pairs}
        if variant.says and any(variant.says in why for why in whys):
            kept.append(name)
    return kept


def judge_without_catalogue(names, root: Path, workers: int = 2) -> list:
    """``HeldOut`` per variant of ``names``, judged on the public inputs of the checks it must fail,
    in the grader's sandbox (a variant may crash its process: passing a full matrix to qdldl does),
    one run per group of variants that edit the same file, each variant on its own checks alone."""
    from autograder.checks import all_checks
    from autograder.grade import grade_many

    checks = {check.name: check for check in all_checks()}
    groups: dict = {}
    for name in names:
        groups.setdefault(VARIANTS[name].file, []).append(name)
    out = []
    for group in groups.values():
        only = sorted(set().union(*(VARIANTS[name].fails for name in group)))
        impls = [build(name, root) for name in group]
        for name, results in zip(group, grade_many(impls, only=only, which="public", workers=workers,
                                                   catalogue=False, each=[VARIANTS[n].fails for n in group])):
            function = edited_function(name)
            assert {result.name for result in results} == set(VARIANTS[name].fails), name
            lost = [result.name for result in results if result.score < result.max_score]
            exercises = {checks[check].exercise for check in lost}
            names_function = any(function == exercise or function.startswith(exercise + ".")
                                 for exercise in exercises)
            feedback = "\n".join(result.message for result in results if result.score < result.max_score)
            locates = None if name not in LOCATES else LOCATES[name] in feedback
            out.append(HeldOut(name, function, lost, feedback, names_function, locates))
    return out
