"""The gauge checks (chapter 4, going further): the reference keeps full marks, the stub
scores zero, each known mistake costs its own group's check only and names its cause, and
the same directions written another way keep full marks."""

import pytest

from autograder.checks import all_checks
from student_variants import (
    ALTERNATIVES_GAUGE,
    BUGS_GAUGE,
    SOLUTIONS,
    apply,
    assert_loses_exactly,
    grade_variants,
)


def test_the_reference_keeps_full_marks_and_the_stub_scores_zero(graded):
    _, results = graded["solutions"]
    assert len(results["tests"]) == 6 and all(t["score"] == t["max_score"] for t in results["tests"])
    _, results = graded["exercises"]
    assert results["tests"] and all(t["score"] == 0 and t["output"].startswith("TODO gauge.gauge_directions")
                                    for t in results["tests"])


@pytest.fixture(scope="module")
def graded(tmp_path_factory):
    """Every variant of this module, the reference and the stubs, graded in one batch run per set of
    checks."""
    jobs = {name: BUGS_GAUGE[name].loaded_by for name in BUGS_GAUGE}
    jobs |= {name: ("gauge",) for name in ALTERNATIVES_GAUGE}
    jobs |= {"solutions": ("gauge",), "exercises": ("gauge",)}
    return grade_variants(tmp_path_factory.mktemp("variants"), jobs)


@pytest.mark.parametrize("name", sorted(BUGS_GAUGE))
def test_a_known_mistake_costs_its_own_check_only(graded, name):
    variant = BUGS_GAUGE[name]
    stdout, results = graded[name]
    assert_loses_exactly(results, variant.fails, stdout)
    feedback = " ".join(t["output"] for t in results["tests"] if t["name"] in variant.fails)
    assert variant.says in feedback, feedback


@pytest.mark.parametrize("name", sorted(ALTERNATIVES_GAUGE))
def test_the_same_directions_written_another_way_keep_full_marks(graded, name):
    stdout, results = graded[name]
    assert_loses_exactly(results, set(), stdout)


def test_five_known_mistakes_and_they_name_real_checks():
    names = {c.name for c in all_checks() if c.exercise == "gauge.gauge_directions"}
    assert len(names) == 3
    assert len(BUGS_GAUGE) >= 5
    for name, variant in {**BUGS_GAUGE, **ALTERNATIVES_GAUGE}.items():
        assert variant.fails <= names, name
        text = (SOLUTIONS / variant.file).read_text()
        assert apply(text, variant) != text, name
