"""The outlier experiment of chapter 4: bundle adjustment with and without robust kernels.

A synthetic BAL problem with a fraction of its observations moved far off (``course.problems.bal.dataset.synthetic``
with ``outliers``) and the same problem without them (:func:`outlier_pair`: the same cameras,
points, start and inlier observations; the outliers' observations at their clean values) are
solved by Levenberg-Marquardt (``course.solver.minimize``, the gauge fixed). The figure of merit
is the inliers' RMS reprojection error at each solution::

    rms = sqrt(mean over inlier observations k of |r_k|^2 / 2)      (pixels per coordinate)

against the outlier-free solution's: least squares lets the outliers pull the scene away from
the inliers; a robust kernel should bring the inliers' RMS back to the outlier-free value.
:func:`run` gives one :class:`OutlierRow` per loss; :func:`table` prints them.
"""

from dataclasses import dataclass

import numpy as np

from course.problems.bal.dataset import BALProblem, residuals, synthetic
from course.problems.bal.problem import BundleAdjustmentProblem
from course.solver import SolverOptions, minimize
from course.solver.robust import RobustLoss

#: the losses of the experiment and their scales, in pixels of |r| (the noise is 1 pixel per
#: coordinate, so an inlier's |r|^2 follows a chi-square with 2 degrees of freedom):
#: Huber and Cauchy at a = sqrt(5.99) = 2.45, the 95% quantile of an inlier's |r| (95% of the
#: inliers in Huber's quadratic part); Tukey at a = 4.5, beyond which an inlier falls with
#: probability exp(-4.5^2 / 2) = 4e-5, so that Tukey ignores outliers (tens of pixels off) only.
#: Tukey ignores whatever is beyond a, at the start too (whose inliers are ~10 pixels off), so it
#: also runs from Cauchy's solution: a list is a schedule, each loss starting where the last ended
DEFAULT_LOSSES = (None, ("huber", 2.45), ("cauchy", 2.45), ("tukey", 4.5), [("cauchy", 2.45), ("tukey", 4.5)])


def outlier_pair(num_cameras: int, num_points: int, seed: int = 0, noise: float = 1.0, outliers: float = 0.1):
    """``(contaminated, clean, inlier)``: the problem with outliers, the same without them, and the
    mask (K,) of the observations both share.

    ``synthetic`` draws the same scene and the same noisy observations for any ``outliers``, then
    moves a random fraction of them; the start it draws afterwards differs. Here ``clean`` is
    ``contaminated`` with the moved observations back at their outlier-free values, so both share
    cameras, points, start and inliers exactly."""
    dirty = synthetic(num_cameras, num_points, seed=seed, noise=noise, outliers=outliers)
    plain = synthetic(num_cameras, num_points, seed=seed, noise=noise, outliers=0.0)
    same = (np.array_equal(dirty.camera_index, plain.camera_index)
            and np.array_equal(dirty.point_index, plain.point_index)
            and dirty.ground_truth is not None and plain.ground_truth is not None
            and all(np.array_equal(a, b) for a, b in zip(dirty.ground_truth, plain.ground_truth)))
    if not same:  # a guard: the generator's draws changed order
        raise RuntimeError("course.problems.bal.dataset.synthetic no longer draws the same scene with and "
                           "without outliers")
    inlier = np.all(dirty.observations == plain.observations, axis=1)
    clean = BALProblem(dirty.cameras.copy(), dirty.points.copy(), dirty.camera_index, dirty.point_index,
                       plain.observations.copy(), name=dirty.name + ":clean", source=plain.source,
                       ground_truth=dirty.ground_truth)
    return dirty, clean, inlier


def inlier_rms(problem: BALProblem, cameras, points, inlier) -> float:
    """RMS reprojection error per coordinate (pixels) over the observations where ``inlier`` (K,)."""
    r = residuals(cameras, points, problem.camera_index, problem.point_index, problem.observations)[inlier]
    return float(np.sqrt(np.mean(r * r)))


