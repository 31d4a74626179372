"""SE(3) for the 3D pose graphs (chapter 6), vectorized over poses and edges: the framework's
own error (to evaluate any solution, a peer's included), the retraction, composition, and
the Euler-angle convention of the ``.graph`` files.

A pose is ``T = (R, t)``, ``x_world = R x_body + t``; arrays of poses are ``t`` (N, 3) and
``R`` (N, 3, 3). A tangent vector is ``delta = (rho, phi)`` (6,): translation first, as in
g2o files. The error of an edge ``i -> j`` measuring ``Z = (R_z, t_z)`` (pose j seen from
pose i) is, with ``D = Z^-1 T_i^-1 T_j``::

    e = [D_t; Log(D_R)] = [R_z^T (R_i^T (t_j - t_i) - t_z); Log(R_z^T R_i^T R_j)]     (6,)

and the retraction is the right perturbation ``T (+) delta = T (Exp(phi), rho)``:
``R <- R Exp(phi)``, ``t <- t + R rho``.

How the peers' errors relate (see ``course.backends.posegraph3d``): g2o's ``EdgeSE3`` is
``[D_t; vec(q(D_R))]`` with ``vec(q) = sin(|phi|/2) phi/|phi|``, about half our rotation
part, so a g2o file's information is for that error and the readers convert it
(:data:`G2O_SCALE`); GTSAM's ``BetweenFactor<Pose3>`` is ``Logmap(D)`` in the order
(rotation, translation), whose translation part is ``V(phi)^-1 D_t``, equal to ours to first
order.
"""

import numpy as np

from course.geometry.so3 import exp_many, log_many

#: our error is ``G2O_SCALE * g2o's error`` to first order: an information matrix for g2o's
#: error becomes ours as ``Omega / outer(G2O_SCALE, G2O_SCALE)``
G2O_SCALE = np.array([1.0, 1.0, 1.0, 2.0, 2.0, 2.0])


def edge_errors(t, R, edges_i, edges_j, t_z, R_z) -> np.ndarray:
    """``e`` (M, 6) of every edge (the formula in the module docstring)."""
    Ri, Rj = R[edges_i], R[edges_j]
    RiT = Ri.transpose(0, 2, 1)
    RzT = np.asarray(R_z).transpose(0, 2, 1)
    d = np.einsum("mab,mb->ma", RiT, t[edges_j] - t[edges_i]) - t_z
    e = np.empty((len(edges_i), 6))
    e[:, :3] = np.einsum("mab,mb->ma", RzT, d)
    e[:, 3:] = log_many(np.matmul(RzT, np.matmul(RiT, Rj)))
    return e


def weighted_chi2(errors, information) -> float:
    """``sum_k e_k^T Omega_k e_k`` for errors (M, 6) and information (M, 6, 6)."""
    return float(np.vdot(errors, np.einsum("mij,mj->mi", information, errors)))  # twice as fast as one einsum


def retract(t, R, delta):
    """``(t + R rho, R Exp(phi))`` for delta (N, 6) = (rho, phi) per pose."""
    delta = np.asarray(delta, dtype=float).reshape(-1, 6)
    return t + np.einsum("nab,nb->na", R, delta[:, :3]), np.matmul(R, exp_many(delta[:, 3:]))


def between(t_a, R_a, t_b, R_b):
    """``T_a^-1 T_b``: ``(R_a^T (t_b - t_a), R_a^T R_b)``, vectorized."""
    RaT = np.swapaxes(R_a, -1, -2)
    return np.einsum("...ab,...b->...a", RaT, t_b - t_a), RaT @ R_b


def compose(t_a, R_a, t_b, R_b):
    """``T_a T_b``: ``(t_a + R_a t_b, R_a R_b)``, vectorized."""
    return t_a + np.einsum("...ab,...b->...a", R_a, t_b), R_a @ R_b


def euler_to_matrix(roll, pitch, yaw) -> np.ndarray:
    """``R = Rz(yaw) Ry(pitch) Rx(roll)`` (K, 3, 3), the convention of ``VERTEX3``/``EDGE3``
    lines (``x y z roll pitch yaw``)."""
    roll, pitch, yaw = (np.asarray(v, dtype=float).reshape(-1) for v in (roll, pitch, yaw))
    cr, sr, cp, sp, cy, sy = np.cos(roll), np.sin(roll), np.cos(pitch), np.sin(pitch), np.cos(yaw), np.sin(yaw)
    return np.stack([
        np.stack([cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr], -1),
        np.stack([sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr], -1),
        np.stack([-sp, cp * sr, cp * cr], -1),
    ], -2)

