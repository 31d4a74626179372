"""The minimizer (:mod:`course.solvers.trust_region`) and its strategies."""

from course.solvers.options import SolverOptions
from course.solvers.strategies import METHODS
from course.solvers.trust_region import Problem, StopReason, minimize

__all__ = ["METHODS", "Problem", "SolverOptions", "StopReason", "minimize"]
