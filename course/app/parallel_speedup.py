"""Measured: the parallel assembly of the normal equations against the serial one, alone and
inside whole Levenberg-Marquardt and dogleg iterations (chapter 4).

``python -m course benchmark`` prints these tables last (:func:`section`); alone::

    .venv/bin/python -m course.app.parallel_speedup [--impl solutions] [--repeats 9] [--iteration-repeats 3]

Every number is a median of several runs in one process, the variants interleaved (each
repeat runs every variant once, in a rotating order), so that a burst of load from other
jobs on the machine hits them all alike. The serial assembly is the implementation's
``bundle_adjustment.normal_equations``; the parallel one is its
``parallel_assembly.normal_equations_parallel`` with that same function as the per-chunk
kernel, so the ratio is the effect of the chunks and threads alone. Each parallel result is
checked against the serial one (rtol 1e-10) before it is timed. Next to each time: ``cores``,
the process's CPU time over the wall time (how many cores the variant really had), and the
minor page faults of one call.

What the figures say (2 cores shared with other engineers' jobs; docs/measured.md, its notes on the parallel assembly):

- Threads do not pay on ladybug-49 (31843 observations): two threads took 0.85 times the
  serial assembly's speed, four 1.1 times, with 1.5 to 1.7 cores busy; when another job held
  a core (``cores`` 1.0) nothing was gained. On 105k observations four chunks of 26k ran 1.5
  times as fast as serial; two chunks of 52k did not gain at all.
- The GIL is not the main limit at these sizes: numpy releases it inside the batched
  products, ``np.add.at`` and fancy indexing, and inside most of ``np.bincount`` (its pass
  over the indices keeps it); but one product of 2-D arrays, ``A.T @ A``, keeps it throughout
  where ``np.dot(A.T, A)`` releases it (the ``GIL held`` line), and the Python glue between
  the calls keeps it too.
- Memory is: the assembly writes 1 to 2 kB of temporaries per observation for a few hundred
  flops, so two threads on one memory bus and one L3 cache each run slower (twice the CPU
  time for the same wall time on ladybug). Fresh temporaries cost page faults (the
  ``faults`` column): glibc maps a temporary of more than 32 MB afresh at every call (the
  52k-observation chunks), and a worker thread's arena returns memory that the main
  thread's keeps, so one chunk on one pool thread (``1w``) is slower than the same serial
  call; the parallel version also pays for the partial sums (a ``V`` of all P points per
  chunk) and for copying W into place. Chunks of a few thousand to 26k observations avoid
  the faults (``2w/16c``, ``4w``).
- Small problems lose: at a thousand observations starting the threads and the GIL held on
  small arrays cost more than the work (2 to 4 times slower). Processes lose everywhere:
  pickling the chunks' Jacobians and blocks alone (``2p``, pool started beforehand) takes
  longer than the serial assembly.
- In a whole step attempt the assembly is only 15 to 22 % of the time (the Schur solve is
  about half, the Jacobians and the trial chi2 the rest), so Amdahl's bound (printed) is
  about 1.0 here, and the measured ratios of whole attempts (0.85 to 1.2 between runs) are
  the run-to-run variation of the serial parts on this shared machine.
- With the reference's earlier assembly (before commit bd64871: U by ``np.bincount`` of every
  observation's 81 entries, 41 ms serial on ladybug-49), two threads were 1.6 times as fast as
  one: the faster the serial code, the less the threads have to split.

The source's table (per solve on EuRoC MH_05: LM 218.77 ms, LM with OpenMP 148.73 ms, dogleg
61.42 ms, dogleg with OpenMP 83.40 ms) shows the same rule from the other side: threads
helped LM, whose solve spent most of its time in assemblies, and hurt the dogleg, a solve
three times shorter in which the threads' fixed costs (starting, synchronizing, sharing
the cores) weigh more than the work they split. A parallel assembly pays when the assembly
is a large share of the time, the chunks are large (thousands of observations), and the
cores are really free; otherwise it does not.
"""

from __future__ import annotations

import argparse
import functools
import os
import statistics
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from course.core import impl as impl_loader

#: the problems of the benchmark: the real one, a larger synthetic one, and a small one where threads lose
PROBLEMS = ("ladybug-49", "bal-synthetic:60:30000:3", "bal-synthetic:8:300:3")
#: (workers, chunks) of the assembly table; chunks None = one per worker
CONFIGS = ((1, None), (2, None), (4, None), (2, 16))
#: the minimizer's methods of the iteration table, and its problems
METHODS = ("lm-type3", "dogleg")
ITERATION_PROBLEMS = ("ladybug-49", "bal-synthetic:60:30000:3")


