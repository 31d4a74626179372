"""Peer back ends: the same problem, from the same start, through other libraries.

``POSE_GRAPH_BACKENDS[name](graph, method, max_iterations=100, **options) -> RunResult``
for ``name`` in ``g2o``, ``ceres``, ``gtsam``; ``POSE_GRAPH_METHODS[name]`` lists the
methods. A back end's module (and its library) is imported on first call only.
"""

import importlib

POSE_GRAPH_METHODS = {
    "g2o": ("gauss-newton", "levenberg", "dogleg"),
    "ceres": ("levenberg-marquardt", "dogleg"),
    "gtsam": ("gauss-newton", "levenberg-marquardt", "dogleg"),
}


def _lazy(module: str):
    def solve(graph, method, max_iterations=100, **options):
        return importlib.import_module(f"course.backends.{module}").solve(
            graph, method, max_iterations, **options
        )

    solve.__name__ = solve.__qualname__ = f"{module}.solve"
    solve.__doc__ = f"``course.backends.{module}.solve``, imported on first call."
    return solve


POSE_GRAPH_BACKENDS = {
    "g2o": _lazy("g2o_posegraph"),
    "ceres": _lazy("ceres_posegraph"),
    "gtsam": _lazy("gtsam_posegraph"),
}
