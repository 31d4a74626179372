"""``python -m course benchmark --suite``: the ratios the project tracks against the peers, each beside
the machine it was measured on (:mod:`course.app.machine`), in one JSON; ``--compare OLD.json``
says what moved between two runs or two machines.

The rows, by item (``--only`` selects items: a name, a part of it before a colon, or its last part;
``2d`` is every 2D item, ``2d:solution`` every 2D time to solution, ``intel`` every item on intel):

- ``bal:ladybug-49``: LM seconds per iteration (:data:`BAL_ITERATIONS` iterations from the BAL start), ours
  (Schur complement, gauge fixed) / Ceres' (pycolmap, one thread): goal 1.0
  (:func:`course.app.benchmark_bal.per_iteration`);
- ``vio:vio-sim:12:0``: the sliding window's seconds per solve, ours (with the prior) / GTSAM's fixed-lag
  smoother: goal 1.0; the batch per iteration, ours / GTSAM's (:func:`course.app.benchmark_vio.speed`);
- ``2d:iteration:w10000``: Gauss-Newton seconds per iteration / g2o's: goal 1.0
  (:func:`course.app.benchmark.gauss_newton_vs_g2o`);
- ``2d:solution:GRAPH``, every graph of ``benchmark.SOLUTION_GRAPHS``: time to solution, our chordal start
  plus Gauss-Newton (the start included) / g2o's Gauss-Newton from the file's poses: goal 1.5
  (:func:`course.app.benchmark.time_to_solution`);
- ``3d:iteration:GRAPH`` and ``3d:solution:GRAPH``, every graph of ``benchmark_3d.GRAPHS``: Gauss-Newton per
  iteration, ours and ours+CHOLMOD / g2o's and / GTSAM's; time to solution / g2o's
  (:mod:`course.app.benchmark_3d`; at most 3 repeats, as ``benchmark`` runs them: g2o takes minutes on torus3D);
- ``autodiff:GRAPH``, every graph of ``benchmark_autodiff.GRAPHS``: one linearisation, automatic (Jets,
  ``ours-autodiff``; JAX) / analytic (``ours``) (:func:`course.app.benchmark_autodiff.measure`).

Each repeat runs ours and the peer one after the other, so a repeat's ratio divides two times taken
under the same load; :data:`WARMUP` more repeats run first and are dropped (the first run of a process
loads the compiled kernels, reads caches, and is several times slower). A row's ``ratio`` is the median
of its repeats' ratios and ``min``/``max`` their spread; ``ours_seconds`` and ``peer_seconds`` are the
medians of each side; ``met`` says whether the ratio is at or under the row's ``goal`` (``None`` without
a goal). A peer, a dataset or a library
missing here, or a TODO of the implementation, is a row with ``status`` "not run" and the reason.

Moved (:func:`moved`): with ``s = ((max_old - min_old) + (max_new - min_new)) / 2``, half the sum of the
two runs' spreads, a row moved when its new median ratio lies outside ``[min_old - s, max_old + s]``:
"slower" above, "faster" below. One repeat has no spread: then any change is flagged, so compare runs of
3 repeats or more.
"""

import json
import statistics
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

from course.app import machine
from course.core import peers
from course.core.errors import CourseError, DatasetError
from course.core.jsonio import write_json
from course.core.peers import PeerMissing

#: the JSON's ``format``
FORMAT = "course-benchmark-suite/1"
#: LM iterations per bundle-adjustment run (the issue's measurement: ``compare ladybug-49``, 20 iterations)
BAL_ITERATIONS = 20
#: at most this many repeats of a 3D item (g2o's time to solution on torus3D takes minutes)
REPEATS_3D = 3
#: repeats run before the measured ones, and dropped
WARMUP = 1
#: our solvers in the 3D rows (``course.app.benchmark_3d.our_solvers``; the second needs cvxopt) and their solves
SOLVES_3D = {"ours": "the implementation's sparse Cholesky", "ours+CHOLMOD": "CHOLMOD's supernodal Cholesky"}
OURS_3D = tuple(SOLVES_3D)
#: the goals the project holds these rows to (ratio at most)
GOAL_AHEAD, GOAL_SMALL_GRAPHS = 1.0, 1.5


