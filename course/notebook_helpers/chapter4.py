"""Chapter 4's lesson: the figures and tables of its theory (``notebooks/chapter4_bundle_adjustment.py``).

The BAL camera: :func:`camera_model_figure`. The angle-axis Jacobian: :func:`rotation_taylor_figure`
(the first-order error of a derivative, for three candidates). Checking your Jacobians where you
work: :data:`CAMERA`, :data:`POINT`, :func:`generic_observation`, :func:`observation_line`,
:func:`observation_setup` (what ``course.check_jacobian`` needs for one observation). Robust costs as
reweighted least squares: :func:`location_data`, :func:`irls_location`, :func:`irls_figure`. The
parallel assembly: :func:`sum_order_table`.

``impl`` is an implementation's name or path (``course.core.impl.load``): the figures and tables
that need an exercise call *that* implementation's function. A cell that calls them is wrapped in
``course.notebook_helpers.lesson.todo_as_one_line``: an unwritten TODO prints one line naming it.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from course.app import plot
from course.geometry.jacobian_check import Space, numerical_jacobian
from course.geometry.so3 import skew, so3_exp
from course.notebook_helpers.lesson import JacobianSetup, exercise
from course.problems.bal.dataset import BALProblem, rotate

# ---------------------------------------------------------------- the camera model


def camera_model_figure(k1_values: Sequence[float] = (-0.5, 0.5), reach: float = 0.5) -> Any:
    """Two panels. Left: a side view (z, y) of a BAL camera at the origin looking down -z, a point
    P in front (P_z < 0), the plane z = -1 where the ray meets p = -P_xy / P_z, and the mirror
    point -P behind the camera, on the same line through the centre: the same p. Right: a square
    grid of normalised points p in [-reach, reach]^2 and its image d(|p|) p under the radial
    factor d = 1 + k1 |p|^2 (k2 = 0) for each k1 of ``k1_values`` (exaggerated values)."""
    fig = plot.figure(12, 4.6)
    side, grid = fig.subplots(1, 2)
    P = np.array([1.6, -4.0])  # (y, z): in front, P_z < 0
    p = -P[0] / P[1]
    side.plot([0.0, 0.0], [-2.2, 2.2], color="0.6", linewidth=0.8)
    side.plot([-1.0, -1.0], [-2.2, 2.2], color="tab:green", linewidth=1.2, label="the plane z = -1 (p lives here)")
    side.plot([P[1], -P[1]], [P[0], -P[0]], color="0.3", linestyle="--", linewidth=0.9,
              label="the line through P and the centre")
    side.plot(P[1], P[0], "o", color="tab:blue", label=f"P, in front (P_z = {P[1]:g} < 0)")
    side.plot(-P[1], -P[0], "s", color="tab:red", label=f"-P, behind (P_z = {-P[1]:g} > 0)")
    side.plot(-1.0, p, "*", color="tab:green", markersize=12, label=f"p_y = -P_y / P_z = {p:g} for both")
    side.plot(0.0, 0.0, "k^", markersize=9, label="the camera centre")
    side.annotate("looks down -z", xy=(-2.6, -1.9), xytext=(-0.3, -1.9),
                  arrowprops={"arrowstyle": "->", "color": "k"}, va="center", fontsize=8)
    side.set_xlim(5.0, -5.0)  # -z to the right: the camera looks that way
    side.set_xlabel("z (camera frame; decreasing to the right)")
    side.set_ylabel("y")
    side.set_title("p = -P_xy / P_z cannot tell P from -P", fontsize=10)
    side.legend(fontsize=7, loc="upper left")
    side.grid(True, alpha=0.3)
    lines = np.linspace(-reach, reach, 9)
    along = np.linspace(-reach, reach, 101)
    colours = ("tab:blue", "tab:orange", "tab:purple")
    for k, k1 in enumerate(k1_values):
        for value in lines:
            for q in (np.column_stack([np.full_like(along, value), along]),
                      np.column_stack([along, np.full_like(along, value)])):
                d = 1.0 + k1 * np.sum(q * q, axis=1)
                grid.plot(*(d[:, None] * q).T, color=colours[k % 3], linewidth=0.8)
        grid.plot([], [], color=colours[k % 3], label=f"d p, k1 = {k1:g} ({'barrel' if k1 < 0 else 'pincushion'})")
    for value in lines:
        grid.plot([value, value], [-reach, reach], color="0.75", linewidth=0.6)
        grid.plot([-reach, reach], [value, value], color="0.75", linewidth=0.6)
    grid.plot([], [], color="0.75", label="p (no distortion)")
    grid.set_aspect("equal")
    grid.set_xlabel("p_x")
    grid.set_ylabel("p_y")
    grid.set_title("radial distortion d = 1 + k1 |p|^2 moves p along its ray (k1 exaggerated)", fontsize=10)
    grid.legend(fontsize=7, loc="upper right")
    return fig


# ---------------------------------------------------------------- the angle-axis Jacobian


@dataclass
class TaylorStudy:
    """The first-order error ``|R(w + e u) X - R(w) X - e D u|`` (3,) norms against ``e`` for three
    candidates D (3, 3) of ``d (R(w) X) / d w``: ``errors`` maps a candidate's name to its errors
    (len(steps),); ``slopes`` to the least-squares slope of log error against log e."""

    steps: np.ndarray
    errors: dict
    slopes: dict
    angle: float


def rotation_taylor_study(angle: float = 2.0, seed: int = 0, steps: np.ndarray | None = None) -> TaylorStudy:
    """The Taylor test of three candidates for ``D = d (R(w) X) / d w`` at a w of norm ``angle`` and a
    random X, along a random unit direction u:

    * ``0``: no derivative at all (the error is first order: slope 1);
    * ``-R [X]_x``: the derivative for a *right perturbation*, ``d/dphi R Exp(phi) X`` at 0, taken
      as if the angle-axis vector moved that way (first order again, unless w is 0);
    * central differences of ``w -> R(w) X`` (the true derivative: the error is second order, slope 2).
    """
    rng = np.random.default_rng(seed)
    direction = rng.normal(size=3)
    w = angle * direction / np.linalg.norm(direction)
    X = rng.normal(size=3) * 2.0
    u = rng.normal(size=3)
    u /= np.linalg.norm(u)
    steps = np.logspace(-5, 0, 21) if steps is None else np.asarray(steps, dtype=float)

    def rotated(v):
        return rotate(np.asarray(v)[None], X[None])[0]

    R = so3_exp(w)
    candidates = {"D = 0 (no derivative)": np.zeros((3, 3)),
                  "D = -R [X]_x (a right perturbation, not w + dw)": -R @ skew(X),
                  "D = central differences of w -> R(w) X": numerical_jacobian(rotated, w)}
    base = rotated(w)
    errors = {name: np.array([np.linalg.norm(rotated(w + e * u) - base - e * (D @ u)) for e in steps])
              for name, D in candidates.items()}
    middle = (steps >= 1e-4) & (steps <= 1e-1)
    slopes = {name: float(np.polyfit(np.log(steps[middle]), np.log(err[middle]), 1)[0]) for name, err in errors.items()}
    return TaylorStudy(steps, errors, slopes, angle)


def rotation_taylor_figure(study: TaylorStudy | None = None) -> Any:
    """:func:`rotation_taylor_study`'s errors against the step, log-log, each labelled with its slope."""
    study = rotation_taylor_study() if study is None else study
    fig = plot.figure(7.5, 4.5)
    ax = fig.add_subplot()
    for name, errors in study.errors.items():
        ax.loglog(study.steps, np.maximum(errors, 1e-18), "o-", markersize=3,
                  label=f"{name}: slope {study.slopes[name]:.2f}")
    ax.set_xlabel("step e along a unit direction u of w")
    ax.set_ylabel("|R(w + e u) X - R(w) X - e D u|")
    ax.set_title(f"the Taylor test of d(R(w) X)/dw at |w| = {study.angle:g} rad: a right derivative is "
                 "first order", fontsize=9)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7)
    return fig


