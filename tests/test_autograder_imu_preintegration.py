"""The IMU preintegration checks (chapter 5): the reference keeps full marks, the stub scores
zero, each known mistake costs its own checks only and names its cause, and the same
preintegration or residual written another way keeps full marks."""

import pytest

from autograder.checks import all_checks
from student_variants import (
    ALTERNATIVES_IMU_PREINTEGRATION,
    BUGS_IMU_PREINTEGRATION,
    SOLUTIONS,
    apply,
    assert_loses_exactly,
    grade_variants,
)

PRE, RES = "imu_preintegration.preintegrate", "imu_preintegration.imu_factor_residual"


def test_the_reference_keeps_full_marks_and_the_stub_scores_zero(graded):
    _, results = graded["solutions"]
    assert len(results["tests"]) == 16 and all(t["score"] == t["max_score"] for t in results["tests"])
    _, results = graded["exercises"]
    assert results["tests"] and all(t["score"] == 0 and t["output"].startswith("TODO imu_preintegration.")
                                    for t in results["tests"])


@pytest.fixture(scope="module")
def graded(tmp_path_factory):
    """Every variant of this module, the reference and the stubs, graded in one batch run per set of
    checks."""
    jobs = {name: BUGS_IMU_PREINTEGRATION[name].loaded_by for name in BUGS_IMU_PREINTEGRATION}
    jobs |= {name: ("imu_preintegration",) for name in ALTERNATIVES_IMU_PREINTEGRATION}
    jobs |= {"solutions": ("imu_preintegration",), "exercises": ("imu_preintegration",)}
    return grade_variants(tmp_path_factory.mktemp("variants"), jobs)


@pytest.mark.parametrize("name", sorted(BUGS_IMU_PREINTEGRATION))
def test_a_known_mistake_costs_its_own_checks_only(graded, name):
    variant = BUGS_IMU_PREINTEGRATION[name]
    stdout, results = graded[name]
    assert_loses_exactly(results, variant.fails, stdout)
    feedback = " ".join(t["output"] for t in results["tests"] if t["name"] in variant.fails)
    assert variant.says in feedback, feedback


@pytest.mark.parametrize("name", sorted(ALTERNATIVES_IMU_PREINTEGRATION))
def test_the_same_results_written_another_way_keep_full_marks(graded, name):
    stdout, results = graded[name]
    assert_loses_exactly(results, set(), stdout)


def test_five_known_mistakes_per_function_and_they_name_real_checks():
    names = {c.name for c in all_checks() if c.exercise in (PRE, RES)}
    assert len(names) == 8
    for exercise in (PRE, RES):
        mine = [v for v in BUGS_IMU_PREINTEGRATION.values() if any(f.startswith(exercise) for f in v.fails)]
        assert len(mine) >= 5, exercise
    for name, variant in {**BUGS_IMU_PREINTEGRATION, **ALTERNATIVES_IMU_PREINTEGRATION}.items():
        assert variant.fails <= names, name
        text = (SOLUTIONS / variant.file).read_text()
        assert apply(text, variant) != text, name
