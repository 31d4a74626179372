"""The chapter-7 checks (jets, autodiff_factor, factor_linearisation): the reference keeps full marks,
the stubs score zero, each known mistake costs its own checks only and names its cause, and correct
code written another way keeps full marks."""

import pytest

from autograder.checks import all_checks
from student_variants import (
    ALTERNATIVES_FACTOR_GRAPH,
    BUGS_FACTOR_GRAPH,
    SOLUTIONS,
    apply,
    assert_loses_exactly,
    grade_variants,
)

MODULES = ("jets", "autodiff_factor", "factor_linearisation")


@pytest.fixture(scope="module")
def graded(tmp_path_factory):
    """Each variant on the checks that load the file it edits (``Variant.loaded_by``: each exercise is
    graded alone); the first mistake of each file, the reference and the stubs on every check of the
    chapter, so that a file's mistake is seen to cost nothing in the other two exercises."""
    first = {}
    for name, variant in BUGS_FACTOR_GRAPH.items():
        first.setdefault(variant.file, name)
    jobs = {name: MODULES if name in first.values() else variant.loaded_by
            for name, variant in {**BUGS_FACTOR_GRAPH, **ALTERNATIVES_FACTOR_GRAPH}.items()}
    jobs |= {"solutions": MODULES, "exercises": MODULES}
    return grade_variants(tmp_path_factory.mktemp("variants"), jobs)


def test_the_reference_keeps_full_marks_and_the_stubs_score_zero(graded):
    _, results = graded["solutions"]
    assert len(results["tests"]) == 34 and all(t["score"] == t["max_score"] for t in results["tests"])
    _, results = graded["exercises"]
    assert results["tests"] and all(t["score"] == 0 and "TODO" in t["output"] for t in results["tests"])


@pytest.mark.parametrize("name", sorted(BUGS_FACTOR_GRAPH))
def test_a_known_mistake_costs_its_own_checks_only(graded, name):
    variant = BUGS_FACTOR_GRAPH[name]
    stdout, results = graded[name]
    assert_loses_exactly(results, variant.fails, stdout)
    feedback = " ".join(t["output"] for t in results["tests"] if t["name"] in variant.fails)
    assert variant.says in feedback, feedback


@pytest.mark.parametrize("name", sorted(ALTERNATIVES_FACTOR_GRAPH))
def test_correct_code_written_another_way_keeps_full_marks(graded, name):
    stdout, results = graded[name]
    assert_loses_exactly(results, set(), stdout)


def test_five_known_mistakes_per_exercise_and_they_name_real_checks():
    names = {c.name for c in all_checks() if c.exercise.split(".")[0] in MODULES}
    for module in MODULES:
        assert sum(v.file == f"{module}.py" for v in BUGS_FACTOR_GRAPH.values()) >= 5, module
    for name, variant in {**BUGS_FACTOR_GRAPH, **ALTERNATIVES_FACTOR_GRAPH}.items():
        assert variant.fails <= names, name
        text = (SOLUTIONS / variant.file).read_text()
        assert apply(text, variant) != text, name
