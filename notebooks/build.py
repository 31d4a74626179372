"""Write the course notebooks with nbformat, and optionally execute them.

    python -m notebooks.build              # write notebooks/*.ipynb, no outputs
    python -m notebooks.build --execute    # write and run them (outputs saved in the file)
    python -m notebooks.build --small      # with --execute: one run per timing, not five,
                                           # and chapters 2 and 3 on small graphs only
    python -m notebooks.build --only chapter2 chapter3   # only those notebooks

Chapter 1 compares damping strategies on the curve, chapter 2 pose graphs (dense against
sparse, every back end on every named dataset, the written questions), chapter 3 the
dogleg against Levenberg-Marquardt.

The notebooks hold no logic of their own: every cell calls the package (``course.compare``,
``course.plot``, ...). Cell ids are fixed, so rebuilding gives the same file and
``tests/test_notebooks.py`` can check that the committed notebook's cells are current.
The cells read their settings from the environment (``COURSE_IMPL``,
``COURSE_NOTEBOOK_REPEAT``, ``COURSE_NOTEBOOK_SMALL``), so they are the same whatever
the build options.

Kernel: ``execute`` runs the kernel on *this* interpreter (``sys.executable``), so the
notebook sees the same packages as the caller. It uses the ``python3`` kernelspec when
that resolves to this interpreter (jupyter_client replaces a bare ``python``/``python3``
in the spec's argv with ``sys.executable``; an absolute path must equal it, compared
without resolving symlinks: a venv's python links to the base interpreter); otherwise it
writes a kernelspec for this interpreter into a temporary folder put first on
``JUPYTER_PATH`` for the run.
"""

import argparse
import contextlib
import os
import sys
import tempfile
import time
from pathlib import Path

import nbformat
from nbformat.v4 import new_code_cell, new_markdown_cell, new_notebook

HERE = Path(__file__).resolve().parent
CHAPTER1 = HERE / "chapter1_curve_fitting.ipynb"
CHAPTER2 = HERE / "chapter2_pose_graphs.ipynb"
CHAPTER3 = HERE / "chapter3_dogleg.ipynb"

# The first lines of every notebook's set-up cell.
_FIND_ROOT = '''\
# Make the repository importable when the kernel starts in notebooks/ (no install needed).
import os
import sys
from pathlib import Path

root = Path.cwd()
while not (root / "course" / "__init__.py").is_file() and root != root.parent:
    root = root.parent
if str(root) not in sys.path:
    sys.path.insert(0, str(root))
'''

# The environment the builder passes to the kernel (see ``execute``).
_SETTINGS = '''
# "solutions", "exercises" or a path to your own copy (python -m notebooks.build --impl sets it)
IMPL = os.environ.get("COURSE_IMPL", "solutions")
# runs per (back end, method); the table keeps the median-time run (--small sets 1)
REPEAT = int(os.environ.get("COURSE_NOTEBOOK_REPEAT", "5"))
'''

SETUP = _FIND_ROOT + '''
import numpy as np
from IPython.display import Image, display

from course import compare, plot
from course.problems.curve import CurveProblem, generate
from course.solvers import SolverOptions
''' + _SETTINGS

# Chapters 2 and 3: pose graphs, the small/full switch and a loader that skips absent data.
SETUP_POSE_GRAPHS = _FIND_ROOT + '''
import statistics
import time

import numpy as np
from IPython.display import Image, Markdown, display
from matplotlib.figure import Figure

from course import benchmark, compare, datasets, plot
from course import impl as impl_loader
from course.problems.posegraph import PoseGraphProblem
from course.solvers import minimize
''' + _SETTINGS + '''# 1: the quick setting (small graphs; the tests run it, --small sets it); else the full one
SMALL = os.environ.get("COURSE_NOTEBOOK_SMALL", "0") == "1"


def load(name):
    \"\"\"The named pose graph, or None (saying why) when its file is not on this machine.\"\"\"
    try:
        return datasets.load_dataset(name)
    except datasets.DatasetError as exc:
        print(f"{name}: skipped ({exc})")
        return None
'''


def _md(cell_id, text):
    cell = new_markdown_cell(text.strip("\n"))
    cell["id"] = cell_id
    return cell


def _code(cell_id, text):
    cell = new_code_cell(text.strip("\n"))
    cell["id"] = cell_id
    return cell


def _notebook(cells):
    nb = new_notebook(cells=cells)
    nb.metadata["kernelspec"] = {"name": "python3", "display_name": "Python 3", "language": "python"}
    nb.metadata["language_info"] = {"name": "python"}
    return nb