# ---------------------------------------------------------------- checking your Jacobians


def _plus(x, delta):
    """``x + delta``: the BAL unknowns (also w) move by plain addition."""
    x = np.asarray(x, dtype=float)
    return x + np.asarray(delta, dtype=float).reshape(x.shape)


#: one camera's 9 unknowns, for ``course.check_jacobian``: the blocks of a wrong entry are named w, t, f, k1, k2
CAMERA = Space("bal camera", lambda x: np.asarray(x).size, _plus, 9,
               (("w", slice(0, 3)), ("t", slice(3, 6)), ("f", slice(6, 7)), ("k1", slice(7, 8)),
                ("k2", slice(8, 9))))
#: one point's 3 unknowns
POINT = Space("bal point", lambda x: np.asarray(x).size, _plus, 3, (("X", slice(0, 3)),))
#: the residual's two rows
ROWS = [("x", slice(0, 1)), ("y", slice(1, 2))]




def generic_observation(problem: BALProblem, angle: float = 2.0) -> int:
    """The first observation whose camera's rotation is closest to ``angle`` radians (a generic
    rotation: far from 0, where the angle-axis derivative is simple, and from pi)."""
    norms = np.linalg.norm(problem.cameras[problem.camera_index, :3], axis=1)
    return int(np.argmin(np.abs(norms - angle)))


