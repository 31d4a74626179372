"""Command line: ``python -m course {demo,compare,datasets,benchmark,ape,vio} ...``, and the subcommands
registered from above the framework (:mod:`course.app.command_plugins`; the instructor's tree registers
``release``).

``main(argv=None) -> int`` is cheap to import: every subcommand imports what it needs
(numpy, pyceres, matplotlib, ...) when it runs. Exit codes: 0 success, 1 a failed
check or a solver/implementation error, 2 a usage error (unknown dataset, method, ...).
"""

import argparse
import shlex
import sys
from pathlib import Path

from course.app import command_plugins
from course.app.starts import INITIALISERS, PEER_INITIALISERS
from course.backends import registry
from course.core import chapters
from course.core.backend_names import BACKENDS
from course.core.data import data_dir
from course.core.errors import DatasetError
from course.core.impl import default_impl
from course.core.jsonio import write_json
from course.core.method_names import DEFAULT_METHODS, OUR_METHODS
from course.core.solve_names import SOLVES

#: ``--information``: the readers' repairs of an information matrix that is not positive definite
#: (``course.solver.information.MODES``, written out here: the command line imports no numpy)
INFORMATION = ("strict", "nearest-psd", "isotropic")


def methods_epilog() -> str:
    """``--help``'s list of every method, one line each: ours (every strategy of the minimizer, on
    every problem) and the peers' per kind of problem; the table ``--methods`` is checked against
    (``course.backends.registry``)."""
    on_request = [m for m in OUR_METHODS if m not in DEFAULT_METHODS]
    lines = ["methods (--methods NAME,...; a name selects it in every back end that has it; without --methods, "
             f"all of them but {', '.join(on_request)}, run only when named):",
             "  ours, on every problem:"]
    width = max(map(len, OUR_METHODS))
    lines += [f"    {name:{width}}  {what}" for name, what in OUR_METHODS.items()]
    lines.append("  the peers', per problem:")
    for kind, title in registry.KINDS.items():
        lines.append(f"    {title}:")
        peers = [(backend, method) for backend, method in registry.pairs(kind) if backend != registry.OURS]
        width = max(len(f"{backend} {method}") for backend, method in peers)
        lines += [f"      {f'{backend} {method}':{width}}  {registry.describe(kind, backend, method)}"
                  for backend, method in peers]
    return "\n".join(lines)


def _names(text):
    return None if text is None else [t.strip() for t in text.split(",") if t.strip()]


def _add_run_arguments(parser):
    parser.add_argument("--impl", default=None,
                        help="solutions, exercises or a directory laid out like exercises/ "
                             "(default: solutions when present, else exercises)")
    parser.add_argument("--methods", default=None,
                        help="comma-separated method names (default: all but "
                             f"{', '.join(m for m in OUR_METHODS if m not in DEFAULT_METHODS)}; "
                             "the list below says what each is)")
    parser.add_argument("--backends", default=None,
                        help=f"comma-separated back ends among {', '.join(BACKENDS)} (default: all)")
    parser.add_argument("--repeat", type=int, default=1,
                        help="solve each pair this many times and keep the median-time run")
    parser.add_argument("--init", default="file", choices=INITIALISERS + PEER_INITIALISERS,
                        help="pose graphs: where every solver starts: the file's poses, a breadth-first "
                             "spanning tree or the chordal relaxation (computed by the implementation), "
                             "or GTSAM's LAGO (2D, diagonal information only) or InitializePose3 (3D) "
                             "(default: file)")


