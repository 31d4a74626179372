"""Chapter 4 benchmark: one Levenberg-Marquardt iteration of bundle adjustment, ours (Schur
complement, the gauge fixed) against the peers' in the same run, and every back end's time
to the minimum of a problem they all solve as it is.

Per iteration: each back end runs ``iterations`` iterations from the BAL start, ``repeats``
times, interleaved; the figure is the median of ``seconds / iterations``. The peers are
Ceres in C++ through pycolmap (one thread, SPARSE_SCHUR), GTSAM's LM and scipy's
``least_squares`` (trf with the Jacobian's sparsity: one "iteration" is one evaluation of
residuals and Jacobian). A peer that is not installed is one line saying so.

How the cost grows (:func:`size_sweep`): ours and Ceres' per iteration on ``bal-synthetic`` from
about 10k to 300k observations, and the ratio.

Time to the minimum, on ``NAME:front`` (the problem without the points that have an
observation behind a camera at the start, so that Ceres through COLMAP deletes nothing and
every back end minimises the same cost over the same observations): each back end runs to
its cap of iterations; the lowest final cost (ours, evaluated on each solution) is the
problem's best known minimum; each back end's time is that of a run stopped at its first
iterate within ``TOLERANCE`` of it, its set-up included. On the full problem the peers' minima
differ from ours because they score other observations (see ``course.backends.bal``).
"""

from __future__ import annotations

import statistics
import time
from dataclasses import dataclass, field
from functools import partial

from course.backends import registry
from course.backends.bal.common import unpack
from course.core.peers import PeerMissing
from course.problems.bal.dataset import FRONT, BALProblem, cost, load_bal
from course.problems.bal.problem import BundleAdjustmentProblem
from course.solver import minimize
from course.solver.options import SolverOptions
from course.solver.scaled_nielsen import SCALED_NIELSEN

#: "reached" means a cost at most (1 + TOLERANCE) times the problem's best known minimum
TOLERANCE = 1e-6
#: the all-observations minimum (0.5 sum of squares) of a named problem that Ceres through COLMAP
#: changes (it deletes points): where an LM with the Schur complement sits after 500 iterations
MINIMA = {"ladybug-49": 13344.2407}
#: step attempts each back end may take toward the minimum (GTSAM's LM, without the Schur
#: complement, needs far more than the others: on ladybug-49:front it is still 77% above the
#: minimum after 200)
CAPS = {"ours": 200, "ceres": 200, "gtsam": 50}
#: a peer's options that keep the problem ours: GTSAM without its gauge priors (which pull camera
#: 0 and point 0 toward their start, another minimum)
SAME_PROBLEM = {"gtsam": {"gauge": "none"}}
#: our method in the comparison, and each peer's
OUR_METHOD = "lm-type3"
#: ours in the time to the minimum: also type 1's scaled damping with type 3's update, as Ceres' LM
TIME_TO_MINIMUM_METHODS = (OUR_METHOD, SCALED_NIELSEN)
PEER_METHODS = (("ceres", "levenberg-marquardt"), ("gtsam", "levenberg-marquardt"), ("scipy", "trf"))


@dataclass
class Timing:
    """One back end's median seconds per iteration and its last run (``None`` when not run);
    ``samples``: each repeat's seconds per iteration, in the order the rounds ran."""

    backend: str
    method: str
    seconds_per_iteration: float | None
    result: object = None
    skipped: str = ""
    samples: list = field(default_factory=list)


def _ours(problem: BALProblem, impl, iterations: int, method: str = OUR_METHOD):
    return minimize(BundleAdjustmentProblem(problem, impl, fix_gauge=True), method, impl=impl,
                    options=SolverOptions(max_iterations=iterations))


def per_iteration(name="ladybug-49", repeats=3, iterations=10, impl="solutions", scipy_evaluations=2,
                  peers=PEER_METHODS) -> list:
    """:class:`Timing` of ours and of each of ``peers`` (``(backend, method)`` pairs) on ``name``,
    medians of ``repeats`` runs, interleaved."""
    problem = load_bal(name)
    runners: dict = {("ours", OUR_METHOD): partial(_ours, problem, impl, iterations)}
    timings = []
    for backend, method in peers:
        try:
            solve = registry.peer_solver("bal", backend)
        except PeerMissing as exc:
            timings.append(Timing(backend, method, None, skipped=str(exc)))
            continue
        count = scipy_evaluations if backend == "scipy" else iterations
        runners[(backend, method)] = partial(solve, problem, method, max_iterations=count)
    samples: dict = {key: [] for key in runners}
    last: dict = {}
    for _ in range(repeats):
        for key, run in runners.items():
            result = run()
            samples[key].append(result.seconds / max(result.iterations, 1))
            last[key] = result
    measured = [Timing(b, m, statistics.median(samples[(b, m)]), last[(b, m)], samples=samples[(b, m)])
                for b, m in runners]
    return measured + timings


