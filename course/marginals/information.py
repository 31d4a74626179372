"""A problem's H at given values, as the upper triangle of a sparse matrix.

``H = J^T W J`` is the information of the least-squares problem at the values (``chi2 = r^T W r``): its
inverse is the covariance of the step ``h``, in the problem's tangent. The problems hand H over in
three storages (``course.solver.linearization``): the upper triangle (CSC), a dense array (the curve
fit, a small VIO window), or bundle adjustment's blocks ``U`` (C, 9, 9), ``V`` (P, 3, 3), ``W`` (K, 9, 3).
"""

import numpy as np
import scipy.sparse as sp

from course.solver.linearization import Linearization


def upper_of(lin: Linearization) -> sp.csc_matrix:
    """The upper triangle (n, n), CSC, of ``lin``'s H in whichever storage it holds it."""
    if lin.H is None and getattr(lin, "U", None) is not None:  # bundle adjustment's BlockLinearization
        return _from_blocks(*(getattr(lin, name) for name in ("U", "V", "W", "camera_index", "point_index")))
    if lin.upper:
        return sp.csc_matrix(sp.triu(lin.H))
    return sp.csc_matrix(np.triu(np.asarray(lin.H, dtype=float)))


def _from_blocks(U, V, W, camera_index, point_index) -> sp.csc_matrix:
    """``[[U, W], [W^T, V]]``'s upper triangle from bundle adjustment's blocks (the observations' ``W_k``
    of one camera and point summed)."""
    C, P = len(U), len(V)
    split = 9 * C
    rows, cols, data = [], [], []

    def add(first_rows, first_cols, blocks, a, b):
        rows.append((first_rows[:, None, None] + np.arange(a)[None, :, None] + np.zeros(b, dtype=np.int64)).ravel())
        cols.append((first_cols[:, None, None] + np.zeros((1, a, 1), dtype=np.int64) + np.arange(b)).ravel())
        data.append(np.asarray(blocks, dtype=float).ravel())

    add(9 * np.arange(C), 9 * np.arange(C), U, 9, 9)
    add(split + 3 * np.arange(P), split + 3 * np.arange(P), V, 3, 3)
    add(9 * np.asarray(camera_index), split + 3 * np.asarray(point_index), W, 9, 3)
    n = split + 3 * P
    H = sp.coo_matrix((np.concatenate(data), (np.concatenate(rows), np.concatenate(cols))), shape=(n, n))
    return sp.csc_matrix(sp.triu(H.tocsc()))
