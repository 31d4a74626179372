"""Absolute pose error (APE) of an estimated 3D trajectory against a reference.

Three steps, as evo (``evo_ape``) does them:

1. **Association** (``associate``): pair the poses by timestamp. The trajectory with fewer
   poses (the estimate when both have as many) is walked in order; each of its stamps ``s``
   is paired with the nearest stamp ``u`` of the other, if ``|s - u| <= max_diff``
   (default 0.01 s); when two neighbours are equally near, the earlier wins. A pose of the
   longer trajectory may be paired twice. Both stamp lists must be increasing.
2. **Alignment** (``umeyama``): the similarity ``(s, R, t)`` minimising
   ``sum_i ||y_i - (s R x_i + t)||^2`` over the paired estimated positions ``x_i`` and
   reference positions ``y_i`` (Umeyama 1991), with ``s = 1`` for SE(3); applied to the
   estimate (``x_i -> s R x_i + t``). Sim(3) is for monocular estimates, whose scale is
   unobservable.
3. **Statistics** (``statistics``) of the translation errors
   ``e_i = ||y_i - (s R x_i + t)||`` in metres: rmse ``sqrt(mean e^2)``, mean, median,
   std (population: ``sqrt(mean (e - mean e)^2)``), max, min, and the number of pairs.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from course.core.errors import CourseError
from course.problems.vio.trajectory_io import Trajectory

#: evo's default maximum time difference of an associated pair, seconds
MAX_DIFF = 0.01
#: alignment is refused when the second singular value of the cross-covariance is below
#: this fraction of the first (points on a line, or a single point: rotation undetermined)
RANK_TOL = 1e-12
ALIGNMENTS = ("se3", "sim3", "none")
STATISTICS = ("rmse", "mean", "median", "std", "max", "min")


class AlignmentError(CourseError, ValueError):
    """No pairs to compare, or positions from which no alignment can be determined."""


# ---------------------------------------------------------------------------------------
# Association


def associate(ref_stamps, est_stamps, max_diff: float = MAX_DIFF) -> tuple[np.ndarray, np.ndarray]:
    """Indices ``(i_ref, i_est)`` (K,) of the pairs of stamps at most ``max_diff`` apart.

    Args: ``ref_stamps`` (N,), ``est_stamps`` (M,) in seconds, each non-decreasing.
    The shorter list (``est_stamps`` when N == M) is walked; stamp ``s`` of it pairs with
    the nearest stamp of the longer list, the earlier one on a tie, when the distance is
    ``<= max_diff``. The pairs come out in the order of the shorter list.
    """
    ref = np.asarray(ref_stamps, dtype=float)
    est = np.asarray(est_stamps, dtype=float)
    for name, stamps in (("reference", ref), ("estimate", est)):
        if stamps.ndim != 1 or len(stamps) == 0:
            raise AlignmentError(f"associate: the {name} has no timestamps (shape {stamps.shape})")
        if np.any(np.diff(stamps) < 0):
            raise AlignmentError(f"associate: the {name}'s timestamps are not sorted")
    est_is_short = len(est) <= len(ref)
    short, long_ = (est, ref) if est_is_short else (ref, est)
    i_short, i_long = _nearest_within(short, long_, max_diff)
    return (i_long, i_short) if est_is_short else (i_short, i_long)


def _nearest_within(short: np.ndarray, long_: np.ndarray, max_diff: float) -> tuple[np.ndarray, np.ndarray]:
    """For each ``short[k]``: the index of its nearest ``long_`` stamp (earlier on a tie), kept when
    within ``max_diff``. Returns (kept k, their indices into ``long_``)."""
    inside = (short >= long_[0] - max_diff) & (short <= long_[-1] + max_diff)
    # upper neighbour: the first stamp strictly after s (the last one if none is)
    upper = np.minimum(np.searchsorted(long_, short, side="right"), len(long_) - 1)
    gap_up = long_[upper] - short
    gap_down = np.full(len(short), np.inf)
    has_lower = upper > 0
    gap_down[has_lower] = short[has_lower] - long_[upper[has_lower] - 1]
    take_up = (gap_up <= max_diff) & (gap_up < gap_down)
    take_down = ~take_up & (gap_down <= max_diff) & (gap_down <= gap_up)
    keep = inside & (take_up | take_down)
    chosen = np.where(take_up, upper, upper - 1)
    k = np.flatnonzero(keep)
    return k, chosen[k].astype(int)


# ---------------------------------------------------------------------------------------
# Alignment


@dataclass(frozen=True)
class Similarity:
    """``x -> scale * R @ x + t``: ``R`` (3, 3) a rotation, ``t`` (3,), ``scale`` > 0."""

    R: np.ndarray
    t: np.ndarray
    scale: float = 1.0

    def apply(self, points) -> np.ndarray:
        """The points (N, 3) mapped: row i becomes ``scale * R @ points[i] + t``."""
        return self.scale * (np.asarray(points, dtype=float) @ self.R.T) + self.t

    @classmethod
    def identity(cls) -> Similarity:
        return cls(np.eye(3), np.zeros(3), 1.0)


def umeyama(source, target, with_scale: bool = False) -> Similarity:
    """The similarity that best maps ``source`` (N, 3) onto ``target`` (N, 3) (Umeyama 1991).

    Minimises ``(1/N) sum_i ||y_i - (c R x_i + t)||^2`` over rotations R, translations t and,
    when ``with_scale``, scales c > 0 (else c = 1), with x = source, y = target:

    * means ``mu_x, mu_y``; source variance ``sigma_x^2 = (1/N) sum ||x_i - mu_x||^2``;
    * cross-covariance ``Sigma = (1/N) sum (y_i - mu_y)(x_i - mu_x)^T`` (3, 3) = ``U D V^T``;
    * ``S = diag(1, 1, -1)`` if ``det(U) det(V) < 0`` (a reflection would fit best), else I;
    * ``R = U S V^T``, ``c = tr(D S) / sigma_x^2``, ``t = mu_y - c R mu_x``.

    Raises AlignmentError when the shapes differ or the points are degenerate
    (rank of Sigma below 2: fewer than 3 non-collinear points).
    """
    x = np.asarray(source, dtype=float)
    y = np.asarray(target, dtype=float)
    if x.shape != y.shape or x.ndim != 2 or x.shape[1] != 3:
        raise AlignmentError(f"umeyama: source {x.shape} and target {y.shape} must both be (N, 3)")
    n = len(x)
    if n == 0:
        raise AlignmentError("umeyama: no points to align")
    mu_x, mu_y = x.mean(axis=0), y.mean(axis=0)
    dx, dy = x - mu_x, y - mu_y
    sigma = dy.T @ dx / n
    U, d, Vt = np.linalg.svd(sigma)
    if not d[0] > 0 or d[1] <= RANK_TOL * d[0]:
        raise AlignmentError(f"umeyama: degenerate positions ({n} points; singular values of the cross-covariance "
                             f"{d.tolist()}): the rotation is undetermined (points on a line or at one place)")
    S = np.eye(3)
    if np.linalg.det(U) * np.linalg.det(Vt) < 0:
        S[2, 2] = -1.0
    R = U @ S @ Vt
    scale = 1.0
    if with_scale:
        var_x = float(np.sum(dx * dx)) / n
        scale = float(np.sum(d * np.diag(S))) / var_x
    return Similarity(R, mu_y - scale * (R @ mu_x), scale)


# ---------------------------------------------------------------------------------------
# APE


def statistics(errors) -> dict:
    """``{"rmse", "median", "mean", "std", "max", "min", "pairs"}`` of the errors (K,), K >= 1.

    std is the population standard deviation (divided by K), as numpy's and evo's default.
    """
    e = np.asarray(errors, dtype=float)
    if e.ndim != 1 or len(e) == 0:
        raise AlignmentError(f"statistics: need a non-empty (K,) array of errors, got shape {e.shape}")
    return {
        "rmse": float(np.sqrt(np.mean(e * e))),
        "median": float(np.median(e)),
        "mean": float(np.mean(e)),
        "std": float(np.std(e)),
        "max": float(np.max(e)),
        "min": float(np.min(e)),
        "pairs": int(len(e)),
    }


@dataclass(frozen=True)
class ApeResult:
    """The outcome of ``ape``: the paired indices (K,), the alignment, the errors (K,) in metres."""

    ref_indices: np.ndarray
    est_indices: np.ndarray
    alignment: Similarity
    align: str
    errors: np.ndarray

    @property
    def stats(self) -> dict:
        return statistics(self.errors)


def ape(reference: Trajectory, estimate: Trajectory, align: str = "se3", max_diff: float = MAX_DIFF) -> ApeResult:
    """APE of the translation part of ``estimate`` against ``reference``.

    ``align``: ``se3`` (rotation and translation), ``sim3`` (also scale) or ``none``. The
    alignment uses every associated pair; the errors are ``||p_ref_i - (c R p_est_i + t)||``.
    """
    if align not in ALIGNMENTS:
        raise ValueError(f"align {align!r}: expected one of {', '.join(ALIGNMENTS)}")
    i_ref, i_est = associate(reference.timestamps, estimate.timestamps, max_diff)
    if len(i_ref) == 0:
        raise AlignmentError(
            f"no timestamps of {estimate.name} ({estimate.timestamps[0]:.6f}..{estimate.timestamps[-1]:.6f} s) are "
            f"within {max_diff:g} s of one of {reference.name} ({reference.timestamps[0]:.6f}.."
            f"{reference.timestamps[-1]:.6f} s)")
    p_ref, p_est = reference.positions[i_ref], estimate.positions[i_est]
    transform = Similarity.identity() if align == "none" else umeyama(p_est, p_ref, with_scale=(align == "sim3"))
    errors = np.linalg.norm(p_ref - transform.apply(p_est), axis=1)
    return ApeResult(i_ref, i_est, transform, align, errors)


def format_row(label: str, stats: dict, width: int = 22) -> str:
    """One table row: the label, then rmse, mean, median, std, max, min (m) and the pairs."""
    values = " ".join(f"{stats[key]:>9.6f}" if stats.get(key) is not None else f"{'-':>9}" for key in STATISTICS)
    pairs = stats.get("pairs")
    return f"{label:<{width}} {values} {pairs if pairs is not None else '-':>6}"


def format_header(width: int = 22) -> str:
    return f"{'':<{width}} " + " ".join(f"{key:>9}" for key in STATISTICS) + f" {'pairs':>6}"


# ---------------------------------------------------------------------------------------
# The source's evaluation: EuRoC MH_05 (``python -m course ape euroc-mh05``)

#: the files in the data folder (``course.core.data.data_dir()``): ground truth, estimate
EUROC_MH05 = ("euroc_mh05/euroc_mh05_groundtruth.csv", "euroc_mh05/vins_course_pose_output.txt")
#: the VIO write-up's row for its own LM run on MH_05 (SE(3) alignment; no mean, no pair count)
SOURCE_LM_ROW = {"rmse": 0.247, "median": 0.239, "mean": None, "std": 0.089, "max": 0.491, "min": 0.029,
                 "pairs": None}
#: evo 1.38.1, ``evo_ape euroc GT.csv EST.txt -a`` on the two shipped files (REFERENCES.md)
EVO_SE3_ROW = {"rmse": 0.245723, "median": 0.244383, "mean": 0.231451, "std": 0.082523, "max": 0.449682,
               "min": 0.033621, "pairs": None}


def euroc_mh05_files(folder=None):
    """(ground truth, estimate) paths of MH_05 in ``folder`` (default: the data folder); raise if absent."""
    from course.core.data import data_dir, missing_data_help
    from course.core.errors import MissingDataError

    root = data_dir() if folder is None else folder
    paths = tuple(root / rel for rel in EUROC_MH05)
    missing = [str(p) for p in paths if not p.is_file()]
    if missing:
        raise MissingDataError(f"euroc-mh05: missing {', '.join(missing)} (data folder {root})", missing_data_help())
    return paths


def compare_to_source(ours: dict, source: dict = SOURCE_LM_ROW) -> str:
    """A sentence on how far our statistics are from the source's, over the ones it reports."""
    keys = [k for k in STATISTICS if source.get(k) is not None]
    gaps = {k: ours[k] - source[k] for k in keys}
    worst = max(keys, key=lambda k: abs(gaps[k]))
    rel = {k: abs(gaps[k]) / abs(source[k]) for k in keys}
    return ("ours - source: " + ", ".join(f"{k} {gaps[k]:+.3f}" for k in keys)
            + f" m; rmse within {100 * rel['rmse']:.1f}%, the largest gap is {worst} "
            f"({abs(gaps[worst]):.3f} m, {100 * rel[worst]:.0f}%).")
