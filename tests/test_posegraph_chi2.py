"""course.problems.posegraph.chi2: the compiled pass and the numpy path give the framework's chi2."""

import numpy as np
import pytest
from conftest import kernel_path

from course.geometry import se2
from course.problems.posegraph.chi2 import chi2
from course.problems.posegraph.graph import PoseGraph


def _graph(seed=5, poses=30, edges=80):
    rng = np.random.default_rng(seed)
    x = np.column_stack([rng.normal(size=(poses, 2)) * 5.0, rng.uniform(-np.pi, np.pi, poses)])
    i, j = rng.integers(0, poses, edges), rng.integers(0, poses, edges)
    z = np.column_stack([rng.normal(size=(edges, 2)), rng.uniform(-np.pi, np.pi, edges)])
    z[0, 2] = x[j[0], 2] - x[i[0], 2] - np.pi  # a raw angle error of exactly -pi: wrapped to -pi, not +pi
    root = rng.normal(size=(edges, 3, 3))
    information = root @ root.transpose(0, 2, 1) + 0.1 * np.eye(3)  # full, symmetric positive definite
    return PoseGraph(x, i, j, z, information)


@pytest.fixture(params=["compiled", "numpy"])
def path(request, monkeypatch):
    kernel_path(request.param == "compiled", monkeypatch)
    return request.param


def test_chi2_is_the_weighted_sum_of_the_framework_errors(path):
    g = _graph()
    e = se2.edge_errors(g.poses, g.edges_i, g.edges_j, g.measurements)
    expected = sum(float(e[k] @ g.information[k] @ e[k]) for k in range(g.num_edges))
    assert chi2(g.poses, g.edges_i, g.edges_j, g.measurements, g.information) == pytest.approx(expected, rel=1e-13)
    assert g.chi2() == pytest.approx(expected, rel=1e-13)


def test_chi2_at_other_poses_and_with_no_edge(path):
    g = _graph()
    moved = g.poses + 0.3
    e = se2.edge_errors(moved, g.edges_i, g.edges_j, g.measurements)
    assert g.chi2(moved) == pytest.approx(se2.weighted_chi2(e, g.information), rel=1e-13)
    empty = PoseGraph(g.poses, np.zeros(0, int), np.zeros(0, int), np.zeros((0, 3)), np.zeros((0, 3, 3)))
    assert empty.chi2() == 0.0
