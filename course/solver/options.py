"""Termination settings and the dogleg's initial radius, validated."""

from dataclasses import dataclass

#: the benchmarks' time to solution, 2D and 3D (``course.app.benchmark``, ``course.app.benchmark_3d``): every
#: run stops at the first step that lowers chi2 by less than this, relative (g2o's gain threshold, our
#: ``cost_tolerance``)
TIME_TO_SOLUTION_STOP = 1e-10


@dataclass(frozen=True)
class SolverOptions:
    """When to stop (Madsen, Nielsen and Tingleff 2004, eqs. 3.15-3.16 style).

    - ``gradient_tolerance``: ``max |b| <= gradient_tolerance`` (b = J^T W r).
    - ``step_tolerance``: ``|h| <= step_tolerance (|x| + step_tolerance)`` (dogleg: the
      radius instead of the step).
    - ``cost_tolerance``: a step, accepted or rejected, with ``|dchi2| <= cost_tolerance chi2``.
    - ``max_iterations``: step attempts, accepted or rejected.
    - ``initial_radius``: the dogleg's first trust region (Ceres' and g2o's default 1e4).

    The defaults are tight, so that different solvers reach the same minimum to
    1e-6 relative; Gavin's lm.m stops much earlier (eps_1 = eps_2 = 1e-3).
    """

    max_iterations: int = 100
    gradient_tolerance: float = 1e-10
    step_tolerance: float = 1e-10
    cost_tolerance: float = 1e-12
    initial_radius: float = 1e4

    def __post_init__(self):
        if isinstance(self.max_iterations, bool) or not isinstance(self.max_iterations, int) \
                or self.max_iterations < 0:
            raise ValueError(f"SolverOptions.max_iterations must be an integer >= 0, got {self.max_iterations!r}")
        for name in ("gradient_tolerance", "step_tolerance", "cost_tolerance"):
            value = getattr(self, name)
            if not isinstance(value, (int, float)) or not value >= 0 or value == float("inf"):
                raise ValueError(f"SolverOptions.{name} must be a finite number >= 0, got {value!r}")
        if not isinstance(self.initial_radius, (int, float)) or not 0 < self.initial_radius < float("inf"):
            raise ValueError(f"SolverOptions.initial_radius must be a finite number > 0, got {self.initial_radius!r}")
