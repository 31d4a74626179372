"""Run one dataset through our methods and the peers; format the table; write JSON.

A *runner* turns a dataset name into ``list[RunResult]``; ``RUNNERS`` lists them in the
order ``find_runner`` tries them, and ``run(dataset, ...)`` takes the first whose ``matches``
accepts the name: ``curve`` (chapter 1, generated data), ``bal`` (chapter 4: ``ladybug-49``,
``dubrovnik-3-7``, ``bal-synthetic:CAMS:POINTS[:seed]``, BAL files) and ``posegraph`` (chapter 2:
named datasets such as ``intel`` or ``m3500``, ``manhattan:N`` and file paths).

A runner is called as ``runner(dataset, impl=..., methods=..., backends=..., repeat=...,
max_iterations=...)`` (``python -m course compare`` passes exactly these, and to pose graphs
``init`` and ``information``, the reader's repair of information matrices that are not positive
definite, ``course.solver.information``; ``repeat`` = solves per pair, the median-time run kept)
and returns ``list[RunResult]`` with ``final_chi2`` evaluated by our own error, whatever the
back end; where the reader repaired edges, every result says how many (``RunResult.note``).

``impl=None`` means this tree's own implementation: ``solutions`` in the course's repository,
``exercises`` in a student tree. ``unimplemented="row"`` (the demo's choice)
turns a pair that stops at an unwritten TODO (``NotImplementedError``) into a row saying
so (``RunResult.not_run``) instead of stopping the whole comparison (``compare`` and ``demo`` always
ask for it; ``todo_hint`` says how to select what is written); the default ``"raise"`` lets the
error through. Each row records the implementation's functions its run called (``RunResult.called``,
``course.core.calls``), and ``advice`` gives the lines naming them when a row that ran the student's
code (ours, and Ceres' with the student's cost) ends above the other peers' best chi2 or at the
iteration limit. A peer whose library is not
installed here is always a row (``not run: gtsam is not installed here``), said once on stderr
(``course.core.peers``).
"""

import contextlib
import re
from collections.abc import Callable
from dataclasses import dataclass
from functools import partial
from pathlib import Path

import numpy as np

from course.backends import registry
from course.core import chapters
from course.core.backend_names import FACTOR_GRAPH_BACKENDS, OURS
from course.core.errors import CourseError
from course.core.impl import default_impl, failure_reason, not_implemented_reason
from course.core.impl import load as load_impl
from course.core.peers import PeerMissing
from course.core.progress import quiet
from course.core.trace import RunResult
from course.solver.choice import check_name


class UnknownDatasetError(CourseError, ValueError):
    """No runner of ``RUNNERS`` accepts the dataset name."""


@dataclass(frozen=True)
class Runner:
    """A dataset kind: ``matches(name)`` says whether ``run(name, ...)`` takes the name."""

    kind: str
    matches: Callable[[str], bool]
    run: Callable
    description: str = ""


def find_runner(dataset: str) -> Runner:
    """The first of ``RUNNERS`` that accepts ``dataset``, or ``UnknownDatasetError`` listing what is known.
    A kind whose chapter this tree does not hold (an assignment's tree) is not tried: the error names it
    as not handed out yet."""
    here = [r for r in RUNNERS if chapters.handed_out(chapters.of_family(r.kind).name)]
    for runner in here:
        if runner.matches(dataset):
            return runner
    known = "; ".join(f"{r.kind}: {r.description}" if r.description else r.kind for r in here)
    later = [f"chapter {chapters.of_family(r.kind).name[2:]}'s {r.kind}: {r.description or r.kind}"
             for r in RUNNERS if r not in here]
    missing = f"; not handed out yet in this tree: {'; '.join(later)}" if later else ""
    raise UnknownDatasetError(f"unknown dataset {dataset!r}; known datasets: {known}{missing}")


def run(dataset: str, impl=None, methods=None, backends=None, **options) -> list:
    """Run ``dataset`` through every (backend, method) pair (filtered by ``methods``/``backends``)."""
    return find_runner(dataset).run(dataset, impl=impl, methods=methods, backends=backends, **options)


# ---------------------------------------------------------------- curve (chapter 1)


def curve_plan(methods=None, backends=None) -> list:
    """The ``(backend, method)`` pairs to run on the curve, filtered, in table order.

    ``methods`` and ``backends`` are iterables of names (None = the default: every back end,
    every peer method and our ``DEFAULT_METHODS``); a method name selects it in every backend
    that has it (``dogleg`` is ours and Ceres'). See ``plan_for``.
    """
    return plan_for("curve", methods, backends)


#: what ``plan_for``'s errors call each kind of problem
WHAT = {"curve": "the curve", "posegraph": "pose graphs", "posegraph3d": "3D pose graphs", "bal": "bundle adjustment"}


def plan_for(kind: str, methods=None, backends=None) -> list:
    """The ``(backend, method)`` pairs to run on problems of ``kind``, filtered, in table order.

    Every method ``registry.pairs(kind, every=True)`` lists is offered: every strategy of our
    minimizer (``course.core.method_names.OUR_METHODS``) and the peers'. ``methods=None`` runs
    the default (``registry.pairs(kind)``: ours but ``lm-scaled-nielsen``, which runs when
    named); ``ValueError`` on an unknown name, listing the valid ones for ``kind``.
    """
    return filter_pairs(registry.pairs(kind, every=True), methods, backends, WHAT[kind], default=registry.pairs(kind))


