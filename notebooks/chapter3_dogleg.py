# %% [markdown] id="title"
# # Chapter 3: Powell's dogleg against Levenberg-Marquardt
#
# Levenberg-Marquardt solves $(H + \lambda D)\,h = -b$ at every step attempt: when the step
# is rejected, $\lambda$ grows and the damped system is factorized again. Powell's dogleg
# computes, once per linearization, the Gauss-Newton step $h_{gn}$ (one factorization of
# $H$) and the Cauchy point (the minimizer of the model along the gradient), and takes the
# point of the path $0 \to$ Cauchy point $\to h_{gn}$ that lies on the trust region of radius
# $\Delta$ (or $h_{gn}$ itself when it fits inside). A rejected step shrinks $\Delta$ and picks
# another point of the *same* path: no factorization. The chapter is a lesson in this order:
#
# 1. **Theory**, derived: the trust-region subproblem; the Cauchy point (exercise
#    `dogleg.cauchy_point`); the Gauss-Newton point, the dogleg path and the point where it
#    leaves the trust region, a root of a quadratic equation, with the decrease the model
#    predicts there (`dogleg.dogleg_step`); the gain ratio and the radius update
#    (`dogleg.update_radius`); why the dogleg needs one factorization per accepted step where
#    Levenberg-Marquardt needs one per attempt. Cells `check("...")` grade your `dogleg.py`
#    here, with the same sandboxed judge and public checks as `python -m autograder --only dogleg`.
# 2. **Experiments**: on the curve of chapter 1 and on pose graphs (intel, m3500, mit; quick
#    setting, `SMALL = True`: the curve and `manhattan:200`), our Gauss-Newton,
#    Levenberg-Marquardt types 1-3 and dogleg against the peers' trust-region methods (Ceres' LM
#    and dogleg (`DOGLEG`, traditional), g2o's Levenberg and dogleg, GTSAM's LM and dogleg; on the
#    curve Ceres and scipy's `lm` and `trf`): chi2 against the iteration and the wall time, the
#    number of factorizations, and whether each reaches the Gauss-Newton minimum.
# 3. **Written questions.**
#
# Stuck on a derivation? `hint("cauchy_point", 1)` (or `python -m autograder hint NAME LEVEL`)
# gives the approach, level 2 the key identity, level 3 the result.
#
# Conventions: as in chapter 1, $\chi^2 = r^\top W r$, $H = J^\top W J$, $b = J^\top W r$. The
# `dogleg` module works, as Madsen, Nielsen and Tingleff do, with $F = \chi^2 / 2$, its gradient
# $g = b$ and the model $L(h) = F + g^\top h + \tfrac12 h^\top H h$: chapter 1's model of $\chi^2$,
# halved. Lengths are Euclidean norms of $h$ in the units of the parameters. One *iteration* is
# one step attempt, accepted or rejected.

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

from autograder.lesson import check, hint
from course.app import compare, plot
from course.notebook_helpers import chapter3
from course.notebook_helpers.common import (
    chi2_against_time,
    load,
    method_table,
    not_run_note,
    ran,
    use_eleven_colours,
)

# "solutions", "exercises" or a path to your own copy (python -m notebooks.build --impl sets it);
# by default this tree's own: "exercises" in a student tree
IMPL = os.environ.get("COURSE_IMPL") or (
    "solutions" if (root / "solutions" / "__init__.py").is_file() else "exercises")
# runs per (back end, method); the table keeps the median-time run (--small sets 1)
REPEAT = int(os.environ.get("COURSE_NOTEBOOK_REPEAT", "5"))
# 1: the quick setting (small graphs; the tests run it, --small sets it); else the full one
SMALL = os.environ.get("COURSE_NOTEBOOK_SMALL", "0") == "1"

# %% [markdown] id="tr-md"
# ## 1. The trust-region subproblem
#
# At the current point $x$ the quadratic model $L(h) = F + g^\top h + \tfrac12 h^\top H h$ is
# trusted only within a radius $\Delta$:
#
# $$\min_h\; L(h) \quad \text{subject to} \quad |h| \le \Delta .$$
#
# Chapter 1 showed that its solution is $h(\lambda) = -(H + \lambda I)^{-1} g$ for the multiplier
# $\lambda \ge 0$ that puts $h$ on the boundary (or $\lambda = 0$, the Gauss-Newton step, when that
# fits inside). As $\Delta$ grows from 0, $h(\lambda)$ draws a curve from the origin, leaving it
# along $-g$ (large $\lambda$: $h \approx -g / \lambda$), to $h_{gn}$ ($\lambda = 0$).
# Levenberg-Marquardt walks along that curve by choosing $\lambda$, and every new $\lambda$ costs a
# factorization of $H + \lambda I$. Powell's idea: replace the curve by a path through two points
# that one factorization of $H$ gives, the **Cauchy point** and the **Gauss-Newton point**, and
# take the point of that path at distance $\Delta$.

