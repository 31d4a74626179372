"""The marginal-covariance checks (chapter 8): the reference keeps full marks, the stubs score zero, each
known mistake costs its own checks only and names its cause, and the same covariances computed another
way keep full marks."""

import pytest

from autograder.checks import all_checks
from student_variants import (
    ALTERNATIVES_MARGINAL_COVARIANCES,
    BUGS_MARGINAL_COVARIANCES,
    SOLUTIONS,
    apply,
    assert_loses_exactly,
    grade_variants,
)

EXERCISES = ("marginal_covariances.marginal_covariances", "marginal_covariances.joint_marginal")


def test_the_reference_keeps_full_marks_and_the_stubs_score_zero(graded):
    _, results = graded["solutions"]
    assert len(results["tests"]) == 12 and all(t["score"] == t["max_score"] for t in results["tests"])
    _, results = graded["exercises"]
    assert results["tests"] and all(t["score"] == 0 and t["output"].startswith("TODO marginal_covariances.")
                                    for t in results["tests"])


@pytest.fixture(scope="module")
def graded(tmp_path_factory):
    """Every variant of this module, the reference and the stubs, graded in one batch run."""
    jobs = {name: BUGS_MARGINAL_COVARIANCES[name].loaded_by for name in BUGS_MARGINAL_COVARIANCES}
    jobs |= {name: ("marginal_covariances",) for name in ALTERNATIVES_MARGINAL_COVARIANCES}
    jobs |= {"solutions": ("marginal_covariances",), "exercises": ("marginal_covariances",)}
    return grade_variants(tmp_path_factory.mktemp("variants"), jobs)


@pytest.mark.parametrize("name", sorted(BUGS_MARGINAL_COVARIANCES))
def test_a_known_mistake_costs_its_own_checks_only(graded, name):
    variant = BUGS_MARGINAL_COVARIANCES[name]
    stdout, results = graded[name]
    assert_loses_exactly(results, variant.fails, stdout)
    feedback = " ".join(t["output"] for t in results["tests"] if t["name"] in variant.fails)
    assert variant.says in feedback, feedback


@pytest.mark.parametrize("name", sorted(ALTERNATIVES_MARGINAL_COVARIANCES))
def test_the_same_covariances_computed_another_way_keep_full_marks(graded, name):
    stdout, results = graded[name]
    assert_loses_exactly(results, set(), stdout)


def test_five_known_mistakes_and_they_name_real_checks():
    names = {c.name for c in all_checks() if c.exercise in EXERCISES}
    assert len(names) == 6
    assert len(BUGS_MARGINAL_COVARIANCES) >= 5
    for name, variant in {**BUGS_MARGINAL_COVARIANCES, **ALTERNATIVES_MARGINAL_COVARIANCES}.items():
        assert variant.fails <= names, name
        text = (SOLUTIONS / variant.file).read_text()
        assert apply(text, variant) != text, name