def build_parser(plugins=None) -> argparse.ArgumentParser:
    """The command line; ``plugins``: the registered subcommands (default
    :func:`course.app.command_plugins.registered`)."""
    parser = argparse.ArgumentParser(
        prog="python -m course",
        description="SLAM back ends from the inside: run our solvers and the peers (Ceres, scipy, g2o, GTSAM).",
    )
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True

    demo = sub.add_parser("demo", help="chapter 1: every method and peer on generated curve data, with plots",
                          epilog=methods_epilog() + "\n(demo: --methods and --backends select on the curve)",
                          formatter_class=argparse.RawDescriptionHelpFormatter)
    _add_run_arguments(demo)
    demo.add_argument("--out", default="out", help="folder for the PNG plots and the JSON (default: out)")
    demo.add_argument("--points", type=int, default=100, help="number of samples (default 100)")
    demo.add_argument("--seed", type=int, default=0, help="noise seed (default 0)")
    demo.add_argument("--curve-only", action="store_true", help="skip the pose graphs (w10000, intel)")
    demo.set_defaults(func=cmd_demo, repeat=3)

    compare = sub.add_parser("compare", help="one dataset through our methods and the peers", epilog=methods_epilog(),
                             formatter_class=argparse.RawDescriptionHelpFormatter)
    compare.add_argument("dataset", help="'curve' (generated data), a named pose graph "
                         "(see `python -m course datasets`), manhattan:N, or a TORO/g2o file; "
                         "a BAL problem: ladybug-49, dubrovnik-3-7, bal-synthetic:CAMS:POINTS[:seed] or a BAL file")
    _add_run_arguments(compare)
    compare.add_argument("--json", metavar="FILE", help="write {dataset, runs[]} as JSON")
    compare.add_argument("--plot", metavar="FILE",
                         help="write a PNG: chi2 per iteration (curve) or the graph before and after (pose graphs)")
    compare.add_argument("--max-iterations", type=int, default=100, help="for every solver (default 100)")
    compare.add_argument("--solver", default=None, choices=SOLVES,
                         help="our sparse solve of H dx = -b (pose graphs, factor graphs): "
                              + "; ".join(f"{name}: {what}" for name, what in SOLVES.items())
                              + " (default: auto); the table's column solve names the one each row ran")
    compare.add_argument("--information", default="strict", choices=INFORMATION,
                         help="pose graphs: an edge whose information matrix is not positive definite is refused "
                              "(strict, the default: the error names file, line and eigenvalues), or repaired: "
                              "nearest-psd (the nearest matrix whose eigenvalues are at least 1e-9 times its "
                              "largest) or isotropic (SE-Sync's scaled identity per block, translation and "
                              "rotation); only such edges are touched, and every row says how many were")
    compare.set_defaults(func=cmd_compare)

    # a command of its own, not a flag of compare: compare solves a dataset with every method and peer and
    # takes their options (--methods, --backends, --init, --solver); this one solves once (ours) and times
    # the peers' marginals at that optimum, a table of other columns
    marg = sub.add_parser("marginals", help="chapter 8: every pose's marginal covariance at our optimum, ours "
                                            "against GTSAM's Marginals, Ceres' Covariance and the dense inverse "
                                            "(median times, ratio to GTSAM, largest difference to ours)")
    marg.add_argument("dataset", help="a named 2D or 3D pose graph (see `python -m course datasets`), manhattan:N "
                                      "or a TORO/g2o file")
    marg.add_argument("--repeat", type=int, default=3, help="runs per method, the median kept (default 3)")
    marg.add_argument("--dense-limit", type=int, default=None, metavar="ROWS",
                      help="the dense inverse runs where H has at most ROWS rows (default 3000)")
    marg.add_argument("--impl", default=None, help="solutions, exercises or a path (default: this tree's)")
    marg.add_argument("--json", metavar="FILE", help="write {facts, rows[]} as JSON")
    marg.set_defaults(func=cmd_marginals)

    listing = sub.add_parser("datasets", help="list the named datasets, their sizes and where each comes from")
    listing.set_defaults(func=cmd_datasets)

    # registered from above the framework: the instructor's tree has release (exercises, student tree, zip)
    for plugin in command_plugins.registered() if plugins is None else plugins:
        plugin.add_parser(sub)

    bench = sub.add_parser("benchmark", help="our time per iteration and to solution against the peers' on pose "
                                             "graphs, bundle adjustment and the VIO window, medians "
                                             "(course.app.benchmark)")
    bench.add_argument("--repeats", type=int, default=5)
    bench.add_argument("--impl", default=None, help="solutions, exercises or a path (default: this tree's)")
    bench.add_argument("--autodiff", action="store_true",
                       help="chapter 7 only: automatic against analytic Jacobians on intel, sphere2500 and ladybug-49 "
                            "(course.app.benchmark_autodiff)")
    bench.add_argument("--suite", action="store_true",
                       help="the tracked ratios (bundle adjustment, the VIO window, w10000, the 2D, 3D and autodiff "
                            "rows), each with its spread over the repeats and its goal, beside a description of "
                            "the machine (course.app.benchmark_suite)")
    bench.add_argument("--only", default=None, metavar="ROW[,ROW]",
                       help="--suite: these rows only: an item (2d:solution:intel), a part of it (2d, 2d:solution) "
                            "or a dataset (intel); a name that selects nothing lists the items")
    bench.add_argument("--json", default=None, metavar="FILE", help="--suite: write the rows and the machine to FILE")
    bench.add_argument("--note", default="", metavar="TEXT",
                       help="--suite: a note kept in the JSON beside the machine (e.g. 'measured on a shared machine')")
    bench.add_argument("--compare", nargs="+", default=(), metavar=("OLD.json", "NEW.json"),
                       help="with --suite: this run against OLD.json; with two files (no --suite): NEW.json against "
                            "OLD.json, nothing run. Prints the machines' differences, then each row's old and new "
                            "ratio, flagging one that moved beyond the noise of its repeats")
    bench.set_defaults(func=cmd_benchmark, parser=bench)

    ape = sub.add_parser("ape", help="chapter 5: absolute pose error of a trajectory against ground truth "
                                     "(TUM files, EuRoC CSVs), after SE(3)/Sim(3) alignment (course.problems.vio.ape)")
    ape.add_argument("reference", metavar="GT",
                     help="ground truth: a TUM file or a EuRoC CSV; or 'euroc-mh05' (the source's evaluation on "
                          "the shipped MH_05 files, beside the source's LM row)")
    ape.add_argument("estimate", metavar="EST", nargs="?", help="the estimated trajectory (TUM file or EuRoC CSV)")
    ape.add_argument("--align", default="se3", choices=["se3", "sim3", "none"],
                     help="Umeyama alignment of the estimate: se3, sim3 (monocular: also the scale) or none "
                          "(default se3)")
    ape.add_argument("--max-diff", type=float, default=0.01,
                     help="largest time difference of an associated pair, seconds (default 0.01, as evo)")
    ape.add_argument("--json", metavar="FILE", help="write {rmse, median, mean, std, max, min, pairs} (metres)")
    ape.set_defaults(func=cmd_ape)

    outliers = sub.add_parser("outliers3d", help="chapter 6: wrong loop closures against least squares, a Cauchy "
                                                 "kernel and GNC, ours and GTSAM's (course.app.outliers3d)")
    outliers.add_argument("dataset", nargs="?", default="sphere2500", help="a 3D graph (default sphere2500)")
    outliers.add_argument("--shares", default="0.1,0.2,0.5", help="shares of loop closures replaced (default "
                                                                  "0.1,0.2,0.5)")
    outliers.add_argument("--seed", type=int, default=1)
    outliers.add_argument("--impl", default=None, help="solutions, exercises or a path (default: this tree's)")
    outliers.set_defaults(func=cmd_outliers3d)

    online = sub.add_parser("online", help="chapter 8: a pose graph fed one pose at a time to our incremental "
                                           "smoother, GTSAM's ISAM2 and batch re-solves (course.app.online)")
    online.add_argument("dataset", help="a 2D or 3D pose graph (m3500, intel, sphere2500, manhattan:N[:seed], a file)")
    online.add_argument("--every", type=int, default=None, metavar="K",
                        help="the batch re-solves every K steps (default: about 20 over the sequence)")
    online.add_argument("--poses", type=int, default=None, metavar="N", help="the first N poses only (default all)")
    online.add_argument("--no-batch", action="store_true", help="the two smoothers only (no batch re-solves)")
    online.add_argument("--plot", metavar="FILE", help="write the time per step over the sequence (PNG)")
    online.add_argument("--breakdown", action="store_true",
                        help="time each function of the implementation our updates call, and print where the time "
                             "went (a timer per call)")
    online.add_argument("--impl", default=None, help="solutions, exercises or a path (default: this tree's)")
    online.set_defaults(func=cmd_online)

    vio = sub.add_parser("vio", help="chapter 5: the sliding window with and without the marginalisation prior, "
                                     "the batch, and GTSAM's, on simulated visual-inertial data (APE, time per solve)")
    vio.add_argument("name", nargs="?", default="vio-sim:12:0", help="vio-sim[:seconds[:seed]] (default vio-sim:12:0)")
    vio.add_argument("--window", type=int, default=10, help="keyframes in the window (default 10)")
    vio.add_argument("--no-peers", action="store_true", help="ours only (no GTSAM rows)")
    vio.add_argument("--impl", default=None, help="solutions, exercises or a path (default: this tree's)")
    vio.add_argument("--json", metavar="FILE", help="write {label: {rmse, max, scale, mean_solve_seconds, ...}}")
    vio.add_argument("--seeds", type=int, metavar="N", help="instead: the window (with the prior) against the batch "
                                                             "on seeds 0..N-1 of NAME's length (APE, scale)")
    vio.add_argument("--consistency", action="store_true", help="instead: chi2 / dof of each factor type at the "
                                                                "truth (near 1 where the factors model the noise)")
    vio.set_defaults(func=cmd_vio)
    return parser


