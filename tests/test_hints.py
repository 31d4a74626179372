"""The exercises' hints: three levels in each module's HINTS, printed by ``python -m autograder hint``,
and into the stubs' docstrings by ``release --hints N`` (0 by default, recorded in exercises/)."""

import json
import shutil

import pytest

from autograder import hints as hint_cli
from autograder.__main__ import main as autograder_main
from autograder.release import stubs as rel
from course.app.cli import main as course_main
from course.core.hints import HintError, insert_hints, read_hints, record_level, recorded_level
from course.core.impl import REPO_ROOT

#: the exercises whose derived results are hints (their docstrings say what to derive)
DERIVED = {
    "pose_graph_edge": ["edge_error_and_jacobians"],
    "pose_graph_assembly": ["assemble_normal_equations"],
    "ceres_edge_cost": ["SE2EdgeCost"],
    "curve_model": ["residuals_and_jacobian"],
    "gauss_newton": ["normal_equations"],
    "damping": ["GavinType1.gain_denominator", "GavinType2.gain_denominator", "GavinType3.gain_denominator"],
    "dogleg": ["cauchy_point", "dogleg_step"],
    "pose_graph_3d": ["edge_errors_and_jacobians"],
    "bundle_adjustment": ["reprojection_residuals_and_jacobians", "schur_solve"],
    "robust_kernels": ["huber", "cauchy", "tukey", "robust_information"],
    "marginalisation": ["marginalise"],
    "imu_preintegration": ["preintegrate", "imu_factor_residual"],
    "gnc": ["tls_weights", "gm_weights", "gnc"],
    "gauge": ["gauge_directions"],
    "chordal_3d": ["relaxed_rotations", "project_to_so3", "translations_given_rotations"],
    "initialisation": ["spanning_tree_poses", "chordal_rotations", "chordal_translations"],
    "parallel_assembly": ["chunk_bounds", "normal_equations_parallel"],
    "pose_graph_3d_assembly": ["SparseAssembler3D"],
    "pose_graph_fast": ["edge_errors_and_jacobians", "SparseAssembler"],
    "sparse_solve": ["dense_solve", "upper_triangle_csc", "SparseCholeskySolver"],
    "jets": ["Jet.__mul__", "Jet.__truediv__", "Jet.__pow__", "sqrt", "sin", "cos", "exp", "log", "arctan2", "matmul"],
    "autodiff_factor": ["tangent_jacobians"],
    "factor_linearisation": ["BlockSparseAssembler"],
    "elimination": ["eliminate_variable"],
    "orderings": ["symbolic_elimination", "minimum_degree_ordering"],
    "bayes_tree": ["bayes_tree", "clique_of"],
    "marginal_covariances": ["marginal_covariances", "joint_marginal"],
    "incremental_update": ["relinearised_keys", "affected_cliques", "orphan_parents", "wildfire_update"],
}


@pytest.mark.parametrize("module", sorted(DERIVED))
def test_every_derived_exercise_has_three_levels(module):
    found = read_hints((REPO_ROOT / "solutions" / f"{module}.py").read_text())
    assert sorted(found) == sorted(DERIVED[module])
    assert all(len(levels) == 3 for levels in found.values())


def test_the_default_stubs_do_not_print_the_results_and_level_3_does():
    default = rel.render(REPO_ROOT / "solutions")
    given = rel.render(REPO_ROOT / "solutions", hints=3)
    edge, edge_given = default["pose_graph_edge.py"], given["pose_graph_edge.py"]
    docstring = edge.split("HINTS = {")[0]
    assert "A_ij = [[" not in docstring and "B_ij = [[" not in docstring
    assert "A_ij = [[-R_ij^T R_i^T" in edge_given.split("HINTS = {")[0]
    assert "B_ij = [[ R_ij^T R_i^T" in edge_given.split("HINTS = {")[0]
    assert "y_hat_k (x_k^2, x_k, 1)" not in default["curve_model.py"].split("HINTS = {")[0]
    assert "y_hat_k (x_k^2, x_k, 1)" in given["curve_model.py"].split("HINTS = {")[0]
    assert "-R(w) [X]_x J_r(w)" not in default["bundle_adjustment.py"].split("HINTS = {")[0]
    assert "-J_r^-1(e_phi) R_j^T R_i" in given["pose_graph_3d.py"].split("HINTS = {")[0]
    assert "Hint 1 (the approach)" in given["dogleg.py"] and "Hint 1 (the approach)" not in default["dogleg.py"]
    for module, result in (("gnc.py", "sqrt(c2 mu (mu + 1) / s) - mu"), ("chordal_3d.py", "U diag(1, 1, d) V^T"),
                           ("initialisation.py", "inverse(dx, dy, da) = (-cos da dx - sin da dy"),
                           ("imu_preintegration.py", "r_v = R_i^T (v_j - v_i - g dT) - Delta v'")):
        assert result not in default[module].split("HINTS = {")[0], module
        assert result in given[module].split("HINTS = {")[0], module
    # level 1 prints the approach only
    first = rel.render(REPO_ROOT / "solutions", hints=1)["pose_graph_edge.py"].split("HINTS = {")[0]
    assert "Hint 1 (the approach)" in first and "Hint 2" not in first and "A_ij = [[" not in first