@dataclass
class Row:
    """One ratio: ``name`` (``ITEM LABEL``), ``divides`` (what over what), the median ratio over the
    repeats and their ``low``/``high``, the medians of ours and the peer in seconds, the per-repeat
    ``ratios``, the ``goal`` (ratio at most; ``None``: none); ``status`` "measured" or "not run" (``reason``)."""

    name: str
    divides: str
    ratio: float | None = None
    low: float | None = None
    high: float | None = None
    ours_seconds: float | None = None
    peer_seconds: float | None = None
    ratios: list = field(default_factory=list)
    goal: float | None = None
    status: str = "measured"
    reason: str = ""

    @property
    def met(self) -> bool | None:
        return None if self.goal is None or self.ratio is None else self.ratio <= self.goal

    def as_json(self) -> dict:
        return {"name": self.name, "divides": self.divides, "ratio": self.ratio, "min": self.low, "max": self.high,
                "ours_seconds": self.ours_seconds, "peer_seconds": self.peer_seconds, "repeats": len(self.ratios),
                "ratios": self.ratios, "goal": self.goal, "met": self.met, "status": self.status,
                "reason": self.reason}


def measured(name: str, divides: str, ours: list, theirs: list, goal: float | None = None) -> Row:
    """The row of paired per-repeat seconds ``ours[i] / theirs[i]``."""
    if not ours or len(ours) != len(theirs):
        raise ValueError(f"{name}: {len(ours)} times of ours against {len(theirs)} of the peer")
    ratios = [a / b for a, b in zip(ours, theirs)]
    return Row(name, divides, statistics.median(ratios), min(ratios), max(ratios), statistics.median(ours),
               statistics.median(theirs), ratios, goal)


#: an item's measurement: ``(repeats, impl) -> {label: (ours seconds, peer seconds) per repeat, or why not run}``
Measure = Callable[[int, str], dict]


@dataclass
class Item:
    """A unit of work and its rows: ``divides[label]`` says what each row divides; ``goals[label]`` its goal;
    ``max_repeats`` caps the repeats."""

    name: str
    divides: dict
    measure: Measure
    goals: dict = field(default_factory=dict)
    max_repeats: int | None = None

    def rows(self, repeats: int, impl: str, warmup: int = WARMUP) -> list:
        """Its rows, of ``repeats`` (at most ``max_repeats``) after ``warmup`` dropped; a peer, dataset or
        library missing, a TODO, or a solve that failed (a ``CourseError``) is a row "not run" saying so."""
        repeats = min(repeats, self.max_repeats or repeats)
        try:
            measured_here = self.measure(repeats + warmup, impl)
        except (PeerMissing, NotImplementedError, CourseError) as exc:
            reason = getattr(exc, "short", None) or str(exc)  # a missing data folder: what is missing, not the help
            if isinstance(exc, NotImplementedError) and "TODO" not in reason:
                reason = f"TODO: {reason}"
            elif isinstance(exc, CourseError) and not isinstance(exc, DatasetError):
                reason = f"failed: {type(exc).__name__}: {reason}"  # the implementation's solve, e.g. a singular system
            measured_here = dict.fromkeys(self.divides, reason)
        out = []
        for label, divides in self.divides.items():
            name, goal = f"{self.name} {label}", self.goals.get(label)
            got = measured_here.get(label, "not measured")
            if isinstance(got, str):
                out.append(Row(name, divides, goal=goal, status="not run", reason=got))
            else:
                ours, theirs = got
                out.append(measured(name, divides, ours[warmup:], theirs[warmup:], goal=goal))
        return out