def main(argv=None) -> int:
    plugins = command_plugins.registered()
    unregistered = command_plugins.unregistered(sys.argv[1:] if argv is None else list(argv),
                                                [plugin.name for plugin in plugins])
    if unregistered:
        print(f"error: {unregistered}", file=sys.stderr)
        return 2
    parser = build_parser(plugins)
    args = parser.parse_args(argv)
    args.command = shlex.join(["python", "-m", "course", *(sys.argv[1:] if argv is None else argv)])
    from course.core.errors import CourseError

    try:
        return int(args.func(args) or 0)
    except (CourseError, NotImplementedError, ArithmeticError) as exc:
        from course.app.compare import UnknownDatasetError

        print(f"error: {exc}", file=sys.stderr)
        return 2 if isinstance(exc, UnknownDatasetError) else 1
    except ValueError as exc:  # unknown method, backend, implementation path
        print(f"error: {exc}", file=sys.stderr)
        return 2


# ---------------------------------------------------------------- subcommands


def _ran(runs) -> list:
    """The runs that ran (a pair stopped at an unwritten TODO is a row, not a curve)."""
    return [r for r in runs if not r.not_run]


def _todo(runs) -> list:
    """The runs that stopped at an unwritten TODO (not those of a peer missing here, nor of an exercise not
    handed out yet in an assignment's tree: nothing for the student to write now)."""
    return [r for r in runs if r.not_run.startswith("not implemented") and "not handed out yet" not in r.not_run]


