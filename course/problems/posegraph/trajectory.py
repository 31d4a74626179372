"""Absolute trajectory error of estimated poses against ground truth."""

import numpy as np

from course.geometry.se2 import wrap_angle


def align_se2(estimate, truth):
    """Rotation angle ``phi`` and translation ``t`` (2,) that best map ``estimate`` onto ``truth``.

    Least squares over positions (Kabsch/Umeyama without scale): ``truth ~ R(phi) p + t``.
    Args: estimate, truth: (N, 3) poses.
    """
    p, q = estimate[:, :2], truth[:, :2]
    p0, q0 = p.mean(0), q.mean(0)
    cross = (p - p0).T @ (q - q0)
    phi = np.arctan2(cross[0, 1] - cross[1, 0], cross[0, 0] + cross[1, 1])
    c, s = np.cos(phi), np.sin(phi)
    R = np.array([[c, -s], [s, c]])
    return phi, q0 - R @ p0


def absolute_trajectory_error(estimate, truth) -> dict:
    """ATE after SE(2) alignment: rmse, median, std, max, min of translation and rotation.

    Returns ``{"translation": {...}, "rotation": {...}}`` in metres and radians.
    """
    estimate, truth = np.asarray(estimate, float), np.asarray(truth, float)
    phi, t = align_se2(estimate, truth)
    c, s = np.cos(phi), np.sin(phi)
    xy = estimate[:, :2] @ np.array([[c, s], [-s, c]]) + t
    translation = np.linalg.norm(xy - truth[:, :2], axis=1)
    rotation = np.abs(wrap_angle(estimate[:, 2] + phi - truth[:, 2]))
    return {"translation": _stats(translation), "rotation": _stats(rotation)}


def _stats(values) -> dict:
    return {
        "rmse": float(np.sqrt(np.mean(values**2))),
        "median": float(np.median(values)),
        "std": float(np.std(values)),
        "max": float(np.max(values)),
        "min": float(np.min(values)),
    }
