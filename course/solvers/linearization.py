"""What a problem hands the loop at one point."""

from dataclasses import dataclass
from typing import Any


@dataclass
class Linearization:
    """``H`` (n, n) dense array or scipy sparse matrix, ``b`` (n,), ``chi2`` at the point.

    ``H = J^T W J``, ``b = J^T W r``, ``chi2 = r^T W r``; the Gauss-Newton step solves
    ``H h = -b``.
    """

    H: Any
    b: Any
    chi2: float

    def diagonal(self):
        return self.H.diagonal()
