"""The in-memory 3D pose graph shared by readers, problems and back ends."""

from dataclasses import dataclass, field

import numpy as np

from course.core.trace import RepairedEdges
from course.geometry import se3


@dataclass
class PoseGraph3D(RepairedEdges):
    """A 3D pose graph (SE(3)); conventions in :mod:`course.geometry.se3`.

    Vertices are renumbered ``0..N-1`` in file order; ``ids`` keeps the file's ids.

    Attributes:
        t, R: (N, 3), (N, 3, 3) initial estimate (``x_world = R x_body + t``).
        edges_i, edges_j: (M,) int vertex indices; the measurement is ``T_i^-1 T_j``.
        t_z, R_z: (M, 3), (M, 3, 3) the measurements.
        information: (M, 6, 6) symmetric positive-definite, for our error ``[D_t; Log(D_R)]``
            (translation first).
        fixed: (K,) int vertices held fixed (at least the first pose).
        ids: (N,) int the file's vertex ids.
        name, source: short name; where it came from (path or generator).
        ground_truth: ``(t, R)`` of the true poses when known (synthetic graphs), else None.
        outliers: (M,) bool, the edges a generator replaced by wrong ones (else None).
        repaired: (M,) bool, the edges whose information the reader repaired (not positive
            definite in the file), all False by default.
        information_repair: how (``course.solver.information.MODES``: ``strict``, the
            default, repairs nothing).
    """

    t: np.ndarray
    R: np.ndarray
    edges_i: np.ndarray
    edges_j: np.ndarray
    t_z: np.ndarray
    R_z: np.ndarray
    information: np.ndarray
    fixed: np.ndarray = field(default_factory=lambda: np.array([0]))
    ids: np.ndarray | None = None
    name: str = "graph"
    source: str = ""
    ground_truth: tuple | None = None
    outliers: np.ndarray | None = None
    repaired: np.ndarray | None = None
    information_repair: str = "strict"

    def __post_init__(self):
        self.t = np.ascontiguousarray(self.t, dtype=float).reshape(-1, 3)
        self.R = np.ascontiguousarray(self.R, dtype=float).reshape(-1, 3, 3)
        self.edges_i = np.asarray(self.edges_i, dtype=np.int64)
        self.edges_j = np.asarray(self.edges_j, dtype=np.int64)
        self.t_z = np.ascontiguousarray(self.t_z, dtype=float).reshape(-1, 3)
        self.R_z = np.ascontiguousarray(self.R_z, dtype=float).reshape(-1, 3, 3)
        self.information = np.ascontiguousarray(self.information, dtype=float).reshape(-1, 6, 6)
        self.fixed = np.asarray(self.fixed, dtype=np.int64).reshape(-1)
        if self.ids is None:
            self.ids = np.arange(len(self.t))
        self.repaired = np.zeros(len(self.edges_i), dtype=bool) if self.repaired is None \
            else np.asarray(self.repaired, dtype=bool).reshape(-1)

    @property
    def num_poses(self) -> int:
        return len(self.t)

    @property
    def num_edges(self) -> int:
        return len(self.edges_i)

    def errors(self, t=None, R=None) -> np.ndarray:
        """Edge errors (M, 6) at ``(t, R)`` (default: the initial estimate)."""
        t, R = (self.t, self.R) if t is None else (t, R)
        return se3.edge_errors(t, R, self.edges_i, self.edges_j, self.t_z, self.R_z)

    def squared_errors(self, t=None, R=None) -> np.ndarray:
        """``s_k = e_k^T Omega_k e_k`` (M,) at ``(t, R)`` (default: the initial estimate)."""
        e = self.errors(t, R)
        return np.einsum("mi,mij,mj->m", e, self.information, e)

    def chi2(self, t=None, R=None) -> float:
        """``sum e^T Omega e`` at ``(t, R)`` (default: the initial estimate)."""
        return se3.weighted_chi2(self.errors(t, R), self.information)

    def with_poses(self, t, R) -> "PoseGraph3D":
        """A copy of this graph whose initial estimate is ``(t, R)``."""
        return PoseGraph3D(np.array(t), np.array(R), self.edges_i, self.edges_j, self.t_z, self.R_z,
                           self.information, self.fixed, self.ids, self.name, self.source, self.ground_truth,
                           self.outliers, self.repaired, self.information_repair)

    def with_edges(self, keep) -> "PoseGraph3D":
        """A copy with only the edges ``keep`` (a boolean mask (M,) or indices)."""
        keep = np.flatnonzero(keep) if np.asarray(keep).dtype == bool else np.asarray(keep)
        return PoseGraph3D(self.t, self.R, self.edges_i[keep], self.edges_j[keep], self.t_z[keep],
                           self.R_z[keep], self.information[keep], self.fixed, self.ids, self.name,
                           self.source, self.ground_truth, None if self.outliers is None else self.outliers[keep],
                           None if self.repaired is None else self.repaired[keep], self.information_repair)
