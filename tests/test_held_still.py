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