def cmd_demo(args) -> int:
    """Chapter 1's experiment: the table on the terminal, the plots in ``args.out``.

    A pair of ours that stops at an unwritten TODO is a row naming it
    (``not implemented: TODO module.function``), not the end of the demo: a student tree
    runs the peers and whatever is written so far, and exits 0."""
    from course.app import compare, plot
    from course.core import peers
    from course.problems.curve.problem import generate

    impl = args.impl or default_impl()
    _DATA_HELP_SAID.clear()  # how to get the data folder: once per demo
    peers.announce_missing(("pyceres", "g2opy", "gtsam", "pycolmap", "qdldl"))  # up front, once, whatever runs
    data = generate(num_points=args.points, seed=args.seed)
    methods, backends = _names(args.methods), _names(args.backends)
    progress = _progress("curve", methods, backends, "curve")
    runs = compare.run_curve(impl=impl, methods=methods, backends=backends, data=data, repeat=args.repeat,
                             unimplemented="row", progress=progress)
    progress.close()
    title = (f"Curve fit y = exp(a x^2 + b x + c), {args.points} points, sigma {data.sigma:g}, seed {args.seed}, "
             f"start {tuple(data.start.tolist())}, truth {tuple(data.truth.tolist())}; impl {impl}; "
             f"median of {args.repeat} runs")
    print(compare.format_table(runs, title=title))
    _advise(runs, "curve", impl)
    out = Path(args.out)
    lm_runs = [r for r in _ran(runs) if r.backend == "ours" and r.method.startswith("lm-type")]
    written = [out / "curve_chi2.png", out / "curve_lambda.png", out / "curve_fit.png"]
    plot.chi2_per_iteration(_ran(runs), written[0])
    plot.damping_per_iteration(lm_runs, written[1], title="lambda per iteration, Gavin's damping types 1-3")
    plot.curve_fit(data, _ran(runs), written[2])
    written.append(write_json(out / "curve.json", compare.to_json("curve", runs), indent=1))
    todo = _todo(runs)
    if not args.curve_only:
        for chapter, part in (("ch2", lambda: _demo_pose_graphs(impl, out, args.init)),
                              ("ch6", lambda: _demo_pose_graphs_3d(impl, out)),
                              ("ch4", lambda: _demo_bundle_adjustment(impl, out))):
            if not chapters.handed_out(chapter):  # an assignment's tree: the chapters handed out so far
                print(f"\nchapter {chapter[2:]} ({chapters.chapter(chapter).title}) is not handed out yet: skipped")
                continue
            part_written, part_todo = part()
            written += part_written
            todo += part_todo
    print("\nwrote " + ", ".join(str(p) for p in written))
    if todo:
        names = sorted({r.not_run.split("TODO ", 1)[-1].split(" ")[0].rstrip(":") for r in todo})
        print(f"\n{len(todo)} run(s) stopped at a TODO of impl {impl} ({', '.join(names)}); "
              "write them, and `python -m autograder --only NAME` checks each piece")
    return 0


