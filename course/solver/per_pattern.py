"""A sparse solver that follows the sparsity pattern of H.

The course's sparse Cholesky (chapter 2's ``SparseCholeskySolver``) analyses the pattern of H on
its first solve and only refactorizes on later ones: it assumes the pattern never changes. Where
a problem cannot promise that (H formed as ``J^T J``, whose product drops an entry that sums to
exactly zero), :class:`PerPattern` makes a new solver whenever the pattern of the upper triangle
differs from the last one's, and keeps the analysis while it does not.
"""

from collections.abc import Callable
from typing import Any

import numpy as np
import scipy.sparse as sp


class PerPattern:
    """``solve(H_upper, b) -> dx`` (``H dx = -b``) by ``make()``'s solver for the current pattern.

    ``analyses``: how many solvers were made (one per pattern met in a row).
    """

    def __init__(self, make: Callable[[], Any]):
        self._make = make
        self._solver: Any = None
        self._indptr: np.ndarray | None = None
        self._indices: np.ndarray | None = None
        self.analyses = 0

    def solve(self, H_upper, b):
        upper = sp.csc_matrix(H_upper)
        if not upper.has_sorted_indices:
            upper = upper.sorted_indices()
        if (self._solver is None or self._indptr is None or self._indices is None
                or not np.array_equal(upper.indptr, self._indptr) or not np.array_equal(upper.indices, self._indices)):
            self._solver, self.analyses = self._make(), self.analyses + 1
            self._indptr, self._indices = upper.indptr.copy(), upper.indices.copy()
        return self._solver.solve(upper, b)
