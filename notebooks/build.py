"""Write the course notebooks with nbformat, and optionally execute them.

    python -m notebooks.build              # write notebooks/*.ipynb, no outputs
    python -m notebooks.build --execute    # write and run them (outputs saved in the file)
    python -m notebooks.build --small      # with --execute: one run per timing, not five

The notebooks hold no logic of their own: every cell calls the package (``course.compare``,
``course.plot``, ...). Cell ids are fixed, so rebuilding gives the same file and
``tests/test_notebooks.py`` can check that the committed notebook's cells are current.

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
from pathlib import Path

import nbformat
from nbformat.v4 import new_code_cell, new_markdown_cell, new_notebook

HERE = Path(__file__).resolve().parent
CHAPTER1 = HERE / "chapter1_curve_fitting.ipynb"

SETUP = '''\
# Make the repository importable when the kernel starts in notebooks/ (no install needed).
import os
import sys
from pathlib import Path

root = Path.cwd()
while not (root / "course" / "__init__.py").is_file() and root != root.parent:
    root = root.parent
if str(root) not in sys.path:
    sys.path.insert(0, str(root))

import numpy as np
from IPython.display import Image, display

from course import compare, plot
from course.problems.curve import CurveProblem, generate
from course.solvers import SolverOptions

# "solutions", "exercises" or a path to your own copy (python -m notebooks.build --impl sets it)
IMPL = os.environ.get("COURSE_IMPL", "solutions")
# runs per (back end, method); the table keeps the median-time run (--small sets 1)
REPEAT = int(os.environ.get("COURSE_NOTEBOOK_REPEAT", "5"))
'''


def _md(cell_id, text):
    cell = new_markdown_cell(text.strip("\n"))
    cell["id"] = cell_id
    return cell


def _code(cell_id, text):
    cell = new_code_cell(text.strip("\n"))
    cell["id"] = cell_id
    return cell


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
    nb = new_notebook(cells=cells)
    nb.metadata["kernelspec"] = {"name": "python3", "display_name": "Python 3", "language": "python"}
    nb.metadata["language_info"] = {"name": "python"}
    return nb


NOTEBOOKS = {CHAPTER1: chapter1}


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


def execute(nb, timeout=600, cwd=HERE, small=False, impl="solutions"):
    """Run every cell of ``nb`` in place (raises ``nbclient`` errors on a failing cell).

    The kernel inherits ``COURSE_IMPL = impl`` and ``COURSE_NOTEBOOK_REPEAT`` (1 when
    ``small``, else 5) and starts in ``cwd``.
    """
    from nbclient import NotebookClient

    with kernel_for_this_interpreter() as kernel_name, \
            _environment(COURSE_IMPL=impl, COURSE_NOTEBOOK_REPEAT=1 if small else 5):
        client = NotebookClient(nb, timeout=timeout, kernel_name=kernel_name,
                                resources={"metadata": {"path": str(cwd)}})
        client.execute()
    return nb


def build(execute_notebooks=False, small=False, impl="solutions", out_dir=HERE) -> list:
    """Write every notebook into ``out_dir``; returns the paths."""
    written = []
    for path, make in NOTEBOOKS.items():
        nb = make()
        if execute_notebooks:
            execute(nb, small=small, impl=impl)
        target = Path(out_dir) / path.name
        nbformat.validate(nb)
        nbformat.write(nb, target)
        written.append(target)
    return written


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python -m notebooks.build", description=__doc__.splitlines()[0])
    parser.add_argument("--execute", action="store_true", help="run the notebooks and keep their outputs")
    parser.add_argument("--small", action="store_true", help="one run per timing instead of five (quicker)")
    parser.add_argument("--impl", default="solutions", help="implementation the notebooks use")
    args = parser.parse_args(argv)
    for path in build(args.execute, args.small, args.impl):
        print(f"wrote {path}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