def observation_line(problem: BALProblem, k: int) -> str:
    """One line naming observation ``k`` of ``problem``: its camera, the camera's rotation angle, its point."""
    c = int(problem.camera_index[k])
    return (f"{problem.name}, observation {k}: camera {c} (rotated by |w| = "
            f"{np.linalg.norm(problem.cameras[c, :3]):.2f} rad), point {int(problem.point_index[k])}")


def observation_setup(problem: BALProblem, k: int, impl: Any = "solutions") -> JacobianSetup:
    """The implementation's residual and Jacobians of observation ``k`` of ``problem`` alone, as
    :class:`JacobianSetup`. Raises ``NotImplementedError`` while the function is a TODO."""
    ba = exercise("bundle_adjustment", impl)
    obs = problem.observations[k:k + 1]
    index = np.zeros(1, dtype=np.int64)

    def f(camera, point):
        r, _, _ = ba.reprojection_residuals_and_jacobians(np.asarray(camera)[None], np.asarray(point)[None],
                                                          index, index, obs)
        return np.asarray(r)[0]

    camera = problem.cameras[problem.camera_index[k]].copy()
    point = problem.points[problem.point_index[k]].copy()
    _, J_cam, J_point = ba.reprojection_residuals_and_jacobians(camera[None], point[None], index, index, obs)
    return JacobianSetup(f, [camera, point], [np.asarray(J_cam)[0], np.asarray(J_point)[0]], [CAMERA, POINT],
                            ["camera", "point"], ROWS)


# ---------------------------------------------------------------- robust costs as reweighted least squares


@dataclass
class LocationData:
    """A 1-D location problem: ``samples`` (n,) of one unknown, ``inlier`` (n,) bool; the truth is 0."""

    samples: np.ndarray
    inlier: np.ndarray


def location_data(inliers: int = 40, outliers: int = 10, offset: float = 12.0, seed: int = 0) -> LocationData:
    """``inliers`` samples N(0, 1) of an unknown whose truth is 0, and ``outliers`` samples
    N(offset, 2^2): a landmark measured many times, a fifth of the matches wrong."""
    rng = np.random.default_rng(seed)
    samples = np.concatenate([rng.normal(0.0, 1.0, inliers), rng.normal(offset, 2.0, outliers)])
    return LocationData(samples, np.arange(len(samples)) < inliers)


@dataclass
class IrlsRun:
    """Iteratively reweighted least squares on a location problem: ``estimates`` (iterations + 1,)
    from the least-squares mean, the ``weights`` (n,) rho'(s) at the last estimate."""

    name: str
    estimates: np.ndarray
    weights: np.ndarray


def irls_location(data: LocationData, losses: Sequence[Any], impl: Any = "solutions",
                  iterations: int = 15) -> list[IrlsRun]:
    """Each loss of ``losses`` (``None`` for least squares, or ``(kernel, scale)``) on ``data`` by
    iteratively reweighted least squares with the implementation's ``robust_kernels``: from the
    mean, ``w_i = rho'(s_i)`` with ``s_i = (y_i - mu)^2``, then ``mu = sum w_i y_i / sum w_i``
    (the Gauss-Newton step of the reweighted problem; all weights zero keeps mu)."""
    kernels = exercise("robust_kernels", impl)
    y = data.samples
    runs = []
    for loss in losses:
        mu = float(np.mean(y))
        estimates = [mu]
        weights = np.ones_like(y)
        for _ in range(iterations):
            if loss is not None:
                kernel, scale = loss
                weights = np.asarray(getattr(kernels, kernel)((y - mu) ** 2, scale)[1], dtype=float)
            if weights.sum() > 0:
                mu = float(np.sum(weights * y) / np.sum(weights))
            estimates.append(mu)
        if loss is not None:
            kernel, scale = loss
            weights = np.asarray(getattr(kernels, kernel)((y - mu) ** 2, scale)[1], dtype=float)
        name = "least squares" if loss is None else f"{loss[0]}(a={loss[1]:g})"
        runs.append(IrlsRun(name, np.array(estimates), weights))
    return runs


