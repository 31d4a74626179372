"""``python -m course online DATASET``: a pose graph fed one pose at a time to our incremental smoother,
GTSAM's ISAM2, and batch re-solves (ours, g2o's) every K steps.

Step k brings pose k with its edges to earlier poses (odometry and the loop closures as they arrive);
each method starts pose k from the odometry composed onto its own current estimate of pose k - 1
(``course.incremental.online``). Step 0 anchors pose 0 with a prior (sigma ``PRIOR_SIGMA``) for the two
smoothers; the batch re-solves hold pose 0 fixed, as the chapter-2 problem does. Per method: the time of
each update (our ``update``, ISAM2's ``update``; a batch's solve of the graph so far), its median, 90th
percentile, worst and total, the variables relinearised and re-eliminated per step, and the final chi2 of
the dataset's edges (``sum e^T Omega e``, the prior left out: GTSAM's ``error`` is half of it) against the
minimum: the course's LM on the whole dataset from the file's poses, or, where that stops in a local minimum
above it (mit), ours iterated to convergence from the online estimate. A peer not installed, or one that
fails at a step (GTSAM's ISAM2 on mit: an indeterminate system), is a row that says so.
"""

import time
from dataclasses import dataclass, field

import numpy as np

from course.core import peers
from course.core.impl import not_implemented_reason

PRIOR_SIGMA = 1e-3
#: the implementation's functions an update calls (``--breakdown`` times each): chapter 8's five exercises and
#: chapter 7's linearisation
SMOOTHER_CALLS = {
    "elimination": ("eliminate_variable",),
    "orderings": ("minimum_degree_ordering", "symbolic_elimination"),
    "bayes_tree": ("bayes_tree",),
    "incremental_update": ("relinearised_keys", "affected_cliques", "orphan_parents", "wildfire_update"),
    "autodiff_factor": ("tangent_jacobians",),
}
#: the batch re-solves run about this many times over the sequence (every K = N // BATCHES steps)
BATCHES = 20


@dataclass
class OnlineRow:
    """One method's run: per-step ``seconds``, the mean variables relinearised and re-eliminated per step
    (NaN where unknown), the final chi2, and ``note`` (why it did not run, or how it ran)."""

    label: str
    seconds: np.ndarray = field(default_factory=lambda: np.zeros(0))
    relinearized: float = float("nan")
    reeliminated: float = float("nan")
    chi2: float = float("nan")
    note: str = ""
    calls: list = field(default_factory=list)  # [(module.function, calls, seconds)] with ``breakdown``


def load(name: str):
    """``(graph, dimension)``: a 2D pose graph (``course.problems.posegraph``) or a 3D one (``posegraph3d``)."""
    from course.problems.posegraph3d import dataset as dataset3d

    if name in dataset3d.dataset_names() or name.endswith(".g2o") and _is_3d(name):
        return dataset3d.load_dataset(name), 3
    from course.problems.posegraph import dataset

    return dataset.load_dataset(name), 2


def _is_3d(path: str) -> bool:
    with open(path) as f:
        return any(line.startswith(("VERTEX_SE3", "EDGE_SE3")) for line in f)


def factor_graph(graph, dim: int):
    if dim == 2:
        from course.problems.posegraph import factor_graph as planar
        return planar.as_factor_graph(graph)
    from course.problems.posegraph3d import factor_graph as spatial
    return spatial.as_factor_graph(graph)


def chi2_of(graph, dim: int, values) -> float:
    """The dataset's chi2 at ``values`` (a list of stored values by pose, or (N, 3) for 2D)."""
    if dim == 2:
        return float(graph.chi2(np.asarray(values, dtype=float).reshape(-1, 3)))
    x = np.asarray(values, dtype=float).reshape(-1, 12)
    return float(graph.chi2(x[:, :3], x[:, 3:].reshape(-1, 3, 3)))


