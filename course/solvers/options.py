"""Termination settings shared by the loops."""

from dataclasses import dataclass


@dataclass
class SolverOptions:
    """When to stop (Madsen, Nielsen and Tingleff 2004, eqs. 3.15-3.16 style).

    - ``gradient_tolerance``: ``max |b| <= gradient_tolerance`` (b = J^T W r).
    - ``step_tolerance``: ``|h| <= step_tolerance (|x| + step_tolerance)``.
    - ``cost_tolerance``: an accepted step with ``|dchi2| <= cost_tolerance chi2``.
    - ``max_iterations``: step attempts, accepted or rejected.

    The defaults are tight, so that different solvers reach the same minimum to
    1e-6 relative; Gavin's lm.m stops much earlier (eps_1 = eps_2 = 1e-3).
    """

    max_iterations: int = 100
    gradient_tolerance: float = 1e-10
    step_tolerance: float = 1e-10
    cost_tolerance: float = 1e-12
