"""An angle at the end of its range is judged by its properties: the edge errors' e_theta (pose_graph_edge,
ceres_edge_cost, pose_graph_fast) wrapped with ``arctan2(sin, cos)`` into (-pi, pi] gives +pi where the raw
angle error is exactly pi, the reference -pi: the same angle, with the same cost and Jacobians, keeps full
marks (``autograder.checks.common.same_angle``); no wrap, or a wrap off by 2 pi, still loses points."""

import numpy as np
import pytest

from autograder.checks.common import same_angle
from student_variants import ALTERNATIVES_WRAP, BUGS_CHAPTERS_2_3, BUGS_WRAP, assert_loses_exactly, grade_variants

pytestmark = pytest.mark.slow

#: the wraps that are wrong, already in the chapters' table
NO_WRAP = ("edge_no_angle_wrap", "fast_edges_angle_not_wrapped")
WRONG = {**BUGS_WRAP, **{name: BUGS_CHAPTERS_2_3[name] for name in NO_WRAP}}


@pytest.fixture(scope="module")
def graded(tmp_path_factory):
    jobs = {name: variant.loaded_by for name, variant in {**ALTERNATIVES_WRAP, **WRONG}.items()}
    return grade_variants(tmp_path_factory.mktemp("wraps"), jobs)


@pytest.mark.parametrize("name", sorted(ALTERNATIVES_WRAP))
def test_a_wrap_into_minus_pi_pi_closed_above_keeps_full_marks(graded, name):
    stdout, results = graded[name]
    assert results["tests"], stdout
    assert_loses_exactly(results, set(), stdout)


@pytest.mark.parametrize("name", sorted(WRONG))
def test_a_wrap_that_is_really_wrong_loses_its_checks(graded, name):
    variant = WRONG[name]
    stdout, results = graded[name]
    assert_loses_exactly(results, variant.fails, stdout)
    feedback = " ".join(t["output"] for t in results["tests"] if t["name"] in variant.fails)
    assert variant.says in feedback, feedback


def test_same_angle_is_the_range_closed_and_equality_modulo_2_pi():
    expected = np.full(6, -np.pi)
    actual = np.array([-np.pi, np.pi, np.pi - 4e-16, 3 * np.pi, -np.pi - 1e-9, np.nan])
    assert same_angle(actual, expected).tolist() == [True, True, True, False, False, False]
    assert same_angle(np.array([1.0, 1.0 + 2 * np.pi]), np.array([1.0, 1.0])).tolist() == [True, False]