def chapter1():
    """The chapter 1 notebook: Gavin's three damping types, Ceres and scipy on the curve.

    Its code reads ``COURSE_IMPL`` and ``COURSE_NOTEBOOK_REPEAT`` from the environment,
    so the cells are the same whatever the build options."""
    cells = [
        _md("title", r"""
# Chapter 1: curve fitting, three ways to damp Levenberg-Marquardt

We fit $y = \exp(a x^2 + b x + c)$ to 100 noisy samples ($x_k = k/100$, noise
$\sigma = 1$, truth $(a, b, c) = (1, 2, 1)$, start $(0, 0, 0)$, weights $W = I$) and
compare:

* our Gauss-Newton and our Levenberg-Marquardt with H. P. Gavin's three damping update
  types (type 1: $\lambda\,\mathrm{diag}(H)$ with fixed factors 9 and 11; type 2:
  $\lambda I$ with a line search on the step length; type 3: Nielsen's
  $\lambda \max(1/3, 1 - (2\rho - 1)^3)$), plus our dogleg (chapter 3);
* the peers on the *same data, start and weights*: Ceres (pyceres) Levenberg-Marquardt and
  dogleg, scipy's `least_squares` `lm` (MINPACK) and `trf`.

One *iteration* is one step attempt, accepted or rejected, for every back end.
chi2 is $\sum_k w_k (\hat y_k - y_k)^2$ everywhere (Ceres reports half of it as its cost).
Set `IMPL = "exercises"` below to run your own code through the same experiment.
"""),
        _code("setup", SETUP),
        _md("run-md", """
## The comparison

`compare.run_curve` runs every (back end, method) pair on one generated data set and
returns one `RunResult` each (the schema of `course/trace.py`); `format_table` prints it.
Times are for the solve alone (milliseconds; the machine is shared, so read them as
orders of magnitude).
"""),
        _code("run", """
data = generate()  # seed 0, 100 points, sigma 1
runs = compare.run_curve(impl=IMPL, data=data, repeat=REPEAT)
print(compare.format_table(runs))
"""),
        _md("source-md", """
## Against the source's figures

The source write-up (a VIO back-end homework, C++) reports on **its own data**:

| damping type | iterations | final chi2 | parameters |
|---|---|---|---|
| type 1 | 4 | 0.914 | about 1.061, 1.962, 1.000 |
| type 2 | 9 | 0.914 | about 1.061, 1.962, 1.000 |
| type 3 | 3 | 0.914 | about 1.061, 1.962, 1.000 |

Ours are below. Do not expect the same numbers: the noise draw (generator and seed) is
different, so the minimum is a different point (our fit is about 0.83, 2.19, 0.96 and
our chi2 about 89, the value expected for 100 residuals of unit variance; the source's
0.914 is on its own scale and data); the source stops much earlier (its thresholds, and
Gavin's lm.m: 1e-3 on the gradient and on the relative step) while ours run until the
relative change of chi2 is below 1e-12, so that every back end agrees to 1e-6; and the
source counts the outer iterations, i.e. the *accepted* steps, which is the column
`accepted` here. The ranking to look for is the one between the damping types.
"""),
        _code("source", """
source = {"lm-type1": 4, "lm-type2": 9, "lm-type3": 3}
ours = {r.method: r for r in runs if r.backend == "ours"}
print(f"{'method':12} {'source iters':>12} {'our attempts':>12} {'accepted':>8} {'final chi2':>12}  params")
for method, r in ours.items():
    accepted = sum(record.accepted for record in r.trace[1:])
    print(f"{method:12} {source.get(method, '-'):>12} {r.iterations:>12} {accepted:>8} "
          f"{r.final_chi2:12.6f}  " + " ".join(f"{v:.6f}" for v in r.params))

print()
print("looser stopping (relative chi2 change 1e-3, gradient and step 1e-3, as in Gavin's lm.m):")
loose = compare.run_curve(impl=IMPL, data=data, backends=["ours"],
                          solver_options=SolverOptions(gradient_tolerance=1e-3, step_tolerance=1e-3,
                                                       cost_tolerance=1e-3))
for r in loose:
    accepted = sum(record.accepted for record in r.trace[1:])
    print(f"{r.method:12} {r.iterations:>3} attempts, {accepted:>3} accepted, chi2 {r.final_chi2:.6f}, "
          "params " + " ".join(f"{v:.4f}" for v in r.params))
"""),
        _md("lambda-md", """
## lambda per iteration

Type 1 divides lambda by 9 after a success and multiplies it by 11 after a failure, and
is clamped to $[10^{-7}, 10^{7}]$; type 2 divides by $1 + \\alpha$ (slowly) and adds
$|\\Delta\\chi^2| / (2\\alpha)$ on a failure; type 3 follows the gain ratio $\\rho$
continuously and doubles its factor $\\nu$ on consecutive failures. The start is far
(chi2 36 000 at $(0, 0, 0)$), so the first steps are rejected and lambda climbs before it
falls.
"""),
        _code("lambda", """
lm = [r for r in runs if r.backend == "ours" and r.method.startswith("lm-type")]
display(Image(plot.to_png(plot.damping_per_iteration(lm, title="lambda per iteration, Gavin's types 1-3"))))
for r in lm:
    print(r.method, " ".join(f"{record.damping:.3g}" for record in r.trace))
"""),
        _md("chi2-md", """
## chi2 per iteration

The line is the chi2 of the point kept; an `x` marks a rejected attempt at the chi2 it
would have given. Undamped Gauss-Newton from this start overshoots by tens of orders of
magnitude (it accepts every step) and needs many iterations to come back: that is what
the damping is for. For the LM types an accepted step never increases chi2.
"""),
        _code("chi2", """
display(Image(plot.to_png(plot.chi2_per_iteration(runs))))
"""),
        _md("params-md", """
## Final parameters against the truth (1, 2, 1)

Every method reaches the same minimum; its distance from the truth is the noise, not the
solver. The standard errors come from the Gauss-Newton covariance $H^{-1}$ at the
minimum ($\\sigma = 1$, $W = I$): the deviation from the truth is within a few of them, and
$a$ and $b$ are strongly correlated (a curve on $[0, 1)$ cannot separate them well).
"""),
        _code("params", """
best = min(runs, key=lambda r: r.final_chi2)
H = CurveProblem(data, impl=IMPL).linearize(best.params).H
covariance = np.linalg.inv(H)
stderr = np.sqrt(np.diag(covariance))
print("truth       ", data.truth)
print("estimate    ", np.round(best.params, 6))
print("std. error  ", np.round(stderr, 4))
print("(est-truth)/stderr", np.round((best.params - data.truth) / stderr, 2))
print("correlation a-b   ", round(covariance[0, 1] / (stderr[0] * stderr[1]), 4))
spread = max(np.max(np.abs(r.params - best.params) / np.abs(best.params)) for r in runs)
print(f"largest relative difference between any two back ends: {spread:.1e}")
display(Image(plot.to_png(plot.curve_fit(data, runs))))
"""),
        _md("peers-md", """
## Ceres and scipy side by side

* **Ceres** (`course/backends/ceres_curve.py`): a Python `pyceres.CostFunction` with all
  100 points in one residual block (one block per point is about 15 times slower: Ceres
  calls Python once per block per evaluation); chi2 per iteration from an
  `IterationCallback`. Its LM starts from a trust radius of $10^4$ (so
  $\\mu = 10^{-4}$, almost Gauss-Newton) and needs several rejections before its first
  success from this start.
* **scipy** (`course/backends/scipy_curve.py`): `least_squares` with the analytic
  Jacobian. scipy has no per-iteration callback for `lm`, so the trace is recorded by
  wrapping the residual function: one record per residual evaluation, i.e. per trial
  point; `iterations = nfev - 1`.
"""),
        _code("peers", """
# the peers, with our type 3 and dogleg for reference
peers = [r for r in runs if r.backend != "ours" or r.method in ("lm-type3", "dogleg")]
print(compare.format_table(peers))
for r in peers:
    print(f"{r.backend:6} {r.method:20} {r.stop_reason}")
"""),
    ]
    return _notebook(cells)


