"""The 2D pose graph's ``chi2 = sum_k e_k^T Omega_k e_k`` in one pass over the edges.

The same error as ``course.geometry.se2.edge_errors`` (``e = [R_ij^T (R_i^T (t_j - t_i) - t_ij);
wrap(wrap(theta_j - theta_i) - theta_ij)]``) and the same weighting as ``weighted_chi2``, summed edge by
edge by a numba kernel (:mod:`course.core.jit`) where it is compiled, else by those two numpy
functions. On fr079 (1217 edges) the numpy path costs 0.17 ms a call, nearly all of it per-call overhead
of a dozen array operations, the kernel 0.01 ms: the Gauss-Newton loop evaluates it at every trial.
The two paths sum in different orders: they agree to rounding (1e-15 relative), not bit for bit.
"""

import math

import numpy as np

from course.core import jit
from course.geometry import se2

#: the compiled functions (:func:`course.core.jit.kernels`), callees first
KERNELS = ("_wrap", "_chi2")


def chi2(poses, edges_i, edges_j, measurements, information) -> float:
    """``sum_k e_k^T Omega_k e_k`` for ``poses`` (N, 3), ``edges_i, edges_j`` (M,) int64,
    ``measurements`` (M, 3), ``information`` (M, 3, 3) (the graph's contiguous arrays)."""
    compiled = jit.kernels(globals(), KERNELS)
    if compiled is None:
        return se2.weighted_chi2(se2.edge_errors(poses, edges_i, edges_j, measurements), information)
    return float(compiled[-1](np.ascontiguousarray(poses, dtype=float), edges_i, edges_j, measurements,
                              information))


def prepare() -> None:
    """Compile the kernel (or load it from numba's cache) now, on a one-edge graph, rather than inside the
    first solve's clock: a problem calls it when it is made (a compiled peer pays no such cost)."""
    if jit.kernels(globals(), KERNELS) is not None:
        chi2(np.zeros((2, 3)), np.zeros(1, np.int64), np.ones(1, np.int64), np.zeros((1, 3)), np.zeros((1, 3, 3)))


def _wrap(angle):
    """``angle`` wrapped to [-pi, pi), as ``se2.wrap_angle``."""
    return (angle + math.pi) % (2.0 * math.pi) - math.pi


def _chi2(poses, edges_i, edges_j, measurements, information):
    total = 0.0
    for k in range(len(edges_i)):
        i, j = edges_i[k], edges_j[k]
        c, s = math.cos(poses[i, 2]), math.sin(poses[i, 2])
        dx, dy = poses[j, 0] - poses[i, 0], poses[j, 1] - poses[i, 1]
        rx = c * dx + s * dy - measurements[k, 0]
        ry = -s * dx + c * dy - measurements[k, 1]
        cz, sz = math.cos(measurements[k, 2]), math.sin(measurements[k, 2])
        e0, e1 = cz * rx + sz * ry, -sz * rx + cz * ry
        e2 = _wrap(_wrap(poses[j, 2] - poses[i, 2]) - measurements[k, 2])
        w = information[k]
        total += (e0 * (w[0, 0] * e0 + w[0, 1] * e1 + w[0, 2] * e2)
                  + e1 * (w[1, 0] * e0 + w[1, 1] * e1 + w[1, 2] * e2)
                  + e2 * (w[2, 0] * e0 + w[2, 1] * e1 + w[2, 2] * e2))
    return total