# %% [markdown] id="cauchy-md"
# ## 2. The Cauchy point: the minimizer of the model along steepest descent
#
# The model decreases fastest at $h = 0$ along $-\nabla L(0) = -g$. How far to go? Restrict the
# model to that line, $h = -\alpha g$ with $\alpha \ge 0$:
#
# $$\varphi(\alpha) = L(-\alpha g) = F - \alpha\, g^\top g + \tfrac12 \alpha^2\, g^\top H g .$$
#
# $\varphi$ is a parabola in the single number $\alpha$. Its slope at $0$ is
# $\varphi'(0) = -|g|^2 < 0$ (the direction descends), its curvature $\varphi'' = g^\top H g$ is
# positive whenever $H$ is positive definite (the contract of `cauchy_point`: $g^\top H g > 0$).
# So $\varphi$ has exactly one minimizer $\alpha^\star > 0$, where $\varphi'(\alpha^\star) = 0$; the
# **Cauchy point** is $a = -\alpha^\star g$. Solve that equation for $\alpha^\star$: that is
# `cauchy_point(g, Hg)`. It receives the product $Hg$ (one matrix-vector product), never $H$
# itself: the Cauchy point needs no factorization.
#
# Why not stop there (steepest descent)? Along $-g$ the model is minimized on one line only; in a
# long narrow valley of $L$ (an ill-conditioned $H$) the next gradient is nearly orthogonal and the
# steps zigzag. The Cauchy point matters for another reason: trust-region convergence theory asks
# every step to decrease the model by at least a fixed fraction of what the minimizer along $-g$
# within the region achieves (the *Cauchy decrease*). The dogleg's steps do at least as well as
# that point, since its path starts along $-g$ and, as section 3 shows, the model keeps decreasing
# along it.
#
# The left panel of the figure in section 3 draws $\varphi$ and the true $F(x - \alpha g)$ on a
# two-parameter problem, with your Cauchy point.

# %% id="hint-cauchy"
hint("cauchy_point", 1)  # level 1, the approach; 2 gives the key identity, 3 the result

# %% id="check-cauchy"
check("dogleg.cauchy_point")

# %% [markdown] id="path-md"
# ## 3. The Gauss-Newton point and the dogleg path
#
# The Gauss-Newton step solves $H h_{gn} = -g$: the minimizer of $L$ over *all* $h$ (chapter 1),
# one factorization of $H$. If $|h_{gn}| \le \Delta$ it solves the trust-region subproblem, and
# the dogleg takes it. Otherwise the dogleg walks the path
#
# $$0 \;\to\; a \;\to\; h_{gn}, \qquad
# h(\beta) = a + \beta\,(h_{gn} - a) \text{ on the second leg, } \beta \in [0, 1],$$
#
# and stops where it leaves the region. That point is the best point of the path inside the
# region, because along the path (for $H$ positive definite)
#
# * **the model decreases**: on the first leg up to the minimizer $a$ of the model along $-g$; on
#   the second, $L(h(\beta))$ is a convex parabola in $\beta$ whose minimum is at $\beta = 1$, since
#   $h_{gn}$ minimizes $L$ everywhere, so it decreases on all of $[0, 1]$;
# * **the length grows**: on the first leg clearly; on the second, with $d = h_{gn} - a$,
#   $\frac{d}{d\beta} \tfrac12 |a + \beta d|^2 = a^\top d + \beta |d|^2$, which is $\ge 0$ for
#   $\beta \ge 0$ once $a^\top d \ge 0$, i.e. $a^\top h_{gn} \ge |a|^2$. Put your $\alpha^\star$ and
#   $h_{gn} = -H^{-1} g$ into that inequality: it becomes the Cauchy-Schwarz inequality for the two
#   vectors $H^{1/2} g$ and $H^{-1/2} g$.
#
# So the path crosses each circle $|h| = \Delta$ at most once, and the three cases of `dogleg_step`
# follow: $|h_{gn}| \le \Delta$, the Gauss-Newton step; $|a| \ge \Delta$, the first leg leaves the
# region already: steepest descent clipped to the boundary, $h = -(\Delta / |g|)\, g$; otherwise the
# second leg does, at the $\beta$ with $|a + \beta d| = \Delta$.
#
# ### $\beta$, the root of a quadratic
#
# Square the condition $|a + \beta d| = \Delta$ and expand:
#
# $$|d|^2\, \beta^2 + 2\,(a^\top d)\,\beta + |a|^2 - \Delta^2 = 0 .$$
#
# In the third case $|a| < \Delta$, so the constant term is negative: the product of the two roots,
# $(|a|^2 - \Delta^2) / |d|^2$, is negative, and exactly one root is positive. It is below 1, since
# at $\beta = 1$ the left side is $|h_{gn}|^2 - \Delta^2 > 0$. That root is $\beta$. Mind the
# arithmetic: the textbook formula $(-B + \sqrt{B^2 - 4AC}) / (2A)$ subtracts two nearly equal
# numbers when $B = 2 a^\top d > 0$ and $|C| = \Delta^2 - |a|^2$ is small (the Cauchy point almost
# on the boundary), and loses most of its digits; write the root in a form that never subtracts
# nearly equal numbers (the check "stable beta" tries that case).
#
# ### The predicted decrease
#
# The solver needs, for the gain ratio below, the decrease the model predicts,
# $L(0) - L(h) = -g^\top h - \tfrac12 h^\top H h$. `dogleg_step` does not receive $H$: in each case,
# write $h$ in terms of $g$, $h_{gn}$ and $\alpha^\star$, and remove $H$ with what you know,
# $H h_{gn} = -g$ and the equation that defines $\alpha^\star$.