def _label(workers, chunks) -> str:
    return f"{workers}w" + ("" if chunks is None else f"/{chunks}c")


def _cores() -> int:
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not Linux
        return os.cpu_count() or 1


def _load() -> float:
    try:
        return os.getloadavg()[0]
    except OSError:
        return float("nan")


@dataclass
class Measure:
    """Medians over the runs of one variant: wall ``seconds``, ``cores`` (the process's CPU
    time over the wall time: 2 when two threads ran all along, less when other jobs took the
    cores or one thread waited) and minor page ``faults`` (memory the allocator took back
    from the operating system and had to fault in again)."""

    seconds: float
    cores: float
    faults: float


@dataclass
class AssemblyTiming:
    """One assembly of ``name`` (K observations): ``serial`` and, per ``(workers, chunks)``,
    ``parallel`` (:class:`Measure`); ``jacobians``: the residuals and Jacobians, for scale."""

    name: str
    num_observations: int
    serial: Measure
    parallel: dict = field(default_factory=dict)
    jacobians: Measure | None = None

    def speedup(self, config) -> float:
        return self.serial.seconds / self.parallel[config].seconds


def _same(serial, parallel, what: str) -> None:
    """Raise AssertionError when a parallel assembly's outputs differ from the serial ones."""
    for name, want, got in zip(("U", "V", "W", "g_cam", "g_point", "chi2"), serial, parallel):
        want, got = np.asarray(want, dtype=float), np.asarray(got, dtype=float)
        scale = max(1.0, float(np.max(np.abs(want), initial=0.0)))
        np.testing.assert_allclose(got, want, rtol=1e-10, atol=1e-12 * scale, err_msg=f"{what}: {name}")


def _faults() -> int:
    try:
        import resource
    except ImportError:  # not Unix
        return 0
    return resource.getrusage(resource.RUSAGE_SELF).ru_minflt


def _interleaved(runs: dict, repeats: int) -> dict:
    """``{name: Measure}`` of ``runs`` (``{name: callable}``), each repeat in a rotated order."""
    names = list(runs)
    samples: dict = {name: [] for name in names}
    for repeat in range(repeats):
        shift = repeat % len(names)
        for name in names[shift:] + names[:shift]:
            faults, cpu, start = _faults(), time.process_time(), time.perf_counter()
            runs[name]()
            wall = time.perf_counter() - start
            samples[name].append((wall, (time.process_time() - cpu) / wall if wall > 0 else float("nan"),
                                  _faults() - faults))
    return {name: Measure(*(statistics.median(column) for column in zip(*values)))
            for name, values in samples.items()}


def _chunked_in_processes(pool, kernel, args, workers):
    """The chunks' assemblies in a process pool, without the final sum: ``workers`` chunks
    of the Jacobians pickled to the processes, their blocks pickled back (the cost threads
    do not pay; the pool is started beforehand)."""
    r, J_cam, J_point, camera_index, point_index, num_cameras, num_points = args
    bounds = np.linspace(0, len(r), workers + 1).astype(int)
    futures = [pool.submit(kernel, r[lo:hi], J_cam[lo:hi], J_point[lo:hi], camera_index[lo:hi],
                           point_index[lo:hi], num_cameras, num_points) for lo, hi in zip(bounds[:-1], bounds[1:])]
    return [future.result() for future in futures]


def _process_pool(workers):
    """A process pool that forks (the workers find the implementation's modules), or None
    where fork is not available."""
    import concurrent.futures
    import multiprocessing

    if "fork" not in multiprocessing.get_all_start_methods():
        return None
    return concurrent.futures.ProcessPoolExecutor(max_workers=workers, mp_context=multiprocessing.get_context("fork"))


