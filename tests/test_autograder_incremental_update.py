"""The incremental update's checks (chapter 8): the reference keeps full marks, the stub scores zero, each known
mistake costs its own checks only and names its cause, and the same update computed another way keeps full
marks."""

import pytest

from autograder.checks import all_checks
from student_variants import (
    ALTERNATIVES_INCREMENTAL_UPDATE,
    BUGS_INCREMENTAL_UPDATE,
    SOLUTIONS,
    apply,
    assert_loses_exactly,
    grade_variants,
)


def test_the_reference_keeps_full_marks_and_the_stub_scores_zero(graded):
    _, results = graded["solutions"]
    assert len(results["tests"]) == 20 and all(t["score"] == t["max_score"] for t in results["tests"])
    _, results = graded["exercises"]
    assert results["tests"] and all(t["score"] == 0 and t["output"].startswith("TODO incremental_update.")
                                    for t in results["tests"])


@pytest.fixture(scope="module")
def graded(tmp_path_factory):
    """Every variant of this module, the reference and the stubs, graded in one batch run."""
    jobs = {name: BUGS_INCREMENTAL_UPDATE[name].loaded_by for name in BUGS_INCREMENTAL_UPDATE}
    jobs |= {name: ("incremental_update",) for name in ALTERNATIVES_INCREMENTAL_UPDATE}
    jobs |= {"solutions": ("incremental_update",), "exercises": ("incremental_update",)}
    return grade_variants(tmp_path_factory.mktemp("variants"), jobs)


@pytest.mark.parametrize("name", sorted(BUGS_INCREMENTAL_UPDATE))
def test_a_known_mistake_costs_its_own_checks_only(graded, name):
    variant = BUGS_INCREMENTAL_UPDATE[name]
    stdout, results = graded[name]
    assert_loses_exactly(results, variant.fails, stdout)
    feedback = " ".join(t["output"] for t in results["tests"] if t["name"] in variant.fails)
    assert variant.says in feedback, feedback


@pytest.mark.parametrize("name", sorted(ALTERNATIVES_INCREMENTAL_UPDATE))
def test_the_same_tree_built_another_way_keeps_full_marks(graded, name):
    stdout, results = graded[name]
    assert_loses_exactly(results, set(), stdout)


def test_six_known_mistakes_and_they_name_real_checks():
    names = {c.name for c in all_checks() if c.exercise.startswith("incremental_update.")}
    assert len(names) == 10
    assert len(BUGS_INCREMENTAL_UPDATE) >= 6 and len(ALTERNATIVES_INCREMENTAL_UPDATE) >= 3
    for name, variant in {**BUGS_INCREMENTAL_UPDATE, **ALTERNATIVES_INCREMENTAL_UPDATE}.items():
        assert variant.fails <= names, name
        text = (SOLUTIONS / variant.file).read_text()
        assert apply(text, variant) != text, name
