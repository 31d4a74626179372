"""What a problem hands the loop at one point."""

from dataclasses import dataclass
from typing import Any

import numpy as np
import scipy.sparse as sp


@dataclass
class Linearization:
    """``H`` (n, n), ``b`` (n,), ``chi2`` at the point.

    ``H = J^T W J``, ``b = J^T W r``, ``chi2 = r^T W r``; the Gauss-Newton step solves
    ``H h = -b``. ``H`` is a dense array, or, with ``upper=True``, the upper triangle of
    H as a scipy CSC matrix whose diagonal entries sit at ``diagonal_positions`` of
    its ``data`` (found on demand when not given).
    """

    H: Any
    b: Any
    chi2: float
    upper: bool = False
    diagonal_positions: Any = None

    def diagonal(self):
        return np.asarray(self.H.diagonal())

    def matvec(self, v):
        """``H v`` (n,), also for upper-triangle storage."""
        if not self.upper:
            return self.H @ v
        return self.H @ v + self.H.T @ v - self.diagonal() * v

    def with_diagonal_added(self, d):
        """``H + diag(d)`` in the same storage (H itself when d is None)."""
        if d is None:
            return self.H
        if not self.upper:
            H = np.array(self.H, dtype=float)  # a copy
            H.flat[::H.shape[0] + 1] += d
            return H
        if self.diagonal_positions is None:
            return self.H + sp.diags(d, format="csc")
        H = self.H.copy()
        H.data[self.diagonal_positions] += d
        return H