def time_assembly(name, impl="solutions", configs=CONFIGS, repeats=9, processes=2) -> AssemblyTiming:
    """Serial against parallel assembly of the BAL problem ``name`` at its start (medians of
    ``repeats``); with ``processes``, also the chunks assembled in that many processes
    (:func:`_chunked_in_processes`, key ``("processes", n)``)."""
    from course.problems.bal.dataset import load_bal

    implementation = impl_loader.load(impl)
    ba, pa = implementation.module("bundle_adjustment"), implementation.module("parallel_assembly")
    p = load_bal(name)
    jacobians = (p.cameras, p.points, p.camera_index, p.point_index, p.observations)
    r, J_cam, J_point = ba.reprojection_residuals_and_jacobians(*jacobians)
    args = (r, J_cam, J_point, p.camera_index, p.point_index, p.num_cameras, p.num_points)
    serial = ba.normal_equations(*args)
    for workers, chunks in configs:
        _same(serial, pa.normal_equations_parallel(*args, workers=workers, chunks=chunks),
              f"{name}, {_label(workers, chunks)}")
    runs: dict[Any, Callable[[], Any]] = {"serial": lambda: ba.normal_equations(*args),
                                          "jacobians": lambda: ba.reprojection_residuals_and_jacobians(*jacobians)}
    for workers, chunks in configs:
        runs[(workers, chunks)] = functools.partial(pa.normal_equations_parallel, *args, workers=workers, chunks=chunks)
    pool = _process_pool(processes) if processes else None
    try:
        if pool is not None:
            _chunked_in_processes(pool, ba.normal_equations, args, processes)  # start the processes
            runs[("processes", processes)] = functools.partial(_chunked_in_processes, pool, ba.normal_equations, args,
                                                               processes)
        medians = _interleaved(runs, repeats)
    finally:
        if pool is not None:
            pool.shutdown()
    return AssemblyTiming(name, p.num_observations, medians.pop("serial"), jacobians=medians.pop("jacobians"),
                          parallel=medians)


def gil_held(function, repeats=3) -> float:
    """How much of a call of ``function`` holds the GIL: the longest stall of a pure-Python
    heartbeat thread while it runs, over its duration (median of ``repeats``). About 1 when the
    call holds the GIL throughout (a pure-Python loop, ``sorted``), near 0 when it releases it
    (the operating system may still stall the heartbeat for a time slice on a busy machine)."""
    import sys
    import threading

    ratios = []
    interval = sys.getswitchinterval()
    sys.setswitchinterval(1e-4)
    try:
        for _ in range(repeats):
            stop = threading.Event()
            gaps: list[float] = []

            def beat(stop=stop, gaps=gaps):
                last, worst = time.perf_counter(), 0.0
                while not stop.is_set():
                    now = time.perf_counter()
                    worst, last = max(worst, now - last), now
                gaps.append(worst)

            thread = threading.Thread(target=beat)
            thread.start()
            time.sleep(0.005)
            start = time.perf_counter()
            function()
            took = time.perf_counter() - start
            stop.set()
            thread.join()
            ratios.append(min(gaps[0] / took, 1.0))
    finally:
        sys.setswitchinterval(interval)
    return statistics.median(ratios)


def gil_table(num_observations=100_000, seed=0) -> dict:
    """:func:`gil_held` of the numpy operations of the assembly on K random observations, and of a
    pure-Python ``sorted`` (the control, which holds the GIL). ``A.T @ A`` is one product of 2-D
    arrays ((2K, 9) here, as ``bundle_adjustment.normal_equations`` forms U_c per camera): numpy
    2.4 keeps the GIL through it, where ``np.dot`` releases it."""
    rng = np.random.default_rng(seed)
    K = num_observations
    J_cam = rng.normal(size=(K, 2, 9))
    index = rng.integers(0, 50, K)
    Jt = J_cam.transpose(0, 2, 1)
    blocks = np.matmul(Jt, J_cam)
    flat = (index[:, None] * 81 + np.arange(81)).ravel()
    items = rng.random(300_000).tolist()
    rows = J_cam.reshape(-1, 9)
    operations = {
        "np.matmul (batched)": lambda: np.matmul(Jt, J_cam),
        "A.T @ A (one 2-D product)": lambda: rows.T @ rows,
        "np.dot(A.T, A)": lambda: np.dot(rows.T, rows),
        "np.einsum": lambda: np.einsum("kai,kaj->kij", J_cam, J_cam),
        "np.bincount (weights)": lambda: np.bincount(flat, weights=blocks.ravel(), minlength=50 * 81),
        "np.add.at": lambda: np.add.at(np.zeros((50, 9, 9)), index, blocks),
        "fancy indexing": lambda: blocks[np.argsort(index, kind="stable")],
        "np.sum": lambda: np.sum(blocks * blocks),
        "sorted(list) (control)": lambda: sorted(items),
    }
    return {name: gil_held(operation) for name, operation in operations.items()}


