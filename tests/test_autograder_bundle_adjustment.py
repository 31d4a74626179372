"""The bundle-adjustment checks (chapter 4): the reference keeps full marks, the stubs score
zero, and each known mistake costs its own checks only and names its cause."""

import pytest

from autograder.checks import all_checks
from student_variants import (
    ALTERNATIVES_BUNDLE_ADJUSTMENT,
    BUGS_BUNDLE_ADJUSTMENT,
    SOLUTIONS,
    apply,
    assert_loses_exactly,
    grade_variants,
)
from student_variants.held_out import LOCATES


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
    jobs = {name: variant.loaded_by for name, variant in {**BUGS_BUNDLE_ADJUSTMENT,
                                                          **ALTERNATIVES_BUNDLE_ADJUSTMENT}.items()}
    jobs |= {"solutions": ("bundle_adjustment",), "exercises": ("bundle_adjustment",)}
    return grade_variants(tmp_path_factory.mktemp("variants"), jobs)


@pytest.mark.parametrize("name", sorted(BUGS_BUNDLE_ADJUSTMENT))
def test_a_known_mistake_costs_its_own_checks_only(graded, name):
    variant = BUGS_BUNDLE_ADJUSTMENT[name]
    stdout, results = graded[name]
    assert_loses_exactly(results, variant.fails, stdout)
    feedback = " ".join(t["output"] for t in results["tests"] if t["name"] in variant.fails)
    assert variant.says in feedback, feedback


@pytest.mark.parametrize("name", sorted(ALTERNATIVES_BUNDLE_ADJUSTMENT))
def test_correct_code_written_another_way_keeps_full_marks(graded, name):
    stdout, results = graded[name]
    assert_loses_exactly(results, set(), stdout)


#: the factor of the chain rule each slip goes through, as the feedback names it (the catalogued slips'
#: phrases are the held-out measure's)
FACTOR_SAID = {name: said for name, said in LOCATES.items() if name.startswith("ba_")} | {
    "ba_projection_derivative_z_sign": "In it, d predicted / d P_z differs"}


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
    for name, variant in {**BUGS_BUNDLE_ADJUSTMENT, **ALTERNATIVES_BUNDLE_ADJUSTMENT}.items():
        assert variant.fails <= {c.name for c in checks}, name
        text = (SOLUTIONS / variant.file).read_text()
        assert apply(text, variant) != text, name
