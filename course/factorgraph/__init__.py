"""Chapter 7's engine: a factor graph whose factors get their Jacobians automatically.

Variables of several kinds (``variables``), factor types with one residual written once for arrays,
Jets and JAX (``factor_type``; the library of them, ``factors``: prior and between on every kind,
range, bearing, position/GPS, pinhole, point-to-plane; the functions they use, ``jetmath``), a graph
keyed by name whose variables can be fixed whole or in part (``graph``), noise models (``noise``:
sigmas, covariance, robust), a solution by key (``values``), the tangent conventions beside GTSAM's and
Ceres' (``conventions``) and the problem the one minimizer solves (``problem``), whose Jacobians come from
the implementation's ``jets`` and ``autodiff_factor`` (or central differences, ``numeric``) and whose
H and b from its ``factor_linearisation``.
"""

from course.factorgraph.factor_type import FactorType
from course.factorgraph.factors import (
    BEARING_2D,
    BEARING_3D,
    BETWEEN_SE2,
    BETWEEN_SE3,
    BETWEEN_SO3,
    GPS,
    PINHOLE,
    POINT_TO_PLANE,
    POSITION_2D,
    PRIOR_SE2,
    PRIOR_SE3,
    PRIOR_SO3,
    RANGE_2D,
    RANGE_3D,
    RANGE_BEARING,
    between,
    prior,
)
from course.factorgraph.graph import FactorGraph, symbol
from course.factorgraph.problem import FactorGraphProblem
from course.factorgraph.values import Values
from course.factorgraph.variables import SE2, SE3, SO3, Pose3, Vector, se3_parts, se3_value

__all__ = ["BEARING_2D", "BEARING_3D", "BETWEEN_SE2", "BETWEEN_SE3", "BETWEEN_SO3", "GPS", "PINHOLE", "POINT_TO_PLANE",
           "POSITION_2D", "PRIOR_SE2", "PRIOR_SE3", "PRIOR_SO3", "RANGE_2D", "RANGE_3D", "RANGE_BEARING", "SE2", "SE3",
           "SO3", "FactorGraph", "FactorGraphProblem", "FactorType", "Pose3", "Values", "Vector", "between", "prior",
           "se3_parts", "se3_value", "symbol"]
