"""The marginalisation checks (chapter 5): the reference keeps full marks, the stub scores
zero, each known mistake costs its own checks only and names its cause, and the same prior
computed another way keeps full marks."""

import pytest

from autograder.checks import all_checks
from student_variants import (
    ALTERNATIVES_MARGINALISATION,
    BUGS_MARGINALISATION,
    SOLUTIONS,
    apply,
    assert_loses_exactly,
    grade_variants,
)

FUNCTIONS = ("marginalisation.marginalise", "marginalisation.prior_residual", "marginalisation.prior_update")


def test_the_reference_keeps_full_marks_and_the_stub_scores_zero(graded):
    _, results = graded["solutions"]
    assert len(results["tests"]) == 14 and all(t["score"] == t["max_score"] for t in results["tests"])
    _, results = graded["exercises"]
    assert results["tests"] and all(t["score"] == 0 and t["output"].startswith("TODO marginalisation.")
                                    for t in results["tests"])


@pytest.fixture(scope="module")
def graded(tmp_path_factory):
    """Every variant of this module, the reference and the stubs, graded in one batch run per set of
    checks."""
    jobs = {name: BUGS_MARGINALISATION[name].loaded_by for name in BUGS_MARGINALISATION}
    jobs |= {name: ("marginalisation",) for name in ALTERNATIVES_MARGINALISATION}
    jobs |= {"solutions": ("marginalisation",), "exercises": ("marginalisation",)}
    return grade_variants(tmp_path_factory.mktemp("variants"), jobs)


@pytest.mark.parametrize("name", sorted(BUGS_MARGINALISATION))
def test_a_known_mistake_costs_its_own_checks_only(graded, name):
    variant = BUGS_MARGINALISATION[name]
    stdout, results = graded[name]
    assert_loses_exactly(results, variant.fails, stdout)
    feedback = " ".join(t["output"] for t in results["tests"] if t["name"] in variant.fails)
    assert variant.says in feedback, feedback


@pytest.mark.parametrize("name", sorted(ALTERNATIVES_MARGINALISATION))
def test_the_same_prior_computed_another_way_keeps_full_marks(graded, name):
    stdout, results = graded[name]
    assert_loses_exactly(results, set(), stdout)


def test_five_known_mistakes_per_function_and_they_name_real_checks():
    names = {c.name for c in all_checks() if c.exercise in FUNCTIONS}
    assert len(names) == 7
    for function in FUNCTIONS:
        assert sum(1 for v in BUGS_MARGINALISATION.values() if any(f.startswith(function) for f in v.fails)) >= 5
    for name, variant in {**BUGS_MARGINALISATION, **ALTERNATIVES_MARGINALISATION}.items():
        assert variant.fails <= names, name
        text = (SOLUTIONS / variant.file).read_text()
        assert apply(text, variant) != text, name
