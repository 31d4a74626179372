"""``python -m course marginals DATASET``: every pose's marginal covariance at the batch optimum, ours
against the peers'.

The optimum is our Levenberg-Marquardt's (``lm-type3``) from the file's poses; every method computes
the marginals of every free pose there (a fixed pose's covariance is 0):

- ``ours``: ``course.marginals.Marginals`` (linearise, order, CHOLMOD, the implementation's
  ``marginal_covariances``), from the problem to the last block;
- ``gtsam (our H)``: GTSAM's ``Marginals`` of the same H (``HessianFactor`` blocks), the same
  linearisation in the same tangent: it should agree with ours to rounding;
- ``gtsam``: GTSAM's ``Marginals`` of its own factor graph (``BetweenFactorPose2/3``) at the same
  values, converted to our tangent (``Pose2`` body frame to ours, ``Pose3``'s rotation-first halves
  swapped). Its between error is not ours: the two H agree to first order in the residuals, so the
  difference is the size of the residuals at the optimum, not rounding;
- ``ceres``: Ceres' ``Covariance`` (sparse QR) of the problem the Ceres runs solve, our error
  whitened, converted to our tangent (the 3D quaternion's left tangent rotated to ours);
- ``dense``: the blocks of ``inv(H)`` (numpy), where H has at most ``dense_limit`` rows, else a row
  saying it was skipped.

Each row: the median time of ``repeat`` runs, its ratio to GTSAM's own (``gtsam``), and the largest
difference of its blocks from ours, relative to each block's scale (its largest entry in ours; "-" where
ours stopped at an unwritten TODO, a row saying so). The
timed span of a peer is its own work (its factorisation and its blocks), not the making of its graph.
A peer not installed here is a row saying so.
"""

import statistics
import time
from dataclasses import dataclass

import numpy as np

from course.core.impl import failure_reason, not_implemented_reason
from course.core.peers import installed, missing_message
from course.marginals import Marginals
from course.marginals.information import upper_of

#: the most rows of H the dense inverse is run on (M3500's 10,497 took 112 s here)
DENSE_LIMIT = 3000


@dataclass
class MarginalsRow:
    """One method: ``seconds`` (median), ``difference`` (largest relative to ours), or ``skipped``."""

    method: str
    seconds: float = float("nan")
    difference: float = float("nan")
    skipped: str = ""


def _load(dataset: str, impl):
    """``(kind, graph, problem)`` of a 2D or 3D pose graph (``compare``'s names and files)."""
    from course.app.compare import find_runner

    kind = find_runner(dataset).kind
    if kind == "posegraph":
        from course.problems.posegraph.dataset import load_dataset
        from course.problems.posegraph.problem import PoseGraphProblem

        graph = load_dataset(dataset)
        return kind, graph, PoseGraphProblem(graph, impl=impl)
    if kind == "posegraph3d":
        from course.problems.posegraph3d.dataset import load_dataset as load_3d
        from course.problems.posegraph3d.problem import PoseGraph3DProblem

        graph_3d = load_3d(dataset)
        return kind, graph_3d, PoseGraph3DProblem(graph_3d, impl=impl)
    raise ValueError(f"marginals: {dataset!r} is a {kind} problem; the comparison runs on 2D and 3D pose graphs "
                     "(the other families' marginals: course.marginals.Marginals)")


def largest_difference(ours, theirs, free) -> float:
    """max over the poses ``free`` of ``max|theirs_k - ours_k| / max|ours_k|``."""
    ours, theirs = np.asarray(ours)[free], np.asarray(theirs)[free]
    scale = np.abs(ours).reshape(len(free), -1).max(axis=1)
    return float((np.abs(theirs - ours).reshape(len(free), -1).max(axis=1) / scale).max())


def _median(run, repeat):
    """``(last result, median seconds)`` of ``run()`` -> ``(result, seconds)``, ``repeat`` times."""
    results = [run() for _ in range(repeat)]
    return results[-1][0], statistics.median(r[1] for r in results)


