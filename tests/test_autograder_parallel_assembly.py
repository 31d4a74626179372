"""The parallel-assembly checks (chapter 4): the reference keeps full marks, the stubs score
zero, each known mistake costs its own checks only and names its cause, and correct but
different implementations (executor.map, another balanced chunking, another way to add the
partial sums) keep full marks."""

import pytest

from autograder.checks import all_checks
from student_variants import (
    ALTERNATIVES_PARALLEL_ASSEMBLY,
    BUGS_PARALLEL_ASSEMBLY,
    SOLUTIONS,
    apply,
    assert_loses_exactly,
    grade_variants,
)


def test_the_reference_keeps_full_marks_and_the_stubs_score_zero(graded):
    _, results = graded["solutions"]
    assert results["tests"] and all(t["score"] == t["max_score"] for t in results["tests"])
    _, results = graded["exercises"]
    assert results["tests"] and all(t["score"] == 0 and t["output"].startswith("TODO parallel_assembly.")
                                    for t in results["tests"])


@pytest.fixture(scope="module")
def graded(tmp_path_factory):
    """Every variant of this module, the reference and the stubs, graded in one batch run per set of
    checks."""
    jobs = {name: BUGS_PARALLEL_ASSEMBLY[name].loaded_by for name in BUGS_PARALLEL_ASSEMBLY}
    jobs |= {name: ALTERNATIVES_PARALLEL_ASSEMBLY[name].loaded_by for name in ALTERNATIVES_PARALLEL_ASSEMBLY}
    jobs |= {"solutions": ("parallel_assembly",), "exercises": ("parallel_assembly",)}
    return grade_variants(tmp_path_factory.mktemp("variants"), jobs)


@pytest.mark.parametrize("name", sorted(BUGS_PARALLEL_ASSEMBLY))
def test_a_known_mistake_costs_its_own_checks_only(graded, name):
    variant = BUGS_PARALLEL_ASSEMBLY[name]
    stdout, results = graded[name]
    assert_loses_exactly(results, variant.fails, stdout)
    feedback = " ".join(t["output"] for t in results["tests"] if t["name"] in variant.fails)
    assert variant.says in feedback, feedback


@pytest.mark.slow
@pytest.mark.parametrize("name", sorted(ALTERNATIVES_PARALLEL_ASSEMBLY))
def test_a_correct_alternative_keeps_full_marks(graded, name):
    stdout, results = graded[name]
    assert_loses_exactly(results, set(), stdout)


def test_every_exercise_has_known_mistakes_and_they_name_real_checks():
    checks = [c for c in all_checks() if c.exercise.startswith("parallel_assembly.")]
    assert {c.exercise for c in checks} == {"parallel_assembly.chunk_bounds",
                                            "parallel_assembly.normal_equations_parallel"}
    assembly = {c.name for c in checks if c.exercise == "parallel_assembly.normal_equations_parallel"}
    assert sum(bool(v.fails & assembly) for v in BUGS_PARALLEL_ASSEMBLY.values()) >= 5
    bounds = {c.name for c in checks if c.exercise == "parallel_assembly.chunk_bounds"}
    assert sum(bool(v.fails & bounds) for v in BUGS_PARALLEL_ASSEMBLY.values()) >= 2
    for name, variant in {**BUGS_PARALLEL_ASSEMBLY, **ALTERNATIVES_PARALLEL_ASSEMBLY}.items():
        assert variant.fails <= {c.name for c in checks}, name
        text = (SOLUTIONS / variant.file).read_text()
        assert apply(text, variant) != text, name
