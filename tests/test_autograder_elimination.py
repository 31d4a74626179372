"""The elimination checks (chapter 8): the reference keeps full marks, the stub scores zero, each known
mistake costs its checks only and names its cause, and the QR route (numpy's signs), a QR of A_x alone and
the Cholesky route written back by eigh keep full marks."""

import pytest

from autograder.checks import all_checks
from student_variants import (
    ALTERNATIVES_ELIMINATION,
    BUGS_ELIMINATION,
    SOLUTIONS,
    apply,
    assert_loses_exactly,
    grade_variants,
)


def test_the_reference_keeps_full_marks_and_the_stub_scores_zero(graded):
    _, results = graded["solutions"]
    assert len(results["tests"]) == 6 and all(t["score"] == t["max_score"] for t in results["tests"])
    _, results = graded["exercises"]
    assert results["tests"] and all(t["score"] == 0 and t["output"].startswith("TODO elimination.eliminate_variable")
                                    for t in results["tests"])


@pytest.fixture(scope="module")
def graded(tmp_path_factory):
    """Every variant of this module, the reference and the stubs, graded in one batch run."""
    jobs = {name: BUGS_ELIMINATION[name].loaded_by for name in BUGS_ELIMINATION}
    jobs |= {name: ("elimination",) for name in ALTERNATIVES_ELIMINATION}
    jobs |= {"solutions": ("elimination",), "exercises": ("elimination",)}
    return grade_variants(tmp_path_factory.mktemp("variants"), jobs)


@pytest.mark.parametrize("name", sorted(BUGS_ELIMINATION))
def test_a_known_mistake_costs_its_checks_only(graded, name):
    variant = BUGS_ELIMINATION[name]
    stdout, results = graded[name]
    assert_loses_exactly(results, variant.fails, stdout)
    feedback = " ".join(t["output"] for t in results["tests"] if t["name"] in variant.fails)
    assert variant.says in feedback, feedback


@pytest.mark.parametrize("name", sorted(ALTERNATIVES_ELIMINATION))
def test_the_same_split_computed_another_way_keeps_full_marks(graded, name):
    stdout, results = graded[name]
    assert_loses_exactly(results, set(), stdout)


def test_five_known_mistakes_and_they_name_real_checks():
    names = {c.name for c in all_checks() if c.exercise == "elimination.eliminate_variable"}
    assert len(names) == 3
    assert len(BUGS_ELIMINATION) >= 5 and len(ALTERNATIVES_ELIMINATION) >= 2
    for name, variant in {**BUGS_ELIMINATION, **ALTERNATIVES_ELIMINATION}.items():
        assert variant.fails <= names, name
        text = (SOLUTIONS / variant.file).read_text()
        assert apply(text, variant) != text, name