def _repeat(repeats: int, once: Callable[[], tuple]) -> tuple:
    """``(ours, theirs)`` lists of ``repeats`` calls of ``once() -> (ours, theirs)`` seconds."""
    ours, theirs = [], []
    for _ in range(repeats):
        a, b = once()
        ours.append(a)
        theirs.append(b)
    return ours, theirs


def _bal(name: str) -> Item:
    from course.app import benchmark_bal

    ceres = next(pair for pair in benchmark_bal.PEER_METHODS if pair[0] == "ceres")

    def measure(repeats, impl):
        from course.backends import registry

        registry.peer_solver("bal", "ceres")  # PeerMissing before ours runs
        timings = {t.backend: t for t in benchmark_bal.per_iteration(name, repeats, iterations=BAL_ITERATIONS,
                                                                     impl=impl, peers=(ceres,))}
        if timings["ceres"].skipped:
            return {"ours/ceres": timings["ceres"].skipped}
        return {"ours/ceres": (timings["ours"].samples, timings["ceres"].samples)}

    return Item(f"bal:{name}", {"ours/ceres": f"LM seconds per iteration on {name} ({BAL_ITERATIONS} iterations from "
                                              f"the BAL start): ours ({benchmark_bal.OUR_METHOD}, Schur complement, "
                                              "gauge fixed) / Ceres (pycolmap, one thread)"},
                measure, {"ours/ceres": GOAL_AHEAD})


def _vio(name: str) -> Item:
    from course.app import benchmark_vio

    window, batch = benchmark_vio.ROWS

    def measure(repeats, impl):
        rows = {row.what: row for row in benchmark_vio.speed(name, repeats, impl=impl)}
        return {"window ours/gtsam": (rows[window].ours, rows[window].theirs),
                "batch ours/gtsam": (rows[batch].ours, rows[batch].theirs)}

    return Item(f"vio:{name}", {
        "window ours/gtsam": f"the sliding window's seconds per solve on {name}: ours (with the marginalisation "
                             "prior) / GTSAM's BatchFixedLagSmoother",
        "batch ours/gtsam": f"the batch's seconds per iteration on {name}: ours / GTSAM's batch LM"},
        measure, {"window ours/gtsam": GOAL_AHEAD})


def _iteration_2d(name: str) -> Item:
    from course.app import benchmark

    def measure(repeats, impl):
        return {"ours/g2o": _repeat(repeats, lambda: benchmark.gauss_newton_vs_g2o(name, 1, impl=impl)[:2])}

    return Item(f"2d:iteration:{name}", {"ours/g2o": f"Gauss-Newton seconds per iteration on {name} from the "
                                                     "file's poses: ours / g2o (g2opy)"},
                measure, {"ours/g2o": GOAL_AHEAD})


def _solution_2d(name: str) -> Item:
    from course.app import benchmark

    def once(impl):
        t = benchmark.time_to_solution(name, 1, impl=impl)
        return t.chordal, t.g2o

    def measure(repeats, impl):
        return {"ours/g2o": _repeat(repeats, lambda: once(impl))}

    return Item(f"2d:solution:{name}", {"ours/g2o": f"seconds to solution on {name}: our chordal start + "
                                                    "Gauss-Newton (the start included) / g2o's Gauss-Newton from "
                                                    "the file's poses, both stopped by the same rule"},
                measure, {"ours/g2o": GOAL_SMALL_GRAPHS})


def _missing_3d(label: str, peer: str) -> str:
    from course.backends import registry

    if label not in _our_solvers_3d():
        return peers.missing_message("cvxopt")
    return peers.missing_message(registry.library("posegraph3d", peer))


def _our_solvers_3d() -> dict:
    from course.app import benchmark_3d

    return benchmark_3d.our_solvers()


