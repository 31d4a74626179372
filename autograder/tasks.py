"""Framework runs that a check asks the child to perform with the student's code.

A task is a function taking ``impl=`` (the loaded implementation) and returning a
dict of numbers or arrays. The parent calls the same function with ``solutions``
for the reference; the child calls it with the student's implementation (a call
target ``"@autograder.tasks:minimize_curve"``).
"""

import numpy as np


def minimize_curve(method, impl, problem_impl=None, num_points=100, seed=0):
    """``course.solvers.minimize`` on the default curve problem.

    The strategy comes from ``impl``; the model and normal equations from
    ``problem_impl`` (default ``impl``), so that a damping strategy can be run on the
    reference model.
    """
    from course.problems.curve import CurveProblem, generate
    from course.solvers import minimize

    data = generate(num_points=num_points, seed=seed)
    problem = CurveProblem(data, impl=impl if problem_impl is None else problem_impl)
    result = minimize(problem, method, impl=impl)
    return {
        "params": np.asarray(result.params, float),
        "final_chi2": float(result.final_chi2),
        "iterations": float(result.iterations),
        "accepted": float(sum(1 for record in result.trace[1:] if record.accepted)),
    }