def chapter2():
    """The chapter 2 notebook: Gauss-Newton on pose graphs, dense against sparse, every
    back end on every named dataset, where an iteration's time goes, two written questions.

    Its code reads ``COURSE_IMPL``, ``COURSE_NOTEBOOK_REPEAT`` and ``COURSE_NOTEBOOK_SMALL``
    (1: w100 and ``manhattan:200`` only, as the test runs it)."""
    cells = [
        _md("title", r"""
# Chapter 2: 2D pose graphs, Gauss-Newton and the sparse solve

A pose graph has poses $x_i = (t_i, \theta_i)$ and edges $(i, j)$ that measure pose $j$
in the frame of pose $i$: $z_{ij} = (t_{ij}, \theta_{ij})$ with information
$\Omega_{ij}$. The edge error is
$e_{ij} = \big[R_{ij}^T (R_i^T (t_j - t_i) - t_{ij});\ \mathrm{wrap}(\theta_j - \theta_i - \theta_{ij})\big]$
and chi2 is $\sum e_{ij}^T \Omega_{ij} e_{ij}$. One Gauss-Newton iteration computes every
$e_{ij}$ with its Jacobians $A_{ij} = \partial e_{ij} / \partial x_i$ and
$B_{ij} = \partial e_{ij} / \partial x_j$, assembles $H = \sum J^T \Omega J$ and
$b = \sum J^T \Omega e$ (first pose fixed), solves $H \Delta x = -b$ and updates the poses.

This notebook runs:

1. Gauss-Newton on intel, before and after;
2. the dense against the sparse solve, on intel and as the graph grows;
3. every method and back end on every named dataset, and who converges on mit;
4. where the time of an iteration goes, then two written questions.

`SMALL = True` (set by `python -m notebooks.build --execute --small`, and by the tests)
runs the quick setting: the scaling up to 200 poses and the table on `w100` and
`manhattan:200` only. The full setting (`make notebooks`) takes a few minutes, most of
it on `w10000`. Set `IMPL = "exercises"` to run your own code through all of it.
"""),
        _code("setup", SETUP_POSE_GRAPHS),
        _md("intel-md", """
## Gauss-Newton on intel

intel (TORO format): 729 poses, 3070 edges, odometry as the start. The source write-up
reports chi2 from 2.05e6 down to 65.40. Without the data folder, the generated
`manhattan:500` stands in (the cell says so), and those figures do not apply.
"""),
        _code("intel", """
graph = load("intel")
if graph is None:
    graph = datasets.load_dataset("manhattan:500")
    display(Markdown("**The data folder is missing here**: the generated `manhattan:500` stands in for "
                     "intel below; the source's figures (2.05e6 -> 65.40) do not apply to it."))
gn = compare.run_posegraph(graph, impl=IMPL, methods=["gauss-newton"], backends=["ours"])[0]
print(f"{graph.name}: {graph.num_poses} poses, {graph.num_edges} edges")
print(f"Gauss-Newton: chi2 {gn.initial_chi2:.4g} -> {gn.final_chi2:.2f} in {gn.iterations} iterations, "
      f"{1e3 * gn.seconds:.1f} ms ({gn.stop_reason}); source: 2.05e6 -> 65.40")
for record in gn.trace:
    print(f"  iteration {record.iteration}: chi2 {record.chi2:.6g}")
display(Image(plot.to_png(plot.pose_graph_before_after(graph, gn))))
"""),
        _md("dense-md", """
## Dense against sparse

$H$ is $3N \\times 3N$ (2187 x 2187 on intel) but has only the $3 \\times 3$ blocks of the
poses that share an edge. A dense Cholesky factorization costs $O(n^3)$ whatever the
zeros; a sparse one, after a fill-reducing ordering (AMD), costs in proportion to the
non-zeros of its factor. `course.benchmark.dense_vs_sparse` solves the same Gauss-Newton
system (at the start) both ways with the implementation's `sparse_solve`, checks that the
two steps agree, and returns the median times. Both run on one thread here (the sparse
solver is single-threaded, and a multithreaded BLAS on a shared machine gives erratic
times; `threadpoolctl`, when installed, sets the limit). The source reported the sparse
solve about 30 times faster on intel. Per iteration, the rest of the work (errors,
Jacobians, assembly) is the same for both, so the ratio per iteration is smaller than
per solve.
"""),
        _code("dense", """
try:
    from threadpoolctl import threadpool_limits

    def one_thread():
        return threadpool_limits(limits=1)
except ImportError:  # then BLAS keeps its own thread count
    from contextlib import nullcontext as one_thread

with one_thread():
    dense, sparse = benchmark.dense_vs_sparse(graph.name, repeats=REPEAT, impl=IMPL)
print(f"{graph.name}, one solve: dense {1e3 * dense:.1f} ms, sparse {1e3 * sparse:.2f} ms, "
      f"dense/sparse = {dense / sparse:.1f}x (median of {REPEAT}; the source: about 30x on intel)")
sparse_iteration = gn.seconds_per_iteration
dense_iteration = sparse_iteration - sparse + dense
print(f"{graph.name}, one Gauss-Newton iteration: sparse {1e3 * sparse_iteration:.1f} ms (measured), "
      f"dense about {1e3 * dense_iteration:.1f} ms (the same with the dense solve), "
      f"ratio {dense_iteration / sparse_iteration:.1f}x")
"""),
        _md("growth-md", """
## How each grows with the number of poses

The same comparison on generated Manhattan worlds of $N$ poses (`manhattan:N`: a robot
on a grid, odometry plus loop closures to earlier visits of the same cell, about three
edges per pose), one thread as above. A dense Cholesky factorization grows like $N^3$
(for small $N$ the measured slope is lower: BLAS runs faster on bigger matrices); the
sparse one grows much more slowly, its cost set by the fill-in that the loop closures
cause. The slopes in the legend are least-squares fits of $\\log t$ against $\\log N$.
"""),
        _code("growth", """
sizes = [100, 200] if SMALL else [250, 500, 1000, 2000]
with one_thread():
    timings = {N: benchmark.dense_vs_sparse(f"manhattan:{N}", repeats=REPEAT, impl=IMPL) for N in sizes}
dense_t = np.array([timings[N][0] for N in sizes])
sparse_t = np.array([timings[N][1] for N in sizes])
slopes = [np.polyfit(np.log(sizes), np.log(t), 1)[0] for t in (dense_t, sparse_t)]
print(f"{'N':>6} {'dense ms':>10} {'sparse ms':>10} {'dense/sparse':>12}")
for N, d, s in zip(sizes, dense_t, sparse_t):
    print(f"{N:>6} {1e3 * d:10.2f} {1e3 * s:10.3f} {d / s:12.1f}")
print(f"growth exponents (slope of log t against log N): dense {slopes[0]:.2f}, sparse {slopes[1]:.2f}")

fig = Figure(figsize=(6, 4.5), layout="constrained")
ax = fig.add_subplot()
ax.loglog(sizes, dense_t, "o-", label=f"dense (dense_solve), slope {slopes[0]:.2f}")
ax.loglog(sizes, sparse_t, "s-", label=f"sparse (SparseCholeskySolver), slope {slopes[1]:.2f}")
ax.set_xlabel("poses N (manhattan:N)")
ax.set_ylabel("seconds per solve")
ax.set_title("one Gauss-Newton solve, dense against sparse")
ax.grid(True, which="both", alpha=0.3)
ax.legend(fontsize="small")
display(Image(plot.to_png(fig)))
"""),
        _md("table-md", """
## Every back end on every named dataset

Our five methods and the peers (g2o through g2opy, Ceres through pyceres, GTSAM), same
start, same fixed pose, at most 100 iterations; `final chi2` is our own error on each
back end's solution (GTSAM minimizes the SE(2) log-map error, so its minimum differs
slightly). Missing data files are skipped with the reason. On `w10000` (10 000 poses,
64 311 edges; full setting only) Ceres is left out: its cost function is Python, about
0.5 s per iteration there, and each pair runs once (an LM run takes 10-25 s); elsewhere
each pair runs `min(REPEAT, 3)` times and keeps its median-time run. Graphs with ground
truth (`manhattan:N`) also get the absolute trajectory error.
"""),
        _code("table", """
names = ["w100", "manhattan:200"] if SMALL else [
    "intel", "test_quadrat", "intel-g2o", "m3500", "mit", "csail", "fr079", "w100", "w10000"]
tables = {}
for name in names:
    g = load(name)
    if g is None:
        continue
    backends, repeat = None, min(REPEAT, 3)
    if g.num_poses > 5000:
        backends, repeat = ["ours", "g2o", "gtsam"], 1
        print(f"{name}: Ceres skipped (its Python cost function takes about 0.5 s per iteration here); "
              "one run per pair")
    runs = compare.run_posegraph(g, impl=IMPL, backends=backends, repeat=repeat)
    tables[name] = runs
    print(compare.format_table(runs, title=f"{name}: {g.num_poses} poses, {g.num_edges} edges"))
    if compare.format_ate(runs):
        print(compare.format_ate(runs))
    print()
"""),
        _md("mit-md", """
## Who converges on mit

mit (808 poses, 827 edges) starts from odometry so far off that chi2 is 4.4e9. The cell
below reads the runs above and says which methods stop by their own convergence test
within the 100 iterations, after how many, and where they end: a pose graph has local
minima, and a method may converge to a different one than Gauss-Newton. It then gives
those that hit the limit up to 2000 iterations. (In the quick setting it reads the last
graph of the table instead.)
"""),
        _code("mit", """
hard = "mit" if "mit" in tables else list(tables)[-1]
runs = tables[hard]
gn_min = next(r.final_chi2 for r in runs if r.backend == "ours" and r.method == "gauss-newton")


def outcome(r):
    \"\"\"'converged', 'limit' (max_iterations) or 'failed', from the stop reason.\"\"\"
    if r.stop_reason.startswith("max_iterations"):
        return "limit"
    if r.stop_reason.startswith(("failed", "lambda_upper_bound", "solver_stopped")):
        return "failed"
    return "converged"


def where(r):
    rel = (r.final_chi2 - gn_min) / gn_min
    if abs(rel) <= 1e-6:
        return "the Gauss-Newton minimum"
    return "a lower minimum" if rel < 0 else "above the Gauss-Newton minimum"


groups = {kind: [r for r in runs if outcome(r) == kind] for kind in ("converged", "limit", "failed")}
text = [f"**{hard}** starts at chi2 {runs[0].initial_chi2:.3g}; Gauss-Newton ends at {gn_min:.6g}."]
text.append("Converged (stopped by their own test within the limit): " + ("; ".join(
    f"{r.backend} {r.method} in {r.iterations} iterations to chi2 {r.final_chi2:.6g} ({where(r)})"
    for r in groups["converged"]) or "none") + ".")
if groups["limit"]:
    text.append("Stopped at the iteration limit without converging: " + "; ".join(
        f"{r.backend} {r.method} at chi2 {r.final_chi2:.6g}" for r in groups["limit"]) + ".")
if groups["failed"]:
    text.append("Failed or gave up: " + "; ".join(
        f"{r.backend} {r.method} ({r.stop_reason.split('.')[0][:70]})" for r in groups["failed"]) + ".")
ours_limit = [r.method for r in groups["limit"] if r.backend == "ours"]
if ours_limit:
    longer = compare.run_posegraph(datasets.load_dataset(hard), impl=IMPL, methods=ours_limit,
                                   backends=["ours"], max_iterations=2000)
    text.append("Given up to 2000 iterations: " + "; ".join(
        f"ours {r.method} {'converges in ' if outcome(r) == 'converged' else 'still runs after '}"
        f"{r.iterations} iterations ({1e3 * r.seconds:.0f} ms) to chi2 {r.final_chi2:.6g} ({where(r)})"
        for r in longer) + ".")
display(Markdown("\\n\\n".join(text)))
"""),
        _md("split-md", """
## Where the time of an iteration goes

Each part of one Gauss-Newton iteration, timed alone at the start of the graph with the
implementation's own pieces (`pose_graph_fast`: errors and Jacobians of all edges at
once, then the scatter-add of the edge blocks into the fixed sparsity pattern of H;
`sparse_solve.SparseCholeskySolver`: numeric factorization and the two triangular
solves, the ordering and symbolic analysis reused from the first call), against the
time per iteration measured in the loop. The one-off costs come after: the sparsity
pattern (once per graph) and the fill-reducing ordering with the symbolic
factorization (once per pattern). On intel, the per-edge loop of
`pose_graph_assembly` (a dense H) is timed too, for comparison.
"""),
        _code("split", """
def median_time(call, repeat):
    \"\"\"(median seconds, result) of ``repeat`` calls of ``call()``.\"\"\"
    seconds, out = [], None
    for _ in range(max(repeat, 1)):
        start = time.perf_counter()
        out = call()
        seconds.append(time.perf_counter() - start)
    return statistics.median(seconds), out


def time_split(g, repeat):
    \"\"\"Seconds of each part of one Gauss-Newton iteration at the start of ``g``.\"\"\"
    pieces = impl_loader.load(IMPL)
    fast, sparse = pieces.module("pose_graph_fast"), pieces.module("sparse_solve")
    parts, once = {}, {}
    parts["errors and Jacobians"], (e, A, B) = median_time(
        lambda: fast.edge_errors_and_jacobians(g.poses, g.edges_i, g.edges_j, g.measurements), repeat)
    once["sparsity pattern of H"], assembler = median_time(
        lambda: fast.SparseAssembler(g.num_poses, g.edges_i, g.edges_j, g.fixed), repeat)
    parts["assembly of H and b (and chi2)"], (H, b, _) = median_time(
        lambda: assembler.assemble(e, A, B, g.information), repeat)
    first, _ = median_time(lambda: sparse.SparseCholeskySolver().solve(H, b), repeat)
    solver = sparse.SparseCholeskySolver()
    solver.solve(H, b)
    parts["factorization and solve"], h = median_time(lambda: solver.solve(H, b), repeat)
    once["ordering and symbolic factorization"] = max(first - parts["factorization and solve"], 0.0)
    problem = PoseGraphProblem(g, IMPL)
    parts["pose update (retract)"], _ = median_time(lambda: problem.retract(problem.x0, h), repeat)
    trial, _ = median_time(lambda: g.chi2(), repeat)
    return parts, once, trial


for name in (["intel"] if SMALL else ["intel", "w10000"]):
    g = load(name)
    if g is None and name == "intel":
        g = datasets.load_dataset("manhattan:500")
    if g is None:
        continue
    repeat = REPEAT if g.num_poses <= 5000 else max(1, min(REPEAT, 3))
    try:
        parts, once, trial = time_split(g, repeat)
    except NotImplementedError as exc:
        print(f"{g.name}: {exc} (the split needs pose_graph_fast and sparse_solve)")
        continue
    run = minimize(PoseGraphProblem(g, IMPL), "gauss-newton", impl=IMPL)
    total = sum(parts.values())
    print(f"{g.name}: {g.num_poses} poses, {g.num_edges} edges; one Gauss-Newton iteration (median of {repeat})")
    for part, seconds in parts.items():
        print(f"  {part:42} {1e3 * seconds:9.2f} ms {100 * seconds / total:6.1f} %")
    print(f"  {'sum':42} {1e3 * total:9.2f} ms; measured in the loop: "
          f"{1e3 * run.seconds_per_iteration:.2f} ms per iteration ({run.iterations} iterations)")
    for part, seconds in once.items():
        print(f"  {'once: ' + part:42} {1e3 * seconds:9.2f} ms")
    print(f"  {'chi2 of a trial point (LM, dogleg)':42} {1e3 * trial:9.2f} ms")
    if g.num_poses <= 1500:
        loop_problem = PoseGraphProblem(g, IMPL, vectorized=False)
        loop, _ = median_time(lambda: loop_problem.linearize(loop_problem.x0), repeat)
        vectorized = parts["errors and Jacobians"] + parts["assembly of H and b (and chi2)"]
        print(f"  {'per-edge loop (pose_graph_assembly)':42} {1e3 * loop:9.2f} ms, "
              f"{loop / vectorized:.0f}x the vectorized errors, Jacobians and assembly")
    print()
"""),
        _md("questions-md", """
## Written questions

Answer in the cells below, in a few sentences each. Use the measurements above.

**Question 1.** Which step of an iteration takes the most time, and how can it be made
faster? Name several ways and say what each one saves.

**Question 2.** Which other methods for nonlinear least squares (and nonlinear
optimization in general) exist besides Gauss-Newton? For each, say in a sentence or two
how it works and when you would choose it.

(Instructors: the reference answers are in `solutions/answers/chapter2.md`, which the
student tree leaves out.)
"""),
        _md("answer-1", """
**Your answer to question 1:** *(double-click to edit)*
"""),
        _md("answer-2", """
**Your answer to question 2:** *(double-click to edit)*
"""),
    ]
    return _notebook(cells)


