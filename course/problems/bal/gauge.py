"""The gauge of bundle adjustment, seen in the spectrum of H (small problems: H is formed densely).

An unanchored BA's H has 7 eigenvalues that are zero up to rounding (the scene's rotation,
translation and scale: the ``gauge`` exercise); ``BundleAdjustmentProblem(fix_gauge=True)``
holds 7 unknowns and leaves none.
"""

import numpy as np

from course.problems.bal.problem import BlockLinearization, BundleAdjustmentProblem

#: an eigenvalue is "zero" below this, relative to the largest
ZERO = 1e-12


def dense_hessian(lin: BlockLinearization) -> np.ndarray:
    """H (9C + 3P, 9C + 3P) assembled from the blocks U, V and W of a linearization."""
    C, P = len(lin.U), len(lin.V)
    n = 9 * C + 3 * P
    H = np.zeros((n, n))
    cam = 9 * np.arange(C)[:, None] + np.arange(9)  # (C, 9) rows of each camera
    pt = 9 * C + 3 * np.arange(P)[:, None] + np.arange(3)  # (P, 3) rows of each point
    H[cam[:, :, None], cam[:, None, :]] = lin.U
    H[pt[:, :, None], pt[:, None, :]] = lin.V
    rows, cols = cam[lin.camera_index][:, :, None], pt[lin.point_index][:, None, :]  # (K, 9, 1), (K, 1, 3)
    np.add.at(H, (rows, cols), lin.W)  # a (camera, point) pair may be observed twice
    np.add.at(H, (cols.transpose(0, 2, 1), rows.transpose(0, 2, 1)), lin.W.transpose(0, 2, 1))
    return H


def spectrum(problem: BundleAdjustmentProblem, x=None) -> np.ndarray:
    """The eigenvalues of H at ``x`` (default: the start), ascending, over the largest."""
    lin = problem.linearize(problem.x0 if x is None else x)
    values = np.linalg.eigvalsh(dense_hessian(lin))
    return values / values[-1]


def gauge_count(problem: BundleAdjustmentProblem, x=None) -> int:
    """How many eigenvalues of H are zero (below ``ZERO`` relative to the largest)."""
    return int(np.sum(np.abs(spectrum(problem, x)) < ZERO))
