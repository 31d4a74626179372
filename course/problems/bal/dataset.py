"""Bundle-adjustment problems in the BAL format ("Bundle Adjustment in the Large").

Format (Agarwal, Snavely, Seitz, Szeliski, ECCV 2010; grail.cs.washington.edu/projects/bal),
whitespace-separated, one record a line::

    num_cameras num_points num_observations
    camera_index point_index x y                     (num_observations lines)
    w_x w_y w_z t_x t_y t_z f k1 k2                  (9 values per camera, one a line)
    X Y Z                                            (3 values per point, one a line)

Projection (the BAL convention: the camera looks down -z)::

    P = R(w) X + t      (R(w) by Rodrigues' formula of the angle-axis vector w)
    p = -P[:2] / P[2]
    d = 1 + k1 |p|^2 + k2 |p|^4
    predicted = f d p,  residual = predicted - observed

A point is in front of the camera when ``P[2] < 0``. The BAL cost is
``0.5 * sum |residual|^2`` over all observations (the course's chi2 is twice that).

Named problems (``load_bal``): ``ladybug-49`` (the data folder), ``dubrovnik-3-7`` (the gtsam
wheel's ``Data/``), ``bal-synthetic:CAMS:POINTS[:seed]`` (the generator :func:`synthetic`),
or a file path; any of them with ``:front`` appended is the same problem without the points
that have an observation behind its camera at the start (:func:`in_front`): the problem every
back end solves as it is (Ceres, through pycolmap, deletes such points before it solves).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from course.core import jit
from course.core.data import locate, origin
from course.core.errors import DatasetError
from course.geometry.so3 import exp_many

#: names of a camera's 9 parameters, in file order
CAMERA_FIELDS = ("w_x", "w_y", "w_z", "t_x", "t_y", "t_z", "f", "k1", "k2")
POINT_FIELDS = ("X", "Y", "Z")
OBSERVATION_FIELDS = ("camera_index", "point_index", "x", "y")
HEADER_FIELDS = ("num_cameras", "num_points", "num_observations")


@dataclass
class BALProblem:
    """A bundle-adjustment problem.

    ``cameras`` (C, 9): angle-axis w (3), translation t (3), f, k1, k2; ``points`` (P, 3);
    ``camera_index``, ``point_index`` (K,) int64; ``observations`` (K, 2) in pixels
    (principal point at 0); ``ground_truth``: ``(cameras, points)`` for synthetic data.
    """

    cameras: np.ndarray
    points: np.ndarray
    camera_index: np.ndarray
    point_index: np.ndarray
    observations: np.ndarray
    name: str = ""
    source: str = ""
    ground_truth: tuple[np.ndarray, np.ndarray] | None = field(default=None, repr=False)

    @property
    def num_cameras(self) -> int:
        return len(self.cameras)

    @property
    def num_points(self) -> int:
        return len(self.points)

    @property
    def num_observations(self) -> int:
        return len(self.observations)

    def __repr__(self):
        return (f"BALProblem({self.name!r}: {self.num_cameras} cameras, {self.num_points} points, "
                f"{self.num_observations} observations)")


# ---------------------------------------------------------------------------------------
# Projection (the framework's own, for costs; the exercise module has the Jacobians)


def rotate(w, X):
    """``R(w) X`` for angle-axis vectors w (K, 3) and points X (K, 3), Rodrigues' formula.

    ``R v = v + a (w x v) + b w x (w x v)`` with ``a = sin(theta) / theta``,
    ``b = (1 - cos(theta)) / theta^2`` (their Taylor series below theta = 1e-4).
    """
    w, X = np.asarray(w, dtype=float), np.asarray(X, dtype=float)
    t2 = np.sum(w * w, axis=-1, keepdims=True)
    theta = np.sqrt(t2)
    small = theta < 1e-4
    safe = np.where(small, 1.0, theta)
    a = np.where(small, 1.0 - t2 / 6.0, np.sin(safe) / safe)
    b = np.where(small, 0.5 - t2 / 24.0, (1.0 - np.cos(safe)) / (safe * safe))
    wx = np.cross(w, X)
    return X + a * wx + b * np.cross(w, wx)


def camera_frame_points(cameras, points, camera_index, point_index):
    """``P = R(w) X + t`` (K, 3) for every observation: each camera's R once (C of them), then one
    batched product (Rodrigues per observation, :func:`rotate`, costs four times as much)."""
    cameras = np.asarray(cameras, dtype=float)
    R = exp_many(cameras[:, :3])
    return np.einsum("kij,kj->ki", R[camera_index], np.asarray(points, dtype=float)[point_index]) \
        + cameras[camera_index, 3:6]


def residuals(cameras, points, camera_index, point_index, observations):
    """``predicted - observed`` (K, 2) with the BAL projection (module docstring).

    Where numba is installed, one compiled loop over the observations (:mod:`course.core.jit`;
    ladybug-49: 0.3 against 3.1 ms, the cost of every trial step), else numpy; the same numbers
    to rounding."""
    compiled = jit.kernels(globals(), KERNELS)
    if compiled is not None and _fits(cameras, points, camera_index, point_index, observations):
        cameras = np.ascontiguousarray(cameras, dtype=float)
        return compiled[0](exp_many(cameras[:, :3]), cameras, np.ascontiguousarray(points, dtype=float),
                           np.ascontiguousarray(camera_index, dtype=np.int64),
                           np.ascontiguousarray(point_index, dtype=np.int64),
                           np.ascontiguousarray(observations, dtype=float))
    cam = np.asarray(cameras)[camera_index]
    P = camera_frame_points(cameras, points, camera_index, point_index)
    with np.errstate(divide="ignore", invalid="ignore"):
        p = -P[:, :2] / P[:, 2:3]
    n = np.sum(p * p, axis=1, keepdims=True)
    d = 1.0 + cam[:, 7:8] * n + cam[:, 8:9] * n * n
    return cam[:, 6:7] * d * p - observations


#: the compiled functions of this module (:func:`course.core.jit.kernels`)
KERNELS = ("_projected",)


def _fits(cameras, points, camera_index, point_index, observations) -> bool:
    """Whether the arrays have the shapes of a problem and every index is in range: the compiled
    loop does not check (numpy's path raises or broadcasts as numpy does)."""
    cameras, points, observations = np.shape(cameras), np.shape(points), np.shape(observations)
    ci, pi = np.asarray(camera_index), np.asarray(point_index)
    K = observations[0] if observations else -1
    if len(cameras) != 2 or cameras[1] != 9 or points[1:] != (3,) or observations != (K, 2) \
            or ci.shape != (K,) or pi.shape != (K,) or not np.issubdtype(ci.dtype, np.integer) \
            or not np.issubdtype(pi.dtype, np.integer):
        return False
    return K == 0 or (0 <= ci.min() and ci.max() < cameras[0] and 0 <= pi.min() and pi.max() < points[0])


def _projected(R, cameras, points, ci, pi, observations):
    """:func:`residuals` as a loop, given every camera's rotation matrix R (C, 3, 3); compiled."""
    r = np.empty((len(ci), 2))
    for k in range(len(ci)):
        c, q = ci[k], pi[k]
        x, y, z = points[q, 0], points[q, 1], points[q, 2]
        P0 = R[c, 0, 0] * x + R[c, 0, 1] * y + R[c, 0, 2] * z + cameras[c, 3]
        P1 = R[c, 1, 0] * x + R[c, 1, 1] * y + R[c, 1, 2] * z + cameras[c, 4]
        P2 = R[c, 2, 0] * x + R[c, 2, 1] * y + R[c, 2, 2] * z + cameras[c, 5]
        p0, p1 = -P0 / P2, -P1 / P2
        n = p0 * p0 + p1 * p1
        fd = cameras[c, 6] * (1.0 + cameras[c, 7] * n + cameras[c, 8] * n * n)
        r[k, 0] = fd * p0 - observations[k, 0]
        r[k, 1] = fd * p1 - observations[k, 1]
    return r


def cost(problem: BALProblem, cameras=None, points=None) -> float:
    """The BAL cost ``0.5 * sum |r|^2`` over all observations (at the problem's own cameras and
    points unless given)."""
    cameras = problem.cameras if cameras is None else cameras
    points = problem.points if points is None else points
    r = residuals(cameras, points, problem.camera_index, problem.point_index, problem.observations)
    return 0.5 * float(np.sum(r * r))


def behind_camera(problem: BALProblem, cameras=None, points=None) -> int:
    """How many observations have their point behind (or on the plane of) the camera, ``P_z >= 0``."""
    cameras = problem.cameras if cameras is None else cameras
    points = problem.points if points is None else points
    P = camera_frame_points(cameras, points, problem.camera_index, problem.point_index)
    return int(np.count_nonzero(P[:, 2] >= 0.0))


def in_front(problem: BALProblem) -> BALProblem:
    """``problem`` without the points that have an observation behind (or on the plane of) its
    camera at the start, ``P_z >= 0``, and without those points' observations; the points kept
    are renumbered in order. The name gains ``:front``; the source says how many went."""
    P = camera_frame_points(problem.cameras, problem.points, problem.camera_index, problem.point_index)
    dropped = np.unique(problem.point_index[P[:, 2] >= 0.0])
    keep_point = np.ones(problem.num_points, dtype=bool)
    keep_point[dropped] = False
    keep = keep_point[problem.point_index]
    renumber = np.cumsum(keep_point) - 1
    truth = problem.ground_truth
    return BALProblem(problem.cameras.copy(), problem.points[keep_point].copy(), problem.camera_index[keep].copy(),
                      renumber[problem.point_index[keep]].astype(np.int64), problem.observations[keep].copy(),
                      name=f"{problem.name}:front",
                      source=f"{problem.source}, without the {len(dropped)} points (and their "
                             f"{int(np.count_nonzero(~keep))} observations) with an observation behind a camera "
                             "at the start",
                      ground_truth=None if truth is None else (truth[0], truth[1][keep_point]))


# ---------------------------------------------------------------------------------------
# Reading and writing


def _field_of(token: int, C: int, P: int, K: int) -> str:
    """The name of token number ``token`` (0-based) of a BAL file with this header."""
    if token < 3:
        return HEADER_FIELDS[token]
    token -= 3
    if token < 4 * K:
        return f"observation {token // 4} field {OBSERVATION_FIELDS[token % 4]}"
    token -= 4 * K
    if token < 9 * C:
        return f"camera {token // 9} field {CAMERA_FIELDS[token % 9]}"
    token -= 9 * C
    if token < 3 * P:
        return f"point {token // 3} field {POINT_FIELDS[token % 3]}"
    return "an extra value after the last point"


def _line_of(text: str, token: int) -> int:
    """The 1-based line of token number ``token`` (error path only)."""
    seen = 0
    lineno = 0
    for lineno, line in enumerate(text.splitlines(), 1):
        seen += len(line.split())
        if seen > token:
            return lineno
    return lineno


def read_bal(path, name: str | None = None) -> BALProblem:
    """Read a BAL text file (module docstring).

    Raises ``DatasetError`` ``"<file>:<line>: <field>: <problem>"`` on a bad header, a value
    that is not a finite number, an index that is not an integer or out of range, a truncated
    file or extra values.
    """
    path = Path(path)
    if not path.is_file():
        raise DatasetError(f"{path}: {'is not a file' if path.exists() else 'does not exist'}")
    text = path.read_text(encoding="utf-8", errors="replace")
    first = text.split("\n", 1)[0].split()
    if len(first) != 3:
        raise DatasetError(f"{path}:1: header: expected 3 values ({' '.join(HEADER_FIELDS)}), got {len(first)}")
    header = []
    for fname, token in zip(HEADER_FIELDS, first):
        try:
            value = int(token)
        except ValueError:
            raise DatasetError(f"{path}:1: {fname}: not an integer: {token!r}") from None
        if value <= 0:
            raise DatasetError(f"{path}:1: {fname}: must be positive, got {value}")
        header.append(value)
    C, P, K = header
    tokens = text.split()
    expected = 3 + 4 * K + 9 * C + 3 * P
    try:
        values = np.array(tokens, dtype=float)
    except ValueError:
        values = None
    if values is None or not np.isfinite(values).all():
        for k, token in enumerate(tokens):
            try:
                ok = np.isfinite(float(token))
            except ValueError:
                ok = False
            if not ok:
                raise DatasetError(f"{path}:{_line_of(text, k)}: {_field_of(k, C, P, K)}: "
                                   f"not a finite number: {token!r}")
    assert values is not None
    if len(values) < expected:
        lines = text.count("\n") + (not text.endswith("\n"))
        raise DatasetError(f"{path}:{lines}: {_field_of(len(values), C, P, K)}: truncated file: "
                           f"the header promises {expected} values, the file ends after {len(values)}")
    if len(values) > expected:
        raise DatasetError(f"{path}:{_line_of(text, expected)}: {_field_of(expected, C, P, K)}: "
                           f"{len(values) - expected} values more than the header's {expected}")
    obs = values[3:3 + 4 * K].reshape(K, 4)
    for col, limit in ((0, C), (1, P)):
        index = obs[:, col]
        bad = np.flatnonzero((index != np.round(index)) | (index < 0) | (index >= limit))
        if len(bad):
            k = int(bad[0])
            token = 3 + 4 * k + col
            what = "not an integer" if index[k] != np.round(index[k]) else f"out of range [0, {limit})"
            raise DatasetError(f"{path}:{_line_of(text, token)}: {_field_of(token, C, P, K)}: {what}: "
                               f"{tokens[token]!r}")
    cameras = values[3 + 4 * K:3 + 4 * K + 9 * C].reshape(C, 9).copy()
    points = values[3 + 4 * K + 9 * C:].reshape(P, 3).copy()
    return BALProblem(cameras, points, obs[:, 0].astype(np.int64), obs[:, 1].astype(np.int64),
                      obs[:, 2:].copy(), name=name or path.stem, source=str(path))


def write_bal(problem: BALProblem, path) -> None:
    """Write ``problem`` in the BAL format at round-trip precision (``read_bal`` gives it back)."""
    lines = [f"{problem.num_cameras} {problem.num_points} {problem.num_observations}"]
    lines += [f"{c} {p} {x!r} {y!r}" for c, p, (x, y) in
              zip(problem.camera_index.tolist(), problem.point_index.tolist(), problem.observations.tolist())]
    lines += [repr(v) for v in problem.cameras.ravel().tolist()]
    lines += [repr(v) for v in problem.points.ravel().tolist()]
    Path(path).write_text("\n".join(lines) + "\n")


# ---------------------------------------------------------------------------------------
# Synthetic problems


def _look_at(center):
    """Angle-axis w and translation t of a BAL camera at ``center`` (3,) looking at the origin
    (its -z axis points at the origin, its y axis roughly along world z)."""
    from scipy.spatial.transform import Rotation

    z = center / np.linalg.norm(center)  # the camera looks down -z, so +z points away
    x = np.cross([0.0, 0.0, 1.0], z)
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    R = np.vstack([x, y, z])  # world -> camera
    return Rotation.from_matrix(R).as_rotvec(), -R @ center


def synthetic(num_cameras: int, num_points: int, seed: int = 0, noise: float = 1.0, outliers: float = 0.0, *,
              perturbation: float = 1.0) -> BALProblem:
    """A synthetic BAL problem with ground truth.

    Cameras on a circle of radius 10 (at heights within +-1) look at the origin; points fill a
    ball of radius 3 around it, so every point is in front of every camera. Each camera has
    f ~ U(450, 550), k1 ~ N(0, 0.02), k2 ~ N(0, 0.005). Point p is seen by camera ``p % C``
    and by 1 to 4 more cameras chosen at random (so every point has at least 2 observations
    and, with P >= C, every camera at least one). Observations are the true projections plus
    Gaussian noise of ``noise`` pixels; a fraction ``outliers`` of them is moved by a further
    N(0, 50^2) pixels. The start (``cameras``, ``points``) is the ground truth perturbed by
    ``perturbation`` times: 0.01 rad on each rotation component, 0.1 on translations and
    points, 1% on f (k1, k2 unchanged). Deterministic for given arguments.
    """
    if num_cameras < 2 or num_points < 1:
        raise ValueError(f"synthetic needs at least 2 cameras and 1 point, got {num_cameras}, {num_points}")
    if not 0.0 <= outliers <= 1.0 or noise < 0 or perturbation < 0:
        raise ValueError(f"synthetic: need 0 <= outliers <= 1, noise >= 0 and perturbation >= 0, "
                         f"got {outliers}, {noise}, {perturbation}")
    rng = np.random.default_rng(seed)
    C, P = num_cameras, num_points
    cameras = np.zeros((C, 9))
    for c in range(C):
        angle = 2.0 * np.pi * c / C
        center = np.array([10.0 * np.cos(angle), 10.0 * np.sin(angle), rng.uniform(-1.0, 1.0)])
        cameras[c, :3], cameras[c, 3:6] = _look_at(center)
    cameras[:, 6] = rng.uniform(450.0, 550.0, C)
    cameras[:, 7] = rng.normal(0.0, 0.02, C)
    cameras[:, 8] = rng.normal(0.0, 0.005, C)
    direction = rng.normal(size=(P, 3))
    direction /= np.linalg.norm(direction, axis=1, keepdims=True)
    points = direction * 3.0 * rng.uniform(0.0, 1.0, (P, 1)) ** (1.0 / 3.0)
    cam_index, pt_index = [], []
    for p in range(P):
        others = np.delete(np.arange(C), p % C)
        extra = rng.choice(others, size=min(len(others), int(rng.integers(1, 5))), replace=False)
        seen = np.sort(np.concatenate([[p % C], extra]))
        cam_index += seen.tolist()
        pt_index += [p] * len(seen)
    ci, pi = np.array(cam_index, dtype=np.int64), np.array(pt_index, dtype=np.int64)
    observations = residuals(cameras, points, ci, pi, np.zeros((len(ci), 2)))
    observations += noise * rng.normal(size=observations.shape)
    bad = rng.random(len(ci)) < outliers
    observations[bad] += rng.normal(0.0, 50.0, (int(bad.sum()), 2))
    start_cameras, start_points = cameras.copy(), points.copy()
    start_cameras[:, :3] += perturbation * rng.normal(0.0, 0.01, (C, 3))
    start_cameras[:, 3:6] += perturbation * rng.normal(0.0, 0.1, (C, 3))
    start_cameras[:, 6] *= 1.0 + perturbation * rng.normal(0.0, 0.01, C)
    start_points += perturbation * rng.normal(0.0, 0.1, (P, 3))
    args = f"{C}, {P}, seed={seed}, noise={noise}, outliers={outliers}, perturbation={perturbation}"
    return BALProblem(start_cameras, start_points, ci, pi, observations, name=f"bal-synthetic:{C}:{P}:{seed}",
                      source=f"course.problems.bal.dataset.synthetic({args})", ground_truth=(cameras, points))


# ---------------------------------------------------------------------------------------
# Named problems

#: name -> (folder: "data" or "gtsam", relative path, documented cameras, points, observations)
_NAMED = {
    "ladybug-49": ("data", "bal_ladybug/problem-49-7776-pre.txt", 49, 7776, 31843),
    "dubrovnik-3-7": ("gtsam", "dubrovnik-3-7-pre.txt", 3, 7, 19),
}


#: the suffix of a problem's variant without the points behind a camera at the start
FRONT = ":front"


def bal_names() -> list[str]:
    """The names ``load_bal`` knows (besides ``bal-synthetic:CAMS:POINTS[:seed]`` and paths)."""
    return list(_NAMED)


def _locate(name: str) -> Path:
    where, rel, *_ = _NAMED[name]
    return locate(f"BAL problem {name!r}", where, rel)


def catalogue() -> list[tuple[str, str, str, str]]:
    """The named problems and the generator: ``(name, size, where, reason missing or "")``."""
    rows = []
    for name, (where, rel, cams, points, obs) in _NAMED.items():
        try:
            _locate(name)
            reason = ""
        except DatasetError as e:
            reason = getattr(e, "short", str(e))
        rows.append((name, f"{cams} cameras, {points} points, {obs} obs", origin(where, rel), reason))
    rows.append(("bal-synthetic:C:P[:seed]", "C cameras, P points", "generator course.problems.bal.dataset.synthetic",
                 ""))
    rows.append(("NAME:front", "NAME without its points behind a camera at the start",
                 "course.problems.bal.dataset.in_front", ""))
    return rows


def load_bal(name: str) -> BALProblem:
    """A named BAL problem (``bal_names()``), ``bal-synthetic:CAMS:POINTS[:seed]`` or a file path;
    with ``:front`` appended, that problem :func:`in_front`."""
    if name.endswith(FRONT) and len(name) > len(FRONT):
        return in_front(load_bal(name[: -len(FRONT)]))
    if name in _NAMED:
        return read_bal(_locate(name), name=name)
    if name.startswith("bal-synthetic:"):
        parts = name.split(":")[1:]
        try:
            if not 2 <= len(parts) <= 3:
                raise ValueError
            numbers = [int(p) for p in parts]
        except ValueError:
            raise DatasetError(f"bad generator name {name!r}: use bal-synthetic:CAMS:POINTS or "
                               "bal-synthetic:CAMS:POINTS:seed") from None
        try:
            return synthetic(*numbers)
        except ValueError as exc:
            raise DatasetError(f"{name}: {exc}") from None
    if Path(name).is_file():
        return read_bal(name)
    known = ", ".join([*_NAMED, "bal-synthetic:CAMS:POINTS[:seed]"])
    raise DatasetError(f"unknown BAL problem {name!r} and no such file; known names: {known}")
