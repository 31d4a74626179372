"""What the bundle-adjustment peers share: their result row and the BAL <-> rotation-matrix maps.

A peer of chapter 4 (``colmap_bal``, ``gtsam_bal``, ``scipy_bal``) returns a
:class:`BALRunResult`: a ``RunResult`` whose ``params`` is the state of
``course.problems.bal.problem`` (``x = concat(cameras.ravel(), points.ravel())``, (9C + 3P,)) and
whose ``initial_chi2`` / ``final_chi2`` are OUR chi2 ``sum |r|^2`` (twice the BAL cost, as
our minimizer reports it) over ALL observations, however the peer treats them. The peer's
own cost (``peer_initial_cost``, ``peer_final_cost``, ``peer_costs`` per iteration) is kept
beside it, in the peer's convention, which ``peer_cost`` names.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, fields

import numpy as np

from course.core.trace import RunResult
from course.problems.bal.dataset import BALProblem, behind_camera, cost

#: rotation by pi about x: BAL's camera looks down -z, COLMAP's and GTSAM's down +z
FLIP = np.diag([1.0, -1.0, -1.0])


def _number(value: float):
    """A JSON-ready float (NaN -> None)."""
    return float(value) if math.isfinite(value) else None


@dataclass
class BALRunResult(RunResult):
    """A bundle-adjustment run (see the module docstring for ``params`` and the chi2).

    ``initial_cost`` / ``final_cost``: our BAL cost ``0.5 sum |r|^2`` on all K observations
    (half the chi2). ``peer_initial_cost`` / ``peer_final_cost``: the peer's own cost as it
    reports it; ``peer_costs``: the peer's own cost of each ``trace`` record (same length;
    index 0 = the start). ``peer_cost`` says what the peer's cost covers. ``removed_points`` /
    ``removed_observations``: what the peer deleted before solving (pycolmap: the points
    with an observation behind the camera). ``behind_camera_start`` / ``behind_camera_final``:
    observations with their point behind (or on the plane of) the camera, at the start and
    at ``params`` (``course.problems.bal.dataset.behind_camera``).
    """

    initial_cost: float = float("nan")
    final_cost: float = float("nan")
    peer_initial_cost: float = float("nan")
    peer_final_cost: float = float("nan")
    peer_costs: list = field(default_factory=list)
    peer_cost: str = ""
    removed_points: int = 0
    removed_observations: int = 0
    behind_camera_start: int = 0
    behind_camera_final: int = 0

    @classmethod
    def from_run(cls, run: RunResult, problem: BALProblem, peer_cost: str = "") -> BALRunResult:
        """``run`` (e.g. our minimizer's, ``params`` the flat state) with the BAL fields filled in
        from our own cost: the peer's cost is ours there."""
        base = {f.name: getattr(run, f.name) for f in fields(RunResult)}
        out = cls(**base)
        if run.not_run:
            return out
        cameras, points = unpack(problem, run.params)
        out.initial_cost = out.peer_initial_cost = 0.5 * float(run.initial_chi2)
        out.final_cost = out.peer_final_cost = cost(problem, cameras, points)
        out.peer_costs = [0.5 * float(r.chi2) for r in run.trace]
        out.peer_cost = peer_cost
        out.behind_camera_start = behind_camera(problem)
        out.behind_camera_final = behind_camera(problem, cameras, points)
        return out

    def to_json(self, with_params: bool = True) -> dict:
        """``RunResult.to_json`` plus a ``"bal"`` entry with the fields above."""
        out = super().to_json(with_params)
        if not self.not_run:
            out["bal"] = {
                "initial_cost": _number(self.initial_cost),
                "final_cost": _number(self.final_cost),
                "peer_initial_cost": _number(self.peer_initial_cost),
                "peer_final_cost": _number(self.peer_final_cost),
                "peer_costs": [_number(c) for c in self.peer_costs],
                "peer_cost": self.peer_cost,
                "removed_points": int(self.removed_points),
                "removed_observations": int(self.removed_observations),
                "behind_camera_start": int(self.behind_camera_start),
                "behind_camera_final": int(self.behind_camera_final),
            }
        return out


def pack(cameras, points) -> np.ndarray:
    """The state ``x = concat(cameras.ravel(), points.ravel())`` (9C + 3P,)."""
    return np.concatenate([np.asarray(cameras, dtype=float).ravel(), np.asarray(points, dtype=float).ravel()])


def unpack(problem: BALProblem, x) -> tuple[np.ndarray, np.ndarray]:
    """``(cameras (C, 9), points (P, 3))`` of a state x of ``problem``."""
    x = np.asarray(x, dtype=float)
    split = 9 * problem.num_cameras
    if x.shape != (split + 3 * problem.num_points,):
        raise ValueError(f"a state of {problem.name or 'this problem'} has shape ({split + 3 * problem.num_points},), "
                         f"got {x.shape}")
    return x[:split].reshape(-1, 9), x[split:].reshape(-1, 3)


def rotation_matrices(w) -> np.ndarray:
    """``R(w)`` (C, 3, 3) of angle-axis vectors w (C, 3), Rodrigues' formula (scipy's)."""
    from scipy.spatial.transform import Rotation

    return Rotation.from_rotvec(np.asarray(w, dtype=float).reshape(-1, 3)).as_matrix().reshape(-1, 3, 3)


def angle_axis(R, near=None) -> np.ndarray:
    """The angle-axis vectors w (C, 3) of rotation matrices R (C, 3, 3).

    Angles in [0, pi] (scipy's), unless ``near`` (C, 3) is given: then, of the vectors of the
    same rotation ``w + 2 pi k w / |w|`` (k = -1, 0, 1), the one nearest to ``near`` (a peer's
    solution then stays on the BAL start's branch, e.g. a start with |w| > pi).
    """
    from scipy.spatial.transform import Rotation

    w = Rotation.from_matrix(np.asarray(R, dtype=float).reshape(-1, 3, 3)).as_rotvec().reshape(-1, 3)
    if near is None:
        return w
    angle = np.linalg.norm(w, axis=1, keepdims=True)
    axis = w / np.where(angle > 0.0, angle, 1.0)
    candidates = np.stack([w + 2.0 * np.pi * k * axis for k in (-1, 0, 1)])  # (3, C, 3)
    best = np.argmin(np.linalg.norm(candidates - np.asarray(near, dtype=float)[None], axis=2), axis=0)
    return candidates[best, np.arange(len(w))]


def check_method(method: str, methods: tuple, peer: str) -> None:
    if method not in methods:
        raise ValueError(f"{peer}: unknown method {method!r} for bundle adjustment; choose one of {methods}")
    return None


def check_max_iterations(max_iterations) -> int:
    if isinstance(max_iterations, bool) or int(max_iterations) != max_iterations or max_iterations < 1:
        raise ValueError(f"max_iterations must be an integer >= 1, got {max_iterations!r}")
    return int(max_iterations)