def _iteration_3d(name: str) -> Item:
    from course.app import benchmark_3d

    labels = [(ours, peer) for ours in OURS_3D for peer in ("g2o", "gtsam")]

    def measure(repeats, impl):
        samples: dict = {}
        for _ in range(repeats):
            for backend, seconds in benchmark_3d.per_iteration(name, 1, impl=impl).items():
                samples.setdefault(backend, []).append(seconds)
        return {f"{ours}/{peer}": (samples[ours], samples[peer]) if ours in samples and peer in samples
                else _missing_3d(ours, peer) for ours, peer in labels}

    return Item(f"3d:iteration:{name}", {
        f"{ours}/{peer}": f"Gauss-Newton seconds per iteration on {name} from the file's poses: {ours} "
                          f"({SOLVES_3D[ours]}) / {'g2o (g2opy)' if peer == 'g2o' else 'GTSAM'}"
        for ours, peer in labels}, measure, max_repeats=REPEATS_3D)


def _solution_3d(name: str) -> Item:
    from course.app import benchmark_3d

    def measure(repeats, impl):
        ours: dict = {}
        theirs = []
        for _ in range(repeats):
            mine, g2o, _ = benchmark_3d.time_to_solution(name, 1, impl=impl)
            for label, (seconds, _run) in mine.items():
                ours.setdefault(label, []).append(seconds)
            theirs.append(g2o)
        return {f"{label}/g2o": (ours[label], theirs) if label in ours else _missing_3d(label, "g2o")
                for label in OURS_3D}

    return Item(f"3d:solution:{name}", {
        f"{label}/g2o": f"seconds to solution on {name}: our chordal start + Gauss-Newton ({SOLVES_3D[label]}; "
                        "the start included) / g2o's Gauss-Newton from the file's poses" for label in OURS_3D},
        measure, max_repeats=REPEATS_3D)


def _autodiff(name: str) -> Item:
    from course.app import benchmark_autodiff
    from course.core.backend_names import JAX, OURS, OURS_AUTODIFF

    automatic = {OURS_AUTODIFF: "Jets", JAX: "JAX"}

    def measure(repeats, impl):
        seconds = benchmark_autodiff.measure(name, repeats, impl)["linearisations"]
        return {f"{backend}/{OURS}": (seconds[backend], seconds[OURS]) if backend in seconds
                else peers.missing_message("jax") for backend in automatic}

    return Item(f"autodiff:{name}", {
        f"{backend}/{OURS}": f"seconds of one linearisation of {name}: the factor graph's Jacobians by {how} "
                             f"({backend}) / the chapter's analytic ones ({OURS})"
        for backend, how in automatic.items()}, measure)


def items(bal=("ladybug-49",), vio=("vio-sim:12:0",), iteration_2d=("w10000",), solution_2d=None,
          iteration_3d=None, solution_3d=None, autodiff=None) -> list:
    """Every :class:`Item` of the suite, in order; each argument lists the datasets of one kind (``None``:
    the benchmark's own list, ``benchmark.SOLUTION_GRAPHS``, ``benchmark_3d.GRAPHS``, ``benchmark_autodiff.GRAPHS``)."""
    from course.app import benchmark, benchmark_3d, benchmark_autodiff

    return [*map(_bal, bal), *map(_vio, vio), *map(_iteration_2d, iteration_2d),
            *map(_solution_2d, benchmark.SOLUTION_GRAPHS if solution_2d is None else solution_2d),
            *map(_iteration_3d, benchmark_3d.GRAPHS if iteration_3d is None else iteration_3d),
            *map(_solution_3d, benchmark_3d.GRAPHS if solution_3d is None else solution_3d),
            *map(_autodiff, benchmark_autodiff.GRAPHS if autodiff is None else autodiff)]


def selects(selector: str, name: str) -> bool:
    """Whether ``--only``'s ``selector`` picks the item ``name``: the name itself, a part of it up to a
    colon (``2d``, ``2d:solution``) or after one (``intel``, ``vio-sim:12:0``)."""
    return name == selector or name.startswith(selector + ":") or name.endswith(":" + selector)