@dataclass
class Reach:
    """One back end's time to the shared minimum: ``iteration`` the first step attempt whose
    iterate is within ``TOLERANCE`` of it (None: not within ``cap`` iterations); ``seconds``
    the median wall time of runs stopped there, their set-up included (building our problem
    or Ceres', not loading the file); ``cost`` our cost where the run stops."""

    backend: str
    method: str
    iteration: int | None
    seconds: float | None
    cost: float
    cap: int
    skipped: str = ""


def _runner(backend: str, method: str, problem: BALProblem, impl):
    """``run(max_iterations) -> result`` of one back end on ``problem``, timed by the wall clock
    around the whole call for ours (problem set-up included) and by the peer's own ``seconds``
    (its problem built, our conversions excluded) for a peer."""
    if backend == "ours":
        def run(max_iterations):
            start = time.perf_counter()
            result = _ours(problem, impl, max_iterations, method)
            result.seconds = time.perf_counter() - start
            return result
        return run
    solve = registry.peer_solver("bal", backend)
    return partial(solve, problem, method, **SAME_PROBLEM.get(backend, {}))


def _first_within(result, target_cost: float) -> int | None:
    """The first accepted step attempt of ``result``'s trace at most ``target_cost`` (0.5 chi2 of
    the trace: ours and GTSAM's are our cost; Ceres' is its own, printed to 7 digits)."""
    return next((r.iteration for r in result.trace[1:] if r.accepted and 0.5 * r.chi2 <= target_cost), None)


def time_to_minimum(name="ladybug-49" + FRONT, repeats=3, impl="solutions", caps=None) -> tuple[float, str, list]:
    """``(minimum, found by, [Reach])`` on ``name``: every back end solves the same problem from
    its start, up to its cap of iterations (``caps``: back end -> cap, default :data:`CAPS`); the
    problem's best known minimum is the lowest of their final costs (our cost on their
    solutions); then each one's time to within ``TOLERANCE`` of it, medians of ``repeats`` runs
    stopped at the iteration its trace first gets there. Ceres' trace prints its cost to 7
    digits: a run stopped there is checked with our cost, and one more iteration is allowed
    at a time until it passes."""
    caps = {**CAPS, **(caps or {})}
    problem = load_bal(name)
    runners, skipped, full = {}, [], {}
    for backend, method in (*(("ours", m) for m in TIME_TO_MINIMUM_METHODS),
                            *((b, m) for b, m in PEER_METHODS if b in caps)):
        try:
            runners[(backend, method)] = _runner(backend, method, problem, impl)
        except PeerMissing as exc:
            skipped.append(Reach(backend, method, None, None, float("nan"), caps[backend], skipped=str(exc)))
    for key, run in runners.items():
        full[key] = run(caps[key[0]])
    (minimum, found_by) = min((cost(problem, *unpack(problem, r.params)), f"{b} {m}") for (b, m), r in full.items())
    target = minimum * (1.0 + TOLERANCE)
    reaches = []
    for (backend, method), run in runners.items():
        cap, result = caps[backend], full[(backend, method)]
        iteration = _first_within(result, target)
        seconds: list[float] = []
        there = cost(problem, *unpack(problem, result.params))
        while iteration is not None and not seconds:
            end = run(iteration)
            there = cost(problem, *unpack(problem, end.params))
            if there <= target:
                seconds.append(end.seconds)
            else:  # the trace's rounding: one more step attempt
                iteration = iteration + 1 if iteration < cap else None
        if iteration is not None:
            seconds += [run(iteration).seconds for _ in range(repeats - 1)]
        reaches.append(Reach(backend, method, iteration, statistics.median(seconds) if seconds else None, there, cap))
    return minimum, found_by, reaches + skipped


#: the size sweep's problems, ``bal-synthetic:CAMERAS:POINTS``: about 10k, 30k, 75k, 150k and 300k
#: observations (3.5 a point), the points seen by random cameras, so S fills in as the cameras multiply
SWEEP = ((20, 2900), (50, 8600), (100, 21500), (200, 43000), (400, 86000))


@dataclass
class SweepRow:
    """One size of the sweep: ``observations``; ours and Ceres' median seconds per iteration
    (``ceres`` None when pycolmap is missing)."""

    name: str
    observations: int
    ours: float
    ceres: float | None

    @property
    def ratio(self) -> float | None:
        return None if self.ceres is None else self.ours / self.ceres


