"""The bundle-adjustment checks (chapter 4): the reference keeps full marks, the stubs score
zero, and each known mistake costs its own checks only and names its cause."""

import pytest

from autograder.checks import all_checks
from student_variants import BUGS_BUNDLE_ADJUSTMENT, SOLUTIONS, apply, assert_loses_exactly, grade_variants


def test_the_reference_keeps_full_marks_and_the_stubs_score_zero(graded):
    _, results = graded["solutions"]
    assert results["tests"] and all(t["score"] == t["max_score"] for t in results["tests"])
    _, results = graded["exercises"]
    assert results["tests"] and all(t["score"] == 0 and t["output"].startswith("TODO bundle_adjustment.")
                                    for t in results["tests"])


@pytest.fixture(scope="module")
def graded(tmp_path_factory):
    """Every variant of this module, the reference and the stubs, graded in one batch run per set of
    checks."""
    jobs = {name: BUGS_BUNDLE_ADJUSTMENT[name].loaded_by for name in BUGS_BUNDLE_ADJUSTMENT}
    jobs |= {"solutions": ("bundle_adjustment",), "exercises": ("bundle_adjustment",)}
    return grade_variants(tmp_path_factory.mktemp("variants"), jobs)


@pytest.mark.parametrize("name", sorted(BUGS_BUNDLE_ADJUSTMENT))
def test_a_known_mistake_costs_its_own_checks_only(graded, name):
    variant = BUGS_BUNDLE_ADJUSTMENT[name]
    stdout, results = graded[name]
    assert_loses_exactly(results, variant.fails, stdout)
    feedback = " ".join(t["output"] for t in results["tests"] if t["name"] in variant.fails)
    assert variant.says in feedback, feedback


#: the factor of the chain rule each slip goes through, as the feedback names it
FACTOR_SAID = {
    "ba_projection_derivative_z_sign": "In it, d predicted / d P_z differs",
    "ba_no_distortion_derivative": "J_cam and J_point both go wrong through the factor they share",
    "ba_small_angle_rotation_jacobian": "is right; d P / d w (J_cam's rotation columns",
    "ba_point_jacobian_without_rotation": "is right; d P / d X = R(w) (J_point",
    "ba_focal_column_without_distortion": "is right; d predicted / d (f, k1, k2)",
}


@pytest.mark.parametrize("name", sorted(FACTOR_SAID))
def test_a_wrong_jacobian_names_the_factor_it_goes_wrong_through(graded, name):
    _, results = graded[name]
    said = [line for t in results["tests"] if "hidden" not in t["name"] for line in t["output"].splitlines()
            if line.startswith("Which factor:")]
    assert said and all(FACTOR_SAID[name] in line for line in said), said


def test_every_exercise_has_five_known_mistakes_and_they_name_real_checks():
    checks = [c for c in all_checks() if c.exercise.startswith("bundle_adjustment.")]
    for exercise in {c.exercise for c in checks}:
        names = {c.name for c in checks if c.exercise == exercise}
        assert sum(bool(v.fails & names) for v in BUGS_BUNDLE_ADJUSTMENT.values()) >= 5, exercise
    for name, variant in BUGS_BUNDLE_ADJUSTMENT.items():
        assert variant.fails <= {c.name for c in checks}, name
        text = (SOLUTIONS / variant.file).read_text()
        assert apply(text, variant) != text, name