def run_ours(graph, dim: int, impl, relinearize_threshold=0.01, wildfire_threshold=0.001, iterate: bool = True,
             breakdown: bool = False):
    """``(row, iterated chi2, smoother)``: our smoother over the sequence; then the last update iterated to
    convergence (relinearisation and wildfire thresholds 0, no new factor, until chi2 stops falling). With
    ``breakdown``, ``row.calls`` holds the calls and seconds of each function of the implementation the updates
    called (``SMOOTHER_CALLS``)."""
    from course.core.call_times import CallTimes
    from course.incremental import IncrementalSmoother
    from course.incremental.online import OnlineSequence

    sequence = OnlineSequence(factor_graph(graph, dim), prior_sigma=PRIOR_SIGMA)
    smoother = IncrementalSmoother(impl, relinearize_threshold, wildfire_threshold)
    n = len(sequence)
    seconds, relin, reelim = np.zeros(n), np.zeros(n), np.zeros(n)
    previous = None
    times = CallTimes(smoother.impl, SMOOTHER_CALLS if breakdown else {})
    with times:
        for k in range(n):
            factors, values = sequence.step(k, previous)
            start = time.perf_counter()
            result = smoother.update(factors, values)
            seconds[k] = time.perf_counter() - start
            relin[k], reelim[k] = result.relinearized, result.reeliminated
            previous = smoother.estimate_of(k)
    estimate = smoother.estimate_list()
    row = OnlineRow("ours (incremental)", seconds, float(relin.mean()), float(reelim.mean()),
                    chi2_of(graph, dim, estimate), calls=times.rows())
    iterated = float("nan")
    if iterate:
        smoother.relinearize_threshold = smoother.wildfire_threshold = 0.0
        last = row.chi2
        for _ in range(50):
            smoother.update()
            iterated = chi2_of(graph, dim, smoother.estimate_list())
            if abs(last - iterated) <= 1e-12 * max(1.0, last):
                break
            last = iterated
    return row, iterated, smoother


def run_gtsam(graph, dim: int) -> OnlineRow:
    label = "GTSAM ISAM2"
    if not peers.installed("gtsam"):
        return OnlineRow(label, note=peers.missing_message("gtsam"))
    from course.backends.gtsam_isam2_feed import IsamFailed

    try:
        if dim == 2:
            from course.backends.posegraph import gtsam_isam2 as planar

            out = planar.run_online(graph, PRIOR_SIGMA)
            chi2 = chi2_of(graph, 2, out["poses"])
        else:
            from course.backends.posegraph3d import gtsam_isam2 as spatial

            out = spatial.run_online(graph, PRIOR_SIGMA)
            chi2 = float(graph.chi2(out["t"], out["R"]))
    except IsamFailed as exc:  # a row that says where, and the other rows still run
        return OnlineRow(label, note=str(exc))
    return OnlineRow(label, out["seconds"], float(out["relinearized"].mean()), float(out["reeliminated"].mean()), chi2)


def _prefix(graph, dim: int, k: int, estimate):
    """The graph of poses 0..k and the edges among them, its poses at ``estimate`` (k + 1 values)."""
    keep = np.maximum(graph.edges_i, graph.edges_j) <= k
    if dim == 2:
        from course.problems.posegraph.graph import PoseGraph

        return PoseGraph(np.asarray(estimate, dtype=float).reshape(-1, 3), graph.edges_i[keep], graph.edges_j[keep],
                         graph.measurements[keep], graph.information[keep], fixed=np.array([0]),
                         name=f"{graph.name}[:{k + 1}]")
    from course.problems.posegraph3d.graph import PoseGraph3D

    x = np.asarray(estimate, dtype=float).reshape(-1, 12)
    return PoseGraph3D(x[:, :3], x[:, 3:].reshape(-1, 3, 3), graph.edges_i[keep], graph.edges_j[keep],
                       graph.t_z[keep], graph.R_z[keep], graph.information[keep], fixed=np.array([0]),
                       name=f"{graph.name}[:{k + 1}]")


def _stored(graph, dim: int):
    """The file's poses as stored values (N, 3) or (N, 12)."""
    if dim == 2:
        return graph.poses.copy()
    return np.concatenate([graph.t, graph.R.reshape(-1, 9)], axis=1)


def _odometry(graph, dim: int) -> dict:
    """Pose k -> the between measurement from pose k - 1 to k (an edge from k to k - 1 reversed)."""
    from course.factorgraph import SE2, SE3
    from course.incremental.online import inverse

    kind = SE2 if dim == 2 else SE3
    odometry: dict = {}
    for e in range(len(graph.edges_i)):
        i, j = int(graph.edges_i[e]), int(graph.edges_j[e])
        z = graph.measurements[e] if dim == 2 else np.concatenate([graph.t_z[e], graph.R_z[e].ravel()])
        if j == i + 1 and j not in odometry:
            odometry[j] = z
        elif i == j + 1 and i not in odometry:
            odometry[i] = inverse(kind, z)
    return odometry


def _compose_tail(graph, dim: int, odometry: dict, estimate, start: int, stop: int):
    """Poses ``start..stop-1`` appended to ``estimate`` by the ``odometry`` from the last one (or the file's)."""
    from course.factorgraph import SE2, SE3
    from course.incremental.online import compose

    kind = SE2 if dim == 2 else SE3
    file = _stored(graph, dim)
    out = list(estimate)
    for k in range(start, stop):
        out.append(compose(kind, out[-1], odometry[k]) if k in odometry and out else file[k])
    return out


