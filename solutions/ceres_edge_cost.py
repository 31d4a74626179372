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
        # BEGIN SOLUTION
        zx, zy, zt = (float(v) for v in np.asarray(measurement, dtype=float).reshape(3))
        c, s = math.cos(zt), math.sin(zt)
        self._zt = zt
        self._c, self._s = c, s
        self._tz = (c * zx + s * zy, -s * zx + c * zy)  # R_ij^T t_ij
        self._u = tuple(float(v) for v in np.asarray(sqrt_information, dtype=float).reshape(9))
        # END SOLUTION

    def Evaluate(self, parameters, residuals, jacobians):  # noqa: N802 (the pyceres name)
        """Fill ``residuals[:] = U e`` and, where not None, ``jacobians[0][:] = (U A).ravel()``,
        ``jacobians[1][:] = (U B).ravel()``; ``parameters[0]``, ``parameters[1]`` are x_i, x_j (3,)."""
        # BEGIN SOLUTION
        xi, yi, ti = parameters[0].tolist()
        xj, yj, tj = parameters[1].tolist()
        dx, dy = xj - xi, yj - yi
        phi = ti + self._zt
        cp, sp = math.cos(phi), math.sin(phi)
        qx = cp * dx + sp * dy  # R(phi)^T d
        qy = -sp * dx + cp * dy
        e0 = qx - self._tz[0]
        e1 = qy - self._tz[1]
        e2 = _wrap(tj - ti - self._zt)
        u00, u01, u02, u10, u11, u12, u20, u21, u22 = self._u
        residuals[:] = (
            u00 * e0 + u01 * e1 + u02 * e2,
            u10 * e0 + u11 * e1 + u12 * e2,
            u20 * e0 + u21 * e1 + u22 * e2,
        )
        if jacobians is None:
            return True
        # de_t/dtheta_i = dR(phi)^T/dphi d = (qy, -qx)
        if jacobians[0] is not None:
            jacobians[0][:] = (
                -u00 * cp + u01 * sp, -u00 * sp - u01 * cp, u00 * qy - u01 * qx - u02,
                -u10 * cp + u11 * sp, -u10 * sp - u11 * cp, u10 * qy - u11 * qx - u12,
                -u20 * cp + u21 * sp, -u20 * sp - u21 * cp, u20 * qy - u21 * qx - u22,
            )
        if jacobians[1] is not None:
            jacobians[1][:] = (
                u00 * cp - u01 * sp, u00 * sp + u01 * cp, u02,
                u10 * cp - u11 * sp, u10 * sp + u11 * cp, u12,
                u20 * cp - u21 * sp, u20 * sp + u21 * cp, u22,
            )
        return True
        # END SOLUTION


#: the derived results, in three levels (``python -m autograder hint NAME LEVEL``; the release
#: prints levels 1..N into the docstrings with ``--hints N``, course.core.hints)
HINTS = {
    "SE2EdgeCost": (
        """Combine the two rotations first: ``R_ij^T R_i^T = R(theta_i + theta_ij)^T``, so e_t depends on
        theta_i through one angle. Then differentiate as in ``pose_graph_edge``.""",
        """With ``phi = theta_i + theta_ij`` and ``d = t_j - t_i``: ``e_t = R(phi)^T d - R_ij^T t_ij``, and
        ``d R(phi)^T / d phi = [[-sin phi, cos phi], [-cos phi, -sin phi]]``.""",
        """Writing ``Q = R(phi)^T`` and ``d = (dx, dy)``::

            de/dx_i = [[-Q, (-sin phi dx + cos phi dy, -cos phi dx - sin phi dy)^T], [0 0 -1]]
            de/dx_j = [[ Q, 0], [0 0 1]]""",
    ),
}
