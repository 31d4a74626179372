"""A 3D pose graph as a factor graph (chapter 7): one SE(3) variable per pose, one
``BETWEEN_SE3`` factor per edge with its information (our error's order: translation first), the
same fixed poses."""

import numpy as np

from course.factorgraph import BETWEEN_SE3, SE3, FactorGraph
from course.factorgraph.variables import se3_value
from course.problems.posegraph3d.graph import PoseGraph3D


def as_factor_graph(graph: PoseGraph3D) -> FactorGraph:
    """The factor graph of ``graph``; variable ``k`` is pose ``k`` (key ``x<k>``)."""
    fg = FactorGraph(graph.name)
    for k, value in enumerate(se3_value(graph.t, graph.R)):
        fg.add_variable(f"x{k}", SE3, value)
    for k in graph.fixed:
        fg.fix(f"x{int(k)}")
    fg.add_many(BETWEEN_SE3, np.stack([graph.edges_i, graph.edges_j], axis=1), se3_value(graph.t_z, graph.R_z),
                graph.information)
    return fg
