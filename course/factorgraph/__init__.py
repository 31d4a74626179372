"""Chapter 7's engine: a factor graph whose factors get their Jacobians automatically.

Variables of several kinds (``variables``), factor types with one residual written once for arrays
and Jets (``factor_type``, ``factors``, ``jetmath``), a graph keyed by name (``graph``), Gaussian
noise (``noise``), a solution by key (``values``), the tangent conventions beside GTSAM's and
Ceres' (``conventions``) and the problem the one minimizer solves (``problem``), whose Jacobians come from
the implementation's ``jets`` and ``autodiff_factor`` (or central differences, ``numeric``) and whose
H and b from its ``factor_linearisation``.
"""

from course.factorgraph.factor_type import FactorType
from course.factorgraph.factors import BETWEEN_SE2, BETWEEN_SE3, PRIOR_SE2, PRIOR_SE3, RANGE_BEARING
from course.factorgraph.graph import FactorGraph, symbol
from course.factorgraph.problem import FactorGraphProblem
from course.factorgraph.values import Values
from course.factorgraph.variables import SE2, SE3, SO3, Pose3, Vector, se3_parts, se3_value

__all__ = ["BETWEEN_SE2", "BETWEEN_SE3", "PRIOR_SE2", "PRIOR_SE3", "RANGE_BEARING", "SE2", "SE3", "SO3",
           "FactorGraph", "FactorGraphProblem", "FactorType", "Pose3", "Values", "Vector", "se3_parts", "se3_value",
           "symbol"]
