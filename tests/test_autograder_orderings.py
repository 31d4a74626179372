"""The orderings checks (chapter 8): the reference keeps full marks, the stubs score zero, each known
mistake costs its own checks only and names its cause, and the same game written another way (a boolean
adjacency matrix, the fill as a set difference, a heap or a plain scan for the minimum degree) keeps full
marks."""

import pytest

from autograder.checks import all_checks
from student_variants import (
    ALTERNATIVES_ORDERINGS,
    BUGS_ORDERINGS,
    SOLUTIONS,
    apply,
    assert_loses_exactly,
    grade_variants,
)


@pytest.fixture(scope="module")
def graded(tmp_path_factory):
    """Every variant of this module, the reference and the stubs, graded in one batch run."""
    jobs = {name: ("orderings",) for name in [*BUGS_ORDERINGS, *ALTERNATIVES_ORDERINGS, "solutions", "exercises"]}
    return grade_variants(tmp_path_factory.mktemp("variants"), jobs)


def test_the_reference_keeps_full_marks_and_the_stubs_score_zero(graded):
    _, results = graded["solutions"]
    assert len(results["tests"]) == 12 and all(t["score"] == t["max_score"] for t in results["tests"])
    _, results = graded["exercises"]
    assert results["tests"] and all(t["score"] == 0 and t["output"].startswith("TODO orderings.")
                                    for t in results["tests"])


@pytest.mark.parametrize("name", sorted(BUGS_ORDERINGS))
def test_a_known_mistake_costs_its_own_checks_only(graded, name):
    variant = BUGS_ORDERINGS[name]
    stdout, results = graded[name]
    assert_loses_exactly(results, variant.fails, stdout)
    feedback = " ".join(t["output"] for t in results["tests"] if t["name"] in variant.fails)
    assert variant.says in feedback, feedback


@pytest.mark.parametrize("name", sorted(ALTERNATIVES_ORDERINGS))
def test_the_same_game_written_another_way_keeps_full_marks(graded, name):
    stdout, results = graded[name]
    assert_loses_exactly(results, set(), stdout)


def test_five_known_mistakes_and_they_name_real_checks():
    names = {c.name for c in all_checks() if c.exercise.startswith("orderings.")}
    assert len(names) == 6
    assert len(BUGS_ORDERINGS) >= 5 and len(ALTERNATIVES_ORDERINGS) >= 2
    for name, variant in {**BUGS_ORDERINGS, **ALTERNATIVES_ORDERINGS}.items():
        assert variant.fails <= names, name
        text = (SOLUTIONS / variant.file).read_text()
        assert apply(text, variant) != text, name