def select(chosen: list, only=None) -> list:
    """The items of ``chosen`` that a selector of ``only`` picks (all for ``None``); ``ValueError``
    naming the items when a selector picks none."""
    if not only:
        return list(chosen)
    for selector in only:
        if not any(selects(selector, item.name) for item in chosen):
            raise ValueError(f"--only {selector!r} selects no row; the items are: "
                             + ", ".join(item.name for item in chosen))
    return [item for item in chosen if any(selects(s, item.name) for s in only)]


def _ms(seconds: float | None) -> str:
    return "-" if seconds is None else f"{seconds * 1e3:.2f} ms"


def format_row(row: Row) -> str:
    """One line: the row's name, its ratio and spread, the two medians and its goal."""
    if row.status != "measured":
        return f"{row.name:44} not run: {row.reason}"
    goal = "" if row.goal is None else f"  goal {row.goal:.1f}: {'met' if row.met else 'NOT MET'}"
    return (f"{row.name:44} {row.ratio:6.3f} ({row.low:.3f} to {row.high:.3f}, {len(row.ratios)} repeats)  "
            f"ours {_ms(row.ours_seconds)}, peer {_ms(row.peer_seconds)}{goal}")


def run(repeats: int = 5, impl: str = "solutions", only=None, out=print, chosen=None, command=None,
        note: str = "") -> dict:
    """Measure the items of ``chosen`` (default :func:`items`) that ``only`` selects, printing each row
    as it comes; returns the JSON: ``format``, ``machine`` (:func:`course.app.machine.describe`, taken
    before the first run), ``impl``, ``repeats``, ``warmup``, ``seconds`` (the whole run), ``note`` (what
    the measurer says of the run, e.g. "measured on a shared machine") and ``rows``."""
    picked = select(chosen if chosen is not None else items(), only)
    description = machine.describe(command)
    out(f"{description['cpu']}, {description['affinity'] or description['cores']} cores, BLAS "
        + ", ".join(f"{b['internal_api']} {b['version']} {b['architecture']} ({b['folder']})"
                    for b in description["blas"]
                    if b.get("user_api") == "blas")
        + f"; commit {(description['commit'] or 'none')[:10]}; impl {impl}, {repeats} repeats")
    start = time.perf_counter()
    rows = []
    for item in picked:
        out(f"{item.name}:")
        for row in item.rows(repeats, impl):
            out(f"  {format_row(row)}")
            out(f"  {'':44} {row.divides}")
            rows.append(row)
    goals = [row for row in rows if row.met is not None]
    out(f"goals met: {sum(bool(row.met) for row in goals)} of {len(goals)}; "
        f"not run: {sum(row.status != 'measured' for row in rows)} of {len(rows)} rows")
    return {"format": FORMAT, "machine": description, "impl": impl, "repeats": repeats, "warmup": WARMUP,
            "seconds": round(time.perf_counter() - start, 3), "note": note, "rows": [row.as_json() for row in rows]}


#: the fields :func:`load` requires of a measured row
ROW_FIELDS = ("name", "ratio", "min", "max", "status")


def load(path) -> dict:
    """A suite JSON; ``ValueError`` naming the file, the line or the row and field that is wrong."""
    path = Path(path)
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except OSError as exc:
        raise ValueError(f"{path}: {exc.strerror or exc}") from None
    except json.JSONDecodeError as exc:
        raise ValueError(f"{path}:{exc.lineno}: {exc.msg}") from None
    if not isinstance(data, dict) or not isinstance(data.get("rows"), list) or not isinstance(data.get("machine"),
                                                                                               dict):
        raise ValueError(f"{path}: not a `benchmark --suite` file: it needs 'machine' (an object) and 'rows' (a list)")
    for i, row in enumerate(data["rows"]):
        if not isinstance(row, dict):
            raise ValueError(f"{path}: rows[{i}]: not an object")
        where = f"{path}: rows[{i}] ({row.get('name', 'no name')})"
        for key in ROW_FIELDS if row.get("status") == "measured" else ("name", "status"):
            if key not in row:
                raise ValueError(f"{where}: no field {key!r}")
            if key in ("ratio", "min", "max") and not isinstance(row[key], (int, float)):
                raise ValueError(f"{where}: {key!r} is {row[key]!r}, not a number")
    return data