#: the demo says how to get the data folder once, after the first dataset it skips for want of it
_DATA_HELP_SAID: list = []


def _skipped(name, exc) -> None:
    """``NAME skipped: why`` in the demo; where the data folder is missing, how to get it, once."""
    short = getattr(exc, "short", None)
    if short is None or str(exc) == short or _DATA_HELP_SAID:
        print(f"\n{name} skipped: {short or exc}")
        return
    _DATA_HELP_SAID.append(name)
    print(f"\n{name} skipped: {exc}")


#: w10000 in the demo: Gauss-Newton and dogleg of every back end but Ceres, whose
#: Python cost takes about 0.5 s per iteration there (see `compare w10000` for all)
DEMO_W10000 = {"methods": ["gauss-newton", "dogleg"], "backends": ["ours", "g2o", "gtsam"]}


def _demo_pose_graphs(impl, out, init="file") -> tuple:
    """w10000 (ships with gtsam) and, when the data folder is there, intel, from ``init``.

    Returns (paths written, the runs that stopped at a TODO)."""
    from course.app import compare, plot
    from course.problems.posegraph import dataset as datasets

    written, todo = [], []
    plans = []
    for name, plan in (("intel", {}), ("w10000", DEMO_W10000)):
        try:
            plans.append((name, datasets.load_dataset(name), plan))
        except DatasetError as exc:
            _skipped(name, exc)
    for name, graph, plan in plans:
        progress = _progress("posegraph", plan.get("methods"), plan.get("backends"), name)
        runs = compare.run_posegraph(graph, impl=impl, unimplemented="row", progress=progress, init=init, **plan)
        progress.close()
        todo += _todo(runs)
        note = "" if not plan else (f"; methods {', '.join(plan['methods'])}, back ends "
                                    f"{', '.join(plan['backends'])} (Ceres' Python cost is slow here: "
                                    f"`python -m course compare {name}` runs everything)")
        print("\n" + compare.format_table(
            runs, title=f"{name}: {graph.num_poses} poses, {graph.num_edges} edges; impl {impl}; init {init}{note}"))
        _advise(runs, "posegraph", impl)
        json_path = write_json(out / f"{name}.json", compare.to_json(name, runs))
        ran = _ran(runs)
        if ran:  # the first run that ran: ours when written, else a peer
            path = out / f"{name}.png"
            plot.pose_graph_before_after(_start(graph, init, impl), ran[0], path)
            written.append(path)
        written.append(json_path)
    return written, todo


#: chapter 6 in the demo: (graph, start, plan). pose3example and sphere_smallnoise ship with gtsam (no
#: download); sphere_smallnoise from the chordal start (from the file's, no back end converges in 100
#: iterations), Gauss-Newton only; smallGrid3D where the data folder is
DEMO_3D: tuple[tuple[str, str, dict], ...] = (("pose3example", "file", {}),
           ("sphere_smallnoise", "chordal", {"methods": ["gauss-newton"]}),
           ("smallGrid3D", "file", {}))
#: under every 3D table: what its final chi2 column means
NOTE_3D = ("final chi2 is our error, [D_t; Log(D_R)], on every back end's solution: g2o minimises its own "
           "(rotation part vec(q), about half the angle) and GTSAM its Logmap, so where residual rotations are "
           "large their minima are not ours; Ceres runs our error as a Python cost (slow per iteration) and "
           "ends at ours")


def _demo_pose_graphs_3d(impl, out) -> tuple:
    """Every method and peer on ``DEMO_3D`` from the file's poses; returns (paths written, the runs
    that stopped at a TODO)."""
    from course.app import compare
    from course.problems.posegraph3d import dataset as datasets

    written, todo = [], []
    for name, init, plan in DEMO_3D:
        try:
            graph = datasets.load_dataset(name)
        except DatasetError as exc:
            _skipped(name, exc)
            continue
        progress = _progress("posegraph3d", plan.get("methods"), None, name)
        runs = compare.run_posegraph3d(graph, impl=impl, unimplemented="row", progress=progress, init=init, **plan)
        progress.close()
        todo += _todo(runs)
        note = f"; methods {', '.join(plan['methods'])}" if plan else ""
        print("\n" + compare.format_table(runs, title=f"{name} (3D): {graph.num_poses} poses, {graph.num_edges} edges; "
                                                      f"impl {impl}; init {init}{note}"))
        _advise(runs, "posegraph3d", impl)
        print(NOTE_3D)
        written.append(write_json(out / f"{name}.json", compare.to_json(name, runs)))
    return written, todo


