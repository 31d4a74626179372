"""The whole minimizer on a pose graph with the student's pieces (``checks/pose_graph.py``,
and ``checks/dogleg.py`` with the dogleg method)."""

from autograder.tasks.common import run_summary


def _graph(graph: dict):
    from course.problems.posegraph.graph import PoseGraph

    return PoseGraph(graph["poses"], graph["edges_i"], graph["edges_j"], graph["measurements"],
                     graph["information"], fixed=graph["fixed"], name=graph.get("name", "graph"))


def minimize_pose_graph(graph, method, impl, problem_impl=None, vectorized=False, cost_tolerance=None):
    """``course.solver.minimize`` on a pose graph given as arrays.

    The problem (edge, assembly, sparse solve; ``vectorized=False``: the per-edge loop)
    comes from ``problem_impl`` (default ``impl``), the method's pieces from ``impl``.
    ``cost_tolerance`` replaces the solver's (1e-12): a dogleg run stopped that late ends with a trial
    step whose decrease is rounding, so whether it is rejected, and the last poses to 1e-10, turn on
    rounding; stopped at 1e-9 it ends the same on every machine.
    """
    from course.problems.posegraph.problem import PoseGraphProblem
    from course.solver import minimize

    problem = PoseGraphProblem(_graph(graph), impl=impl if problem_impl is None else problem_impl,
                               vectorized=vectorized)
    from course.solver.options import SolverOptions

    options = SolverOptions() if cost_tolerance is None else SolverOptions(cost_tolerance=float(cost_tolerance))
    return run_summary(minimize(problem, method, impl=impl, options=options))
