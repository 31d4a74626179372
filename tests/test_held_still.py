"""``check_held_still``: a fixed pose's rows and columns of H are the identity's, its entries of b zero."""

import numpy as np
import pytest
import scipy.sparse as sp

from course.core.errors import ContractError
from course.solver.held_still import check_held_still


def _system(n=9, held=(0, 1, 2)):
    rng = np.random.default_rng(0)
    A = rng.standard_normal((n, n))
    H = A @ A.T + n * np.eye(n)
    b = rng.standard_normal(n)
    H[list(held), :] = 0.0
    H[:, list(held)] = 0.0
    H[list(held), list(held)] = 1.0
    b[list(held)] = 0.0
    return H, b


@pytest.mark.parametrize("form", [np.asarray, lambda H: sp.csc_matrix(np.triu(H)), sp.csr_matrix])
def test_a_held_system_passes_in_every_form(form):
    H, b = _system()
    check_held_still(form(H), b, [0, 1, 2], "where", 3)
    check_held_still(form(H), b, [], "where", 3)


def test_each_slip_is_named():
    H, b = _system()
    wrong = H.copy()
    wrong[1, 5] = wrong[5, 1] = 0.5
    with pytest.raises(ContractError, match=r"where: pose 0 is fixed but not held still: H\[1, 5\] = 0.5 where 0"):
        check_held_still(wrong, b, [0, 1, 2], "where", 3)
    wrong = H.copy()
    wrong[2, 2] = 7.0
    with pytest.raises(ContractError, match=r"H\[2, 2\] = 7 where 1 is expected"):
        check_held_still(sp.csc_matrix(np.triu(wrong)), b, [0, 1, 2], "where", 3)
    missing = sp.csc_matrix(np.triu(H))
    missing = sp.csc_matrix(missing.multiply(np.abs(np.arange(9)[:, None] - np.arange(9)) > 0))
    with pytest.raises(ContractError, match=r"H\[0, 0\] = 0 where 1 is expected"):
        check_held_still(missing, b, [0, 1, 2], "where", 3)
    slipped = b.copy()
    slipped[1] = 1e-3
    with pytest.raises(ContractError, match=r"b\[1\] = 0.001 where 0 is expected.*3 gauge freedoms"):
        check_held_still(H, slipped, [0, 1, 2], "where", 3)


def test_a_fixed_pose_in_the_middle_and_duplicate_entries_are_read_as_summed():
    """The fixed rows and columns are read from the CSC arrays alone: a pose in the middle (its
    column's entries above the diagonal and its row's entries to the right), and an H whose
    entries are stored twice (summed, as the solver reads them), the caller's H left as it was."""
    H, b = _system(held=(3, 4, 5))
    check_held_still(sp.csc_matrix(np.triu(H)), b, [3, 4, 5], "where", 3)
    wrong = H.copy()
    wrong[4, 7] = wrong[7, 4] = 0.25  # in pose 1's row, right of the diagonal
    with pytest.raises(ContractError, match=r"pose 1 is fixed but not held still: H\[4, 7\] = 0.25"):
        check_held_still(sp.csc_matrix(np.triu(wrong)), b, [3, 4, 5], "where", 3)
    upper = sp.csc_matrix(np.triu(H))  # each entry stored twice, as two halves
    halves = sp.csc_matrix((np.repeat(upper.data / 2, 2), np.repeat(upper.indices, 2), 2 * upper.indptr),
                           shape=H.shape)
    assert not halves.has_canonical_format
    stored = halves.data.copy()
    check_held_still(halves, b, [3, 4, 5], "where", 3)
    np.testing.assert_array_equal(halves.data, stored)
