"""Chapter 7's benchmark: the factor graph's automatic Jacobians against our analytic ones, same run.

``python -m course benchmark --autodiff`` prints, on intel, sphere2500 and ladybug-49 (those here), the
median time of one linearisation (the Jacobians and H, b) and of one iteration of a whole solve
(Levenberg-Marquardt, Nielsen's rule), for the chapter's problem with analytic Jacobians
(``ours``), the same problem as a factor graph with Jacobians by Jets (``ours-autodiff``), by
central differences (``ours-numeric``) and by JAX (``jax``), and the factor graph through GTSAM with
custom factors (``gtsam-custom``), with each one's ratio to ``ours``. The runs are interleaved
(one of each per round), so that the machine's load falls on all alike.

Where a back end changes the problem or the solve:

- the factor graph eliminates the points first, as chapter 4 does, but from the H its generic
  assembly stores (``course.factorgraph.schur_elimination``), where chapter 4's problem keeps H as its
  blocks: the linearisation's ratio is the automatic differentiation's and the generic assembly's;
- ``jax``: the same problem and the same minimizer; only the factors' residuals and Jacobians in
  each linearisation come from JAX (``course.backends.factorgraph.jax_factors``). Its compilation
  (once per factor type and size, before the first linearisation) is kept out of both times and
  printed on a line of its own; JAX may use more than one thread;
- ``gtsam-custom``: GTSAM's optimizer, not ours: its Levenberg-Marquardt (``lambda I``, its own
  update and stopping rule) and its linear solver (multifrontal Cholesky on its own ordering);
  fixed variables are constants, not variables; 3D poses are ``Pose3`` with GTSAM's retraction
  (the same to first order, not beyond); its linearisation is ``NonlinearFactorGraph.linearize``, one
  Python callback per factor, each evaluating our Jets on that factor; an iteration of its LM also
  counts the error evaluations of its retries. It runs ``GTSAM_CUSTOM_ITERATIONS`` iterations at most
  (one of its iterations costs about as much as a whole solve of ours), so its final chi2 is where
  that stopped; on bundle adjustment (ladybug-49) only its linearisation is timed (about 11 s here),
  not its solve: its first LM iteration from ladybug-49's start took 342 s (GTSAM's retries, each
  one evaluating the 31843 callbacks).
- the references (``REFERENCES``): GTSAM's native factors (``BetweenFactorPose2``,
  ``BetweenFactorPose3``, ``GeneralSFMFactorCal3Bundler``: C++ Jacobians written by hand), g2o
  (C++) and Ceres (pycolmap's C++ cost on bundle adjustment; on pose graphs pyceres evaluating our
  edge cost in Python, so not a compiled reference there), each its own Levenberg-Marquardt for
  ``REFERENCE_ITERATIONS`` iterations from the same start, per iteration; GTSAM's linearisation
  (``NonlinearFactorGraph.linearize``) timed beside ours. Their problems differ where chapter 4 and 6
  say: GTSAM fixes BAL's gauge with priors, pycolmap deletes the points behind a camera.
"""

import importlib
import statistics
import time

from course.core import peers
from course.core.backend_names import FACTOR_GRAPH_BACKENDS, GTSAM_CUSTOM, JAX, OURS, OURS_AUTODIFF
from course.core.errors import DatasetError
from course.factorgraph import FactorGraphProblem
from course.solver import SolverOptions, minimize

#: the graphs, and the method every back end of ours runs on them
GRAPHS = ("intel", "sphere2500", "ladybug-49")
METHOD = "lm-type3"
#: iterations of GTSAM's Levenberg-Marquardt on custom factors per solve (see the module doc)
GTSAM_CUSTOM_ITERATIONS = 5
#: the graphs on which only gtsam-custom's linearisation is timed, not its solve (see the module doc)
GTSAM_CUSTOM_LINEARISATION_ONLY = ("ladybug-49",)
#: the references run beside (``course.backends.registry``'s peers): backend -> its Levenberg-Marquardt
REFERENCES = {"gtsam": "levenberg-marquardt", "g2o": "levenberg", "ceres": "levenberg-marquardt"}
#: iterations of each reference per solve
REFERENCE_ITERATIONS = 10