#: chapter 4's demo problem: generated (no download), every back end in a few seconds
DEMO_BAL = "bal-synthetic:10:200"


def _demo_bundle_adjustment(impl, out) -> tuple:
    """Every method and peer on ``DEMO_BAL``; returns (paths written, the runs that stopped at a TODO)."""
    from course.app import compare, plot
    from course.problems.bal.dataset import load_bal

    problem = load_bal(DEMO_BAL)
    progress = _progress("bal", None, None, DEMO_BAL)
    runs = compare.run_bal(problem, impl=impl, unimplemented="row", progress=progress)
    progress.close()
    print("\n" + compare.format_table(runs, title=f"{DEMO_BAL}: {problem.num_cameras} cameras, {problem.num_points} "
                                                  f"points, {problem.num_observations} observations; impl {impl}; "
                                                  "ours with the gauge fixed"))
    _advise(runs, "bal", impl)
    if compare.format_bal(runs):
        print("\n" + compare.format_bal(runs))
    name = DEMO_BAL.replace(":", "_")
    json_path, png = out / f"{name}.json", out / f"{name}.png"
    write_json(json_path, compare.to_json(DEMO_BAL, runs))
    written = [json_path]
    if _ran(runs):
        plot.chi2_per_iteration(_ran(runs), png, title=f"{DEMO_BAL}: chi2 per iteration")
        written.insert(0, png)
    return written, _todo(runs)


def _start(graph, init, impl):
    """``graph`` with the poses the solvers started from (``init``), for the plots."""
    from course.app.starts import initialise

    return initialise(graph, init, impl)[0]


def _progress(kind, methods, backends, label):
    """A progress line over the runs of one comparison (on a terminal only)."""
    from course.app import compare
    from course.core.progress import Progress

    plan = {"curve": compare.curve_plan, "bal": compare.bal_plan,
            "posegraph3d": compare.posegraph3d_plan}.get(kind, compare.posegraph_plan)(methods, backends)
    return Progress(len(plan), label=label)


def cmd_compare(args) -> int:
    from course.app import compare

    runner = compare.find_runner(args.dataset)  # fails early and clearly on unknown names
    impl = args.impl or default_impl()
    methods, backends = _names(args.methods), _names(args.backends)
    init = {}
    if runner.kind in ("posegraph", "posegraph3d"):
        init = {"init": args.init, "information": args.information}
    elif args.init != "file":
        raise ValueError(f"--init {args.init}: only pose graphs have an initialisation; "
                         f"{args.dataset} starts from its own given start (use --init file)")
    elif args.information != "strict":
        raise ValueError(f"--information {args.information}: only pose graphs have information matrices to repair; "
                         f"{args.dataset} is not one (leave --information out)")
    progress = _progress(runner.kind, methods, backends, args.dataset)
    runs = runner.run(args.dataset, impl=impl, methods=methods, backends=backends, repeat=args.repeat,
                      max_iterations=args.max_iterations, progress=progress, unimplemented="row",
                      solver=args.solver, **init)
    progress.close()
    where = f"impl {impl}; init {args.init}" if init else f"impl {impl}"
    notes = list(dict.fromkeys(r.note for r in runs if r.note))
    print(compare.format_table(runs, title=f"{args.dataset} ({where}{''.join(f'; {n}' for n in notes)})"))
    _say_what_to_check(runs, runner.kind, impl)
    if runner.kind == "posegraph3d":
        print(NOTE_3D)
    if runner.kind == "posegraph":
        ate = compare.format_ate(runs)
        if ate:
            print("\n" + ate)
    if runner.kind == "bal" and compare.format_bal(runs):
        print("\n" + compare.format_bal(runs))
    if args.json:
        print(f"wrote {write_json(args.json, compare.to_json(args.dataset, runs), indent=1)}")
    if args.plot:
        from course.app import plot

        if runner.kind == "posegraph3d":
            raise ValueError("--plot: the 3D pose graphs have no plot yet")
        if runner.kind == "posegraph":
            from course.problems.posegraph import dataset as datasets

            if not _ran(runs):
                raise ValueError(f"--plot: no run finished on {args.dataset}, nothing to plot")
            best = min(_ran(runs), key=lambda r: (r.backend != "ours", r.final_chi2))
            graph = datasets.load_dataset(args.dataset, information=args.information)
            plot.pose_graph_before_after(_start(graph, args.init, impl), best, args.plot)
        else:
            plot.chi2_per_iteration(_ran(runs), args.plot, title=f"{args.dataset}: chi2 per iteration")
        print(f"wrote {args.plot}")
    return 0


