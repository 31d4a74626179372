"""A 2D pose graph as a factor graph (chapter 7): one SE(2) variable per pose, one
``BETWEEN_SE2`` factor per edge with its information, the same fixed poses."""

import numpy as np

from course.factorgraph import BETWEEN_SE2, SE2, FactorGraph
from course.problems.posegraph.graph import PoseGraph


def as_factor_graph(graph: PoseGraph) -> FactorGraph:
    """The factor graph of ``graph``; variable ``k`` is pose ``k`` (key ``x<k>``)."""
    fg = FactorGraph(graph.name)
    for k, pose in enumerate(np.asarray(graph.poses, dtype=float)):
        fg.add_variable(f"x{k}", SE2, pose)
    for k in graph.fixed:
        fg.fix(f"x{int(k)}")
    fg.add_many(BETWEEN_SE2, np.stack([graph.edges_i, graph.edges_j], axis=1), graph.measurements,
                graph.information)
    return fg