def run_batch(graph, dim: int, every: int, solve) -> OnlineRow:
    """A batch solve of the graph so far every ``every`` steps (and at the last), from the previous solution
    with the poses since composed by odometry; ``solve(subgraph) -> stored values`` times itself."""
    n = graph.num_poses
    stops = sorted(set(range(every - 1, n, every)) | {n - 1})
    odometry = _odometry(graph, dim)
    estimate: list = []
    seconds = []
    for k in stops:
        estimate = _compose_tail(graph, dim, odometry, estimate, len(estimate), k + 1)
        sub = _prefix(graph, dim, k, estimate)
        values, elapsed = solve(sub)
        seconds.append(elapsed)
        estimate = list(np.asarray(values, dtype=float).reshape(k + 1, -1))
    return OnlineRow("", np.array(seconds), chi2=chi2_of(graph, dim, estimate))


def _problem(graph, dim: int, impl):
    """The chapter-2 or chapter-6 problem of ``graph``."""
    if dim == 2:
        from course.problems.posegraph.problem import PoseGraphProblem
        return PoseGraphProblem(graph, impl=impl)
    from course.problems.posegraph3d.problem import PoseGraph3DProblem
    return PoseGraph3DProblem(graph, impl=impl)


def ours_batch_solve(impl, dim: int, method="gauss-newton", max_iterations=20):
    from course.solver.minimizer import minimize
    from course.solver.options import SolverOptions

    def solve(sub):
        start = time.perf_counter()
        problem = _problem(sub, dim, impl)
        result = minimize(problem, method, impl, SolverOptions(max_iterations=max_iterations))
        return np.asarray(result.params), time.perf_counter() - start
    return solve


def g2o_batch_solve(dim: int):
    def solve(sub):
        if dim == 2:
            from course.backends.posegraph.g2o import solve as g2o_solve

            result = g2o_solve(sub, "gauss-newton", 20)
            return np.asarray(result.params), result.seconds
        from course.backends.posegraph3d.g2o import solve as g2o_solve

        result = g2o_solve(sub, "gauss-newton", 20)
        return np.asarray(result.params).reshape(-1, 12), result.seconds
    return solve


def batch_minimum(graph, dim: int, impl) -> float:
    """The chi2 of the course's LM run to convergence on the whole dataset from the file's poses."""
    from course.solver.minimizer import minimize
    from course.solver.options import SolverOptions

    result = minimize(_problem(graph, dim, impl), "lm-type3", impl, SolverOptions(max_iterations=200))
    return float(result.final_chi2)


