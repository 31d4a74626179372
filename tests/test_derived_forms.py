"""Derive, don't transcribe: a result derived in another form than the hints' (level 3) keeps
full marks, since the checks compare values and finite differences, never the form."""

import pytest

from student_variants import ALTERNATIVES_DERIVED, assert_loses_exactly, grade_variants

pytestmark = pytest.mark.slow

#: the exercises these variants touch
ONLY = ("curve_model", "pose_graph_edge", "damping", "dogleg", "pose_graph_3d.edge_errors_and_jacobians",
        "bundle_adjustment.reprojection_residuals_and_jacobians", "robust_kernels.cauchy", "robust_kernels.tukey")


@pytest.fixture(scope="module")
def graded(tmp_path_factory):
    jobs = {name: ONLY for name in ALTERNATIVES_DERIVED}
    return grade_variants(tmp_path_factory.mktemp("derived"), jobs)


@pytest.mark.parametrize("name", sorted(ALTERNATIVES_DERIVED))
def test_a_correct_result_written_another_way_keeps_full_marks(graded, name):
    stdout, results = graded[name]
    assert results["tests"], stdout
    assert_loses_exactly(results, set(), stdout)
