"""Chapter 4 benchmark: one Levenberg-Marquardt iteration of bundle adjustment, ours (Schur
complement, the gauge fixed) against the peers' in the same run, and our time to solution.

Per iteration: each back end runs ``iterations`` iterations from the BAL start, ``repeats``
times, interleaved; the figure is the median of ``seconds / iterations``. The peers are
Ceres in C++ through pycolmap (one thread, SPARSE_SCHUR), GTSAM's LM and scipy's
``least_squares`` (trf with the Jacobian's sparsity: one "iteration" is one evaluation of
residuals and Jacobian). A peer that is not installed is one line saying so.

Time to solution: the seconds our LM takes to bring the all-observations cost within
``TOLERANCE`` relative of :data:`MINIMA` (ladybug-49: 13344.2407, where an LM with the Schur
complement sits after 500 iterations, still falling by 1e-10 relative per iteration; the
peers' own minima differ because they score other observations, see ``course.backends``).
"""

from __future__ import annotations

import statistics
from dataclasses import dataclass
from functools import partial

from course.backends import registry
from course.core.peers import PeerMissing
from course.problems.bal.dataset import BALProblem, load_bal
from course.problems.bal.problem import BundleAdjustmentProblem
from course.solver import minimize
from course.solver.options import SolverOptions

#: the all-observations minimum (0.5 sum of squares) of each named problem
MINIMA = {"ladybug-49": 13344.2407}
#: "reached" means a cost at most (1 + TOLERANCE) times the minimum
TOLERANCE = 1e-6
#: our method in the comparison, and each peer's
OUR_METHOD = "lm-type3"
PEER_METHODS = (("ceres", "levenberg-marquardt"), ("gtsam", "levenberg-marquardt"), ("scipy", "trf"))


@dataclass
class Timing:
    """One back end's median seconds per iteration and its last run (``None`` when not run)."""

    backend: str
    method: str
    seconds_per_iteration: float | None
    result: object = None
    skipped: str = ""


def _ours(problem: BALProblem, impl, iterations: int):
    return minimize(BundleAdjustmentProblem(problem, impl, fix_gauge=True), OUR_METHOD, impl=impl,
                    options=SolverOptions(max_iterations=iterations))


def per_iteration(name="ladybug-49", repeats=3, iterations=10, impl="solutions", scipy_evaluations=2) -> list:
    """:class:`Timing` of ours and of each peer on ``name``, medians of ``repeats`` runs, interleaved."""
    problem = load_bal(name)
    runners: dict = {("ours", OUR_METHOD): partial(_ours, problem, impl, iterations)}
    timings = []
    for backend, method in PEER_METHODS:
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
    measured = [Timing(b, m, statistics.median(samples[(b, m)]), last[(b, m)]) for b, m in runners]
    return measured + timings


def time_to_solution(name="ladybug-49", repeats=3, impl="solutions", max_iterations=100):
    """``(median seconds, iterations, cost)`` for our LM to reach ``MINIMA[name] (1 + TOLERANCE)``;
    seconds and iterations are None when it does not within ``max_iterations``."""
    problem = load_bal(name)
    target = 2.0 * MINIMA[name] * (1.0 + TOLERANCE)  # in chi2
    seconds, reached = [], None
    for _ in range(repeats):
        result = _ours(problem, impl, max_iterations)
        hit = next((r for r in result.trace[1:] if r.accepted and r.chi2 <= target), None)
        if hit is None:
            return None, None, 0.5 * result.final_chi2
        seconds.append(hit.seconds)
        reached = hit
    return statistics.median(seconds), reached.iteration, 0.5 * reached.chi2


def main(names=("ladybug-49",), repeats=3, impl="solutions", out=print) -> None:
    """Print the per-iteration table (ratios over Ceres) and our time to solution."""
    from course.core.errors import DatasetError

    for name in names:
        try:
            timings = per_iteration(name, repeats, impl=impl)
        except DatasetError as exc:
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
        if name in MINIMA:
            seconds, iteration, cost = time_to_solution(name, repeats, impl=impl)
            if seconds is None:
                out(f"{name}: ours did not reach {MINIMA[name]} (1 + {TOLERANCE:g}) within 100 iterations "
                    f"(cost {cost:.4f})")
            else:
                out(f"{name}: ours reaches {cost:.6f} (within {TOLERANCE:g} of {MINIMA[name]}) at iteration "
                    f"{iteration} in {seconds:.2f} s (median of {repeats})")