@dataclass
class OutlierRow:
    """One solve: the loss (``"least squares"`` or ``kernel(a=...)``), the inliers' RMS (pixels),
    its ratio to the outlier-free solution's, iterations, stop reason and seconds."""

    loss: str
    rms: float
    ratio: float
    iterations: int
    stop_reason: str
    seconds: float


def solve(problem: BALProblem, loss=None, method: str = "lm-type3", impl="solutions", max_iterations: int = 100):
    """``(cameras, points, [RunResult])`` of LM on ``problem`` (gauge fixed) with ``loss``: None, a
    loss ``(kernel, scale)``, or a list of them solved in turn, each from the previous solution. At
    most ``max_iterations`` step attempts each (least squares with outliers converges slowly)."""
    schedule = list(loss) if isinstance(loss, list) else [loss]
    cameras, points, results = problem.cameras, problem.points, []
    for step in schedule:
        start = BALProblem(cameras, points, problem.camera_index, problem.point_index, problem.observations,
                           name=problem.name)
        ba = BundleAdjustmentProblem(start, impl, fix_gauge=True, loss=step)
        results.append(minimize(ba, method, impl, SolverOptions(max_iterations=max_iterations)))
        cameras, points = ba.unpack(results[-1].params)
    return cameras, points, results


def run(num_cameras: int = 12, num_points: int = 300, seed: int = 1, noise: float = 1.0, outliers: float = 0.1,
        losses=DEFAULT_LOSSES, method: str = "lm-type3", impl="solutions", max_iterations: int = 100):
    """``(reference, rows)``: the :class:`OutlierRow` of the outlier-free solution (least squares on
    ``clean``, ratio 1), then one per loss of ``losses`` on the contaminated problem (see :func:`solve`)."""
    dirty, clean, inlier = outlier_pair(num_cameras, num_points, seed, noise, outliers)

    def row(problem, loss, name, reference_rms=None):
        cameras, points, results = solve(problem, loss, method, impl, max_iterations)
        rms = inlier_rms(problem, cameras, points, inlier)
        return OutlierRow(name, rms, rms / (reference_rms or rms), sum(r.iterations for r in results),
                          results[-1].stop_reason.value, sum(r.seconds for r in results))

    reference = row(clean, None, "no outliers, least squares")
    return reference, [row(dirty, loss, loss_name(loss), reference.rms) for loss in losses]


def loss_name(loss) -> str:
    """``least squares``, ``cauchy(a=2.45)``, or a schedule ``cauchy(a=2.45) > tukey(a=4.5)``."""
    if isinstance(loss, list):
        return " > ".join(loss_name(step) for step in loss)
    value = RobustLoss.of(loss)
    return "least squares" if value is None else str(value)


def table(reference: OutlierRow, rows) -> str:
    """A text table of :func:`run`'s output (the inliers' RMS in pixels per coordinate)."""
    width = max(len(row.loss) for row in (reference, *rows))
    lines = [f"{'loss':<{width}} {'inliers RMS':>12} {'/ outlier-free':>15} {'iterations':>11} {'seconds':>8}  stop"]
    for row in (reference, *rows):
        lines.append(f"{row.loss:<{width}} {row.rms:>12.4f} {row.ratio:>15.3f} {row.iterations:>11d} "
                     f"{row.seconds:>8.2f}  {row.stop_reason}")
    return "\n".join(lines)


def main(argv=None) -> int:
    """``python -m course.problems.bal.outliers [CAMERAS POINTS SEED]``: print the table."""
    import sys

    args = [int(a) for a in (sys.argv[1:] if argv is None else argv)]
    if len(args) > 3:
        raise SystemExit("usage: python -m course.problems.bal.outliers [CAMERAS POINTS SEED]")
    cameras, points, seed = [*args, *(12, 300, 1)[len(args):]]  # the defaults of run for what is not given
    reference, rows = run(cameras, points, seed)
    print(table(reference, rows))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