def chapter3():
    """The chapter 3 notebook: Powell's dogleg against Gauss-Newton, Gavin's three LM types
    and the peers' LM and dogleg, per iteration, per second and per factorization.

    Its code reads ``COURSE_IMPL``, ``COURSE_NOTEBOOK_REPEAT`` and ``COURSE_NOTEBOOK_SMALL``
    (1: the curve and ``manhattan:200`` only, as the test runs it)."""
    cells = [
        _md("title", r"""
# Chapter 3: Powell's dogleg against Levenberg-Marquardt

Levenberg-Marquardt solves $(H + \lambda D)\,h = -b$ at every step attempt: when the step
is rejected, $\lambda$ grows and the damped system is factorized again. Powell's dogleg
computes, once per linearization, the Gauss-Newton step $h_{gn}$ (one factorization of
$H$) and the Cauchy point $h_{sd} = -\alpha b$ (the minimizer of the model along the
gradient), and takes the point of the path $0 \to h_{sd} \to h_{gn}$ that lies on the
trust region of radius $\Delta$ (or $h_{gn}$ itself when it fits inside). A rejected step
shrinks $\Delta$ and picks another point of the *same* path: no factorization.

This notebook compares, on the curve of chapter 1 and on the pose graphs intel, m3500
and mit (quick setting, `SMALL = True`: the curve and `manhattan:200`):

* our Gauss-Newton, Levenberg-Marquardt types 1-3 and dogleg;
* the peers' trust-region methods: Ceres' LM and dogleg (`DOGLEG`, traditional), g2o's
  Levenberg and dogleg, GTSAM's LM and dogleg (on the curve: Ceres' LM and dogleg and
  scipy's `lm` and `trf`);

by chi2 against the iteration and against the wall time, by the number of
factorizations, and by whether each reaches the Gauss-Newton minimum. Set
`IMPL = "exercises"` to run your own dogleg.
"""),
        _code("setup", SETUP_POSE_GRAPHS),
        _md("helpers-md", """
Two helpers for this chapter: a figure of chi2 against wall time (`course.plot` has the
one against the iteration) and the table. The factorization count is exact for our
solvers; for the peers it is what the library reports, marked `*` (Ceres'
`num_linear_solves`, g2o's count of Levenberg damping attempts) or `n/a` where it
reports none (GTSAM, scipy, g2o's dogleg, Ceres on the curve).
"""),
        _code("helpers", """
import matplotlib
from cycler import cycler

# eleven runs per pose graph: ten colours are not enough
matplotlib.rcParams["axes.prop_cycle"] = cycler(color=[*matplotlib.colormaps["tab10"].colors, "black"])


def rejected(r):
    \"\"\"Indices of the rejected step attempts in ``r.trace``.

    When the LM loop stops on a tiny step it records that step (no trial point, rho NaN):
    not an attempt that was rejected.\"\"\"
    last = len(r.trace)
    if r.stop_reason == "step_tolerance" and not np.isfinite(r.trace[-1].rho):
        last -= 1
    return [k for k in range(1, last) if not r.trace[k].accepted]


def gauss_newton_minimum(runs):
    return next(r.final_chi2 for r in runs if r.backend == "ours" and r.method == "gauss-newton")


def reached(r, runs):
    \"\"\"'yes' when ``r`` ends at the Gauss-Newton minimum (1e-6 relative), else 'no' or 'lower'.\"\"\"
    gn = gauss_newton_minimum(runs)
    rel = (r.final_chi2 - gn) / gn
    return "yes" if abs(rel) <= 1e-6 else ("lower" if rel < 0 else "no")


def factorizations(r):
    if r.backend == "ours":
        return str(r.factorizations)
    if (r.backend == "ceres" and r.factorizations > 0) or (r.backend == "g2o" and r.method == "levenberg"):
        return f"{r.factorizations}*"
    return "n/a"


def method_table(runs, title):
    head = (f"{'backend':8} {'method':20} {'iters':>5} {'factorizations':>14} {'time ms':>9} "
            f"{'final chi2':>17}  at GN minimum")
    lines = [title, head, "-" * len(head)]
    for r in runs:
        lines.append(f"{r.backend:8} {r.method:20} {r.iterations:5d} {factorizations(r):>14} "
                     f"{1e3 * r.seconds:9.2f} {r.final_chi2:17.10g}  {reached(r, runs)}")
    return "\\n".join(lines)


def chi2_against_time(runs, title):
    \"\"\"chi2 of the point kept against the time since the solve started, log-log.\"\"\"
    fig = Figure(figsize=(7, 4.5), layout="constrained")
    ax = fig.add_subplot()
    values, starts = [], []
    for r in runs:
        t = np.array([record.seconds for record in r.trace])
        kept = plot.kept_chi2(r)
        keep = (t > 0) & np.isfinite(kept) & (kept > 0)
        if not keep.any():
            continue
        ax.plot(1e3 * t[keep], kept[keep], marker=".", label=f"{plot.label(r)} ({1e3 * r.seconds:.1f} ms)")
        values.append(kept[keep])
        starts.append(r.trace[0].chi2)
    ax.axhline(gauss_newton_minimum(runs), color="k", linestyle=":", linewidth=1, label="Gauss-Newton minimum")
    ax.set_xscale("log")
    ax.set_yscale("log")
    if values:
        v = np.concatenate(values)
        ax.set_ylim(v.min() / 2, min(v.max() * 5, max(starts) * 1e3))
    ax.set_xlabel("milliseconds since the solve started (the start, at 0, is off the axis)")
    ax.set_ylabel("chi2")
    ax.set_title(title)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize="x-small")
    return fig
"""),
        _md("runs-md", """
## The runs

Each (back end, method) pair runs `REPEAT` times from the same start and keeps its
median-time run; at most 100 iterations. One *iteration* is one step attempt for our
solvers and Ceres; g2o and GTSAM count an outer iteration, with their damping or radius
retries inside it.
"""),
        _code("runs", """
PEER_METHODS = ["levenberg-marquardt", "levenberg", "dogleg"]  # Ceres and GTSAM LM, g2o Levenberg, dogleg
names = ["curve", "manhattan:200"] if SMALL else ["curve", "intel", "m3500", "mit"]
results = {}
for name in names:
    if name == "curve":
        results[name] = compare.run_curve(impl=IMPL, repeat=REPEAT)
    else:
        g = load(name)
        if g is None:
            continue
        results[name] = (compare.run_posegraph(g, impl=IMPL, backends=["ours"], repeat=REPEAT)
                         + compare.run_posegraph(g, impl=IMPL, methods=PEER_METHODS,
                                                 backends=["ceres", "g2o", "gtsam"], repeat=REPEAT))
    print(f"{name}: {len(results[name])} runs")
"""),
        _md("compare-md", """
## chi2 against iteration and against time, per dataset

For each dataset: the table (`at GN minimum`: the final chi2 equals our Gauss-Newton's to
1e-6 relative; `lower`: a different, lower local minimum), chi2 per iteration (an `x`
marks a rejected attempt) and chi2 against wall time. Our solvers and the peers run in
the same process on a shared machine: read the times as orders of magnitude. Ceres
calls a Python cost function, which makes it several times slower per iteration.
"""),
        _code("compare", """
for name, runs in results.items():
    print(method_table(runs, f"{name} (start chi2 {runs[0].initial_chi2:.4g})"))
    print()
    display(Image(plot.to_png(plot.chi2_per_iteration(runs, title=f"{name}: chi2 per iteration"))))
    display(Image(plot.to_png(chi2_against_time(runs, f"{name}: chi2 against time"))))
"""),
        _md("factorizations-md", """
## Factorizations

The cost of an iteration of these methods is mostly the factorization (chapter 2), so
their number is the fairer count. For Gauss-Newton and Levenberg-Marquardt there is one
per step attempt; dogleg has one per *accepted* step (plus one at the start), so it
spends fewer than its attempts whenever it rejects.
"""),
        _code("factorizations", """
methods = ["gauss-newton", "lm-type1", "lm-type2", "lm-type3", "dogleg"]
rows = ["| dataset | " + " | ".join(methods) + " |", "|---" * (len(methods) + 1) + "|"]
for name, runs in results.items():
    ours = {r.method: r for r in runs if r.backend == "ours"}
    cells = []
    for m in methods:
        r = ours.get(m)
        if r is None:
            cells.append("-")
            continue
        note = "" if reached(r, runs) == "yes" else f", {reached(r, runs)}"
        cells.append(f"{r.factorizations} / {r.iterations} ({len(rejected(r))} rejected){note}")
    rows.append(f"| {name} | " + " | ".join(cells) + " |")
display(Markdown("Our methods: factorizations / step attempts (rejected attempts); "
                 "a note where the run did not end at the Gauss-Newton minimum.\\n\\n" + "\\n".join(rows)))
"""),
        _md("rejection-md", """
## A rejected step costs no factorization

The trace of our dogleg on a graph where it rejects steps (mit, else intel-g2o, else the
curve): the rows around each rejected attempt. `factorizations` is the running count
when the step was computed, `new` how many happened since the row before. After a
rejection the retry reuses the Gauss-Newton step and the Cauchy point, with a smaller
radius: `new` is 0. Levenberg-Marquardt (type 1) on the same problem, for contrast,
factorizes again for each retry.
"""),
        _code("rejection", """
for name in ("mit", "intel-g2o", "curve"):
    if name == "curve":
        demo = compare.run_curve(impl=IMPL, methods=["lm-type1", "dogleg"], backends=["ours"])
        break
    g = load(name)
    if g is not None:
        demo = compare.run_posegraph(g, impl=IMPL, methods=["lm-type1", "dogleg"], backends=["ours"])
        break


def show_rejections(run, limit):
    \"\"\"Print the trace rows around each rejection; return the factorizations before each retry.\"\"\"
    trace, rejections = run.trace, rejected(run)
    rows = sorted({j for k in rejections for j in (k - 1, k, k + 1) if 0 <= j < len(trace)})
    print(f"{name}, ours {run.method}: {run.iterations} attempts, {len(rejections)} rejected, "
          f"{run.factorizations} factorizations ({run.stop_reason})")
    print(f"{'iter':>5} {'chi2':>15} {'radius/lambda':>13} {'rho':>10} {'accepted':>8} {'factorizations':>14} {'new':>4}")
    previous = None
    for j in rows[:limit]:
        if previous is not None and j != previous + 1:
            print(f"{'...':>5}")
        r = trace[j]
        new = r.factorizations - trace[j - 1].factorizations if j > 0 else r.factorizations
        print(f"{r.iteration:5d} {r.chi2:15.8g} {r.damping:13.4g} {r.rho:10.3g} {str(r.accepted):>8} "
              f"{r.factorizations:14d} {new:4d}")
        previous = j
    if len(rows) > limit:
        print(f"{'...':>5} ({len(rows) - limit} more rows)")
    return [trace[k + 1].factorizations - trace[k].factorizations for k in rejections if k + 1 < len(trace)]


by_method = {r.method: r for r in demo}
dogleg_retries = show_rejections(by_method["dogleg"], limit=40)
print()
lm_retries = show_rejections(by_method["lm-type1"], limit=12)
print()
print(f"dogleg: {len(dogleg_retries)} retries after a rejection, new factorizations before each: "
      f"{sorted(set(dogleg_retries))}")
print(f"lm-type1: {len(lm_retries)} retries after a rejection, new factorizations before each: "
      f"{sorted(set(lm_retries))}")
"""),
    ]
    return _notebook(cells)


