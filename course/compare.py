"""Run one dataset through our methods and the peers; format the table; write JSON.

A *runner* turns a dataset name into ``list[RunResult]``; ``RUNNERS`` maps a dataset
kind to its runner and ``run(dataset, ...)`` picks the first kind whose ``matches``
accepts the name: ``curve`` (chapter 1, generated data) and ``posegraph`` (chapter 2:
named datasets such as ``intel`` or ``m3500``, ``manhattan:N`` and file paths).

A runner is called as ``runner(dataset, impl=..., methods=..., backends=..., repeat=...,
max_iterations=...)``
(``python -m course compare`` passes exactly these; ``repeat`` = solves per pair, the
median-time run kept) and returns ``list[RunResult]`` with ``final_chi2`` evaluated by
our own error, whatever the back end.
"""

import importlib
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Optional

import numpy as np

from course.errors import CourseError
from course.trace import RunResult

#: our methods on the curve, in table order; "dogleg" runs once course.solvers.dogleg exists
OUR_CURVE_METHODS = ("gauss-newton", "lm-type1", "lm-type2", "lm-type3", "dogleg")
#: the peers' methods on the curve: backend -> (module, methods)
PEER_CURVE_METHODS = {
    "ceres": ("course.backends.ceres_curve", ("levenberg-marquardt", "dogleg")),
    "scipy": ("course.backends.scipy_curve", ("lm", "trf")),
}


class UnknownDatasetError(CourseError, ValueError):
    """No registered runner accepts the dataset name."""


@dataclass
class Runner:
    kind: str
    run: Callable
    matches: Callable[[str], bool]
    description: str = ""


RUNNERS: dict = {}


def register(kind: str, runner: Callable, matches: Optional[Callable[[str], bool]] = None, description=""):
    """Register ``runner`` for dataset ``kind``; ``matches(name)`` defaults to ``name == kind``."""
    RUNNERS[kind] = Runner(kind, runner, matches or (lambda name, kind=kind: name == kind), description)


def find_runner(dataset: str) -> Runner:
    """The runner for ``dataset``, or ``UnknownDatasetError`` listing what is known."""
    for runner in RUNNERS.values():
        if runner.matches(dataset):
            return runner
    known = "; ".join(f"{r.kind}: {r.description}" if r.description else r.kind for r in RUNNERS.values())
    raise UnknownDatasetError(f"unknown dataset {dataset!r}; known datasets: {known}")


def run(dataset: str, impl="solutions", methods=None, backends=None, **options) -> list:
    """Run ``dataset`` through every (backend, method) pair (filtered by ``methods``/``backends``)."""
    return find_runner(dataset).run(dataset, impl=impl, methods=methods, backends=backends, **options)


# ---------------------------------------------------------------- curve (chapter 1)


def curve_plan(methods=None, backends=None) -> list:
    """The ``(backend, method)`` pairs to run on the curve, filtered, in table order.

    ``methods`` and ``backends`` are iterables of names (None = all); a method name
    selects it in every backend that has it (``dogleg`` is ours and Ceres').
    """
    pairs = [("ours", m) for m in OUR_CURVE_METHODS]
    pairs += [(backend, m) for backend, (_, names) in PEER_CURVE_METHODS.items() for m in names]
    return filter_pairs(pairs, methods, backends, "the curve")


def filter_pairs(pairs, methods, backends, what: str) -> list:
    """``pairs`` whose backend is in ``backends`` and method in ``methods`` (None = all).

    A method name selects it in every backend that has it; unknown names raise
    ``ValueError`` listing the valid ones for ``what``.
    """
    for names, index, kind in ((backends, 0, "backend"), (methods, 1, "method")):
        if names is None:
            continue
        names = list(names)
        valid = sorted({p[index] for p in pairs})
        unknown = [n for n in names if n not in valid]
        if unknown:
            raise ValueError(f"unknown {kind}(s) {unknown} for {what}; choose from {valid}")
        pairs = [p for p in pairs if p[index] in names]
    if not pairs:
        raise ValueError(f"no (backend, method) pair left for backends={backends} and methods={methods}")
    return pairs


