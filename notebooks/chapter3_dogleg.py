# %% [markdown] id="title"
# # Chapter 3: Powell's dogleg against Levenberg-Marquardt
#
# Levenberg-Marquardt solves $(H + \lambda D)\,h = -b$ at every step attempt: when the step
# is rejected, $\lambda$ grows and the damped system is factorized again. Powell's dogleg
# computes, once per linearization, the Gauss-Newton step $h_{gn}$ (one factorization of
# $H$) and the Cauchy point $h_{sd} = -\alpha b$ (the minimizer of the model along the
# gradient), and takes the point of the path $0 \to h_{sd} \to h_{gn}$ that lies on the
# trust region of radius $\Delta$ (or $h_{gn}$ itself when it fits inside). A rejected step
# shrinks $\Delta$ and picks another point of the *same* path: no factorization.
#
# This notebook compares, on the curve of chapter 1 and on the pose graphs intel, m3500
# and mit (quick setting, `SMALL = True`: the curve and `manhattan:200`):
#
# * our Gauss-Newton, Levenberg-Marquardt types 1-3 and dogleg;
# * the peers' trust-region methods: Ceres' LM and dogleg (`DOGLEG`, traditional), g2o's
#   Levenberg and dogleg, GTSAM's LM and dogleg (on the curve: Ceres' LM and dogleg and
#   scipy's `lm` and `trf`);
#
# by chi2 against the iteration and against the wall time, by the number of
# factorizations, and by whether each reaches the Gauss-Newton minimum. Set
# `IMPL = "exercises"` to run your own dogleg.

# %% id="setup"
# Make the repository importable when the kernel starts in notebooks/ (no install needed).
import os
import sys
from pathlib import Path

root = Path.cwd()
while not (root / "course" / "__init__.py").is_file() and root != root.parent:
    root = root.parent
if str(root) not in sys.path:
    sys.path.insert(0, str(root))

from IPython.display import Image, Markdown, display

from course.app import compare, plot
from course.notebook_helpers.common import load

# "solutions", "exercises" or a path to your own copy (python -m notebooks.build --impl sets it);
# by default this tree's own: "exercises" in a student tree
IMPL = os.environ.get("COURSE_IMPL") or (
    "solutions" if (root / "solutions" / "__init__.py").is_file() else "exercises")
# runs per (back end, method); the table keeps the median-time run (--small sets 1)
REPEAT = int(os.environ.get("COURSE_NOTEBOOK_REPEAT", "5"))
# 1: the quick setting (small graphs; the tests run it, --small sets it); else the full one
SMALL = os.environ.get("COURSE_NOTEBOOK_SMALL", "0") == "1"

# %% [markdown] id="helpers-md"
# The helpers of this chapter, in `course/notebook_helpers/common.py`: a figure of chi2 against wall
# time (`course.app.plot` has the one against the iteration) and the table. The factorization
# count is exact for our solvers; for the peers it is what the library reports, marked `*` (Ceres'
# `num_linear_solves`, g2o's count of Levenberg damping attempts) or `n/a` where it
# reports none (GTSAM, scipy, g2o's dogleg, Ceres on the curve).

# %% id="helpers"
from course.notebook_helpers.common import (
    chi2_against_time,
    method_table,
    not_run_note,
    ran,
    reached,
    rejected,
    show_rejections,
    use_eleven_colours,
)

use_eleven_colours()  # eleven runs per pose graph: ten colours are not enough

# %% [markdown] id="runs-md"
# ## The runs
#
# Each (back end, method) pair runs `REPEAT` times from the same start and keeps its
# median-time run; at most 100 iterations. One *iteration* is one step attempt for our
# solvers and Ceres; g2o and GTSAM count an outer iteration, with their damping or radius
# retries inside it.

# %% id="runs"
PEER_METHODS = ["levenberg-marquardt", "levenberg", "dogleg"]  # Ceres and GTSAM LM, g2o Levenberg, dogleg
names = ["curve", "manhattan:200"] if SMALL else ["curve", "intel", "m3500", "mit"]
results = {}
for name in names:
    if name == "curve":
        runs = compare.run_curve(impl=IMPL, repeat=REPEAT)
    else:
        g = load(name)
        if g is None:
            continue
        runs = (compare.run_posegraph(g, impl=IMPL, backends=["ours"], repeat=REPEAT)
                + compare.run_posegraph(g, impl=IMPL, methods=PEER_METHODS,
                                        backends=["ceres", "g2o", "gtsam"], repeat=REPEAT))
    results[name] = ran(runs)
    print(f"{name}: {len(results[name])} runs{not_run_note(runs)}")

# %% [markdown] id="compare-md"
# ## chi2 against iteration and against time, per dataset
#
# For each dataset: the table (`at GN minimum`: the final chi2 equals our Gauss-Newton's to
# 1e-6 relative; `lower`: a different, lower local minimum), chi2 per iteration (an `x`
# marks a rejected attempt) and chi2 against wall time. Our solvers and the peers run in
# the same process on a shared machine: read the times as orders of magnitude. Ceres
# calls a Python cost function, which makes it several times slower per iteration.

# %% id="compare"
for name, runs in results.items():
    print(method_table(runs, f"{name} (start chi2 {runs[0].initial_chi2:.4g})"))
    print()
    display(Image(plot.to_png(plot.chi2_per_iteration(runs, title=f"{name}: chi2 per iteration"))))
    display(Image(plot.to_png(chi2_against_time(runs, f"{name}: chi2 against time"))))

# %% [markdown] id="factorizations-md"
# ## Factorizations
#
# The cost of an iteration of these methods is mostly the factorization (chapter 2), so
# their number is the fairer count. For Gauss-Newton and Levenberg-Marquardt there is one
# per step attempt; dogleg has one per *accepted* step (plus one at the start), so it
# spends fewer than its attempts whenever it rejects.

# %% id="factorizations"
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
                 "a note where the run did not end at the Gauss-Newton minimum.\n\n" + "\n".join(rows)))

# %% [markdown] id="rejection-md"
# ## A rejected step costs no factorization
#
# The trace of our dogleg on a graph where it rejects steps (mit, else intel-g2o, else the
# curve): the rows around each rejected attempt. `factorizations` is the running count
# when the step was computed, `new` how many happened since the row before. After a
# rejection the retry reuses the Gauss-Newton step and the Cauchy point, with a smaller
# radius: `new` is 0. Levenberg-Marquardt (type 1) on the same problem, for contrast,
# factorizes again for each retry.

# %% id="rejection"
for name in ("mit", "intel-g2o", "curve"):
    if name == "curve":
        demo = compare.run_curve(impl=IMPL, methods=["lm-type1", "dogleg"], backends=["ours"])
        break
    g = load(name)
    if g is not None:
        demo = compare.run_posegraph(g, impl=IMPL, methods=["lm-type1", "dogleg"], backends=["ours"])
        break

by_method = {r.method: r for r in demo}
dogleg_retries = show_rejections(by_method["dogleg"], limit=40, name=name)
print()
lm_retries = show_rejections(by_method["lm-type1"], limit=12, name=name)
print()
print(f"dogleg: {len(dogleg_retries)} retries after a rejection, new factorizations before each: "
      f"{sorted(set(dogleg_retries))}")
print(f"lm-type1: {len(lm_retries)} retries after a rejection, new factorizations before each: "
      f"{sorted(set(lm_retries))}")