NOTEBOOKS = {CHAPTER1: chapter1, CHAPTER2: chapter2, CHAPTER3: chapter3}


@contextlib.contextmanager
def kernel_for_this_interpreter():
    """Yield a kernel name whose kernel runs on ``sys.executable`` (see the module docstring)."""
    from jupyter_client.kernelspec import KernelSpecManager, NoSuchKernel

    bare = {"python", f"python{sys.version_info[0]}", "python%d.%d" % sys.version_info[:2]}
    try:
        argv0 = KernelSpecManager().get_kernel_spec("python3").argv[0]
    except NoSuchKernel:
        argv0 = None
    if argv0 is not None and (argv0 in bare or os.path.abspath(argv0) == os.path.abspath(sys.executable)):
        yield "python3"
        return
    import json

    with tempfile.TemporaryDirectory(prefix="course-kernel-") as tmp:
        spec_dir = Path(tmp) / "kernels" / "course-python"
        spec_dir.mkdir(parents=True)
        spec = {
            "argv": [sys.executable, "-m", "ipykernel_launcher", "-f", "{connection_file}"],
            "display_name": "course (this interpreter)",
            "language": "python",
        }
        (spec_dir / "kernel.json").write_text(json.dumps(spec))
        old = os.environ.get("JUPYTER_PATH")
        os.environ["JUPYTER_PATH"] = tmp + (os.pathsep + old if old else "")
        try:
            yield "course-python"
        finally:
            if old is None:
                os.environ.pop("JUPYTER_PATH", None)
            else:
                os.environ["JUPYTER_PATH"] = old