def compare(name: str, impl, every=None, batches: bool = True, poses=None, breakdown: bool = False) -> dict:
    """Every method's row on dataset ``name`` (its first ``poses`` poses where given): ``{"rows", "every",
    "minimum", "iterated", "poses", "name", "edges"}``; ``breakdown``: our row's ``calls`` (:func:`run_ours`)."""
    graph, dim = load(name)
    if poses is not None and poses < graph.num_poses:
        if poses < 2:
            raise ValueError(f"--poses must be at least 2, got {poses}")
        graph = _prefix(graph, dim, poses - 1, _stored(graph, dim)[:poses])
        name = f"{name}[:{poses}]"
    n = graph.num_poses
    every = every or max(1, n // BATCHES)
    rows = []
    iterated = float("nan")
    try:
        ours, iterated, _ = run_ours(graph, dim, impl, breakdown=breakdown)
        rows.append(ours)
    except NotImplementedError as exc:
        rows.append(OnlineRow("ours (incremental)", note=not_implemented_reason(exc)))
    rows.append(run_gtsam(graph, dim))
    if batches:
        try:
            row = run_batch(graph, dim, every, ours_batch_solve(impl, dim))
            row.label = "ours batch (Gauss-Newton)"
            rows.append(row)
        except NotImplementedError as exc:
            rows.append(OnlineRow("ours batch (Gauss-Newton)", note=not_implemented_reason(exc)))
        if peers.installed("g2opy"):
            row = run_batch(graph, dim, every, g2o_batch_solve(dim))
            row.label = "g2o batch (Gauss-Newton)"
            rows.append(row)
        else:
            rows.append(OnlineRow("g2o batch (Gauss-Newton)", note=peers.missing_message("g2opy")))
    from_file = float("nan")
    try:
        from_file = batch_minimum(graph, dim, impl)
    except NotImplementedError as exc:
        rows.append(OnlineRow("batch minimum", note=not_implemented_reason(exc)))
    # LM from the file's poses can stop in a local minimum above the one the online estimate, iterated, finds
    # (mit's start): the rows are compared with the lower of the two
    minimum = float(np.nanmin([from_file, iterated])) if np.isfinite([from_file, iterated]).any() else from_file
    return {"rows": rows, "every": every, "minimum": minimum, "from_file": from_file, "iterated": iterated,
            "poses": n, "name": name, "edges": graph.num_edges}


def format_table(result: dict) -> str:
    """The table: per method the step times (ms), totals (s), variables per step and final chi2."""
    header = (f"{'method':<28}{'steps':>6}{'median ms':>11}{'p90 ms':>9}{'worst ms':>10}{'total s':>9}"
              f"{'relin/step':>11}{'reelim/step':>12}{'final chi2':>14}{'vs minimum':>12}")
    lines = [header, "-" * len(header)]
    minimum = result["minimum"]
    for row in result["rows"]:
        if row.note and not len(row.seconds):
            lines.append(f"{row.label:<28}{row.note}")
            continue
        ms = 1e3 * row.seconds
        ratio = f"{row.chi2 / minimum - 1:+.2e}" if np.isfinite(minimum) else "-"
        lines.append(f"{row.label:<28}{len(ms):>6}{np.median(ms):>11.3f}{np.percentile(ms, 90):>9.3f}{ms.max():>10.1f}"
                     f"{ms.sum() / 1e3:>9.2f}{_number(row.relinearized):>11}{_number(row.reeliminated):>12}"
                     f"{row.chi2:>14.6f}{ratio:>12}")
    timed = {row.label: row.seconds for row in result["rows"] if len(row.seconds)}
    if "ours (incremental)" in timed and "GTSAM ISAM2" in timed:
        ours, isam = timed["ours (incremental)"], timed["GTSAM ISAM2"]
        lines.append(f"ours / GTSAM ISAM2, this run: total time {ours.sum() / isam.sum():.2f}x, median step "
                     f"{np.median(ours) / np.median(isam):.2f}x")
    from_file = result.get("from_file", minimum)
    if np.isfinite(from_file) and from_file > minimum * (1 + 1e-9):
        lines.append(f"minimum: chi2 {minimum:.6f}, ours iterated to convergence from the online estimate; LM on the "
                     f"whole dataset from the file's poses stops at {from_file:.6f}, a local minimum above it")
    elif np.isfinite(minimum):
        lines.append(f"batch minimum (ours, LM on the whole dataset): chi2 {minimum:.6f}")
    if np.isfinite(result["iterated"]) and np.isfinite(minimum):
        lines.append(f"ours, the last update iterated to convergence: chi2 {result['iterated']:.6f} "
                     f"({result['iterated'] / minimum - 1:+.2e} vs the minimum)")
    ours = next((row for row in result["rows"] if row.label == "ours (incremental)" and row.calls), None)
    if ours is not None:
        lines += ["", format_breakdown(ours)]
    return "\n".join(lines)


def format_breakdown(row: OnlineRow) -> str:
    """Where our updates' time went: each function of the implementation they called (its calls, seconds, share
    of the updates' total, microseconds a call), then the framework's part (the rest)."""
    total = float(row.seconds.sum())
    lines = [f"our updates' {total:.2f} s by the implementation's function (each call timed; the rest is the "
             "framework's)",
             f"{'function':<42}{'calls':>8}{'total s':>9}{'share':>7}{'us/call':>9}"]
    inside = 0.0
    for label, calls, seconds in row.calls:
        inside += seconds
        lines.append(f"{label:<42}{calls:>8}{seconds:>9.3f}{seconds / total:>7.0%}{1e6 * seconds / calls:>9.0f}")
    steps = len(row.seconds)
    count = sum(calls for _, calls, _ in row.calls)
    lines.append(f"{'all of them (' + f'{count / steps:.1f} calls per update)':<42}{count:>8}{inside:>9.3f}"
                 f"{inside / total:>7.0%}")
    lines.append(f"{'the framework':<42}{'':>8}{total - inside:>9.3f}{(total - inside) / total:>7.0%}")
    return "\n".join(lines)


def _number(value: float) -> str:
    return "-" if not np.isfinite(value) else f"{value:.1f}"


def figure(result: dict):
    """The time per step over the sequence: ours, GTSAM's, and the batch re-solves at their steps (a
    matplotlib Figure, log scale)."""
    from course.app.plot import figure as new_figure

    fig = new_figure(9, 4)
    ax = fig.add_subplot()
    n, every = result["poses"], result["every"]
    for row in result["rows"]:
        if not len(row.seconds):
            continue
        if len(row.seconds) == n:
            ax.plot(np.arange(n), 1e3 * row.seconds, lw=0.6, label=row.label)
        else:
            steps = sorted(set(range(every - 1, n, every)) | {n - 1})
            ax.plot(steps, 1e3 * row.seconds, "o-", ms=3, label=f"{row.label}, every {every} steps")
    ax.set_yscale("log")
    ax.set_xlabel("step (pose added)")
    ax.set_ylabel("time per step (ms)")
    ax.set_title(f"{result['name']}: online, one pose per step")
    ax.legend()
    return fig


def plot(result: dict, path) -> None:
    """:func:`figure` written as a PNG at ``path``."""
    from course.app.plot import save

    save(figure(result), path)