def filter_pairs(pairs, methods, backends, what: str, default=None) -> list:
    """``pairs`` whose backend is in ``backends`` and method in ``methods`` (None = all). With
    ``default`` given, a back end that ``default`` leaves out (chapter 7's) runs only when ``backends``
    names it, with every method it offers unless ``methods`` says which; ``methods=None`` otherwise
    means the pairs of ``default``.

    A method name selects it in every backend that has it; unknown names raise
    ``ValueError`` listing the valid ones for ``what``, in table order.
    """
    offered = pairs
    if default is not None:  # a back end the default leaves out runs when --backends names it
        in_default = {p[0] for p in default}
        named = set(backends or ())
        if methods is None:  # the default, and every method of a named back end it leaves out
            pairs = [p for p in offered if p in default or p[0] in named and p[0] not in in_default]
        else:
            pairs = [p for p in offered if p[0] in in_default or p[0] in named]
    for names, index, kind in ((backends, 0, "backend"), (methods, 1, "method")):
        if names is None:
            continue
        names = list(names)
        valid = list(dict.fromkeys(p[index] for p in offered))
        unknown = [n for n in names if n not in valid]
        if unknown:
            see = " (`python -m course compare --help` says what each is)" if kind == "method" else ""
            raise ValueError(f"unknown {kind}(s) {', '.join(unknown)} for {what}; choose from {', '.join(valid)}{see}")
        pairs = [p for p in pairs if p[index] in names]
    if not pairs:
        raise ValueError(f"no (backend, method) pair left for backends={backends} and methods={methods}")
    return pairs


def _tree_impl(impl):
    """``impl``, or this tree's default (``solutions`` when present, else ``exercises``)."""
    if impl is not None:
        return impl
    return default_impl()


def _solve_or_row(solve, repeat, backend, method, unimplemented) -> RunResult:
    """``_median_run(solve, repeat)``; with ``unimplemented="row"`` a ``NotImplementedError``
    becomes a ``RunResult.skipped`` row naming the TODO, and any other error of our run a row
    ``failed: ...`` naming it (the implementation's code raised or broke a contract), so that one
    broken exercise never hides the other rows; a missing peer library always is a row."""
    if unimplemented not in ("raise", "row"):
        raise ValueError(f"unimplemented must be 'raise' or 'row', got {unimplemented!r}")
    try:
        return _median_run(solve, repeat)
    except PeerMissing as exc:
        return RunResult.skipped(backend, method, f"not run: {exc.library} is not installed here")
    except chapters.NotHandedOut as exc:  # an assignment's tree: a later chapter's back end
        return RunResult.skipped(backend, method, f"not run: {exc}")
    except NotImplementedError as exc:
        if unimplemented == "raise":
            raise
        return RunResult.skipped(backend, method, not_implemented_reason(exc))
    except Exception as exc:  # our run on the implementation's code: a row that names the error
        if unimplemented == "raise" or not backend.startswith(OURS):
            raise
        return RunResult.skipped(backend, method, failure_reason(exc))


def factor_graph_run(graph, backend: str, method: str, impl, options, solver=None, callback=None) -> RunResult:
    """A factor graph (chapter 7) solved by ``backend``: our minimizer's ``method``, its Jacobians as
    ``FACTOR_GRAPH_BACKENDS`` says (the implementation's Jets, central differences, or JAX, compiled
    before the solve: ``compile_seconds``), or a factor graphs' peer (``registry.FACTOR_GRAPH_PEERS``:
    GTSAM on custom factors, ``options.max_iterations`` iterations at most). ``solver``: our sparse
    solve (``course.solver.choice``; ``None``: ``auto``); ``callback``: our minimizer's, after each step
    attempt. ``PeerMissing`` when the back end's library is not installed here."""
    from course.core import peers
    from course.factorgraph import FactorGraphProblem
    from course.solver import minimize

    if backend in registry.FACTOR_GRAPH_PEERS:
        result = registry.factor_graph_peer_solver(backend)(graph, method, options.max_iterations, impl=impl)
        return result
    compile_seconds = 0.0
    if FACTOR_GRAPH_BACKENDS[backend] == "jax":
        peers.require("jax")
        from course.backends.factorgraph import jax_factors

        problem = jax_factors.problem(graph, impl, solver=solver)
        compile_seconds = problem.jacobians.compile_seconds
    else:
        problem = FactorGraphProblem(graph, impl, jacobians=FACTOR_GRAPH_BACKENDS[backend], solver=solver)
    result = minimize(problem, method, impl=impl, options=options, callback=callback)
    result.backend, result.compile_seconds = backend, compile_seconds
    return result


def _run_peer(kind, backend, *args, **kwargs) -> RunResult:
    """One solve by a peer; ``PeerMissing`` when its library is not installed here."""
    return registry.peer_solver(kind, backend)(*args, **kwargs)


def _start_or_rows(initialise, graph, init, impl, plan, unimplemented):
    """``initialise(graph, init, impl)`` (``(graph, seconds, called)``: ``called`` the implementation's
    functions it ran, ``course.core.calls``), or, when the start is an unwritten TODO and
    ``unimplemented == "row"``, one row per pair of ``plan`` naming it."""
    try:
        with load_impl(impl).recording() as recording:
            graph, seconds = initialise(graph, init, impl)
        return graph, seconds, recording.names
    except NotImplementedError as exc:
        if unimplemented != "row":
            raise
        rows = [RunResult.skipped(backend, method, not_implemented_reason(exc)) for backend, method in plan]
        for row in rows:
            row.init = init
        return rows


def _with_repairs(results, graph) -> list:
    """``results``, each marked with how many of ``graph``'s edges had their information repaired
    by the reader (``graph.repaired``, ``graph.information_repair``)."""
    for result in results:
        result.repaired_edges, result.information_repair = graph.num_repaired, graph.information_repair
    return results