@contextlib.contextmanager
def _environment(**values):
    old = {k: os.environ.get(k) for k in values}
    os.environ.update({k: str(v) for k, v in values.items()})
    try:
        yield
    finally:
        for k, v in old.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v


def execute(nb, timeout=900, cwd=HERE, small=False, impl="solutions"):
    """Run every cell of ``nb`` in place (raises ``nbclient`` errors on a failing cell).

    The kernel inherits ``COURSE_IMPL = impl``, ``COURSE_NOTEBOOK_REPEAT`` (1 when
    ``small``, else 5) and ``COURSE_NOTEBOOK_SMALL`` (1 when ``small``: chapters 2 and 3
    run on small graphs only) and starts in ``cwd``.
    """
    from nbclient import NotebookClient

    with kernel_for_this_interpreter() as kernel_name, \
            _environment(COURSE_IMPL=impl, COURSE_NOTEBOOK_REPEAT=1 if small else 5,
                         COURSE_NOTEBOOK_SMALL=1 if small else 0):
        client = NotebookClient(nb, timeout=timeout, kernel_name=kernel_name,
                                resources={"metadata": {"path": str(cwd)}})
        client.execute()
    return nb


def select(names=None) -> dict:
    """``NOTEBOOKS`` restricted to the notebooks whose file name starts with one of ``names``
    (e.g. ``chapter2``); all of them when ``names`` is empty."""
    if not names:
        return dict(NOTEBOOKS)
    chosen = {path: make for path, make in NOTEBOOKS.items() if any(path.name.startswith(n) for n in names)}
    unknown = [n for n in names if not any(path.name.startswith(n) for path in NOTEBOOKS)]
    if unknown:
        raise ValueError(f"no notebook named {unknown}; choose from {[p.stem for p in NOTEBOOKS]}")
    return chosen


