"""The gauge of bundle adjustment, seen in the spectrum of H (small problems: H is formed densely).

An unanchored BA's H has 7 eigenvalues that are zero up to rounding (the scene's rotation,
translation and scale, ``solutions/gauge.py``); ``BundleAdjustmentProblem(fix_gauge=True)``
holds 7 unknowns and leaves none.
"""

import numpy as np

from course.problems.bal import BlockLinearization, BundleAdjustmentProblem

#: an eigenvalue is "zero" below this, relative to the largest
ZERO = 1e-12


def dense_hessian(lin: BlockLinearization) -> np.ndarray:
    """H (9C + 3P, 9C + 3P) assembled from the blocks U, V and W of a linearization."""
    C, P = len(lin.U), len(lin.V)
    n = 9 * C + 3 * P
    H = np.zeros((n, n))
    for c in range(C):
        H[9 * c:9 * c + 9, 9 * c:9 * c + 9] = lin.U[c]
    for p in range(P):
        H[9 * C + 3 * p:9 * C + 3 * p + 3, 9 * C + 3 * p:9 * C + 3 * p + 3] = lin.V[p]
    for k, (c, p) in enumerate(zip(lin.camera_index, lin.point_index)):
        H[9 * c:9 * c + 9, 9 * C + 3 * p:9 * C + 3 * p + 3] += lin.W[k]
        H[9 * C + 3 * p:9 * C + 3 * p + 3, 9 * c:9 * c + 9] += lin.W[k].T
    return H


def spectrum(problem: BundleAdjustmentProblem, x=None) -> np.ndarray:
    """The eigenvalues of H at ``x`` (default: the start), ascending, over the largest."""
    lin = problem.linearize(problem.x0 if x is None else x)
    values = np.linalg.eigvalsh(dense_hessian(lin))
    return values / values[-1]


def gauge_count(problem: BundleAdjustmentProblem, x=None) -> int:
    """How many eigenvalues of H are zero (below ``ZERO`` relative to the largest)."""
    return int(np.sum(np.abs(spectrum(problem, x)) < ZERO))
