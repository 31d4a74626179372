"""The chapter-6 GNC checks: the reference keeps full marks, the stubs score zero, each known
mistake costs its own check only and names its cause, and correct code written another way keeps
full marks."""

import pytest

from autograder.checks import all_checks
from student_variants import (
    ALTERNATIVES_GNC,
    BUGS_GNC,
    SOLUTIONS,
    apply,
    assert_loses_exactly,
    grade_variants,
)


@pytest.fixture(scope="module")
def graded(tmp_path_factory):
    jobs = {name: ("gnc",) for name in [*BUGS_GNC, *ALTERNATIVES_GNC, "solutions", "exercises"]}
    return grade_variants(tmp_path_factory.mktemp("variants"), jobs)


def test_the_reference_keeps_full_marks_and_the_stubs_score_zero(graded):
    _, results = graded["solutions"]
    assert len(results["tests"]) == 6 and all(t["score"] == t["max_score"] for t in results["tests"])
    _, results = graded["exercises"]
    assert results["tests"] and all(t["score"] == 0 and t["output"].startswith("TODO gnc")
                                    for t in results["tests"])


@pytest.mark.parametrize("name", sorted(BUGS_GNC))
def test_a_known_mistake_costs_its_own_check_only(graded, name):
    variant = BUGS_GNC[name]
    stdout, results = graded[name]
    assert_loses_exactly(results, variant.fails, stdout)
    feedback = " ".join(t["output"] for t in results["tests"] if t["name"] in variant.fails)
    assert variant.says in feedback, feedback


@pytest.mark.parametrize("name", sorted(ALTERNATIVES_GNC))
def test_correct_code_written_another_way_keeps_full_marks(graded, name):
    stdout, results = graded[name]
    assert_loses_exactly(results, set(), stdout)


def test_five_known_mistakes_and_they_name_real_checks():
    names = {c.name for c in all_checks() if c.exercise.startswith("gnc")}
    assert len(names) == 3 and len(BUGS_GNC) >= 5
    for name, variant in {**BUGS_GNC, **ALTERNATIVES_GNC}.items():
        assert variant.fails <= names, name
        text = (SOLUTIONS / variant.file).read_text()
        assert apply(text, variant) != text, name