def build(execute_notebooks=False, small=False, impl="solutions", out_dir=HERE, only=None, log=None) -> list:
    """Write the notebooks (all, or those ``select(only)`` picks) into ``out_dir``; returns the paths.

    ``log``, when given, is called with one line per notebook written (and its run time)."""
    written = []
    for path, make in select(only).items():
        nb = make()
        start = time.perf_counter()
        if execute_notebooks:
            execute(nb, small=small, impl=impl)
        target = Path(out_dir) / path.name
        nbformat.validate(nb)
        nbformat.write(nb, target)
        written.append(target)
        if log is not None:
            ran = f" (executed in {time.perf_counter() - start:.0f} s)" if execute_notebooks else ""
            log(f"wrote {target}{ran}")
    return written


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python -m notebooks.build", description=__doc__.splitlines()[0])
    parser.add_argument("--execute", action="store_true", help="run the notebooks and keep their outputs")
    parser.add_argument("--small", action="store_true",
                        help="one run per timing instead of five, small graphs only (quicker)")
    parser.add_argument("--impl", default="solutions", help="implementation the notebooks use")
    parser.add_argument("--only", nargs="+", metavar="NAME",
                        help="only these notebooks, by the start of their file name (e.g. chapter2)")
    args = parser.parse_args(argv)
    build(args.execute, args.small, args.impl, only=args.only, log=print)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
