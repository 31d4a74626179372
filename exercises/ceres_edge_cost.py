"""Chapter 2 exercise: the Ceres cost function of one SE(2) pose-graph edge.

Ceres calls ``Evaluate`` with the two poses and fills flat, row-major buffers in place:
``residuals`` (3,), and ``jacobians[k]`` (9,) for parameter block k unless it is None.
Return True on success. See ``pose_graph_edge`` for the error and its Jacobians.

Inputs at the edges of the contract (each is a check input):
- raw angle error theta_j - theta_i - theta_ij exactly pi: r uses e_theta = -pi
- information diagonal but anisotropic (U diagonal, unequal entries)
- U not triangular (a symmetric square root of Omega)

Allowed imports: numpy, scipy, pyceres.
"""

import math

import numpy as np
import pyceres


def _wrap(angle):
    """``angle`` (a float) wrapped to ``[-pi, pi)``; math, not numpy: Ceres calls this often."""
    return (angle + math.pi) % (2.0 * math.pi) - math.pi


class SE2EdgeCost(pyceres.CostFunction):
    """Whitened error of one pose-graph edge, for Ceres.

    Residual ``r = U e`` (3,) with parameter blocks ``x_i = (x, y, theta)`` and ``x_j``:

        e = [R_ij^T (R_i^T (t_j - t_i) - t_ij); wrap(theta_j - theta_i - theta_ij)]

    The Jacobians Ceres receives are ``U de/dx_i``, ``U de/dx_j`` (3x3, row-major): derive
    ``de/dx_i`` and ``de/dx_j`` in scalars (Ceres calls this often: no small numpy matrices), as in
    ``pose_graph_edge`` (``python -m autograder hint SE2EdgeCost``).

    Args:
        measurement: (3,) ``z_ij = (dx, dy, dtheta)``, pose j in the frame of pose i.
        sqrt_information: (3, 3) ``U`` with ``U^T U = Omega_ij`` (any square root works;
            the back end passes the upper Cholesky factor, the checks others too).
    """

    def __init__(self, measurement, sqrt_information):
        pyceres.CostFunction.__init__(self)  # without it pyceres segfaults
        self.set_num_residuals(3)
        self.set_parameter_block_sizes([3, 3])
        raise NotImplementedError("TODO ceres_edge_cost.SE2EdgeCost.__init__: not implemented yet")

    def Evaluate(self, parameters, residuals, jacobians):  # noqa: N802 (the pyceres name)
        """Fill ``residuals[:] = U e`` and, where not None, ``jacobians[0][:] = (U A).ravel()``,
        ``jacobians[1][:] = (U B).ravel()``; ``parameters[0]``, ``parameters[1]`` are x_i, x_j (3,)."""
        raise NotImplementedError("TODO ceres_edge_cost.SE2EdgeCost.Evaluate: not implemented yet")