def _advise(runs, kind, impl) -> None:
    """Under a table: the lines of ``compare.advice`` (the student's runs that look wrong), if any."""
    from course.app import compare

    for line in compare.advice(runs, kind, impl):
        print(line)


def _say_what_to_check(runs, kind, impl) -> None:
    """Under a table: the runs of the student's that look wrong (``compare.advice``), and the TODOs
    that stopped runs with how to select what is written (``compare.todo_hint``)."""
    from course.app import compare

    lines = compare.advice(runs, kind, impl)
    hint = compare.todo_hint(runs, impl)
    if hint:
        lines.append(hint)
    if lines:
        print("\n".join(lines))


def cmd_marginals(args) -> int:
    from dataclasses import asdict

    chapters.require("ch8", "marginals")
    from course.app import marginals

    if args.repeat < 1:
        raise ValueError(f"--repeat {args.repeat}: at least 1")
    limit = marginals.DENSE_LIMIT if args.dense_limit is None else args.dense_limit
    rows, facts = marginals.compare(args.dataset, impl=args.impl or default_impl(), repeat=args.repeat,
                                    dense_limit=limit)
    print(marginals.format_rows(rows, facts))
    if args.json:
        rows_json = [{k: (None if isinstance(v, float) and v != v else v) for k, v in asdict(r).items()}
                     for r in rows]  # NaN (not measured) as null
        print(f"wrote {write_json(args.json, {'facts': facts, 'rows': rows_json}, indent=1)}")
    return 0


def cmd_outliers3d(args) -> int:
    chapters.require("ch6", "outliers3d")
    from course.app import outliers3d

    shares = tuple(float(v) for v in args.shares.split(",") if v.strip())
    outliers3d.main(args.dataset, shares, args.seed, args.impl or default_impl())
    return 0


def cmd_datasets(args) -> int:
    graphs = []
    if chapters.handed_out("ch2"):
        from course.problems.posegraph import dataset as datasets

        graphs += datasets.list_datasets()
    if chapters.handed_out("ch6"):
        from course.problems.posegraph3d import dataset as datasets3d

        graphs += datasets3d.list_datasets()
    print(f"data folder: {data_dir()} (override with COURSE_DATA)")
    print(f"{'name':18} {'poses':>6} {'edges':>6}  {'format':9}  where")
    for info in graphs:
        poses = "?" if info.poses is None else info.poses
        edges = "?" if info.edges is None else info.edges
        where = info.origin if info.available else f"{info.origin} (missing: {info.reason})"
        print(f"{info.name:18} {poses:>6} {edges:>6}  {info.format:9}  {where}")
    print(f"\n{'name':28} {'size':36} where")
    from course.app.datasets import list_other_data

    other = list_other_data()
    for name, size, where, reason in other:
        print(f"{name:28} {size:36} {where}{f' (missing: {reason})' if reason else ''}")
    if not data_dir().is_dir() or any(reason for *_, reason in other):
        from course.core.data import missing_data_help

        print(f"\n{missing_data_help()}.")
    return 0


def cmd_benchmark(args) -> int:
    if args.suite or args.compare:
        return _benchmark_suite(args)
    for flag in ("only", "json", "note"):
        if getattr(args, flag):
            args.parser.error(f"--{flag} needs --suite")
    if args.autodiff:
        chapters.require("ch7", "benchmark --autodiff")
        from course.app import benchmark_autodiff

        benchmark_autodiff.main(repeats=args.repeats, impl=args.impl or default_impl())
        return 0
    chapters.require("ch2", "benchmark")  # its first tables are the pose graphs'
    from course.app import benchmark

    benchmark.main(repeats=args.repeats, impl=args.impl or default_impl())
    return 0


