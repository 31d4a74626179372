"""The robust-kernel checks (chapter 4): the reference keeps full marks, the stubs score zero,
each known mistake costs its own checks only and names its cause, and correct code written
another way keeps full marks."""

import pytest

from autograder.checks import all_checks
from student_variants import (
    ALTERNATIVES_ROBUST_KERNELS,
    BUGS_ROBUST_KERNELS,
    SOLUTIONS,
    apply,
    assert_loses_exactly,
    grade_variants,
    losing,
)


def test_the_reference_keeps_full_marks_and_the_stubs_score_zero(graded):
    _, results = graded["solutions"]
    assert results["tests"] and all(t["score"] == t["max_score"] for t in results["tests"])
    _, results = graded["exercises"]
    assert results["tests"] and all(t["score"] == 0 and t["output"].startswith("TODO robust_kernels.")
                                    for t in results["tests"])


@pytest.fixture(scope="module")
def graded(tmp_path_factory):
    """Every variant of this module, the reference and the stubs, graded in one batch run per set of
    checks."""
    jobs = {name: BUGS_ROBUST_KERNELS[name].loaded_by for name in BUGS_ROBUST_KERNELS}
    jobs |= {name: ALTERNATIVES_ROBUST_KERNELS[name].loaded_by for name in ALTERNATIVES_ROBUST_KERNELS}
    jobs |= {"solutions": ("robust_kernels",), "exercises": ("robust_kernels",)}
    return grade_variants(tmp_path_factory.mktemp("variants"), jobs)


@pytest.mark.parametrize("name", sorted(BUGS_ROBUST_KERNELS))
def test_a_known_mistake_costs_its_own_checks_only(graded, name):
    variant = BUGS_ROBUST_KERNELS[name]
    stdout, results = graded[name]
    assert_loses_exactly(results, variant.fails, stdout)
    feedback = " ".join(t["output"] for t in results["tests"] if t["name"] in variant.fails)
    assert variant.says in feedback, feedback


@pytest.mark.parametrize("name", sorted(ALTERNATIVES_ROBUST_KERNELS))
def test_correct_code_written_another_way_keeps_full_marks(graded, name):
    stdout, results = graded[name]
    assert results["tests"] and not losing(results), stdout


def test_every_exercise_has_five_known_mistakes_and_they_name_real_checks():
    checks = [c for c in all_checks() if c.exercise.startswith("robust_kernels.")]
    assert {c.exercise for c in checks} == {"robust_kernels.huber", "robust_kernels.cauchy", "robust_kernels.tukey",
                                            "robust_kernels.robust_information"}
    for exercise in {c.exercise for c in checks}:
        names = {c.name for c in checks if c.exercise == exercise}
        assert sum(bool(v.fails & names) for v in BUGS_ROBUST_KERNELS.values()) >= 5, exercise
    for name, variant in {**BUGS_ROBUST_KERNELS, **ALTERNATIVES_ROBUST_KERNELS}.items():
        assert variant.fails <= {c.name for c in checks}, name
        text = (SOLUTIONS / variant.file).read_text()
        assert apply(text, variant) != text, name
