"""The in-memory 2D pose graph shared by readers, problems and back ends."""

from dataclasses import dataclass, field

import numpy as np

from course.core.trace import RepairedEdges
from course.geometry import se2 as geometry
from course.problems.posegraph.chi2 import chi2


@dataclass
class PoseGraph(RepairedEdges):
    """A 2D pose graph.

    Vertices are renumbered ``0..N-1`` in file order; ``ids`` keeps the file's ids.

    Attributes:
        poses: (N, 3) initial estimate ``(x, y, theta)``.
        edges_i, edges_j: (M,) int vertex indices; measurement is ``x_i^-1 o x_j``.
        measurements: (M, 3) ``(dx, dy, dtheta)``.
        information: (M, 3, 3) symmetric positive-definite information matrices.
        fixed: (K,) int indices of vertices held fixed (at least the first pose).
        ids: (N,) int the file's vertex ids.
        name: short name; source: where it came from (path or generator).
        ground_truth: (N, 3) true poses when known (synthetic graphs), else None.
        repaired: (M,) bool, the edges whose information the reader repaired (not positive
            definite in the file), all False by default.
        information_repair: how (``course.solver.information.MODES``: ``strict``, the
            default, repairs nothing).
    """

    poses: np.ndarray
    edges_i: np.ndarray
    edges_j: np.ndarray
    measurements: np.ndarray
    information: np.ndarray
    fixed: np.ndarray = field(default_factory=lambda: np.array([0]))
    ids: np.ndarray | None = None
    name: str = "graph"
    source: str = ""
    ground_truth: np.ndarray | None = None
    repaired: np.ndarray | None = None
    information_repair: str = "strict"

    def __post_init__(self):
        self.poses = np.ascontiguousarray(self.poses, dtype=float)
        self.edges_i = np.ascontiguousarray(self.edges_i, dtype=np.int64)
        self.edges_j = np.ascontiguousarray(self.edges_j, dtype=np.int64)
        self.measurements = np.ascontiguousarray(self.measurements, dtype=float)
        self.information = np.ascontiguousarray(self.information, dtype=float)
        self.fixed = np.asarray(self.fixed, dtype=np.int64).reshape(-1)
        if self.ids is None:
            self.ids = np.arange(len(self.poses))
        self.repaired = np.zeros(len(self.edges_i), dtype=bool) if self.repaired is None \
            else np.asarray(self.repaired, dtype=bool).reshape(-1)

    @property
    def num_poses(self) -> int:
        return len(self.poses)

    @property
    def num_edges(self) -> int:
        return len(self.edges_i)

    def errors(self, poses=None) -> np.ndarray:
        """Edge errors (M, 3) at ``poses`` (default: the initial estimate)."""
        poses = self.poses if poses is None else poses
        return geometry.edge_errors(poses, self.edges_i, self.edges_j, self.measurements)

    def chi2(self, poses=None) -> float:
        """``sum e^T Omega e`` at ``poses`` (default: the initial estimate), by
        :func:`course.problems.posegraph.chi2.chi2` (compiled where numba is)."""
        return chi2(self.poses if poses is None else poses, self.edges_i, self.edges_j, self.measurements,
                    self.information)

    def with_poses(self, poses) -> "PoseGraph":
        """A copy of this graph whose initial estimate is ``poses``."""
        return PoseGraph(
            poses.copy(), self.edges_i, self.edges_j, self.measurements, self.information,
            self.fixed, self.ids, self.name, self.source, self.ground_truth, self.repaired, self.information_repair,
        )
