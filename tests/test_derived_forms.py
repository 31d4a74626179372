"""Derive, don't transcribe: a result derived in another form than the hints' (level 3) keeps
full marks, since the checks compare values and finite differences, never the form."""

import pytest

from student_variants import ALTERNATIVES_DERIVED, assert_loses_exactly, grade_variants

pytestmark = pytest.mark.slow

@pytest.fixture(scope="module")
def graded(tmp_path_factory):
    """Each variant on every check whose child loads the file it edits (``Variant.loaded_by``: the
    other checks never import it), one batch run per set of checks."""
    jobs = {name: variant.loaded_by for name, variant in ALTERNATIVES_DERIVED.items()}
    return grade_variants(tmp_path_factory.mktemp("derived"), jobs)


@pytest.mark.parametrize("name", sorted(ALTERNATIVES_DERIVED))
def test_a_correct_result_written_another_way_keeps_full_marks(graded, name):
    stdout, results = graded[name]
    assert results["tests"], stdout
    assert_loses_exactly(results, set(), stdout)
