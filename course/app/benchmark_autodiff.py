"""Chapter 7's benchmark: the factor graph's automatic Jacobians against our analytic ones, same run.

``python -m course benchmark --autodiff`` prints, on intel, sphere2500 and ladybug-49 (those here), the
median time of one linearisation (the Jacobians and H, b) and of one iteration of a whole solve
(Levenberg-Marquardt, Nielsen's rule), for the chapter's problem with analytic Jacobians
(``ours``), the same problem as a factor graph with Jacobians by Jets (``ours-autodiff``) and by
central differences (``ours-numeric``), with each one's ratio to ``ours``. The runs are interleaved
(one of each per round), so that the machine's load falls on all alike. The factor graph solves
the full H by the sparse Cholesky factorisation where chapter 4 eliminates the points first (the
Schur complement): on ladybug-49 that is part of the gap per iteration, and the linearisation's
ratio is the automatic differentiation's own.
"""

import statistics
import time
from typing import Any

from course.core.backend_names import FACTOR_GRAPH_BACKENDS, OURS
from course.core.errors import DatasetError
from course.factorgraph import FactorGraphProblem
from course.solver import SolverOptions, minimize

#: the graphs, and the method every back end runs on them
GRAPHS = ("intel", "sphere2500", "ladybug-49")
METHOD = "lm-type3"


def problems(name: str, impl="solutions") -> dict:
    """``{backend: problem}``: the chapter's problem of ``name`` and its factor graph (autodiff, numeric)."""
    data: Any  # each family's data and problem
    ours: Any
    if name == "ladybug-49":
        from course.problems.bal.dataset import load_bal
        from course.problems.bal.factor_graph import as_factor_graph as bal_graph
        from course.problems.bal.problem import BundleAdjustmentProblem

        data = load_bal(name)
        ours, graph = BundleAdjustmentProblem(data, impl), bal_graph(data)
    elif name in ("sphere2500",):
        from course.problems.posegraph3d import dataset as datasets_3d
        from course.problems.posegraph3d.factor_graph import as_factor_graph as graph_3d
        from course.problems.posegraph3d.problem import PoseGraph3DProblem

        data = datasets_3d.load_dataset(name)
        ours, graph = PoseGraph3DProblem(data, impl), graph_3d(data)
    else:
        from course.problems.posegraph import dataset as datasets_2d
        from course.problems.posegraph.factor_graph import as_factor_graph as graph_2d
        from course.problems.posegraph.problem import PoseGraphProblem

        data = datasets_2d.load_dataset(name)
        ours, graph = PoseGraphProblem(data, impl), graph_2d(data)
    out: dict[str, Any] = {OURS: ours}
    for backend, jacobians in FACTOR_GRAPH_BACKENDS.items():
        out[backend] = FactorGraphProblem(graph, impl, jacobians=jacobians)
    return out


def measure(name: str, repeats: int = 5, impl="solutions", max_iterations: int = 50) -> dict:
    """``{backend: (seconds per linearisation, seconds per iteration, final chi2, iterations)}``, medians
    of ``repeats`` interleaved rounds."""
    chosen = problems(name, impl)
    lin: dict[str, list[float]] = {b: [] for b in chosen}
    per_iteration: dict[str, list[float]] = {b: [] for b in chosen}
    last: dict = {}
    options = SolverOptions(max_iterations=max_iterations)
    for _ in range(repeats):
        for backend, problem in chosen.items():
            start = time.perf_counter()
            problem.linearize(problem.x0)
            lin[backend].append(time.perf_counter() - start)
            result = minimize(problem, METHOD, impl=impl, options=options)
            per_iteration[backend].append(result.seconds / max(result.iterations, 1))
            last[backend] = result
    return {b: (statistics.median(lin[b]), statistics.median(per_iteration[b]), last[b].final_chi2,
                last[b].iterations) for b in chosen}


def main(repeats: int = 5, impl="solutions", graphs=GRAPHS, out=print) -> None:
    out(f"automatic against analytic Jacobians: medians of {repeats} interleaved rounds, {METHOD}, "
        "ratio = the back end's time / ours")
    out(f"{'graph':12} {'backend':14} {'ms/linearize':>12} {'ratio':>6} {'ms/iter':>9} {'ratio':>6} "
        f"{'iters':>5} {'final chi2':>16}")
    for name in graphs:
        try:
            rows = measure(name, repeats, impl)
        except DatasetError as exc:
            out(f"{name:12} not run: {exc}")
            continue
        lin0, it0 = rows[OURS][0], rows[OURS][1]
        for backend, (lin, it, chi2, iterations) in rows.items():
            out(f"{name:12} {backend:14} {1e3 * lin:12.2f} {lin / lin0:6.2f} {1e3 * it:9.2f} {it / it0:6.2f} "
                f"{iterations:5d} {chi2:16.10g}")