def _benchmark_suite(args) -> int:
    """``benchmark --suite [--only ...] [--json FILE] [--compare OLD.json]`` or ``benchmark --compare OLD NEW``."""
    from course.app import benchmark_suite

    if len(args.compare) > 2:
        args.parser.error("--compare takes OLD.json, or OLD.json NEW.json")
    if args.repeats < 1:
        args.parser.error("--repeats must be at least 1")
    if args.autodiff:
        args.parser.error("--suite has the autodiff rows already; --autodiff is the full chapter 7 table")
    if len(args.compare) == 2 and (args.suite or args.only or args.json):
        args.parser.error("--compare OLD.json NEW.json runs nothing: give OLD.json alone to compare with a --suite run")
    if len(args.compare) == 1 and not args.suite:
        args.parser.error("--compare OLD.json compares with a --suite run: add --suite, or give a second file")
    return benchmark_suite.main(repeats=args.repeats, impl=args.impl or default_impl(), only=_names(args.only),
                                json_path=args.json, compare_with=args.compare, command=args.command,
                                note=args.note)


def cmd_online(args) -> int:
    """``online DATASET``: :func:`course.app.online.compare`'s table (and ``--plot``, ``--breakdown``)."""
    chapters.require("ch8", "online")
    from course.app import online

    result = online.compare(args.dataset, impl=args.impl or default_impl(), every=args.every,
                            batches=not args.no_batch, poses=args.poses, breakdown=args.breakdown)
    print(f"{result['name']}: {result['poses']} poses, {result['edges']} edges, fed one pose per step; batch re-solves "
          f"every {result['every']} steps (from the previous solution); chi2 = sum e^T Omega e over the edges "
          "(GTSAM's error is half of it)")
    print(online.format_table(result))
    if args.plot:
        online.plot(result, args.plot)
        print(f"wrote {args.plot}")
    return 0


def cmd_vio(args) -> int:
    """``vio [NAME]``: :func:`course.app.vio.compare`'s table (or ``--seeds``, ``--consistency``)."""
    chapters.require("ch5", "vio")
    from course.app import vio
    from course.problems.vio.sim import parse_name

    impl = args.impl or default_impl()
    if args.consistency:
        print(f"{args.name}: the batch problem at the truth, plain squares")
        print(vio.format_consistency(vio.consistency(args.name, impl=impl)))
        return 0
    if args.seeds:
        seconds, _ = parse_name(args.name)
        rows = vio.seeds(args.seeds, seconds, window=args.window, impl=impl)
        print(f"vio-sim:{seconds:g}:0..{args.seeds - 1}: APE rmse after SE(3) alignment, scale from Sim(3)")
        print(vio.format_seeds(rows))
        if args.json:
            print(f"wrote {write_json(args.json, rows, indent=1)}")
        return 0
    results = vio.compare(args.name, window=args.window, impl=impl,
                          peers=not args.no_peers)
    print(f"{args.name}: keyframes every 0.25 s, window {args.window}; APE after SE(3) alignment, "
          "scale from Sim(3)")
    print(vio.format_comparison(results))
    if args.json:
        print(f"wrote {write_json(args.json, results, indent=1)}")
    return 0


def cmd_ape(args) -> int:
    """``ape GT EST``: the APE table; ``ape euroc-mh05``: also the source's LM row and evo's."""
    chapters.require("ch5", "ape")
    from course.problems.vio import ape
    from course.problems.vio.trajectory_io import read_trajectory

    source = args.reference == "euroc-mh05"
    if source and args.estimate is None:
        gt_path, est_path = ape.euroc_mh05_files()
    elif args.estimate is None:
        raise ValueError("ape: give GT and EST files, or 'euroc-mh05' alone")
    else:
        gt_path, est_path, source = Path(args.reference), Path(args.estimate), False
    result = ape.ape(read_trajectory(gt_path), read_trajectory(est_path), align=args.align, max_diff=args.max_diff)
    stats = result.stats
    print(f"APE, translation part (m); alignment {args.align}; pairs within {args.max_diff:g} s")
    print(f"  GT  {gt_path}\n  EST {est_path}")
    if args.align == "sim3":
        print(f"  Sim(3) scale {result.alignment.scale:.6f}")
    print(ape.format_header())
    print(ape.format_row("ours", stats))
    if source:
        if args.align == "se3":
            print(ape.format_row("evo 1.38.1 (-a)", ape.EVO_SE3_ROW))
        print(ape.format_row("source's LM run", ape.SOURCE_LM_ROW))
        print("\n" + ape.compare_to_source(stats))
        print("The source's row is its own LM run of its VIO back end, evaluated by the source with SE(3) "
              "alignment. On the shipped files ours equals evo's (tests/test_ape.py: to 1e-9), and evo's is not "
              "the source's row either: that row came from another run of its estimator (or another evaluation), "
              "not from these files, so closeness, not equality, is what to expect.")
    if args.json:
        print(f"wrote {write_json(args.json, stats, indent=1)}")
    return 0