def factor_graph(name: str, impl="solutions"):
    """``(ours, graph)``: the chapter's problem of ``name`` and its factor graph."""
    if name == "ladybug-49":
        from course.problems.bal.dataset import load_bal
        from course.problems.bal.factor_graph import as_factor_graph as bal_graph
        from course.problems.bal.problem import BundleAdjustmentProblem

        bal = load_bal(name)
        return BundleAdjustmentProblem(bal, impl), bal_graph(bal)
    if name in ("sphere2500",):
        from course.problems.posegraph3d import dataset as datasets_3d
        from course.problems.posegraph3d.factor_graph import as_factor_graph as graph_3d
        from course.problems.posegraph3d.problem import PoseGraph3DProblem

        graph3d = datasets_3d.load_dataset(name)
        return PoseGraph3DProblem(graph3d, impl), graph_3d(graph3d)
    from course.problems.posegraph import dataset as datasets_2d
    from course.problems.posegraph.factor_graph import as_factor_graph as graph_2d
    from course.problems.posegraph.problem import PoseGraphProblem

    data = datasets_2d.load_dataset(name)
    return PoseGraphProblem(data, impl), graph_2d(data)


def family(name: str) -> str:
    """The kind of problem (``course.backends.registry.KINDS``) of a graph of ``GRAPHS`` or a 2D one."""
    return {"ladybug-49": "bal", "sphere2500": "posegraph3d"}.get(name, "posegraph")


class _Reference:
    """One reference's row: its solve (``REFERENCE_ITERATIONS`` iterations of its LM) and, for GTSAM's
    native factors, its linearisation."""

    def __init__(self, kind: str, backend: str, data, impl):
        from course.backends import registry

        self.kind, self.backend, self.data, self.impl = kind, backend, data, impl
        self._solve = registry.peer_solver(kind, backend)  # PeerMissing where its library is not here
        self.factors = self.values = None
        if backend == "gtsam":
            module = {"bal": "course.backends.bal.gtsam", "posegraph3d": "course.backends.posegraph3d.gtsam",
                      "posegraph": "course.backends.posegraph.gtsam"}[kind]
            build = getattr(importlib.import_module(module), "to_gtsam" if kind == "bal" else "build_factor_graph")
            self.factors, self.values = build(data)[:2]

    def linearize_seconds(self) -> float:
        if self.factors is None:
            return float("nan")
        start = time.perf_counter()
        self.factors.linearize(self.values)
        return time.perf_counter() - start

    def solve(self):
        kwargs = {"impl": self.impl} if self.backend == "ceres" and self.kind != "bal" else {}
        return self._solve(self.data, REFERENCES[self.backend], REFERENCE_ITERATIONS, **kwargs)


def references(name: str, ours, impl) -> dict:
    """``{backend: _Reference}`` of the references offered for ``name``'s kind and installed here
    (a missing library is said once on stderr by ``course.core.peers``)."""
    from course.backends import registry

    kind = family(name)
    data = ours.problem if kind == "bal" else ours.graph
    out = {}
    for backend, method in REFERENCES.items():
        if method not in registry.PEERS[kind].get(backend, (None, {}))[1]:
            continue
        try:
            out[backend] = _Reference(kind, backend, data, impl)
        except peers.PeerMissing:
            continue
    return out


def problems(name: str, impl="solutions") -> dict:
    """``{backend: problem}``: the chapter's problem of ``name`` and its factor graph for our minimizer
    (autodiff, numeric, and JAX's where jax is installed: compiled here)."""
    ours, graph = factor_graph(name, impl)
    out = {OURS: ours}
    for backend, jacobians in FACTOR_GRAPH_BACKENDS.items():
        if jacobians == "jax":
            if peers.installed("jax"):
                from course.backends.factorgraph import jax_factors

                out[backend] = jax_factors.problem(graph, impl)
            continue
        out[backend] = FactorGraphProblem(graph, impl, jacobians=jacobians)
    return out


class _GtsamCustom:
    """The ``gtsam-custom`` row: GTSAM's linearisation of the custom factors, and its solve."""

    def __init__(self, graph, impl):
        from course.backends.factorgraph import gtsam_custom

        self.graph, self.impl, self.solver = graph, impl, gtsam_custom
        self.factors, self.values, _, _ = gtsam_custom.build(graph, impl)

    def linearize_seconds(self) -> float:
        start = time.perf_counter()
        self.factors.linearize(self.values)
        return time.perf_counter() - start

    def solve(self):
        return self.solver.solve(self.graph, "levenberg-marquardt", GTSAM_CUSTOM_ITERATIONS, impl=self.impl)