# %% id="hint-dogleg-step"
hint("dogleg_step", 1)

# %% [markdown] id="figure-path-md"
# ### The path on a two-parameter problem
#
# Rosenbrock's function as least squares, $r(x) = (x_2 - x_1^2,\; 1 - x_1)$, linearized at
# $x = (-0.5, 0.5)$, where the model is a quadratic in the plane. Left: along $-g$, the model
# $\varphi(\alpha)$ and the true cost; near $\alpha = 0$ they agree, further on they part. Right: the
# contours of $L$, the exact trust-region curve $h(\lambda)$, the dogleg path through your Cauchy
# point, and on three circles your dogleg step (dot) against the exact trust-region step (cross).
# The full Gauss-Newton step raises $F$ from 1.156 to 2.531 here: a trust region is needed.

# %% id="figure-path"
display(Image(plot.to_png(chapter3.dogleg_path(IMPL))))

# %% [markdown] id="radius-md"
# ## 4. The gain ratio and the radius
#
# After a step, compare the decrease of the cost with the model's prediction, the **gain ratio**
#
# $$\rho = \frac{F(x) - F(x + h)}{L(0) - L(h)}$$
#
# (chapter 1's $\rho$: numerator and denominator are both halved). The step is accepted when
# $\rho > 0$ (the cost went down). Then `update_radius` (Madsen et al., algorithm 3.21):
#
# * $\rho < 0.25$: the model predicted the cost poorly at this length: $\Delta \leftarrow \Delta / 2$;
# * $\rho > 0.75$: the model is good: $\Delta \leftarrow \max(\Delta,\, 3|h|)$;
# * otherwise $\Delta$ stays.
#
# Why $3|h|$ and not $3\Delta$: when the step was $h_{gn}$, strictly inside the region, tripling
# $\Delta$ after every good step would let it grow without bound while the steps stay short, and
# the next rejection would take many halvings to come back; $\max(\Delta, 3|h|)$ never shrinks the
# radius after a good step, and grows it only to three times the step actually taken. The pair of
# thresholds is the dogleg's counterpart of chapter 1's rules for $\lambda$ (a large $\lambda$ is a
# small radius); a rejected step halves $\Delta$ and retries *from the same $a$ and $h_{gn}$*.
#
# Our dogleg on chapter 1's curve, from $(0, 0, 0)$ and $\Delta_0 = 10^4$: per attempt the radius,
# the step's length and $\rho$, and below the same as numbers (`inside`: the Gauss-Newton step;
# `boundary`: a step of length $\Delta$). The first attempts take $h_{gn}$ (the radius is far larger)
# and overshoot by tens of orders of magnitude, as in chapter 1; each rejection halves $\Delta$
# without a factorization, until $\Delta$ falls below $|h_{gn}|$ and the steps follow the path.

# %% id="figure-radius"
run = chapter3.dogleg_on_curve(IMPL)  # None (one line naming the TODO) until dogleg.py is written
if run is not None:
    display(Image(plot.to_png(chapter3.radius_per_attempt(run))))
    print(chapter3.attempts_table(run))