def size_sweep(sizes=SWEEP, repeats=3, iterations=5, impl="solutions") -> list:
    """:class:`SweepRow` per ``(cameras, points)`` of ``sizes``: our LM (:data:`OUR_METHOD`, the
    Schur complement) and Ceres' per iteration on ``bal-synthetic:C:P``, medians of ``repeats``
    interleaved runs of ``iterations`` iterations from the generator's start."""
    try:
        ceres = registry.peer_solver("bal", "ceres")
    except PeerMissing:
        ceres = None
    rows = []
    for cameras, points in sizes:
        problem = load_bal(f"bal-synthetic:{cameras}:{points}")
        ours, theirs = [], []
        for _ in range(repeats):
            result = _ours(problem, impl, iterations)
            ours.append(result.seconds / max(result.iterations, 1))
            if ceres is not None:
                result = ceres(problem, "levenberg-marquardt", max_iterations=iterations)
                theirs.append(result.seconds / max(result.iterations, 1))
        rows.append(SweepRow(problem.name, len(problem.observations), statistics.median(ours),
                             statistics.median(theirs) if theirs else None))
    return rows


def format_sweep(rows: list) -> str:
    lines = [f"{'problem':26} {'observations':>12} {'ours ms/it':>11} {'ceres ms/it':>12} {'ours / ceres':>13}"]
    for row in rows:
        theirs = f"{row.ceres * 1e3:12.1f}" if row.ceres is not None else f"{'not run':>12}"
        ratio = f"{row.ratio:13.2f}" if row.ratio is not None else f"{'-':>13}"
        lines.append(f"{row.name:26} {row.observations:12d} {row.ours * 1e3:11.1f} {theirs} {ratio}")
    return "\n".join(lines)


def main(names=("ladybug-49",), repeats=3, impl="solutions", out=print, sweep=SWEEP) -> None:
    """Print the per-iteration table of each problem and the time to the minimum of its
    ``:front`` variant (ratios over Ceres)."""
    from course.core.errors import DatasetError

    for name in names:
        try:
            timings = per_iteration(name, repeats, impl=impl)
        except (DatasetError, NotImplementedError) as exc:
            out(f"{name} bundle adjustment skipped: {exc}")
            continue
        ceres = next((t.seconds_per_iteration for t in timings if t.backend == "ceres" and t.seconds_per_iteration),
                     None)
        out(f"{name}: seconds per iteration, median of {repeats} (scipy: per evaluation); ours is "
            f"{OUR_METHOD} with the Schur complement and the gauge fixed; impl {impl}")
        out(f"{'back end':8} {'method':20} {'ms/it':>9} {'/ ceres':>8} {'cost after':>14}")
        for t in timings:
            if t.seconds_per_iteration is None:
                out(f"{t.backend:8} {t.method:20} not run: {t.skipped}")
                continue
            ratio = f"{t.seconds_per_iteration / ceres:8.2f}" if ceres else f"{'-':>8}"
            cost = 0.5 * t.result.final_chi2
            out(f"{t.backend:8} {t.method:20} {t.seconds_per_iteration * 1e3:9.1f} {ratio} {cost:14.4f}")
        shared = name if name.endswith(FRONT) else name + FRONT
        try:
            minimum, found_by, reaches = time_to_minimum(shared, repeats, impl=impl)
        except NotImplementedError as exc:
            out(f"{shared} time to the minimum skipped: {exc}")
            continue
        out(f"{shared} (the same problem for every back end; Ceres deletes nothing): best known minimum "
            f"{minimum:.6f}, found by {found_by}; time to within {TOLERANCE:g} of it, runs stopped at the first "
            f"iterate there, set-up included, median of {repeats}")
        ceres = next((r.seconds for r in reaches if r.backend == "ceres" and r.seconds), None)
        out(f"{'back end':8} {'method':20} {'iteration':>9} {'s':>8} {'/ ceres':>8} {'cost there':>14}")
        for r in reaches:
            if r.skipped:
                out(f"{r.backend:8} {r.method:20} not run: {r.skipped}")
            elif r.seconds is None:
                out(f"{r.backend:8} {r.method:20} not within {r.cap} iterations (cost {r.cost:.4f} there)")
            else:
                ratio = f"{r.seconds / ceres:8.2f}" if ceres else f"{'-':>8}"
                out(f"{r.backend:8} {r.method:20} {r.iteration:9d} {r.seconds:8.2f} {ratio} {r.cost:14.6f}")
    if sweep:
        out(f"how the cost grows: LM seconds per iteration on bal-synthetic, median of {repeats} runs of 5 "
            "iterations, ours (the Schur complement) and Ceres' (pycolmap, one thread)")
        try:
            rows = size_sweep(sweep, repeats, impl=impl)
        except NotImplementedError as exc:
            out(f"skipped: {exc}")
        else:
            for line in format_sweep(rows).splitlines():
                out(line)
