"""Chapter 6 exercise: the SE(3) pose-graph edge, its Jacobians on the manifold, and the
retraction, vectorized over edges and poses.

A pose is ``T = (R, t)`` (``x_world = R x_body + t``); N poses are ``t`` (N, 3) and ``R``
(N, 3, 3); M edges ``i -> j`` measure ``Z = (R_z, t_z)``, pose j seen from pose i. With
``D = Z^-1 T_i^-1 T_j`` the error (translation first, as in g2o files) is::

    d   = R_i^T (t_j - t_i)
    e   = [R_z^T (d - t_z);  Log(R_z^T R_i^T R_j)]                       (M, 6)

A step ``delta = (rho, phi)`` (6,) moves a pose on the right::

    T (+) delta = (R Exp(phi), t + R rho)

and the Jacobians ``A = de/d delta_i`` and ``B = de/d delta_j`` (M, 6, 6) are taken in that
perturbation, at ``delta = 0``: derive them (``python -m autograder hint
pose_graph_3d.edge_errors_and_jacobians 1``, then 2 and 3). The grader compares values and
finite differences, so any correct form scores.
With ``D_R = R_z^T R_i^T R_j``, g2o's ``EdgeSE3`` error is ``[D_t; vec(q(D_R))]``, about
half our rotation part (``vec(q) = sin(theta/2) u``); GTSAM's ``BetweenFactor<Pose3>`` is
``Logmap(D)``, rotation first, whose translation part ``V(phi)^-1 D_t`` equals ours to
first order.

Given (``course.geometry``): ``so3.skew`` (K, 3) -> (K, 3, 3), ``so3.exp_many``,
``so3.log_many`` and ``so3.right_jacobian_inverse_many`` (``J_r^-1``, the inverse right Jacobian of
SO(3)), all vectorized over K.

Inputs at the edges of the contract (each is a check input):
- edge_errors_and_jacobians: one edge (M = 1)
- edge_errors_and_jacobians: a residual rotation exactly 0 (J_r^-1 at 0)
- edge_errors_and_jacobians: a residual rotation of 1e-9 rad (the small-angle branch)
- edge_errors_and_jacobians: a residual rotation within 1e-3 of pi (pi - 1e-4)
- edge_errors_and_jacobians: edges from the larger pose index to the smaller
- retract: one pose (N = 1)
- retract: a zero step
- retract: a rotation step of 1e-10 rad (the small-angle branch)

Allowed imports: numpy, scipy, course.geometry.so3.
"""

import numpy as np

from course.geometry.so3 import exp_many, log_many, right_jacobian_inverse_many, skew


def edge_errors_and_jacobians(t, R, edges_i, edges_j, t_z, R_z):
    """``e`` (M, 6), ``A = de/d delta_i`` (M, 6, 6), ``B = de/d delta_j`` (M, 6, 6) of all
    edges at once, no Python loop over edges (definitions in the module docstring)."""
    # BEGIN SOLUTION
    Ri, Rj = R[edges_i], R[edges_j]
    RiT, RzT = Ri.transpose(0, 2, 1), R_z.transpose(0, 2, 1)
    d = np.einsum("mab,mb->ma", RiT, t[edges_j] - t[edges_i])
    D_R = np.matmul(RzT, np.matmul(RiT, Rj))
    e = np.empty((len(edges_i), 6))
    e[:, :3] = np.einsum("mab,mb->ma", RzT, d - t_z)
    e[:, 3:] = log_many(D_R)
    Jr_inv = right_jacobian_inverse_many(e[:, 3:])
    A = np.zeros((len(edges_i), 6, 6))
    A[:, :3, :3] = -RzT
    A[:, :3, 3:] = np.matmul(RzT, skew(d))
    A[:, 3:, 3:] = -np.matmul(Jr_inv, np.matmul(Rj.transpose(0, 2, 1), Ri))
    B = np.zeros((len(edges_i), 6, 6))
    B[:, :3, :3] = D_R
    B[:, 3:, 3:] = Jr_inv
    return e, A, B
    # END SOLUTION


def retract(t, R, delta):
    """The poses moved by ``delta`` (N, 6), one ``(rho, phi)`` per pose: ``(t + R rho, R Exp(phi))``,
    shapes (N, 3) and (N, 3, 3)."""
    # BEGIN SOLUTION
    delta = np.asarray(delta, dtype=float).reshape(-1, 6)
    return t + np.einsum("nab,nb->na", R, delta[:, :3]), np.matmul(R, exp_many(delta[:, 3:]))
    # END SOLUTION


#: the derived results, in three levels (``python -m autograder hint NAME LEVEL``; the release
#: prints levels 1..N into the docstrings with ``--hints N``, course.core.hints)
HINTS = {
    "edge_errors_and_jacobians": (
        """Perturb one pose at a time: replace ``T_i`` by ``T_i (+) delta_i`` in ``d`` and in ``R_z^T R_i^T R_j``,
        keep the terms of first order in ``rho_i`` and ``phi_i`` (``Exp(phi) = I + [phi]x + ...``), and
        read off the blocks. The translation error is a vector; the rotation error is a ``Log``,
        so for it move the perturbation to the right of ``D_R`` and use the right Jacobian.""",
        """Three identities: ``[phi]x v = -[v]x phi``; ``R^T Exp(phi) R = Exp(R^T phi)`` (moving a
        perturbation through a rotation); ``Log(Exp(e) Exp(dphi)) = e + J_r^-1(e) dphi`` to first order.
        So ``D_R Exp(phi_j)`` gives ``J_r^-1(e_phi) phi_j``, and
        ``R_z^T Exp(-phi_i) R_i^T R_j = D_R Exp(-R_j^T R_i phi_i)``.""",
        """::

            A = de/d delta_i = [[-R_z^T,  R_z^T [d]x              ],
                                [ 0,      -J_r^-1(e_phi) R_j^T R_i  ]]             (M, 6, 6)
            B = de/d delta_j = [[ D_R,    0                        ],
                                [ 0,      J_r^-1(e_phi)             ]]             (M, 6, 6)

        with ``D_R = R_z^T R_i^T R_j`` and ``e_phi = e[3:]``.""",
    ),
}