def test_the_hints_move_to_hints_json_and_the_stubs_still_compile():
    for level in range(4):
        files = rel.render(REPO_ROOT / "solutions", hints=level)
        shipped = json.loads(files["hints.json"])
        assert sorted(shipped) == sorted(DERIVED)
        for rel_path, text in files.items():
            if rel_path.endswith(".py"):
                compile(text, rel_path, "exec")
                assert "HINTS = {" not in text and "the derived results, in three levels" not in text, rel_path
                assert read_hints(text) == {}
                if rel_path[:-3] in DERIVED:
                    reference = read_hints((REPO_ROOT / "solutions" / rel_path).read_text())
                    assert shipped[rel_path[:-3]] == {owner: list(levels) for owner, levels in reference.items()}


def test_the_level_is_recorded_and_check_compares_with_it(tmp_path):
    repo = tmp_path / "repo"
    for name in ("solutions", "exercises"):
        shutil.copytree(REPO_ROOT / name, repo / name, ignore=shutil.ignore_patterns("__pycache__"))
    assert rel.hints_level(repo) == 0
    assert rel.release(check=True, root=repo) == []
    assert "pose_graph_edge.py" in rel.release(check=True, root=repo, hints=3)
    rel.release(root=repo, hints=3)
    assert rel.hints_level(repo) == 3
    assert rel.release(check=True, root=repo) == []  # the recorded level
    assert "A_ij = [[" in (repo / "exercises" / "pose_graph_edge.py").read_text().split("HINTS = {")[0]
    assert course_main(["release", "--root", str(repo), "--check", "--hints", "0"]) == 1
    assert course_main(["release", "--root", str(repo), "--hints", "0"]) == 0
    assert rel.hints_level(repo) == 0 and rel.release(check=True, root=repo) == []


def test_record_level_replaces_the_previous_record():
    text = record_level(record_level('"""Package."""\n', 2), 1)
    assert recorded_level(text) == 1 and text.count("HINTS_LEVEL") == 1


def test_insert_into_one_line_and_method_docstrings():
    source = '''
class A:
    def f(self):
        """One line."""
        return 1


def g():
    """Two
    lines.
    """


HINTS = {"A.f": ("first", "second", "third\\n    more"), "g": ("a", "b", "c")}
'''
    out = insert_hints(source, 3)
    compile(out, "x", "exec")
    namespace: dict = {}
    exec(out, namespace)
    assert namespace["A"].f.__doc__.startswith("One line.\n\n        Hint 1 (the approach): first")
    assert "Hint 3 (the result): third\n            more" in namespace["A"].f.__doc__
    assert "Hint 2 (the key identity): b" in namespace["g"].__doc__
    with pytest.raises(HintError, match="no docstring"):
        insert_hints(source.replace('"g": (', '"h": ('), 1)
    with pytest.raises(HintError, match="3 non-empty strings"):
        read_hints('HINTS = {"f": ("only one",)}')


@pytest.mark.parametrize("level", [1, 2, 3])
def test_cli_prints_each_level(level, capsys):
    assert autograder_main(["hint", "pose_graph_edge", str(level)]) == 0
    out = capsys.readouterr().out
    assert f"hint {level} of 3" in out and f"Hint {level} (" in out
    assert ("A_ij = [[-R_ij^T R_i^T" in out) == (level == 3)
    assert [f"Hint {other} (" in out for other in (1, 2, 3)].count(True) == 1


def test_cli_names_a_function_a_method_or_a_class(capsys):
    assert autograder_main(["hint", "GavinType3.gain_denominator", "3"]) == 0
    assert "h^T (lambda h - b)" in capsys.readouterr().out
    assert autograder_main(["hint", "damping.GavinType1"]) == 0
    out = capsys.readouterr().out
    assert "GavinType1.gain_denominator" in out and "GavinType2" not in out
    assert autograder_main(["hint", "cauchy_point"]) == 0
    assert "hint python -m autograder hint cauchy_point 2" not in capsys.readouterr().out
    assert autograder_main(["hint", "no_such_thing"]) == 2
    assert "exercises with hints" in capsys.readouterr().err


def test_the_hints_are_read_from_the_stubs_without_a_reference(tmp_path):
    shutil.copytree(REPO_ROOT / "exercises", tmp_path / "exercises", ignore=shutil.ignore_patterns("__pycache__"))
    text = hint_cli.text("residuals_and_jacobian", 3, root=tmp_path)
    assert "y_hat_k (x_k^2, x_k, 1)" in text


def test_no_result_of_a_hint_is_left_in_the_default_stubs():
    """Every line of every level-3 hint (beyond a few words) is absent from the default release's code
    and docstrings, and present in the release with --hints 3."""
    from course.core.hints import level_text

    default = rel.render(REPO_ROOT / "solutions")
    given = rel.render(REPO_ROOT / "solutions", hints=3)
    for name, text in default.items():
        if not name.endswith(".py"):
            continue
        body, body_given = text.split("\nHINTS = {")[0], given[name].split("\nHINTS = {")[0]
        for owner, levels in read_hints((REPO_ROOT / "solutions" / name).read_text()).items():
            for line in level_text(levels[2]).splitlines():
                words = line.strip().strip("`:").strip()
                if len(words) > 25:
                    assert words not in body, (name, owner, words)
                    assert words in body_given, (name, owner, words)