class TimedBundleAdjustment:
    """An implementation's ``bundle_adjustment`` with its three pieces timed and, with
    ``workers``, ``normal_equations`` run by ``parallel_assembly.normal_equations_parallel``
    (the serial one as its kernel). Set as ``BundleAdjustmentProblem.ba``."""

    PIECES = ("reprojection_residuals_and_jacobians", "normal_equations", "schur_solve")

    def __init__(self, module, parallel=None, workers=None, chunks=None):
        self.module, self.parallel, self.workers, self.chunks = module, parallel, workers, chunks
        self.seconds = dict.fromkeys(self.PIECES, 0.0)
        self.calls = dict.fromkeys(self.PIECES, 0)
        self.faults = dict.fromkeys(self.PIECES, 0)

    def _timed(self, piece, function, *args, **kwargs):
        faults, start = _faults(), time.perf_counter()
        try:
            return function(*args, **kwargs)
        finally:
            self.seconds[piece] += time.perf_counter() - start
            self.calls[piece] += 1
            self.faults[piece] += _faults() - faults

    def reprojection_residuals_and_jacobians(self, *args):
        return self._timed("reprojection_residuals_and_jacobians", self.module.reprojection_residuals_and_jacobians,
                           *args)

    def normal_equations(self, *args):
        if self.parallel is None:
            return self._timed("normal_equations", self.module.normal_equations, *args)
        return self._timed("normal_equations", self.parallel.normal_equations_parallel, *args, workers=self.workers,
                           chunks=self.chunks, kernel=self.module.normal_equations)

    def schur_solve(self, *args, **kwargs):
        return self._timed("schur_solve", self.module.schur_solve, *args, **kwargs)


@dataclass
class IterationTiming:
    """Median milliseconds per step attempt of ``method`` on ``name`` for each assembly
    (``per_attempt``: ``"serial"`` and ``workers`` -> ms), each run's split (``pieces``: assembly
    -> {piece: ms per attempt}) and the serial run's linearizations per attempt."""

    name: str
    method: str
    per_attempt: dict
    pieces: dict
    linearizations: float

    def speedup(self, workers) -> float:
        return self.per_attempt["serial"] / self.per_attempt[workers]

    @property
    def assembly_share(self) -> float:
        """The assembly's share of a serial step attempt."""
        return self.pieces["serial"]["normal_equations"] / self.per_attempt["serial"]

    def amdahl(self, workers) -> float:
        """The step attempt's speed-up if only the assembly changed, by its speed-up in these runs."""
        s = self.pieces["serial"]["normal_equations"] / self.pieces[workers]["normal_equations"]
        share = self.assembly_share
        return 1.0 / (1.0 - share + share / s)