def compare(dataset: str, impl="solutions", repeat: int = 3, dense_limit: int = DENSE_LIMIT) -> tuple[list, dict]:
    """``(rows, facts)``: :class:`MarginalsRow` per method (module docstring) and ``facts`` (poses, rows of
    H, the optimum's chi2)."""
    from course.solver import minimize

    kind, graph, problem = _load(dataset, impl)
    x = minimize(problem, "lm-type3", impl).params
    dof = 3 if kind == "posegraph" else 6
    N = graph.num_poses
    free = np.setdiff1d(np.arange(N), graph.fixed)

    def ours():
        start = time.perf_counter()
        blocks = Marginals(problem, x, impl=impl).covariances()
        return np.array([blocks[k] for k in range(N)]), time.perf_counter() - start

    try:
        reference, seconds = _median(ours, repeat)
        rows = [MarginalsRow("ours", seconds, 0.0)]
    except NotImplementedError as exc:  # the student's TODO: a row, and the peers still run
        reference, rows = None, [MarginalsRow("ours", skipped=not_implemented_reason(exc))]
    H = upper_of(problem.linearize(x))
    held = np.zeros(N, dtype=bool)
    held[graph.fixed] = True
    keep = np.repeat(~held, dof)
    H_free = H[keep][:, keep]
    starts = np.arange(len(free) + 1) * dof

    def difference(result) -> float:
        return float("nan") if reference is None else largest_difference(reference, result, free)

    def peer(method, library, run):
        if not installed(library):
            rows.append(MarginalsRow(method, skipped=missing_message(library)))
            return
        try:
            result, seconds = _median(run, repeat)
        except NotImplementedError as exc:  # Ceres' cost is the implementation's: its TODO is a row
            rows.append(MarginalsRow(method, skipped=not_implemented_reason(exc)))
            return
        except ArithmeticError as exc:
            rows.append(MarginalsRow(method, skipped=failure_reason(exc)))
            return
        rows.append(MarginalsRow(method, seconds, difference(result)))

    def gtsam_linear():
        from course.backends.factorgraph import gtsam_marginals

        blocks, seconds = gtsam_marginals.marginals(H_free, starts, range(len(free)))
        out = np.zeros((N, dof, dof))
        out[free] = np.array(blocks)
        return out, seconds

    if kind == "posegraph":
        from course.backends.posegraph import gtsam_marginals as gtsam_native

        poses = x.reshape(-1, 3)
        peer("gtsam", "gtsam", lambda: gtsam_native.marginals(graph, poses))
        peer("gtsam (our H)", "gtsam", gtsam_linear)

        def ceres():
            from course.backends.posegraph import ceres_covariance

            return ceres_covariance.marginals(graph, poses, impl=impl)
    else:
        from course.backends.posegraph3d import gtsam_marginals as gtsam_native_3d
        from course.problems.posegraph3d.problem import unpack

        t, R = unpack(x)
        peer("gtsam", "gtsam", lambda: gtsam_native_3d.marginals(graph, t, R))
        peer("gtsam (our H)", "gtsam", gtsam_linear)

        def ceres():
            from course.backends.posegraph3d import ceres_covariance

            return ceres_covariance.marginals(graph, t, R, impl=impl)

    peer("ceres", "pyceres", ceres)
    n = H_free.shape[0]
    if n <= dense_limit:
        def dense():
            full = H_free.toarray()
            full = full + np.triu(full, 1).T
            start = time.perf_counter()
            inverse = np.linalg.inv(full)
            blocks = np.zeros((N, dof, dof))
            blocks[free] = [inverse[a:a + dof, a:a + dof] for a in starts[:-1]]
            return blocks, time.perf_counter() - start

        result, seconds = _median(dense, repeat)
        rows.append(MarginalsRow("dense", seconds, difference(result)))
    else:
        rows.append(MarginalsRow("dense", skipped=f"skipped: H has {n} rows, above --dense-limit {dense_limit}"))
    facts = {"dataset": dataset, "poses": N, "rows": n, "chi2": problem.chi2(x), "repeat": repeat}
    return rows, facts


def format_rows(rows, facts) -> str:
    """The table: method, median ms, ratio to ``gtsam``, largest difference to ours, and a skipped row's
    reason."""
    gtsam = next((r.seconds for r in rows if r.method == "gtsam" and not r.skipped), float("nan"))
    header = ["method", "ms (median)", "/ gtsam", "max diff to ours"]
    body = []
    for r in rows:
        if r.skipped:
            body.append([r.method, r.skipped])
            continue
        body.append([r.method, f"{1e3 * r.seconds:.1f}", f"{r.seconds / gtsam:.3f}" if gtsam == gtsam else "-",
                     f"{r.difference:.2e}" if r.difference == r.difference else "-"])
    widths = [max(len(h), *(len(b[k]) for b in body if len(b) == len(header))) for k, h in enumerate(header)]

    def line(cells):
        if len(cells) != len(header):
            return f"{cells[0].ljust(widths[0])}  {cells[1]}"
        return "  ".join(c.ljust(w) if k == 0 else c.rjust(w) for k, (c, w) in enumerate(zip(cells, widths)))

    title = (f"{facts['dataset']}: marginals of all {facts['poses']} poses at our optimum (chi2 "
             f"{facts['chi2']:.6g}; H has {facts['rows']} rows without the fixed pose), median of {facts['repeat']}")
    return "\n".join([title, line(header), line(["-" * w for w in widths]), *map(line, body)])
