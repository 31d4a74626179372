"""The initialisation checks (chapter 3b): the reference keeps full marks, the stubs score
zero, each known mistake costs its own check only and names its cause, and correct code
written another way keeps full marks."""

import pytest

from autograder.checks import all_checks
from student_variants import (
    ALTERNATIVES_INITIALISATION,
    BUGS_INITIALISATION,
    SOLUTIONS,
    apply,
    assert_loses_exactly,
    grade_variants,
)


def initialisation_checks():
    return [c for c in all_checks() if c.exercise.startswith("initialisation.")]


def test_the_reference_keeps_full_marks_and_the_stubs_score_zero(graded):
    _, results = graded["solutions"]
    assert results["tests"] and all(t["score"] == t["max_score"] for t in results["tests"])
    _, results = graded["exercises"]
    assert results["tests"] and all(t["score"] == 0 and t["output"].startswith("TODO initialisation.")
                                    for t in results["tests"])


@pytest.fixture(scope="module")
def graded(tmp_path_factory):
    """Every variant of this module, the reference and the stubs, graded in one batch run per set of
    checks."""
    jobs = {name: BUGS_INITIALISATION[name].loaded_by for name in BUGS_INITIALISATION}
    jobs |= {name: ("initialisation",) for name in ALTERNATIVES_INITIALISATION}
    jobs |= {"solutions": ("initialisation",), "exercises": ("initialisation",)}
    return grade_variants(tmp_path_factory.mktemp("variants"), jobs)


@pytest.mark.parametrize("name", sorted(BUGS_INITIALISATION))
def test_a_known_mistake_costs_its_own_check_only(graded, name):
    variant = BUGS_INITIALISATION[name]
    stdout, results = graded[name]
    assert_loses_exactly(results, variant.fails, stdout)
    feedback = " ".join(t["output"] for t in results["tests"] if t["name"] in variant.fails)
    assert variant.says in feedback, feedback


@pytest.mark.parametrize("name", sorted(ALTERNATIVES_INITIALISATION))
def test_correct_code_written_another_way_keeps_full_marks(graded, name):
    stdout, results = graded[name]
    assert_loses_exactly(results, set(), stdout)


def test_every_initialiser_has_five_known_mistakes_and_they_name_real_checks():
    names = {c.name for c in initialisation_checks()}
    for check in names:
        assert sum(check in v.fails for v in BUGS_INITIALISATION.values()) >= 5, check
    for name, variant in {**BUGS_INITIALISATION, **ALTERNATIVES_INITIALISATION}.items():
        assert variant.fails <= names, name
        text = (SOLUTIONS / variant.file).read_text()
        assert apply(text, variant) != text, name
