"""Trajectory files: TUM text files and EuRoC ground-truth CSVs.

Formats (one pose a line; blank lines and lines starting with ``#`` are skipped)::

    TUM:    t x y z qx qy qz qw                  t in seconds, fields split on whitespace
    EuRoC:  t_ns, p.x, p.y, p.z, q.w, q.x, q.y, q.z[, more columns ...]
            t in integer nanoseconds, fields split on commas; the first 8 columns are read,
            every row has the first data row's number of columns

Both readers return a ``Trajectory``: ``timestamps`` (N,) in seconds, strictly increasing,
``positions`` (N, 3) and unit ``quaternions`` (N, 4) in the order (w, x, y, z) (Hamilton,
the rotation from the body frame to the world frame, ``p_world = R(q) p_body + position``).

EuRoC timestamps become seconds as ``float(t_ns) / 1e9``, the conversion evo uses (a double
holds about 16 digits: the 19-digit nanosecond stamps of 2014 keep about 0.2 microseconds,
far below any association tolerance). A quaternion whose norm differs from 1 by more than
``QUATERNION_NORM_TOL`` is an error; within it, it is normalised.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from course.core.errors import CourseError

#: a stored quaternion may differ from unit norm by this much (files carry 6 decimals)
QUATERNION_NORM_TOL = 1e-3
#: the columns a EuRoC ground-truth row starts with
EUROC_COLUMNS = ("timestamp [ns]", "p.x", "p.y", "p.z", "q.w", "q.x", "q.y", "q.z")
#: the fields of a TUM row
TUM_COLUMNS = ("t", "x", "y", "z", "qx", "qy", "qz", "qw")


class TrajectoryError(CourseError, ValueError):
    """A trajectory file that cannot be read; the message names the file, line and field."""


@dataclass(frozen=True)
class Trajectory:
    """Timed poses: ``timestamps`` (N,) s, ``positions`` (N, 3), ``quaternions`` (N, 4) as (w, x, y, z)."""

    timestamps: np.ndarray
    positions: np.ndarray
    quaternions: np.ndarray
    path: Path | None = field(default=None, compare=False)

    def __post_init__(self):
        n = len(self.timestamps)
        if self.timestamps.shape != (n,) or self.positions.shape != (n, 3) or self.quaternions.shape != (n, 4):
            raise ValueError(f"Trajectory: shapes {self.timestamps.shape}, {self.positions.shape}, "
                             f"{self.quaternions.shape}; expected (N,), (N, 3), (N, 4)")

    def __len__(self) -> int:
        return len(self.timestamps)

    @property
    def name(self) -> str:
        return str(self.path) if self.path is not None else "trajectory"

    def rotations(self) -> np.ndarray:
        """(N, 3, 3) rotation matrices of the unit quaternions."""
        return quaternion_to_rotation(self.quaternions)

    def subset(self, indices) -> Trajectory:
        """The poses at ``indices`` (an integer array), in that order."""
        idx = np.asarray(indices, dtype=int)
        return Trajectory(self.timestamps[idx], self.positions[idx], self.quaternions[idx], self.path)


def quaternion_to_rotation(q) -> np.ndarray:
    """Rotation matrices (N, 3, 3) of unit quaternions ``q`` (N, 4) = (w, x, y, z).

    ``R = I + 2 w [v]_x + 2 [v]_x^2`` with ``v = (x, y, z)``, written out entry by entry.
    """
    q = np.asarray(q, dtype=float)
    w, x, y, z = q[:, 0], q[:, 1], q[:, 2], q[:, 3]
    R = np.empty((len(q), 3, 3))
    R[:, 0, 0] = 1 - 2 * (y * y + z * z)
    R[:, 0, 1] = 2 * (x * y - w * z)
    R[:, 0, 2] = 2 * (x * z + w * y)
    R[:, 1, 0] = 2 * (x * y + w * z)
    R[:, 1, 1] = 1 - 2 * (x * x + z * z)
    R[:, 1, 2] = 2 * (y * z - w * x)
    R[:, 2, 0] = 2 * (x * z - w * y)
    R[:, 2, 1] = 2 * (y * z + w * x)
    R[:, 2, 2] = 1 - 2 * (x * x + y * y)
    return R


# ---------------------------------------------------------------------------------------
# Reading


def _lines(path: Path) -> Iterator[tuple[int, str]]:
    """(line number, text) of the lines that carry data (not blank, not ``#`` comments)."""
    try:
        text = path.read_text(encoding="utf-8-sig")  # a UTF-8 byte-order mark is dropped
    except FileNotFoundError:
        raise TrajectoryError(f"{path}: no such file") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise TrajectoryError(f"{path}: cannot read: {exc}") from None
    for lineno, line in enumerate(text.splitlines(), 1):
        stripped = line.strip()
        if stripped and not stripped.startswith("#"):
            yield lineno, stripped


def _number(token: str, path: Path, lineno: int, column: str) -> float:
    try:
        value = float(token)
    except ValueError:
        raise TrajectoryError(f"{path}:{lineno}: field {column}: {token!r} is not a number") from None
    if not math.isfinite(value):
        raise TrajectoryError(f"{path}:{lineno}: field {column}: {token!r} is not a finite number")
    return value


def _finish(path: Path, stamps: list, rows: list, quats: list, lines: list) -> Trajectory:
    """Check the order of the stamps and the quaternions' norms; build the Trajectory."""
    if not stamps:
        raise TrajectoryError(f"{path}: no poses (every line is blank or a # comment)")
    t = np.array(stamps, dtype=float)
    steps = np.diff(t)
    if np.any(steps <= 0):
        k = int(np.argmax(steps <= 0)) + 1
        raise TrajectoryError(f"{path}:{lines[k]}: field timestamp: {t[k]!r} s does not increase on line "
                              f"{lines[k - 1]} ({t[k - 1]!r} s); timestamps must be strictly increasing")
    q = np.array(quats, dtype=float)
    norms = np.linalg.norm(q, axis=1)
    bad = np.abs(norms - 1.0) > QUATERNION_NORM_TOL
    if np.any(bad):
        k = int(np.argmax(bad))
        raise TrajectoryError(f"{path}:{lines[k]}: field quaternion: norm {norms[k]:.6g} differs from 1 by more "
                              f"than {QUATERNION_NORM_TOL:g}")
    return Trajectory(t, np.array(rows, dtype=float).reshape(-1, 3), q / norms[:, None], path)


def read_tum(path) -> Trajectory:
    """A TUM trajectory file: ``t x y z qx qy qz qw`` a line (t in seconds)."""
    path = Path(path)
    stamps, positions, quats, lines = [], [], [], []
    for lineno, line in _lines(path):
        tokens = line.split()
        if len(tokens) != len(TUM_COLUMNS):
            raise TrajectoryError(f"{path}:{lineno}: {len(tokens)} fields, expected {len(TUM_COLUMNS)} "
                                  f"({' '.join(TUM_COLUMNS)}) in a TUM file")
        values = [_number(tok, path, lineno, col) for tok, col in zip(tokens, TUM_COLUMNS)]
        stamps.append(values[0])
        positions.append(values[1:4])
        quats.append([values[7], values[4], values[5], values[6]])  # (qx qy qz qw) -> (w x y z)
        lines.append(lineno)
    return _finish(path, stamps, positions, quats, lines)


def read_euroc_csv(path) -> Trajectory:
    """A EuRoC ground-truth CSV: ``t_ns, p.x, p.y, p.z, q.w, q.x, q.y, q.z, ...`` a line."""
    path = Path(path)
    stamps, positions, quats, lines = [], [], [], []
    width = None
    for lineno, line in _lines(path):
        tokens = [tok.strip() for tok in line.split(",")]
        if width is None:
            width = len(tokens)
            if width < len(EUROC_COLUMNS):
                raise TrajectoryError(f"{path}:{lineno}: {width} columns, expected at least {len(EUROC_COLUMNS)} "
                                      f"({', '.join(EUROC_COLUMNS)}) in a EuRoC CSV")
        elif len(tokens) != width:
            raise TrajectoryError(f"{path}:{lineno}: {len(tokens)} columns, expected {width} like the first row")
        try:
            nanoseconds = int(tokens[0])
        except ValueError:
            raise TrajectoryError(f"{path}:{lineno}: field {EUROC_COLUMNS[0]}: {tokens[0]!r} is not an integer "
                                  "number of nanoseconds") from None
        values = [_number(tok, path, lineno, col) for tok, col in zip(tokens[1:8], EUROC_COLUMNS[1:])]
        stamps.append(float(nanoseconds) / 1e9)
        positions.append(values[0:3])
        quats.append(values[3:7])
        lines.append(lineno)
    return _finish(path, stamps, positions, quats, lines)


def read_trajectory(path) -> Trajectory:
    """A TUM file or a EuRoC CSV: a ``.csv`` name, or a first data line with commas, is EuRoC."""
    path = Path(path)
    if path.suffix.lower() == ".csv":
        return read_euroc_csv(path)
    first = next(_lines(path), None)
    if first is not None and "," in first[1]:
        return read_euroc_csv(path)
    return read_tum(path)
