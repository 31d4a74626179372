"""Minimizer loops. Each owns iteration, acceptance, termination and the trace."""

from course.solvers.options import SolverOptions
from course.solvers.levenberg_marquardt import METHODS, minimize

__all__ = ["METHODS", "SolverOptions", "minimize"]