def _median_run(solve, repeat: int) -> RunResult:
    """Run ``solve()`` ``repeat`` times and keep the run with the median time."""
    runs = [solve() for _ in range(max(int(repeat), 1))]
    return sorted(runs, key=lambda r: r.seconds)[len(runs) // 2]


#: the sparse solve each peer's runs use (its library's default, as the back ends configure them)
PEER_SOLVES = {"gtsam": "gtsam-multifrontal", "gtsam-custom": "gtsam-multifrontal", "g2o": "g2o-eigen",
               "ceres": "ceres", "scipy": "scipy"}


def _run_pairs(plan, ours, peer, repeat=1, unimplemented="raise", progress=None,
               failures: type[Exception] | tuple[type[Exception], ...] = (), impl=None, started=()) -> list:
    """One ``RunResult`` per ``(backend, method)`` of ``plan``, in its order: the run loop of every kind.

    ``ours(method, callback)`` solves with our minimizer (``callback`` the progress line's, or
    None); ``peer(backend, method)`` with a peer. Each pair runs ``repeat`` times (the
    median-time run kept) or becomes a row (``_solve_or_row``); an exception among ``failures``
    becomes a row ``failed: ...``. With ``impl``, each row records in ``called`` the functions of
    the implementation that its pair ran (``course.core.calls``; a peer's row too: Ceres runs the
    implementation's cost), after ``started``, those the shared start ran.
    """
    progress = progress or quiet()
    results = []
    for backend, method in plan:
        with progress.run(backend, method) as callback:
            solve = partial(ours, method, callback) if backend == "ours" else partial(peer, backend, method)
            recording = load_impl(impl).recording() if impl is not None else None
            with recording or contextlib.nullcontext():
                try:
                    result = _solve_or_row(solve, repeat, backend, method, unimplemented)
                except failures as exc:
                    result = RunResult.skipped(backend, method, f"failed: {exc}")
                except Exception as exc:  # a peer's run that failed in the implementation's code (Ceres' cost)
                    if unimplemented == "raise" or recording is None or not recording.names:
                        raise
                    result = RunResult.skipped(backend, method, failure_reason(exc))
            if recording is not None:
                result.called = tuple(dict.fromkeys((*started, *recording.names)))
        if not result.linear_solve and not result.not_run:
            result.linear_solve = PEER_SOLVES.get(backend, "")
        results.append(result)
    return results


def run_curve(impl=None, methods=None, backends=None, data=None, repeat=1, max_iterations=100,
              solver_options=None, unimplemented="raise", progress=None) -> list:
    """The chapter 1 comparison: our methods and the peers on one ``CurveData``.

    Args:
        impl: ``solutions``, ``exercises`` or a path (whose pieces our solvers use);
            None: this tree's own (see the module docstring).
        methods, backends: filters, see ``curve_plan`` (None = the default).
        data: a ``CurveData``; default ``course.problems.curve.problem.generate()``.
        repeat: solve each pair ``repeat`` times and keep the median-time run.
        max_iterations: for every solver (step attempts; scipy: ``max_nfev - 1``).
        solver_options: a ``SolverOptions`` for our solvers (its ``max_iterations``
            wins); default ``SolverOptions(max_iterations=max_iterations)``. The peers
            keep their own tight tolerances.
        unimplemented: ``"raise"`` or ``"row"`` (a pair stopped by a TODO becomes a
            ``not_run`` row).
        progress: a ``course.core.progress.Progress`` to report to (default: quiet).

    Returns:
        ``list[RunResult]`` in ``curve_plan`` order; an error other than a TODO (with
        ``unimplemented="row"``) propagates.
    """
    from course.problems.curve.problem import CurveProblem, generate
    from course.solver import SolverOptions, minimize

    impl = _tree_impl(impl)
    data = generate() if data is None else data
    options = SolverOptions(max_iterations=max_iterations) if solver_options is None else solver_options

    def ours(method, callback):
        return minimize(CurveProblem(data, impl=impl), method, impl=impl, options=options, callback=callback)

    def peer(backend, method):  # the peers run the implementation's curve_model: its errors are rows too
        try:
            return _run_peer("curve", backend, data, method, max_iterations=max_iterations, impl=impl)
        except (PeerMissing, NotImplementedError):
            raise
        except Exception as exc:
            if unimplemented == "raise":
                raise
            return RunResult.skipped(backend, method, failure_reason(exc))

    return _run_pairs(curve_plan(methods, backends), ours, peer, repeat, unimplemented, progress, impl=impl)


#: the C++ source's own data (``course.problems.curve.source_data``), as a dataset name
CURVE_SOURCE = "curve:source"


def is_curve_name(name: str) -> bool:
    """``curve`` (generated, seed 0) and ``curve:source`` (the C++ source's draw): no files."""
    return name in ("curve", CURVE_SOURCE)


def _curve_runner(dataset, impl=None, methods=None, backends=None, solver=None, **options):
    if check_name(solver) != "auto":
        raise ValueError(f"--solver {solver}: the curve solves its 3 x 3 system dense (gauss_newton.solve_step); "
                         "the sparse solves are for pose graphs, bundle adjustment's factor graph and the like")
    if dataset == CURVE_SOURCE and options.get("data") is None:
        from course.problems.curve.source_data import source_data

        options["data"] = source_data()
    return run_curve(impl=impl, methods=methods, backends=backends, **options)


# ---------------------------------------------------------------- pose graphs (chapter 2)

def posegraph_plan(methods=None, backends=None) -> list:
    """The ``(backend, method)`` pairs to run on a pose graph, filtered, in table order."""
    return plan_for("posegraph", methods, backends)


def run_posegraph(graph, impl=None, methods=None, backends=None, repeat=1, max_iterations=100,
                  unimplemented="raise", progress=None, init="file", solver=None) -> list:
    """Every method and peer on one ``PoseGraph``, same start, same fixed poses.

    Returns ``list[RunResult]`` (``params`` (N, 3) poses); where the graph has ground
    truth each result carries ``ate`` (see ``course.problems.posegraph.trajectory``). ``impl`` and
    ``unimplemented`` and ``progress`` as in ``run_curve`` (Ceres' cost is the
    implementation's too). ``init`` (``course.app.starts.INITIALISERS``): the start,
    computed once by the implementation's initialiser and shared by every back end; each
    result records it in ``init`` and its time in ``init_seconds``. With
    ``unimplemented="row"`` an unwritten initialiser makes every pair a row naming its TODO.
    ``solver``: our sparse solve, a name of ``course.solver.choice.SOLVES`` (``None``: ``auto``), for
    ours and the factor-graph back ends; each row names the one it ran (``linear_solve``).
    """
    from course.app.starts import check_method, initialise
    from course.problems.posegraph.problem import MAX_DENSE_POSES, PoseGraphProblem
    from course.problems.posegraph.trajectory import absolute_trajectory_error
    from course.solver import SolverOptions, minimize

    impl = _tree_impl(impl)
    check_name(solver)
    options = SolverOptions(max_iterations=max_iterations)
    plan = posegraph_plan(methods, backends)
    check_method(init)
    started = _start_or_rows(initialise, graph, init, impl, plan, unimplemented)
    if isinstance(started, list):
        return _with_repairs(started, graph)
    graph, init_seconds, init_called = started

    def problem():
        try:
            return PoseGraphProblem(graph, impl, solver=solver)
        except ValueError as exc:  # too large for the per-edge loop while pose_graph_fast is a stub
            if unimplemented == "row" and graph.num_poses > MAX_DENSE_POSES and "pose_graph_fast" in str(exc):
                raise NotImplementedError(
                    f"TODO pose_graph_fast (the per-edge loop's dense H stops at {MAX_DENSE_POSES} poses)") from exc
            raise

    def ours(method, callback):
        result = minimize(problem(), method, impl=impl, options=options, callback=callback)
        result.params = result.params.reshape(-1, 3)
        return result

    def peer(backend, method):
        if backend in FACTOR_GRAPH_BACKENDS or backend in registry.FACTOR_GRAPH_PEERS:
            chapters.require("ch7", f"back end {backend}")
            from course.problems.posegraph.factor_graph import as_factor_graph

            result = factor_graph_run(as_factor_graph(graph), backend, method, impl, options, solver)
            result.params = result.params.reshape(-1, 3)
            return result
        kwargs = {"impl": impl} if backend == "ceres" else {}  # Ceres' edge cost is the implementation's
        return _run_peer("posegraph", backend, graph, method, max_iterations, **kwargs)

    results = _run_pairs(plan, ours, peer, repeat, unimplemented, progress, impl=impl, started=init_called)
    for result in results:
        if graph.ground_truth is not None and not result.not_run:
            result.ate = absolute_trajectory_error(result.params, graph.ground_truth)
        result.init, result.init_seconds = init, init_seconds
    return _with_repairs(results, graph)


def is_posegraph_name(name: str) -> bool:
    from course.problems.posegraph import dataset as datasets

    return name in datasets.dataset_names() or name.startswith("manhattan:") or Path(name).exists() \
        or Path(name + "-v.dat").exists()


def _posegraph_runner(dataset, impl=None, methods=None, backends=None, information="strict", **options):
    from course.problems.posegraph import dataset as datasets

    return run_posegraph(datasets.load_dataset(dataset, information=information), impl=impl, methods=methods,
                         backends=backends, **options)


def format_ate(runs) -> str:
    """Absolute trajectory error per run (only runs that carry ``ate``)."""
    rows = [r for r in runs if r.ate]
    if not rows:
        return ""
    head = f"{'backend':13} {'method':22} " + " ".join(
        f"{kind[:5]}-{stat:6}" for kind in ("translation", "rotation")
        for stat in ("rmse", "median", "std", "max", "min"))
    lines = ["absolute trajectory error (m, rad) after SE(2) alignment", head]
    for r in rows:
        cells = [f"{r.ate[kind][stat]:12.4g}" for kind in ("translation", "rotation")
                 for stat in ("rmse", "median", "std", "max", "min")]
        lines.append(f"{r.backend:13} {r.method:22} " + " ".join(cells))
    return "\n".join(lines)


# ---------------------------------------------------------------- bundle adjustment (chapter 4)

def bal_plan(methods=None, backends=None) -> list:
    """The ``(backend, method)`` pairs to run on a BAL problem, filtered, in table order."""
    return plan_for("bal", methods, backends)


def run_bal(problem, impl=None, methods=None, backends=None, repeat=1, max_iterations=100,
            unimplemented="raise", progress=None, fix_gauge=True, solver=None) -> list:
    """Every method and peer on one ``BALProblem`` (``course.problems.bal.dataset``), all from its own start.

    Ours: ``minimize(BundleAdjustmentProblem(problem, impl, fix_gauge), method)``: by default
    the gauge is fixed (camera 0's pose and one coordinate of camera 1), as every peer fixes it
    (pycolmap by itself, GTSAM with priors); ``fix_gauge=False`` shows what the free gauge does
    (Gauss-Newton then fails, and LM with lambda I converges slowly); the factor-graph back ends
    (chapter 7, run when named) solve its factor graph with the same gauge fixed (``graph.fix(key, dofs)``);
    the peers: ``course.backends.bal.colmap`` (Ceres), ``gtsam_bal``, ``scipy_bal``. Returns
    ``list[BALRunResult]`` (``course.backends.bal.common``: ``params`` the flat state,
    ``final_chi2`` our ``sum |r|^2`` over all observations, and each peer's own cost beside
    it). A run that stops on a singular system (undamped Gauss-Newton meets bundle
    adjustment's 7-dimensional gauge freedom) is a row ``failed: ...``. ``impl``,
    ``unimplemented``, ``progress`` as in ``run_curve``. ``solver`` (``course.solver.choice``) is the
    factor-graph back ends' sparse solve; ours keeps ``bundle_adjustment.schur_solve``.
    """
    from course.backends.bal.common import BALRunResult
    from course.core.errors import SingularSystemError
    from course.problems.bal.problem import BundleAdjustmentProblem
    from course.solver import SolverOptions, minimize

    impl = _tree_impl(impl)
    check_name(solver)
    options = SolverOptions(max_iterations=max_iterations)
    plan = bal_plan(methods, backends)

    def ours(method, callback):
        with steps_before_failure(callback) as watch:
            result = minimize(BundleAdjustmentProblem(problem, impl, fix_gauge=fix_gauge), method, impl=impl,
                              options=options, callback=watch)
        return BALRunResult.from_run(result, problem, peer_cost="ours: 0.5 sum |r|^2 over all observations")

    def peer(backend, method):
        if backend in FACTOR_GRAPH_BACKENDS or backend in registry.FACTOR_GRAPH_PEERS:
            chapters.require("ch7", f"back end {backend}")
            from course.problems.bal.factor_graph import as_factor_graph

            graph = as_factor_graph(problem, fix_gauge=fix_gauge)
            if backend in registry.FACTOR_GRAPH_PEERS:
                result = factor_graph_run(graph, backend, method, impl, options, solver)
            else:
                with steps_before_failure() as watch:
                    result = factor_graph_run(graph, backend, method, impl, options, solver, callback=watch)
            return BALRunResult.from_run(result, problem, peer_cost="ours: 0.5 sum |r|^2 over all observations")
        return _run_peer("bal", backend, problem, method, max_iterations)

    return _run_pairs(plan, ours, peer, repeat, unimplemented, progress, failures=SingularSystemError, impl=impl)


@contextlib.contextmanager
def steps_before_failure(callback=None):
    """A minimizer's callback (calling ``callback`` too) that records the chi2 of its steps, and a
    context that adds them to a ``SingularSystemError`` raised inside: ``(after 2 steps, chi2 7.2e+09,
    4.4e+18: the steps diverged first)`` says that the system went singular where the steps had
    diverged (undamped Gauss-Newton from a far start), not at the start (a free gauge)."""
    from course.core.errors import SingularSystemError

    chi2: list = []

    def watch(record):
        if record.accepted:
            chi2.append(record.chi2)
        return callback(record) if callback is not None else None

    try:
        yield watch
    except SingularSystemError as exc:
        if not chi2:
            raise
        path = ", ".join(f"{c:.2g}" for c in chi2[-4:])
        diverged = ": the steps diverged first" if len(chi2) > 1 and chi2[-1] > 10.0 * chi2[0] else ""
        raise SingularSystemError(f"{exc} (after {len(chi2)} step{'s' * (len(chi2) != 1)}, chi2 "
                                  f"{'..., ' * (len(chi2) > 4)}{path}{diverged})") from exc


def is_bal_name(name: str) -> bool:
    """A named BAL problem, ``bal-synthetic:CAMS:POINTS[:seed]``, or a file whose first line is a
    BAL header (three integers); any of them with ``:front`` appended."""
    from course.problems.bal.dataset import FRONT, bal_names

    if name.endswith(FRONT) and len(name) > len(FRONT):
        return is_bal_name(name[: -len(FRONT)])
    if name in bal_names() or name.startswith("bal-synthetic:"):
        return True
    path = Path(name)
    try:
        with path.open(encoding="utf-8", errors="replace") as file:
            first = file.readline().split()
    except OSError:  # not a file, or unreadable: not ours to claim
        return False
    return len(first) == 3 and all(token.isdigit() for token in first)


def _bal_runner(dataset, impl=None, methods=None, backends=None, **options):
    from course.problems.bal.dataset import load_bal

    return run_bal(load_bal(dataset), impl=impl, methods=methods, backends=backends, **options)


# ---------------------------------------------------------------- 3D pose graphs (chapter 6)

def posegraph3d_plan(methods=None, backends=None) -> list:
    """The ``(backend, method)`` pairs to run on a 3D pose graph, filtered, in table order."""
    return plan_for("posegraph3d", methods, backends)


def run_posegraph3d(graph, impl=None, methods=None, backends=None, repeat=1, max_iterations=100,
                    unimplemented="raise", progress=None, init="file", solver=None) -> list:
    """Every method and peer on one ``PoseGraph3D``, same start, same fixed poses.

    Returns ``list[RunResult]`` (``params`` the packed poses (12N,), ``final_chi2`` our error
    for every back end, see ``course.geometry.se3``). Arguments as in ``run_posegraph``;
    ``init`` is ``file``, ``chordal`` (the implementation's ``chordal_3d``) or ``initializepose3``
    (GTSAM's), computed once and shared by every back end, its time in each result's
    ``init_seconds``. ``solver`` as in ``run_posegraph``.
    """
    from course.app.starts import initialise_3d as initialise
    from course.problems.posegraph3d.problem import PoseGraph3DProblem
    from course.solver import SolverOptions, minimize

    impl = _tree_impl(impl)
    check_name(solver)
    options = SolverOptions(max_iterations=max_iterations)
    plan = posegraph3d_plan(methods, backends)
    started = _start_or_rows(initialise, graph, init, impl, plan, unimplemented)
    if isinstance(started, list):
        return _with_repairs(started, graph)
    graph, init_seconds, init_called = started

    def ours(method, callback):
        return minimize(PoseGraph3DProblem(graph, impl, solver=solver), method, impl=impl, options=options,
                        callback=callback)

    def peer(backend, method):
        if backend in FACTOR_GRAPH_BACKENDS or backend in registry.FACTOR_GRAPH_PEERS:
            chapters.require("ch7", f"back end {backend}")
            from course.problems.posegraph3d.factor_graph import as_factor_graph

            return factor_graph_run(as_factor_graph(graph), backend, method, impl, options, solver)
        kwargs = {"impl": impl} if backend == "ceres" else {}  # Ceres' edge error is the implementation's
        return _run_peer("posegraph3d", backend, graph, method, max_iterations, **kwargs)

    results = _run_pairs(plan, ours, peer, repeat, unimplemented, progress, impl=impl, started=init_called)
    for result in results:
        result.init, result.init_seconds = init, init_seconds
    return _with_repairs(results, graph)


#: the tags a 3D graph file starts with
TAGS_3D = ("VERTEX_SE3:QUAT", "EDGE_SE3:QUAT", "VERTEX3", "EDGE3")


def is_posegraph3d_name(name: str) -> bool:
    """A named 3D graph, or a file whose first record is a 3D vertex or edge."""
    from course.problems.posegraph3d import dataset as datasets

    if name in datasets.dataset_names():
        return True
    path = Path(name)
    if not path.is_file():
        return False
    with open(path, encoding="utf-8", errors="replace") as f:
        for line in f:
            parts = line.split()
            if parts and not parts[0].startswith("#"):
                return parts[0] in TAGS_3D
    return False


def _posegraph3d_runner(dataset, impl=None, methods=None, backends=None, information="strict", **options):
    from course.problems.posegraph3d import dataset as datasets

    return run_posegraph3d(datasets.load_dataset(dataset, information=information), impl=impl, methods=methods,
                           backends=backends, **options)


# ---------------------------------------------------------------- the dataset kinds, in the order tried

#: ``find_runner`` takes the first that matches: ``bal`` and ``posegraph3d`` before ``posegraph``,
#: whose matcher takes any existing path
RUNNERS: tuple[Runner, ...] = (
    Runner("curve", is_curve_name, _curve_runner, "y = exp(a x^2 + b x + c), 100 generated points (chapter 1); "
           "curve:source, the C++ source's own 100 points (try --methods lm-source)"),
    Runner("bal", is_bal_name, _bal_runner,
           "a BAL problem: ladybug-49, dubrovnik-3-7, bal-synthetic:CAMS:POINTS[:seed] or a BAL file, "
           "each also as NAME:front (without the points behind a camera at the start)"),
    Runner("posegraph3d", is_posegraph3d_name, _posegraph3d_runner,
           "a named 3D pose graph (sphere2500, torus3D, parking-garage, smallGrid3D, tinyGrid3D, "
           "sphere_smallnoise, pose3example) or a g2o SE(3) / .graph file (chapter 6)"),
    Runner("posegraph", is_posegraph_name, _posegraph_runner,
           "a named pose graph (python -m course datasets), manhattan:N, or a TORO/g2o file"),
)


def format_bal(runs) -> str:
    """Per bundle-adjustment run: our final cost, the peer's own, and how it treated the observations
    behind a camera (only runs that carry the BAL fields)."""
    rows = [r for r in runs if not r.not_run and hasattr(r, "peer_final_cost")]
    if not rows:
        return ""
    lines = ["costs: ours = 0.5 sum |r|^2 over all observations (half the chi2 above); the peer's own as it reports it",
             f"{'backend':8} {'method':22} {'final cost (ours)':>18} {'peer final cost':>16}  "
             "behind camera start->final  removed by the peer"]
    for r in rows:
        removed = f"{r.removed_points} points, {r.removed_observations} observations" \
            if r.removed_points or r.removed_observations else "-"
        lines.append(f"{r.backend:8} {r.method:22} {r.final_cost:18.10g} {r.peer_final_cost:16.10g}  "
                     f"{r.behind_camera_start:>12} -> {r.behind_camera_final:<11}  {removed}")
    return "\n".join(lines)


# ---------------------------------------------------------------- table and JSON


def _params_text(params) -> str | None:
    p = np.asarray(params, dtype=float)
    if p.ndim != 1 or p.size > 6:
        return None
    return " ".join(f"{v:.6f}" for v in p)


#: scipy's ``least_squares`` status codes, as the stop column names them
SCIPY_STATUS = {"-1": "failed", "0": "max_iterations", "1": "gradient_tolerance", "2": "cost_tolerance",
                "3": "step_tolerance", "4": "cost+step_tolerance"}


#: Ceres' messages, as the stop column names them
CERES_MESSAGES = (("Function tolerance", "function_tolerance"), ("Gradient tolerance", "gradient_tolerance"),
                  ("Parameter tolerance", "parameter_tolerance"), ("Maximum number of iterations", "max_iterations"))


def short_stop_reason(reason) -> str:
    """A run's ``stop_reason`` as the table's ``stop`` column prints it: ours as it is
    (``cost_tolerance``, ``max_iterations``, ...), scipy's status by name, a peer's longer text
    up to its first ``:`` or ``;`` (``convergence``, ``max_iterations``)."""
    text = str(getattr(reason, "value", reason) or "").strip()
    for words, short in CERES_MESSAGES:  # Ceres' termination type says less than its message
        if words in text:
            return short
    if text.startswith("status "):
        code = text[len("status "):].split(":", 1)[0].strip()
        return SCIPY_STATUS.get(code, f"status {code}")
    for mark in (":", ";", " ("):
        text = text.split(mark, 1)[0]
    text = text.strip().replace(" ", "_").lower()
    return text[:24] if text else "-"


def format_table(runs, title: str = "") -> str:
    """A plain-text table: backend, method, iterations, initial and final chi2, total
    and per-iteration time (milliseconds), why the run stopped (``short_stop_reason``), and
    the parameters when they are few (the curve). A column ``solve`` names the sparse solve each
    run used (``RunResult.linear_solve``: ours ``ours``, ``cholmod``, ``superlu``, ``dense`` or ``schur``;
    a peer's its library's), where any run says.
    A run that did not run (``not_run``) is a row with its backend, method and the reason (a
    failure's by what failed, ``short_not_run``: ``advice`` prints the whole message once).
    Runs started from an initialisation (``RunResult.init`` other than ``file``) get a note
    line under the table naming it and its time, and so do runs whose back end compiled first
    (``RunResult.compile_seconds``, JAX). Where a run's data had edges repaired
    (``RunResult.note``), a last column ``note`` says so on every row (after the reason on a
    row that did not run)."""
    header = ["backend", "method", "iters", "initial chi2", "final chi2", "total ms", "ms/iter", "stop"]
    ran = [r for r in runs if not r.not_run]
    show_solve = any(r.linear_solve for r in ran)
    if show_solve:
        header.insert(7, "solve")
    params = [_params_text(r.params) for r in ran]
    show_params = bool(ran) and all(p is not None for p in params)
    if show_params:
        header.append("params")
    show_notes = any(r.note for r in runs)
    if show_notes:
        header.append("note")
    rows = []
    for r, p in zip(ran, params):
        row = [
            r.backend,
            r.method,
            str(r.iterations),
            f"{r.initial_chi2:.6g}",
            f"{r.final_chi2:.10g}",
            f"{1e3 * r.seconds:.3f}",
            f"{1e3 * r.seconds_per_iteration:.4f}",
            *([r.linear_solve or "-"] if show_solve else []),
            short_stop_reason(r.stop_reason),
        ]
        if show_params:
            row.append(p)
        if show_notes:
            row.append(r.note)
        rows.append(row)
    widths = [max(len(h), *(len(row[k]) for row in rows)) if rows else len(h) for k, h in enumerate(header)]
    skipped = [[r.backend, r.method] for r in runs if r.not_run]
    for k in (0, 1):
        widths[k] = max([widths[k]] + [len(row[k]) for row in skipped])
    numeric = {2, 3, 4, 5, 6}

    def line(cells):
        padded = (c.rjust(w) if k in numeric else c.ljust(w) for k, (c, w) in enumerate(zip(cells, widths)))
        return "  ".join(padded).rstrip()

    lines, done = {}, iter(rows)
    for k, r in enumerate(runs):  # table order: ran and not-run rows where the plan put them
        note = f"; {r.note}" if r.note else ""
        lines[k] = line(next(done)) if not r.not_run else \
            f"{r.backend.ljust(widths[0])}  {r.method.ljust(widths[1])}  {short_not_run(r.not_run)}{note}"
    out = [title] if title else []
    out += [line(header), line(["-" * w for w in widths])]
    out += [lines[k] for k in range(len(runs))]
    out += _init_notes(runs)
    out += [f"{r.backend}: compiled in {1e3 * r.compile_seconds:.3f} ms before its first linearisation "
            f"({r.method}); not in total ms" for r in runs if r.compile_seconds and not r.not_run]
    return "\n".join(out)


#: the exercise each of our methods stands on (its strategy's pieces), for ``advice``
METHOD_EXERCISES = {
    "gauss-newton": "gauss_newton.solve_step",
    "lm-type1": "damping.GavinType1",
    "lm-type2": "damping.GavinType2",
    "lm-type3": "damping.GavinType3",
    "lm-scaled-nielsen": "damping.GavinType1.damping_diagonal and damping.GavinType3.update",
    "dogleg": "dogleg (cauchy_point, dogleg_step, update_radius)",
}
#: the exercises every method of ours uses on a kind of problem (its model and normal equations)
MODEL_EXERCISES = {
    "curve": "curve_model and gauss_newton.normal_equations",
    "posegraph": "pose_graph_edge and pose_graph_assembly (pose_graph_fast on large graphs)",
    "posegraph3d": "pose_graph_3d and pose_graph_3d_assembly",
    "bal": "bundle_adjustment",
}
#: how far above the peers' best chi2 a run of the student's may end (relative)
ABOVE_PEERS = 1e-6


#: the kinds of method a run of ours is compared within (a pose graph far from its minimum can lead
#: Gauss-Newton and Levenberg-Marquardt to different local minima, and ours and the peers' alike)
FAMILIES = {"gauss-newton": "gauss-newton", "dogleg": "dogleg"}


def _family(method: str) -> str:
    """``gauss-newton``, ``dogleg`` or, for every damped method (ours and the peers'), ``levenberg-marquardt``."""
    return FAMILIES.get(method, "levenberg-marquardt")


def runs_students_code(run) -> bool:
    """True for a row that ran the implementation's code: one that recorded calling it (``called``;
    ours, and a peer that runs the implementation's cost, as Ceres does), or, where nothing was
    recorded, one of ours."""
    return bool(run.called) if run.called is not None else run.backend == OURS


def named_functions(names) -> str:
    """``pose_graph_fast (edge_errors_and_jacobians, SparseAssembler.assemble), sparse_solve (...)``:
    the functions of ``names`` (``module.qualname``) by module, in their order."""
    by_module: dict = {}
    for name in names:
        module, _, rest = name.partition(".")
        by_module.setdefault(module, []).append(rest)
    return ", ".join(f"{module} ({', '.join(rest)})" for module, rest in by_module.items())


def _look_at(run, shared=()) -> str:
    """What to look at for a run that went wrong: the functions of the implementation it called and
    not among ``shared`` (named once for every flagged run); where nothing was recorded, the
    exercise its method stands on (``METHOD_EXERCISES``)."""
    if run.called is None:
        return METHOD_EXERCISES.get(run.method, run.method)
    own = [name for name in run.called if name not in shared]
    return named_functions(own) if own else "what every run flagged here ran (below)"


def advice(runs, kind: str, impl) -> list:
    """Lines for under the table when one of the rows that ran the student's code looks wrong
    (``runs_students_code``: ours, and a peer that runs the implementation's cost): one ending above
    the best chi2 of the other peers' runs of the same kind of method (``_family``; of every such
    peer when none ran; of the peers that ran the student's model too when every peer did, as the
    curve's do) by more than ``ABOVE_PEERS`` (relative), or at the iteration limit, or
    failed. Each names what to look at: the implementation's functions the run called
    (``RunResult.called``, recorded while it ran: a function never called is never named), those
    that every flagged run called once, in a last line; where nothing was recorded, the exercise its
    method stands on (``METHOD_EXERCISES``) and the problem's model (``MODEL_EXERCISES``) when every
    method of ours is off. None for the reference (``solutions``).
    Before them, whatever the implementation, the whole message of every other back end's failed row."""
    lines = []
    students = [r for r in runs if runs_students_code(r)]
    others = [r for r in runs if (r.backend != OURS or str(impl) == "solutions") and r.not_run.startswith("failed:")
              and (not runs_students_code(r) or str(impl) == "solutions")]  # the reference's rows are never judged
    for backend in dict.fromkeys(r.backend for r in others):
        for reason in dict.fromkeys(r.not_run for r in others if r.backend == backend):
            methods = [r.method for r in others if r.backend == backend and r.not_run == reason]
            lines.append(f"{backend} {', '.join(methods)} {reason}")
    if str(impl) == "solutions":
        return lines
    ran = [r for r in students if not r.not_run]
    peers = [r for r in runs if not runs_students_code(r) and not r.not_run and np.isfinite(r.final_chi2)]
    if not peers:  # every peer ran the student's model (the curve's): they still judge our strategies
        peers = [r for r in runs if r.backend != OURS and not r.not_run and np.isfinite(r.final_chi2)]
    flagged = []
    for r in ran:
        reasons = []
        family = [p.final_chi2 for p in peers if _family(p.method) == _family(r.method)]
        best, whose = (min(family), f"the peers' best {_family(r.method)}") if family else \
            (min(p.final_chi2 for p in peers), "the peers' best") if peers else (None, "")
        if not np.isfinite(r.final_chi2):
            reasons.append(f"ended at chi2 {r.final_chi2}")
        elif best is not None and r.final_chi2 > best * (1 + ABOVE_PEERS) + 1e-300:
            reasons.append(f"ended at chi2 {r.final_chi2:.10g}, above {whose} {best:.10g} "
                           f"(relative {(r.final_chi2 - best) / max(abs(best), 1e-300):.2g})")
        if short_stop_reason(r.stop_reason) == "max_iterations":
            reasons.append(f"stopped at the iteration limit ({r.iterations} step attempts)")
        if reasons:
            flagged.append((r, reasons))
    failed = [r for r in students if r.not_run.startswith("failed:")]
    if not flagged and not failed:
        return lines
    for backend in dict.fromkeys(r.backend for r in failed):  # each failure once, with every method it stopped
        for reason in dict.fromkeys(r.not_run for r in failed if r.backend == backend):
            stopped = [r for r in failed if r.backend == backend and r.not_run == reason]
            look = _failed_exercise(reason, impl) or _look_at(stopped[0])
            lines.append(f"check: {backend} {', '.join(r.method for r in stopped)} {reason}\n  look at {look}")
    recorded = [r for r, _ in flagged if r.called is not None]
    shared = [name for name in recorded[0].called if all(name in r.called for r in recorded)] \
        if len(recorded) > 1 else []
    for r, reasons in flagged:
        look = _look_at(r, shared)
        if reasons[-1].startswith("stopped at the iteration limit"):  # it may only be slow: more iterations first
            lines.append(f"check: {r.backend} {r.method} {' and '.join(reasons)} without converging: if more "
                         f"iterations (--max-iterations) do not end it at the peers' chi2, look at {look}")
        else:
            lines.append(f"check: {r.backend} {r.method} {' and '.join(reasons)}: look at {look}")
    ours = [r for r in ran if r.backend == OURS]
    everyone = len(ours) > 1 and all(any(r is f for f, _ in flagged) for r in ours)
    if shared:
        who = "every method of ours is off" if everyone else f"the {len(recorded)} runs above are off"
        lines.append(f"check: {who}: look first at {named_functions(shared)}, which every one of them ran")
    elif everyone and not recorded and MODEL_EXERCISES.get(kind):
        lines.append(f"check: every method of ours is off: look first at {MODEL_EXERCISES[kind]}, which every "
                     "method uses on this problem")
    lines.append("(`python -m autograder --only NAME` grades one exercise)")
    return lines


def short_not_run(reason: str) -> str:
    """A row's reason: a failure (``failed: where: what``) by where it failed only, pointing below."""
    if not reason.startswith("failed: "):
        return reason
    where = reason[len("failed: "):].split(": ", 1)[0]
    return f"failed: {where} (see below)"


def _failed_exercise(reason: str, impl) -> str:
    """The module of ``impl`` that a ``failed: module.function: ...`` reason names first, or whose file
    its ``(at FILE:LINE)`` is ('' for none)."""
    import importlib

    from course.core import impl as impl_loader

    folder = Path(importlib.import_module(impl_loader.load(impl).package).__file__ or ".").parent
    at = re.search(r"\(at (.+):\d+\)$", reason)  # another error: the frame in the implementation's file
    if at and Path(at.group(1)).parent.resolve() == folder.resolve():
        return Path(at.group(1)).stem
    for word in reason.replace(":", " ").split():
        module = word.split(".", 1)[0]
        if "." in word and module.isidentifier() and (folder / f"{module}.py").is_file():
            return module
    return ""


def todo_names(runs) -> list:
    """The TODOs the runs stopped at (``not implemented: TODO dogleg.cauchy_point``), once each, sorted."""
    return sorted({r.not_run.split("TODO ", 1)[-1].split(" ")[0].rstrip(":") for r in runs
                   if r.not_run.startswith("not implemented") and "not handed out yet" not in r.not_run})


def todo_hint(runs, impl) -> str:
    """For under the table when runs stopped at an unwritten TODO: which, how to grade them, and the
    ``--methods``/``--backends`` that select only what runs (empty when none stopped)."""
    names = todo_names(runs)
    if not names:
        return ""
    stopped = [r for r in runs if r.not_run.startswith("not implemented")]
    ran = [r for r in runs if not r.not_run]
    select = []
    ours_ran = list(dict.fromkeys(r.method for r in ran if r.backend == "ours"))
    ours_stopped = any(r.backend == "ours" for r in stopped)
    if ours_stopped and ours_ran:
        select.append(f"--methods {','.join(ours_ran)}")
    peers_stopped = {r.backend for r in stopped if r.backend != "ours"}
    if peers_stopped or (ours_stopped and not ours_ran):
        keep = [b for b in dict.fromkeys(r.backend for r in ran) if b not in peers_stopped]
        if keep:
            select.append(f"--backends {','.join(keep)}")
    modules = sorted({name.split(".")[0] for name in names})
    them = "it" if len(names) == 1 else "them"
    text = (f"{len(stopped)} run(s) stopped at a TODO of impl {impl} ({', '.join(names)}); write {them} "
            f"(`python -m autograder --only {modules[0]}` grades {'it' if len(modules) == 1 else 'one exercise'})")
    if select:
        text += f", or select what is written: {' or '.join(select)}"
    return text


def _init_notes(runs) -> list:
    """One line per initialisation other than the file's poses: its name and time."""
    notes = []
    for init in dict.fromkeys(r.init for r in runs if r.init != "file"):
        ran = [r for r in runs if r.init == init and not r.not_run]
        took = f"took {1e3 * ran[0].init_seconds:.3f} ms" if ran else "did not run"
        notes.append(f"start: {init} initialisation (shared by every row), {took}; not in total ms "
                     "(time to solution = initialisation + total ms)")
    return notes


def to_json(dataset: str, runs) -> dict:
    """``{"dataset": dataset, "runs": [RunResult.to_json(), ...]}`` (JSON-ready)."""
    return {"dataset": str(dataset), "runs": [r.to_json() for r in runs]}