def measure(name: str, repeats: int = 5, impl="solutions", max_iterations: int = 50, custom_solves=True) -> dict:
    """``{backend: (seconds per linearisation, seconds per iteration, final chi2, iterations)}``, medians
    of ``repeats`` interleaved rounds; ``jax``, ``gtsam-custom`` and the references only where their
    library is installed (``custom_solves`` False: ``gtsam-custom``'s linearisation alone, on every
    graph); under ``"jax compile"``, JAX's compile seconds (where it ran); under ``"not run"``,
    ``{backend: why}`` for a reference that stopped at a TODO of ``impl``; under ``"linearisations"``,
    ``{backend: [seconds of each round's linearisation]}``."""
    chosen = problems(name, impl)
    custom = _GtsamCustom(chosen[OURS_AUTODIFF].graph, impl) if peers.installed("gtsam") else None
    custom_solves = custom_solves and name not in GTSAM_CUSTOM_LINEARISATION_ONLY
    native = references(name, chosen[OURS], impl)
    names = list(chosen) + ([GTSAM_CUSTOM] if custom is not None else []) + list(native)
    not_run: dict = {}
    lin: dict = {b: [] for b in names}
    per_iteration: dict = {b: [] for b in names}
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
        if custom is not None:
            lin[GTSAM_CUSTOM].append(custom.linearize_seconds())
            if custom_solves:
                result = custom.solve()
                per_iteration[GTSAM_CUSTOM].append(result.seconds / max(result.iterations, 1))
                last[GTSAM_CUSTOM] = result
        for backend, reference in list(native.items()):
            try:
                result = reference.solve()
            except NotImplementedError as exc:  # Ceres on pose graphs runs the implementation's edge cost
                not_run[backend] = f"not run: {exc}"
                del native[backend]
                names.remove(backend)
                continue
            lin[backend].append(reference.linearize_seconds())
            if not result.not_run:
                per_iteration[backend].append(result.seconds / max(result.iterations, 1))
                last[backend] = result
    nan = float("nan")
    rows: dict = {b: (statistics.median(lin[b]), statistics.median(per_iteration[b]) if per_iteration[b] else nan,
                last[b].final_chi2 if b in last else nan, last[b].iterations if b in last else 0) for b in names}
    if JAX in chosen:
        rows["jax compile"] = chosen[JAX].jacobians.compile_seconds
    rows["not run"] = not_run
    rows["linearisations"] = {b: lin[b] for b in names}
    return rows


def main(repeats: int = 5, impl="solutions", graphs=GRAPHS, out=print, custom_solves=True) -> None:
    out(f"automatic against analytic Jacobians: medians of {repeats} interleaved rounds, {METHOD} "
        f"({GTSAM_CUSTOM}: GTSAM's LM, {GTSAM_CUSTOM_ITERATIONS} iterations at most; {', '.join(REFERENCES)}: "
        f"GTSAM's native factors and the compiled references, their own LM, {REFERENCE_ITERATIONS} iterations; "
        "nan: not timed), ratio = the back end's time / ours")
    out(f"{'graph':12} {'backend':14} {'ms/linearize':>12} {'ratio':>6} {'ms/iter':>9} {'ratio':>6} "
        f"{'iters':>5} {'final chi2':>16}")
    for name in graphs:
        try:
            rows = measure(name, repeats, impl, custom_solves=custom_solves)
        except DatasetError as exc:
            out(f"{name:12} not run: {exc}")
            continue
        compile_seconds = rows.pop("jax compile", None)
        not_run = rows.pop("not run", {})
        rows.pop("linearisations", None)
        lin0, it0 = rows[OURS][0], rows[OURS][1]
        for backend, (lin, it, chi2, iterations) in rows.items():
            out(f"{name:12} {backend:14} {1e3 * lin:12.2f} {lin / lin0:6.2f} {1e3 * it:9.2f} {it / it0:6.2f} "
                f"{iterations:5d} {chi2:16.10g}")
        for backend, library in ((JAX, "jax"), (GTSAM_CUSTOM, "gtsam")):
            if backend not in rows:
                out(f"{name:12} {backend:14} not run: {library} is not installed here")
        for backend, reason in not_run.items():
            out(f"{name:12} {backend:14} {reason}")
        if compile_seconds is not None:
            out(f"{name:12} {JAX:14} compiled in {1e3 * compile_seconds:.1f} ms before its first linearisation "
                "(not in the times above)")
        if GTSAM_CUSTOM in rows:
            what, k = ("per iteration", 1) if rows[GTSAM_CUSTOM][3] else ("per linearisation (its solve not run)", 0)
            ratio = rows[GTSAM_CUSTOM][k] / rows[OURS_AUTODIFF][k]
            out(f"{name:12} {what}, {GTSAM_CUSTOM} / {OURS_AUTODIFF}: {ratio:.1f}x")
