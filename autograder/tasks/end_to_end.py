"""The whole minimizer on the curve problem with the student's pieces (``checks/end_to_end.py``)."""

import numpy as np


def minimize_curve(method, impl, num_points=100, seed=0, cost_tolerance=None):
    """``course.solver.minimize`` on the curve problem (noise ``seed``), every piece from ``impl``;
    ``cost_tolerance`` replaces the solver's (1e-12), see :data:`autograder.checks.end_to_end.COST_TOLERANCE`."""
    from course.problems.curve.problem import CurveProblem, generate
    from course.solver import minimize
    from course.solver.options import SolverOptions

    problem = CurveProblem(generate(num_points=num_points, seed=seed), impl=impl)
    options = SolverOptions() if cost_tolerance is None else SolverOptions(cost_tolerance=float(cost_tolerance))
    result = minimize(problem, method, impl=impl, options=options)
    return {
        "params": np.asarray(result.params, float),
        "final_chi2": float(result.final_chi2),
        "iterations": float(result.iterations),
        "accepted": float(sum(1 for record in result.trace[1:] if record.accepted)),
    }