def moved(old: dict, new: dict) -> str:
    """"slower", "faster" or "" (steady): whether ``new``'s median ratio lies outside ``old``'s
    ``[min, max]`` widened on each side by half the sum of both rows' spreads (see the module doc)."""
    s = ((old["max"] - old["min"]) + (new["max"] - new["min"])) / 2
    if new["ratio"] > old["max"] + s:
        return "slower"
    if new["ratio"] < old["min"] - s:
        return "faster"
    return ""


def _when(description: dict) -> str:
    return (f"{description.get('date')}, commit {(description.get('commit') or 'none')[:10]}"
            f"{' (changed)' if description.get('dirty') else ''}, {description.get('cpu')}")


def compare(old: dict, new: dict, out=print) -> dict:
    """Print the two machines' differences, then per row in both the old and new ratio (spread) and the
    flag of :func:`moved`, then the rows in one only; returns ``{row name: flag}`` of the rows in both."""
    out(f"old: {_when(old['machine'])}")
    out(f"new: {_when(new['machine'])}")
    differences = machine.differences(old["machine"], new["machine"])
    if differences:
        out("the machines differ:")
        for line in differences:
            out(f"  {line}")
    else:
        out("the same CPU, cores, BLAS and versions")
    before = {row["name"]: row for row in old["rows"]}
    after = {row["name"]: row for row in new["rows"]}
    flags: dict = {}
    out(f"{'row':44} {'old ratio (min to max)':>24} {'new ratio (min to max)':>24}  moved beyond the noise")
    for name, row in after.items():
        if name not in before:
            continue
        was = before[name]
        if was["status"] != "measured" or row["status"] != "measured":
            flags[name] = "not run"
            out(f"{name:44} {_ratio(was):>24} {_ratio(row):>24}")
            continue
        flags[name] = moved(was, row)
        out(f"{name:44} {_ratio(was):>24} {_ratio(row):>24}  {flags[name].upper() or '-'}")
    for label, names in (("only in the old run", [n for n in before if n not in after]),
                         ("only in the new run", [n for n in after if n not in before])):
        if names:
            out(f"{label}: {', '.join(names)}")
    out(f"moved: {sum(flag in ('slower', 'faster') for flag in flags.values())} of {len(flags)} rows in both "
        f"({', '.join(n for n, f in flags.items() if f == 'slower') or 'none'} slower)")
    return flags


def _ratio(row: dict) -> str:
    if row["status"] != "measured":
        return "not run"
    return f"{row['ratio']:.3f} ({row['min']:.3f} to {row['max']:.3f})"


def main(repeats: int = 5, impl: str = "solutions", only=None, json_path=None, compare_with=(), out=print,
         chosen=None, command=None, note: str = "") -> int:
    """``benchmark --suite``: run (unless ``compare_with`` holds two files), write ``json_path``, and compare
    with ``compare_with[0]`` (``ValueError`` on a file that is not a suite's, before anything runs)."""
    files = [load(path) for path in compare_with]
    if len(files) == 2:
        compare(files[0], files[1], out=out)
        return 0
    result = run(repeats, impl, only, out, chosen, command, note)
    if json_path:
        write_json(json_path, result, indent=1, newline=True)
        out(f"wrote {json_path}")
    if files:
        out(f"compared with {compare_with[0]}:")
        compare(files[0], result, out=out)
    return 0