def _dogleg_missing(exc: ModuleNotFoundError) -> bool:
    """True when the error says our dogleg is not written yet (loop or exercise module)."""
    name = exc.name or ""
    return name == "course.solvers.dogleg" or name.endswith(".dogleg")


def _median_run(solve, repeat: int) -> RunResult:
    """Run ``solve()`` ``repeat`` times and keep the run with the median time."""
    runs = [solve() for _ in range(max(int(repeat), 1))]
    return sorted(runs, key=lambda r: r.seconds)[len(runs) // 2]


def run_curve(impl="solutions", methods=None, backends=None, data=None, repeat=1, max_iterations=100,
              solver_options=None) -> list:
    """The chapter 1 comparison: our methods and the peers on one ``CurveData``.

    Args:
        impl: ``solutions``, ``exercises`` or a path (whose pieces our solvers use).
        methods, backends: filters, see ``curve_plan`` (None = everything).
        data: a ``CurveData``; default ``course.problems.curve.generate()``.
        repeat: solve each pair ``repeat`` times and keep the median-time run.
        max_iterations: for every solver (step attempts; scipy: ``max_nfev - 1``).
        solver_options: a ``SolverOptions`` for our solvers (its ``max_iterations``
            wins); default ``SolverOptions(max_iterations=max_iterations)``. The peers
            keep their own tight tolerances.

    Returns:
        ``list[RunResult]`` in ``curve_plan`` order. Our ``dogleg`` is skipped while
        ``course.solvers.dogleg`` (or the implementation's ``dogleg`` module) does not
        exist; any other error propagates.
    """
    from course.problems.curve import CurveProblem, generate
    from course.solvers import SolverOptions, minimize

    data = generate() if data is None else data
    options = SolverOptions(max_iterations=max_iterations) if solver_options is None else solver_options
    results = []
    for backend, method in curve_plan(methods, backends):
        if backend == "ours":
            def solve(method=method):
                return minimize(CurveProblem(data, impl=impl), method, impl=impl, options=options)
        else:
            module = importlib.import_module(PEER_CURVE_METHODS[backend][0])

            def solve(module=module, method=method):
                return module.solve(data, method, max_iterations=max_iterations)
        try:
            results.append(_median_run(solve, repeat))
        except ModuleNotFoundError as exc:
            if backend == "ours" and method == "dogleg" and _dogleg_missing(exc):
                continue
            raise
    return results


def _curve_runner(dataset, impl="solutions", methods=None, backends=None, **options):
    return run_curve(impl=impl, methods=methods, backends=backends, **options)


register("curve", _curve_runner, description="y = exp(a x^2 + b x + c), 100 generated points (chapter 1)")


# ---------------------------------------------------------------- pose graphs (chapter 2)

OUR_POSE_GRAPH_METHODS = ("gauss-newton", "lm-type1", "lm-type2", "lm-type3", "dogleg")


def posegraph_plan(methods=None, backends=None) -> list:
    """The ``(backend, method)`` pairs to run on a pose graph, filtered, in table order."""
    from course.backends import POSE_GRAPH_METHODS

    pairs = [("ours", m) for m in OUR_POSE_GRAPH_METHODS]
    pairs += [(b, m) for b, names in POSE_GRAPH_METHODS.items() for m in names]
    return filter_pairs(pairs, methods, backends, "pose graphs")


def run_posegraph(graph, impl="solutions", methods=None, backends=None, repeat=1, max_iterations=100) -> list:
    """Every method and peer on one ``PoseGraph``, same start, same fixed poses.

    Returns ``list[RunResult]`` (``params`` (N, 3) poses); where the graph has ground
    truth each result carries ``ate`` (see ``course.trajectory``).
    """
    from course.backends import POSE_GRAPH_BACKENDS
    from course.problems.posegraph import PoseGraphProblem
    from course.solvers import SolverOptions, minimize
    from course.trajectory import absolute_trajectory_error

    options = SolverOptions(max_iterations=max_iterations)
    results = []
    for backend, method in posegraph_plan(methods, backends):
        if backend == "ours":
            def solve(method=method):
                result = minimize(PoseGraphProblem(graph, impl), method, impl=impl, options=options)
                result.params = result.params.reshape(-1, 3)
                return result
        else:
            def solve(backend=backend, method=method):
                kwargs = {"impl": impl} if backend == "ceres" else {}
                return POSE_GRAPH_BACKENDS[backend](graph, method, max_iterations, **kwargs)
        result = _median_run(solve, repeat)
        if graph.ground_truth is not None:
            result.ate = absolute_trajectory_error(result.params, graph.ground_truth)
        results.append(result)
    return results


def is_posegraph_name(name: str) -> bool:
    from course import datasets

    return name in datasets.dataset_names() or name.startswith("manhattan:") or Path(name).exists() \
        or Path(name + "-v.dat").exists()


def _posegraph_runner(dataset, impl="solutions", methods=None, backends=None, **options):
    from course import datasets

    return run_posegraph(datasets.load_dataset(dataset), impl=impl, methods=methods,
                         backends=backends, **options)


register("posegraph", _posegraph_runner, matches=is_posegraph_name,
         description="a named pose graph (python -m course datasets), manhattan:N, or a TORO/g2o file")


def format_ate(runs) -> str:
    """Absolute trajectory error per run (only runs that carry ``ate``)."""
    rows = [r for r in runs if getattr(r, "ate", None)]
    if not rows:
        return ""
    head = f"{'backend':8} {'method':22} " + " ".join(
        f"{kind[:5]}-{stat:6}" for kind in ("translation", "rotation") for stat in ("rmse", "median", "std", "max", "min"))
    lines = ["absolute trajectory error (m, rad) after SE(2) alignment", head]
    for r in rows:
        cells = [f"{r.ate[kind][stat]:12.4g}" for kind in ("translation", "rotation")
                 for stat in ("rmse", "median", "std", "max", "min")]
        lines.append(f"{r.backend:8} {r.method:22} " + " ".join(cells))
    return "\n".join(lines)


# ---------------------------------------------------------------- table and JSON


def _params_text(params) -> Optional[str]:
    p = np.asarray(params, dtype=float)
    if p.ndim != 1 or p.size > 6:
        return None
    return " ".join(f"{v:.6f}" for v in p)


def format_table(runs, title: str = "") -> str:
    """A plain-text table: backend, method, iterations, initial and final chi2, total
    and per-iteration time (milliseconds), and the parameters when they are few (the curve)."""
    header = ["backend", "method", "iters", "initial chi2", "final chi2", "total ms", "ms/iter"]
    params = [_params_text(r.params) for r in runs]
    show_params = bool(runs) and all(p is not None for p in params)
    if show_params:
        header.append("params")
    rows = []
    for r, p in zip(runs, params):
        row = [
            r.backend,
            r.method,
            str(r.iterations),
            f"{r.initial_chi2:.6g}",
            f"{r.final_chi2:.10g}",
            f"{1e3 * r.seconds:.3f}",
            f"{1e3 * r.seconds_per_iteration:.4f}",
        ]
        if show_params:
            row.append(p)
        rows.append(row)
    widths = [max(len(h), *(len(row[k]) for row in rows)) if rows else len(h) for k, h in enumerate(header)]
    numeric = {2, 3, 4, 5, 6}

    def line(cells):
        return "  ".join(c.rjust(w) if k in numeric else c.ljust(w) for k, (c, w) in enumerate(zip(cells, widths))).rstrip()

    out = [title] if title else []
    out += [line(header), line(["-" * w for w in widths])]
    out += [line(row) for row in rows]
    return "\n".join(out)


def to_json(dataset: str, runs) -> dict:
    """``{"dataset": dataset, "runs": [RunResult.to_json(), ...]}`` (JSON-ready)."""
    return {"dataset": str(dataset), "runs": [r.to_json() for r in runs]}