# %% [markdown] id="factorize-md"
# ## 5. One factorization per accepted step
#
# Count the work per attempt. Levenberg-Marquardt: the step solves $(H + \lambda D) h = -g$ for the
# current $\lambda$; a rejection changes $\lambda$, so the retry factorizes again: **one
# factorization per attempt**, accepted or not. Dogleg: $a$ and $h_{gn}$ depend only on the point
# $x$ (through $g$ and $H$); a rejection changes $\Delta$ alone, and the new step is a few vector
# operations on the same $a$ and $h_{gn}$ (and $\alpha^\star$, $|g|$): **one factorization per point
# where the model is built**, that is, at the start and after each accepted step. In the table
# above, the running count of factorizations stays at 1 through every rejection. Where a
# factorization dominates an iteration (large pose graphs, chapter 2) the dogleg's rejections are
# nearly free.
#
# The price: the dogleg needs $h_{gn}$, so $H$ must be positive definite (our solver, as Ceres,
# adds a small $\mu\,\mathrm{diag}(H)$ when the factorization fails, where Levenberg-Marquardt's
# damping regularizes by construction); and its steps lie in the plane of $g$ and $h_{gn}$, on a
# path with a corner, not on the exact curve (the distances printed under the figure of section 3).

# %% id="check-dogleg"
check("dogleg")

# %% [markdown] id="experiments-md"
# # Experiments
#
# The runs, with `IMPL` (set `IMPL = "exercises"` in the setup cell to run your own dogleg).
# The factorization count is exact for our solvers; for the peers it is what the library
# reports, marked `*` (Ceres' `num_linear_solves`, g2o's count of Levenberg damping attempts) or
# `n/a` where it reports none (GTSAM, scipy, g2o's dogleg, Ceres on the curve).

# %% id="helpers"
use_eleven_colours()  # eleven runs per pose graph: ten colours are not enough

# %% [markdown] id="runs-md"
# ## The runs
#
# Each (back end, method) pair runs `REPEAT` times from the same start and keeps its
# median-time run; at most 100 iterations. One *iteration* is one step attempt for our
# solvers and Ceres; g2o and GTSAM count an outer iteration, with their damping or radius
# retries inside it. A pair whose exercise is not written yet is left out, with a line naming
# its TODO.

# %% id="runs"
PEER_METHODS = ["levenberg-marquardt", "levenberg", "dogleg"]  # Ceres and GTSAM LM, g2o Levenberg, dogleg
names = ["curve", "manhattan:200"] if SMALL else ["curve", "intel", "m3500", "mit"]
results = {}
for name in names:
    if name == "curve":
        runs = compare.run_curve(impl=IMPL, repeat=REPEAT, unimplemented="row")
    else:
        g = load(name)
        if g is None:
            continue
        runs = (compare.run_posegraph(g, impl=IMPL, backends=["ours"], repeat=REPEAT, unimplemented="row")
                + compare.run_posegraph(g, impl=IMPL, methods=PEER_METHODS, backends=["ceres", "g2o", "gtsam"],
                                        repeat=REPEAT, unimplemented="row"))
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
display(Markdown(chapter3.factorization_table(results)))

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
chapter3.rejection_demo(IMPL, load)

# %% [markdown] id="questions-md"
# # Written questions
#
# Answer in the cells below, in a few sentences each; use the figures and tables above.
#
# **Question 1.** Under the figure of the dogleg path (section 3), the distance between your
# dogleg step and the exact trust-region step is printed for three radii. Where along the path is
# the dogleg close to the exact curve, and where not, and why? (Think of where both begin and end,
# and of the corner at $a$.) For which $H$ do the dogleg path and the exact curve coincide?
#
# **Question 2.** On the curve (section 4) the dogleg's first eight attempts take the very same
# step and are all rejected. Why the same step, and what decides when the step changes? What did
# these rejections cost, in factorizations, compared with what Levenberg-Marquardt type 1 pays for
# each of its rejected attempts (the table "Factorizations")?
#
# **Question 3.** On `manhattan:200` (the factorization table) the dogleg needs as many
# factorizations as Gauss-Newton, and on the curve many fewer than Levenberg-Marquardt. When does
# the dogleg's one-factorization-per-accepted-step pay, and when does it make no difference?
#
# **Question 4.** Suppose $H$ is singular at some point (for example a pose graph whose first pose
# is not fixed). What goes wrong in the dogleg's construction (which of $a$, $h_{gn}$, $\beta$), and why
# does Levenberg-Marquardt not have that problem?

# %% [markdown] tags=["answer"] id="answer-1"
# **Your answer to question 1:** *(double-click to edit)*

# %% [markdown] tags=["answer"] id="answer-2"
# **Your answer to question 2:** *(double-click to edit)*

# %% [markdown] tags=["answer"] id="answer-3"
# **Your answer to question 3:** *(double-click to edit)*

# %% [markdown] tags=["answer"] id="answer-4"
# **Your answer to question 4:** *(double-click to edit)*
