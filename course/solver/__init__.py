"""The minimizer (:mod:`course.solver.minimizer`) and its strategies."""

from course.solver.minimizer import Problem, StopReason, minimize
from course.solver.options import SolverOptions
from course.solver.strategies import ALL_METHODS, METHODS

__all__ = ["ALL_METHODS", "METHODS", "Problem", "SolverOptions", "StopReason", "minimize"]
