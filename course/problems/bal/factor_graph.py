"""A bundle-adjustment problem as a factor graph (chapter 7): one BAL camera and one point variable
each, one ``REPROJECTION_BAL`` factor per observation (unit information); the gauge left to the
damping, or fixed as chapter 4 fixes it (``fix_gauge``: the 7 camera parameters of
``course.problems.bal.problem.gauge_parameters``, held by ``FactorGraph.fix(key, dofs)``)."""

import numpy as np

from course.factorgraph import FactorGraph
from course.factorgraph.factors import REPROJECTION_BAL
from course.factorgraph.variables import BAL_CAMERA, Vector
from course.problems.bal.dataset import BALProblem
from course.problems.bal.problem import gauge_parameters


def as_factor_graph(problem: BALProblem, loss=None, fix_gauge: bool = False) -> FactorGraph:
    """The factor graph of ``problem``: cameras first (keys ``c<k>``), then points (``p<k>``); ``loss``
    None or a robust loss such as ``("huber", 2.0)`` on every observation (chapter 4's); ``fix_gauge``:
    hold camera 0's pose and one translation component of camera 1 (Gauss-Newton then works)."""
    fg = FactorGraph(problem.name or "bal")
    for k, camera in enumerate(np.asarray(problem.cameras, dtype=float)):
        fg.add_variable(f"c{k}", BAL_CAMERA, camera)
    point = Vector(3)
    for k, X in enumerate(np.asarray(problem.points, dtype=float)):
        fg.add_variable(f"p{k}", point, X)
    C = len(problem.cameras)
    keys = np.stack([problem.camera_index, C + np.asarray(problem.point_index)], axis=1)
    fg.add_many(REPROJECTION_BAL, keys, problem.observations, loss=loss)
    if fix_gauge:
        for k, held in enumerate(gauge_parameters(problem)):
            if held.any():
                fg.fix(f"c{k}", dofs=np.flatnonzero(held).tolist())
    return fg
