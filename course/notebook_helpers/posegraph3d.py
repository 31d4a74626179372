"""Helpers notebook 6 (``notebooks/chapter6_pose_graphs_3d.py``) calls, so its cells stay short:
``load3d``, ``poses_figure`` (3D trajectories: the start and the solution), ``rotation_spectrum``
(the edges' residual rotation angles, sorted, at each start and at the solution) and
``outlier_table``.
"""

from __future__ import annotations

import numpy as np

from course.app import plot
from course.core.errors import DatasetError
from course.geometry.so3 import log_many
from course.problems.posegraph3d import dataset as datasets
from course.problems.posegraph3d.graph import PoseGraph3D


def load3d(name: str) -> PoseGraph3D | None:
    """The named 3D graph, or None (saying why) when it is not on this machine."""
    try:
        return datasets.load_dataset(name)
    except DatasetError as exc:
        print(f"{name}: skipped ({exc})")
        return None


def poses_figure(panels, title=""):
    """A figure with one 3D panel per ``(label, t (N, 3))``: the positions joined in pose order."""
    fig = plot.figure(4.2 * len(panels), 4.2)
    for k, (label, t) in enumerate(panels, 1):
        ax = fig.add_subplot(1, len(panels), k, projection="3d")
        ax.plot(t[:, 0], t[:, 1], t[:, 2], lw=0.4)
        ax.set_title(label, fontsize=9)
        ax.set_box_aspect(np.ptp(t, axis=0) + 1e-9)
        ax.tick_params(labelsize=6)
    if title:
        fig.suptitle(title, fontsize=10)
    return fig


def residual_angles(graph: PoseGraph3D, t, R) -> np.ndarray:
    """Every edge's residual rotation angle ``|Log(R_z^T R_i^T R_j)|`` (M,), in degrees."""
    return np.degrees(np.linalg.norm(graph.errors(t, R)[:, 3:], axis=1))


def rotation_spectrum(curves, title=""):
    """A figure of the sorted residual rotation angles (degrees, log scale) of each ``(label, angles)``."""
    fig = plot.figure(6.4, 3.6)
    ax = fig.add_subplot()
    for label, angles in curves:
        ax.semilogy(np.sort(angles)[::-1], label=label, lw=1.2)
    ax.set_xlabel("edges, largest residual first")
    ax.set_ylabel("residual rotation (degrees)")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    if title:
        ax.set_title(title, fontsize=10)
    return fig


def rotation_errors_to_truth(R, R_true) -> np.ndarray:
    """``|Log(R_true^T R)|`` per pose (N,), degrees (both anchored at pose 0)."""
    return np.degrees(np.linalg.norm(log_many(np.matmul(np.swapaxes(R_true, 1, 2), R)), axis=1))


def outlier_table(rows) -> str:
    """The rows of ``course.app.outliers3d.run`` as a text table."""
    from course.app.outliers3d import HEADER, format_row

    return "\n".join([HEADER, *(format_row(r) for r in rows)])
