"""The chapter-6 checks (the SE(3) edge, its Jacobians, the retraction, the 6x6-block
assembly): the reference keeps full marks, the stubs score zero, each known mistake costs its
own checks only and names its cause, and correct code written another way keeps full marks."""

import pytest

from autograder.checks import all_checks
from student_variants import (
    ALTERNATIVES_POSE_GRAPH_3D,
    ALTERNATIVES_POSE_GRAPH_3D_ASSEMBLY,
    BUGS_POSE_GRAPH_3D,
    BUGS_POSE_GRAPH_3D_ASSEMBLY,
    SOLUTIONS,
    apply,
    assert_loses_exactly,
    grade_variants,
)

BUGS = {**BUGS_POSE_GRAPH_3D, **BUGS_POSE_GRAPH_3D_ASSEMBLY}
ALTERNATIVES = {**ALTERNATIVES_POSE_GRAPH_3D, **ALTERNATIVES_POSE_GRAPH_3D_ASSEMBLY}
ONLY = ("pose_graph_3d", "pose_graph_3d_assembly")  # the edge's checks and the assembly's


@pytest.fixture(scope="module")
def graded(tmp_path_factory):
    jobs = {name: ONLY for name in [*BUGS, *ALTERNATIVES, "solutions", "exercises"]}
    return grade_variants(tmp_path_factory.mktemp("variants"), jobs)


def test_the_reference_keeps_full_marks_and_the_stubs_score_zero(graded):
    _, results = graded["solutions"]
    assert len(results["tests"]) == 10 and all(t["score"] == t["max_score"] for t in results["tests"])
    _, results = graded["exercises"]
    assert results["tests"] and all(t["score"] == 0 and t["output"].startswith("TODO pose_graph_3d")
                                    for t in results["tests"])


@pytest.mark.parametrize("name", sorted(BUGS))
def test_a_known_mistake_costs_its_own_checks_only(graded, name):
    variant = BUGS[name]
    stdout, results = graded[name]
    assert_loses_exactly(results, variant.fails, stdout)
    feedback = " ".join(t["output"] for t in results["tests"] if t["name"] in variant.fails)
    assert variant.says in feedback, feedback


@pytest.mark.parametrize("name", sorted(ALTERNATIVES))
def test_correct_code_written_another_way_keeps_full_marks(graded, name):
    stdout, results = graded[name]
    assert_loses_exactly(results, set(), stdout)


def test_a_wrong_jacobian_is_told_from_a_wrong_error(graded):
    """A Jacobian consistent with a wrong e says 'fix e first'; a wrong derivative says so and names its block."""
    _, results = graded["p3_error_negated"]
    text = " ".join(t["output"] for t in results["tests"] if t["name"].endswith("Jacobian B = de/d delta_j"))
    assert "agrees with central differences of your own e" in text and "fix e first" in text, text
    _, results = graded["p3_b_rotation_transposed"]
    text = " ".join(t["output"] for t in results["tests"] if t["name"].endswith("Jacobian B = de/d delta_j"))
    assert "the derivative is wrong" in text and "d e_phi / d phi (rotation rows, rotation columns)" in text, text
    assert "d e_t / d rho" not in text, text


def test_five_known_mistakes_each_and_they_name_real_checks():
    names = {c.name for c in all_checks() if c.exercise.startswith("pose_graph_3d")}
    assert len(names) == 5
    assert len(BUGS_POSE_GRAPH_3D) >= 5 and len(BUGS_POSE_GRAPH_3D_ASSEMBLY) >= 5
    for name, variant in {**BUGS, **ALTERNATIVES}.items():
        assert variant.fails <= names, name
        text = (SOLUTIONS / variant.file).read_text()
        assert apply(text, variant) != text, name