def time_iterations(name, method, impl="solutions", workers=(1, 2), attempts=5, repeats=3) -> IterationTiming:
    """``attempts`` step attempts of ``method`` on ``name`` (gauge fixed, tolerances 0) with the
    serial assembly and the parallel one on each of ``workers`` (one chunk per worker),
    interleaved; the run of median time of ``repeats`` for each."""
    from course.problems.bal.dataset import load_bal
    from course.problems.bal.problem import BundleAdjustmentProblem
    from course.solver import SolverOptions, minimize

    implementation = impl_loader.load(impl)
    pa = implementation.module("parallel_assembly")
    bal = load_bal(name)
    options = SolverOptions(max_iterations=attempts, gradient_tolerance=0.0, step_tolerance=0.0, cost_tolerance=0.0)
    modes = ("serial", *workers)
    results: dict = {mode: [] for mode in modes}

    def run(mode):
        problem = BundleAdjustmentProblem(bal, implementation, fix_gauge=True)
        timed = TimedBundleAdjustment(problem.ba, None if mode == "serial" else pa,
                                      None if mode == "serial" else mode)
        problem.ba = timed
        result = minimize(problem, method, impl=implementation, options=options)
        count = max(result.iterations, 1)
        results[mode].append((result.seconds * 1e3 / count, {k: v * 1e3 / count for k, v in timed.seconds.items()},
                              timed.calls["normal_equations"] / count))

    _interleaved({mode: (lambda m=mode: run(m)) for mode in modes}, repeats)
    chosen = {mode: sorted(runs, key=lambda item: item[0])[len(runs) // 2] for mode, runs in results.items()}
    return IterationTiming(name, method, {mode: run[0] for mode, run in chosen.items()},
                           {mode: run[1] for mode, run in chosen.items()}, chosen["serial"][2])


def section(repeats=9, impl="solutions", out=print, problems=PROBLEMS, configs=CONFIGS, methods=METHODS,
            iteration_problems=ITERATION_PROBLEMS, attempts=5, iteration_repeats=3) -> None:
    """Print the assembly table and the iteration table; what cannot run here is one line."""
    from course.core.errors import DatasetError

    cores, load = _cores(), _load()
    out(f"Parallel assembly of the normal equations (threads), impl {impl}: medians of {repeats} interleaved runs; "
        f"{cores} cores, load average {load:.2f} at the start (other jobs share the cores)")
    out("  variant: serial = bundle_adjustment.normal_equations; Nw = normal_equations_parallel on N threads, one "
        "chunk per worker (/Nc: N chunks); Np = the chunks' assemblies in N forked processes, without the final sum "
        "(pool started beforehand); cores = this process's CPU time / wall time; faults = minor page faults per "
        "assembly")
    out(f"{'problem':24} {'K':>7} {'variant':>9} {'ms':>8} {'speed-up':>8} {'vs 1w':>6} {'cores':>5} {'faults':>7}")
    for name in problems:
        try:
            t = time_assembly(name, impl, configs, repeats)
        except DatasetError as exc:
            out(f"{name:24} skipped: {exc}")
            continue
        except NotImplementedError as exc:
            out(f"{name:24} skipped: {exc}")
            return
        one = t.parallel.get((1, None))
        rows = [("jacobians", t.jacobians, ""), ("serial", t.serial, "1.00x")]
        rows += [(_label(*c), t.parallel[c], f"{t.speedup(c):7.2f}x") for c in configs]
        rows += [(f"{n}p", m, f"{t.serial.seconds / m.seconds:7.2f}x") for (kind, n), m in t.parallel.items()
                 if kind == "processes"]
        for number, (label, m, ratio) in enumerate(rows):
            assert m is not None
            versus = f"{one.seconds / m.seconds:5.2f}x" if one is not None and label.endswith("w") else ""
            head = f"{name:24} {t.num_observations:7d}" if number == 0 else " " * 32
            out(f"{head} {label:>9} {m.seconds * 1e3:8.2f} {ratio:>8} {versus:>6} {m.cores:5.2f} {m.faults:7.0f}")
    held = gil_table()
    out("GIL held during each call (1 = throughout, ~0 = released; a pure-Python thread's longest stall over the "
        "call's time, K = 100000): " + ", ".join(f"{name} {value:.2f}" for name, value in held.items()))
    out(f"Whole step attempts (gauge fixed, {attempts} attempts a run, median of {iteration_repeats} runs): ms per "
        "attempt with the serial, 1-worker and 2-worker assembly; the assembly's share of a serial attempt and the "
        "serial run's ms per attempt in the Jacobians, the assembly and the Schur solve (the rest: trial chi2 and "
        "the loop); Amdahl's bound for 2 workers from the assembly's own speed-up in these runs")
    out(f"{'problem':24} {'method':9} {'serial':>7} {'1w':>7} {'2w':>7} {'2w/serial':>9} {'2w/1w':>6} "
        f"{'amdahl':>6} {'share':>6} {'lin/att':>7} {'jac':>6} {'assembly':>8} {'schur':>6}")
    for name in iteration_problems:
        for method in methods:
            try:
                run = time_iterations(name, method, impl, (1, 2), attempts, iteration_repeats)
            except DatasetError as exc:
                out(f"{name:24} skipped: {exc}")
                break
            except NotImplementedError as exc:
                out(f"{name:24} skipped: {exc}")
                return
            per, piece = run.per_attempt, run.pieces["serial"]
            out(f"{name:24} {method:9} {per['serial']:7.1f} {per[1]:7.1f} {per[2]:7.1f} {run.speedup(2):8.2f}x "
                f"{per[1] / per[2]:5.2f}x {run.amdahl(2):5.2f}x {run.assembly_share:6.0%} {run.linearizations:7.2f} "
                f"{piece['reprojection_residuals_and_jacobians']:6.1f} {piece['normal_equations']:8.1f} "
                f"{piece['schur_solve']:6.1f}")
    out(f"load average {_load():.2f} at the end")


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python -m course.app.parallel_speedup", description=__doc__.split("\n\n")[0])
    parser.add_argument("--impl", default="solutions")
    parser.add_argument("--repeats", type=int, default=9, help="runs per assembly median (default 9)")
    parser.add_argument("--iteration-repeats", type=int, default=3, help="runs per iteration median (default 3)")
    args = parser.parse_args(argv)
    section(args.repeats, args.impl, iteration_repeats=args.iteration_repeats)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
