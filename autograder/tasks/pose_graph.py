"""The whole minimizer on a pose graph with the student's pieces (``checks/pose_graph.py``,
and ``checks/dogleg.py`` with the dogleg method)."""

from autograder.tasks.common import run_summary


def _graph(graph: dict):
    from course.problems.posegraph.graph import PoseGraph

    return PoseGraph(graph["poses"], graph["edges_i"], graph["edges_j"], graph["measurements"],
                     graph["information"], fixed=graph["fixed"], name=graph.get("name", "graph"))


def minimize_pose_graph(graph, method, impl, problem_impl=None, vectorized=False):
    """``course.solver.minimize`` on a pose graph given as arrays.

    The problem (edge, assembly, sparse solve; ``vectorized=False``: the per-edge loop)
    comes from ``problem_impl`` (default ``impl``), the method's pieces from ``impl``.
    """
    from course.problems.posegraph.problem import PoseGraphProblem
    from course.solver import minimize

    problem = PoseGraphProblem(_graph(graph), impl=impl if problem_impl is None else problem_impl,
                               vectorized=vectorized)
    return run_summary(minimize(problem, method, impl=impl))