def irls_figure(data: LocationData, runs: Sequence[IrlsRun]) -> Any:
    """Left: each run's estimate per iteration, the inliers' mean dotted. Right: each sample's
    weight rho'(s) at the run's last estimate, against the sample's value."""
    fig = plot.figure(12, 4.4)
    path, weight = fig.subplots(1, 2)
    for k, run in enumerate(runs):
        colour = f"C{k}"
        path.plot(np.arange(len(run.estimates)), run.estimates, "o-", markersize=3, color=colour,
                  label=f"{run.name}: {run.estimates[-1]:.3f}")
        weight.plot(data.samples, run.weights, "osD^"[k % 4], markersize=7 - k, color=colour, label=run.name,
                    alpha=0.7)
    path.axhline(float(np.mean(data.samples[data.inlier])), color="k", linestyle=":", linewidth=1,
                 label="the inliers' mean")
    path.set_xlabel("IRLS iteration (0: the least-squares mean)")
    path.set_ylabel("estimate mu")
    path.set_title("iteratively reweighted least squares, a 1-D location", fontsize=10)
    path.legend(fontsize=7)
    weight.set_xlabel("sample y_i (inliers near 0, outliers near 12)")
    weight.set_ylabel("weight rho'(s_i) at the last estimate")
    weight.set_title("who still pulls at the end", fontsize=10)
    weight.legend(fontsize=7)
    for ax in (path, weight):
        ax.grid(True, alpha=0.3)
    return fig


# ---------------------------------------------------------------- the parallel assembly


def _relative(a: Sequence[Any], b: Sequence[Any]) -> float:
    """The largest ``max |a_i - b_i| / max |b_i|`` over the arrays of two assemblies."""
    worst = 0.0
    for x, y in zip(a, b):
        x, y = np.asarray(x, dtype=float), np.asarray(y, dtype=float)
        scale = float(np.max(np.abs(y))) if y.size else 0.0
        if scale > 0:
            worst = max(worst, float(np.max(np.abs(x - y))) / scale)
    return worst


def _same(a: Sequence[Any], b: Sequence[Any]) -> bool:
    return all(np.array_equal(np.asarray(x), np.asarray(y)) for x, y in zip(a, b))


def sum_order_table(problem: BALProblem, impl: Any = "solutions", chunks: Sequence[int] = (1, 2, 3, 8),
                    workers: Sequence[int] = (1, 2, 4), repeats: int = 3) -> str:
    """The implementation's ``normal_equations_parallel`` against its serial ``normal_equations`` at
    the start of ``problem``: per number of chunks, the largest relative difference of (U, V, g_cam,
    g_point, chi2) from the serial assembly for each number of workers, and whether every workers
    count and every one of ``repeats`` runs gave the same bits (they should: the chunks fix the
    sums, and adding the partial sums in chunk order fixes their order)."""
    ba = exercise("bundle_adjustment", impl)
    parallel = exercise("parallel_assembly", impl)
    args = (problem.camera_index, problem.point_index, problem.num_cameras, problem.num_points)
    r, J_cam, J_point = ba.reprojection_residuals_and_jacobians(problem.cameras, problem.points, problem.camera_index,
                                                                problem.point_index, problem.observations)
    U, V, _, g_cam, g_point, chi2 = ba.normal_equations(r, J_cam, J_point, *args)
    serial = (U, V, g_cam, g_point, np.array([chi2]))
    head = (f"{'chunks':>6} " + " ".join(f"{f'{w} worker(s)':>12}" for w in workers)
            + "  same bits for every workers count and run")
    lines = [f"{problem.name}, {problem.num_observations} observations: the largest relative difference of "
             "U, V, g and chi2 from the serial assembly", head]
    for n in chunks:
        cells, first, same = [], None, True
        for w in workers:
            for _ in range(max(repeats, 1)):
                out = parallel.normal_equations_parallel(r, J_cam, J_point, *args, workers=w, chunks=n)
                parts = (out[0], out[1], out[3], out[4], np.array([out[5]]))
                if first is None:
                    first = parts
                elif not _same(parts, first):
                    same = False
            cells.append(_relative(parts, serial))
        lines.append(f"{n:6d} " + " ".join(f"{c:12.1e}" for c in cells) + f"  {'yes' if same else 'NO'}")
    return "\n".join(lines)
