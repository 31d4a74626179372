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
    raise NotImplementedError("TODO pose_graph_3d.edge_errors_and_jacobians: not implemented yet")


def retract(t, R, delta):
    """The poses moved by ``delta`` (N, 6), one ``(rho, phi)`` per pose: ``(t + R rho, R Exp(phi))``,
    shapes (N, 3) and (N, 3, 3)."""
    raise NotImplementedError("TODO pose_graph_3d.retract: not implemented yet")
