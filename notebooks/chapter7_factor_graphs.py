# %% [markdown] id="title"
# # Chapter 7: a factor graph with automatic differentiation
#
# Every chapter so far handed you one problem, its Jacobians derived by hand and its normal equations
# assembled by hand. The back ends you will use next (Ceres with its Jets, GTSAM with its factors and
# keys, g2o, SymForce) rest on one more layer: a **generic factor graph** whose factors get their
# Jacobians automatically and are linearised together into one block-sparse system. This chapter builds
# that layer (`course.factorgraph`), and the chapter is a lesson in this order:
#
# 1. **Theory**, derived: dual numbers from scratch and forward-mode differentiation in $k$ directions
#    (exercise `jets`); why automatic derivatives are exact and finite differences are not; the chain
#    rule through a retraction, the retraction's derivative at 0 as the Jets' seed (Ceres' `Manifold`),
#    and why $\mathrm{Exp}$ at $\delta = 0$ needs its series (exercise `autodiff_factor`); the generic
#    linearisation: factors grouped by type, whitened, assembled into a
#    pattern found once for variables of mixed sizes (exercise `factor_linearisation`). After each
#    exercise's theory, a cell `check("...")` grades it here, with the same sandboxed judge and public
#    checks as `python -m autograder --only ...`; before it, a cell checks your code where you work.
# 2. **Experiments**: intel (in the full setting also sphere2500 and ladybug-49) as factor graphs:
#    automatic against analytic Jacobians, the minimum each solve ends at, what the automatic Jacobians
#    cost, a new factor in five lines that the graph solves with no Jacobian written by hand, and a new
#    problem built from the factor library alone (range-only SLAM) against GTSAM's own factors.
# 3. **Written questions.**
#
# Stuck on a derivation? `hint("jets", 1)` (or `python -m autograder hint NAME LEVEL` in a terminal)
# gives the approach, level 2 the key identity, level 3 the result.
#
# Conventions, everywhere in this chapter: a variable is stored as an array of its kind's shape (an SE(2)
# pose $(x, y, \theta)$; an SE(3) pose as 12 numbers, $t$ then $R$ row by row; a BAL camera as 9) and is
# moved by its kind's **retraction** $x \boxplus \delta$, $\delta$ of the kind's tangent size: SE(2) by
# addition, the angle wrapped (chapter 2); SE(3) on the **right**, $(t + R\rho,\ R\,\mathrm{Exp}(\phi))$,
# **translation first** (chapter 6); vectors and BAL cameras by addition (chapter 4). A Jet has a
# `value` of shape $(\dots)$ and a `grad` of shape $(\dots, k)$: the last axis holds the $k$ seeded
# directions. A factor adds $e^\top \Omega e$ to $\chi^2$; $H = \sum J^\top \Omega J$,
# $b = \sum J^\top \Omega e$, and the step solves $H \delta = -b$.

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

import numpy as np
from IPython.display import Image, display

from autograder.lesson import check, hint
from course import check_jacobian
from course.app import benchmark_autodiff, compare, plot
from course.core.errors import DatasetError
from course.factorgraph import SE2, SE3, FactorType
from course.notebook_helpers import chapter7
from course.notebook_helpers.chapter7 import todo_as_one_line

SMALL = os.environ.get("COURSE_NOTEBOOK_SMALL") == "1"
# "solutions", "exercises" or a path to your own copy (python -m notebooks.build --impl sets it);
# by default this tree's own: "exercises" in a student tree
IMPL = os.environ.get("COURSE_IMPL") or ("solutions" if (root / "solutions").is_dir() else "exercises")
# rounds of the benchmark (--small sets 1)
REPEAT = int(os.environ.get("COURSE_NOTEBOOK_REPEAT", "5"))
GRAPHS = ["intel"] if SMALL else ["intel", "sphere2500", "ladybug-49"]
print(f"implementation: {IMPL}; graphs: {', '.join(GRAPHS)}")

# %% [markdown] id="dual-md"
# ## 1. Dual numbers, from scratch (exercise `jets`)
#
# Take numbers of the form $a + b\,\varepsilon$ with a new symbol $\varepsilon$ whose square is zero,
# $\varepsilon^2 = 0$ (as $i$ has $i^2 = -1$; $\varepsilon$ is no real number, just a rule of
# arithmetic). Adding and multiplying them by the usual rules and dropping $\varepsilon^2$:
#
# $$(a + b\varepsilon) + (c + d\varepsilon) = (a + c) + (b + d)\,\varepsilon, \qquad
#   (a + b\varepsilon)(c + d\varepsilon) = ac + (ad + bc)\,\varepsilon + bd\,\varepsilon^2
#   = ac + (ad + bc)\,\varepsilon .$$
#
# The $\varepsilon$-part of a product obeys the product rule. For a power, the binomial theorem leaves two
# terms, $(a + \varepsilon)^n = a^n + n a^{n-1} \varepsilon$ (every other term holds $\varepsilon^2$), so
# for every polynomial
#
# $$p(a + \varepsilon) = p(a) + p'(a)\,\varepsilon .$$
#
# *Worked example*, $f(x) = x^3 - 3x + 1$ at $a = 2$: $(2 + \varepsilon)^2 = 4 + 4\varepsilon$,
# $(2 + \varepsilon)^3 = (4 + 4\varepsilon)(2 + \varepsilon) = 8 + 12\varepsilon$,
# $-3(2 + \varepsilon) = -6 - 3\varepsilon$, and in all $f(2 + \varepsilon) = 3 + 9\varepsilon$: the value
# $f(2) = 3$ and the derivative $f'(2) = 3 \cdot 2^2 - 3 = 9$, from one evaluation, with no step and no
# subtraction. (`chapter7.Dual` is exactly this arithmetic, sums and products; the figure below uses it.)
#
# For any smooth $f$, Taylor's series $f(a + b\varepsilon) = f(a) + f'(a)\, b\varepsilon + \tfrac12 f''(a)\,
# b^2 \varepsilon^2 + \dots$ stops after its second term. So **define** every function on dual numbers by
#
# $$f(a + b\,\varepsilon) = f(a) + f'(a)\, b\, \varepsilon ,$$
#
# and composition follows by itself: with $g(a + b\varepsilon) = g(a) + g'(a)\,b\,\varepsilon$,
# $f(g(a + b\varepsilon)) = f(g(a)) + f'(g(a))\, g'(a)\, b\,\varepsilon$, the **chain rule**. A program
# built from $+$, $\times$, $/$, $\sin$, $\sqrt{\ }$, ... and run on $a + 1\varepsilon$ returns $f(a)$ and
# $f'(a)$, whatever its length: each operation applies its own rule to what it receives.
#
# **Forward mode in $k$ directions.** A residual depends on many numbers. Give each of $k$ inputs its own
# symbol, $\varepsilon_1, \dots, \varepsilon_k$ with $\varepsilon_i \varepsilon_j = 0$ for all $i, j$: a
# number is now $a + \sum_j b_j \varepsilon_j$, and the vector $b = (b_1, \dots, b_k)$ is its gradient.
# **Seeding** input $i$ means giving it $b = e_i$ (the unit vector $i$); every intermediate then carries its
# derivatives in all $k$ inputs, and the outputs' $\varepsilon$-parts are the Jacobian's rows. One pass
# costs the evaluation plus about $k$ times its arithmetic, against $k + 1$ evaluations for forward
# differences and $2k$ for central ones. (Reverse mode, backpropagation, wins when there are far more
# inputs than outputs; a factor has a handful of each, which is why Ceres differentiates its factors in
# forward mode.)
#
# **The exercise** (`exercises/jets.py`): a `Jet` is a *batch* of such numbers, `value` $(\dots)$ and `grad`
# $(\dots, k)$, so that all $M$ factors of one type are differentiated at once (M rotation matrices:
# `value` (M, 3, 3), `grad` (M, 3, 3, k)). Write the rules of $\times$, $/$, powers, $\sqrt{\ }$, $\sin$,
# $\cos$, $\exp$, $\log$, $\operatorname{arctan2}$ and the matrix product, each derived from
# $f(a + da\,\varepsilon) = f(a) + f'(a)\,da\,\varepsilon$ where $da$ is the operand's `grad`. Mind three
# things: a value must meet the extra last axis of a `grad`; an operand that is a plain number or array
# is a constant, its derivative zero; and the points where $f'$ is infinite or the general formula meets
# $0 \cdot \infty$ ($\sqrt{x}$ at 0; $x^0$, $x^1$ and $x^p$ with $0 < p < 1$ at $x = 0$), where the contract
# says what to return, or where $x^2 + y^2$ overflows ($\operatorname{arctan2}$ at $10^{200}$: scale first).
# numpy sends its functions to your rules (`np.sin(jet)` calls `jets.sin`, given), so a residual written
# once for arrays runs on Jets unchanged: the factors of `course.factorgraph.factors` are written so.
# The rest of the numpy a residual is written with is given, built from your rules: `abs` (at 0 the
# derivative of the right side), comparisons (`x < 0` compares the values) with `np.where`, `np.minimum` and
# `np.maximum`, `np.sum`, `np.stack`, `np.concatenate`, `.T`, `np.linalg.norm`, `np.dot`, `np.einsum`, `@`
# with a vector on either side, `np.arctan`, `np.tanh` and `np.hypot`; any other function fails with one
# line naming it and what to write instead (`np.tan`: `np.sin(x) / np.cos(x)`).

# %% id="figure-dual"
print(f"f(2 + eps) = {chapter7.cubic(chapter7.Dual(2.0, 1.0))!r}")
display(Image(plot.to_png(chapter7.tangent_figure())))

# %% id="hint-jets"
hint("jets", 1)  # level 1, the approach; 2 the key identity, 3 the result

# %% [markdown] id="jets-check-md"
# **Check your Jets where you work.** The cell below evaluates a small function of two numbers $x$ and $y$
# whose twelve rows use every rule once (`chapter7.RULES`: $xy$, $x/y$, $2/y$, $y^3$,
# $\sqrt{x^2 + y^2}$, ..., a rotation matrix times a vector) on your Jets seeded in two directions at
# $(0.7, 1.3)$, and compares the values with numpy's and the derivatives with central differences
# (`course.check_jacobian`); a wrong row is named by its rule. Try your own inputs too: $\sqrt{\ }$ at 0,
# a batch, a constant operand on either side.

# %% id="jets-check"
with todo_as_one_line():
    Jet = chapter7.exercise("jets", IMPL).Jet
    chapter7.jets_check(Jet, point=(0.7, 1.3))

# %% id="check-jets"
check("jets")

# %% [markdown] id="exact-md"
# ## 2. Why automatic derivatives are exact and finite differences are not
#
# **Forward differences.** By Taylor, $\frac{f(x + h) - f(x)}{h} = f'(x) + \tfrac12 f''(\xi)\, h$: a
# **truncation** error of order $h$. But $f(x)$ is computed with a relative error of about
# $\epsilon = 2.2 \times 10^{-16}$ (the machine epsilon), so the difference of two nearby values carries
# an absolute error of about $\epsilon\,|f|$, and dividing by $h$ makes it a **rounding** error
# $\epsilon |f| / h$. The total, about $\tfrac12 |f''|\,h + \epsilon |f| / h$, is smallest where both terms
# are equal: $h^* \sim \sqrt{\epsilon} \approx 1.5 \times 10^{-8}$ with an error of the same size,
# $\sqrt{\epsilon}$: **half the digits** are lost, at best.
#
# **Central differences.** $\frac{f(x + h) - f(x - h)}{2h} = f'(x) + \tfrac16 f'''(\xi)\, h^2$: the truncation
# is of order $h^2$, the rounding still $\epsilon / h$; the optimum is $h^* \sim \epsilon^{1/3} \approx 6
# \times 10^{-6}$ with an error $\sim \epsilon^{2/3} \approx 4 \times 10^{-11}$: a third of the digits lost,
# for $2k$ evaluations. Both optima assume $f$ and its derivatives of order 1; a badly scaled variable, or
# a kink within $h$, makes them worse, and nothing tells you so.
#
# **Jets.** A Jet computes $f'$ with the same operations as $f$ itself: no step (no truncation) and no
# difference of nearby values (no cancellation that the step creates). Each rule's derivative is
# rounded like a value, to a few $\epsilon$.
#
# The figure shows all three on chapter 2's edge residual, its $3 \times 6$ Jacobian in both poses'
# steps, for steps $h$ from $10^{-15}$ to $10^{-1}$: the largest error relative to the largest entry,
# against your Jets. To check the Jets themselves against something independent, a fourth method: the
# **complex step**, $f'(x) \approx \mathrm{Im}\, f(x + i h) / h$ with $h = 10^{-100}$. Like $\varepsilon$,
# $i$ carries the derivative in a second component ($f(x + ih) = f(x) + i h f'(x) - \tfrac12 h^2 f''(x) +
# \dots$): the imaginary part is read without any subtraction, and its truncation, of order $h^2$, is far
# below rounding. (It needs a residual that is analytic and runs on complex numbers, which Jets do not.)

# %% id="figure-steps"
study = chapter7.step_study(IMPL)  # step_study(IMPL, shift=1000.0): the edge moved 1000 m along x and y
display(Image(plot.to_png(chapter7.step_figure(study))))
print(chapter7.step_table(study))

# %% [markdown] id="retraction-md"
# ## 3. The chain rule through a retraction (exercise `autodiff_factor`)
#
# A factor's residual $r(x_1, \dots, x_s)$ takes its variables' stored values. The solver needs its
# Jacobians in the **tangent spaces**, the derivative in each variable's step:
#
# $$J_a = \frac{\partial\, r(x_1, \dots, x_a \boxplus \delta_a, \dots, x_s)}{\partial \delta_a}
#   \Big|_{\delta_a = 0} \qquad (m \times d_a) .$$
#
# Seeding the 12 stored numbers of an SE(3) pose directly would give the derivative in those numbers,
# $\partial r / \partial x$ ($m \times 12$): of no use to the solver, since the 12 numbers are not free (R
# stays a rotation) and a step along them leaves SE(3). The **chain rule** connects the two:
#
# $$J_a = \underbrace{\frac{\partial r}{\partial x_a}\Big|_{x_a}}_{m \times 12}\;
#   \underbrace{\frac{\partial (x_a \boxplus \delta)}{\partial \delta}\Big|_{\delta = 0}}_{12 \times 6} .$$
#
# For SE(3), $x \boxplus (\rho, \phi) = (t + R\rho,\ R\,\mathrm{Exp}(\phi))$ and $\mathrm{Exp}(\phi) = I +
# [\phi]_\times + O(|\phi|^2)$, so the second factor has $\partial t / \partial \rho = R$,
# $\partial R / \partial \phi_k = R\,[e_k]_\times$, and zeros elsewhere.
#
# **The retraction's derivative as the seed.** Jets can take $J_a$ two ways. The first: seed the *steps*
# $\delta_a$ at zero, move each variable through its retraction on Jets, and evaluate the residual on the
# moved values; the arithmetic applies the chain rule itself. But then the retraction runs on Jets at
# every linearisation, $\mathrm{Exp}$ and a product of rotations each carrying $k$ derivatives: on
# sphere2500 more than half the time of the Jacobians. The second writes the second factor down once, as
# just derived. Call it $P_a = \partial\, \mathrm{vec}(x_a \boxplus \delta) / \partial \delta \,|_{\delta = 0}$
# ($n_a \times d_a$, $n_a$ the stored numbers): to first order
#
# $$\mathrm{vec}(x_a \boxplus \delta_a) = \mathrm{vec}(x_a) + P_a\, \delta_a .$$
#
# A Jet *is* a first-order expansion, so the Jet whose value is $x_a$ and whose derivative in $\delta_a$'s
# directions is $P_a$ is the moved value, as far as any derivative can tell; the residual evaluated on it
# has the derivative $\frac{\partial r}{\partial x_a} P_a = J_a$, and no retraction runs on Jets. This is
# Ceres' way: a `Manifold` gives `Plus` and `PlusJacobian`, the latter exactly $P_a$, and Ceres seeds
# through it. Here each kind of variable gives `plus_jacobian(x)` in closed form
# (`course.factorgraph.variables`: the identity for vectors and SE(2), the blocks above for SE(3),
# $R\,[e_k]_\times$ for SO(3)), and the factor graph hands them with the values to your
# `tangent_jacobians` (`exercises/autodiff_factor.py`). One evaluation gives all of a factor's Jacobians
# when its $k = d_1 + \dots + d_s$ directions are shared out among the variables; how to lay them out so
# that each block comes out where it belongs is yours to work out. (The factor graph calls it one
# variable at a time, the others plain arrays: a product of two Jets of different variables spends half
# its arithmetic on zeros, so on sphere2500 two evaluations in 6 directions cost less than one in 12.)
# A fixed variable is not
# differentiated: where a factor holds one, its $P_a$ is 0 there (its block comes out 0; the assembly
# holds it still anyway), and a slot fixed in every factor of a group is passed as a plain array, a
# constant with no directions.
#
# **Why $\mathrm{Exp}$ at $\delta = 0$ needs its series.** The first way's seeds sit exactly at
# $\delta = 0$ (and so does any Jet that checks a plus-Jacobian, as below). By
# Rodrigues, $\mathrm{Exp}(\phi) = I + a(t)\,[\phi]_\times + b(t)\,[\phi]_\times^2$ with $t = |\phi| =
# \sqrt{\phi^\top \phi}$, $a = \sin t / t$, $b = (1 - \cos t) / t^2$. At $\phi = 0$ the closed forms are
# $0/0$: `nan` in the value and in every derivative, and a `nan` spreads to everything computed from it.
# The square root is the deeper trouble: $t = |\phi|$ is not differentiable at 0 (a cone, whose slope
# depends on the direction), and the rule for $\sqrt{\ }$ meets its infinite derivative there. But $a$
# and $b$ are even in $t$, smooth functions of $t^2 = \phi^\top \phi$:
#
# $$a = 1 - \frac{t^2}{6} + \frac{t^4}{120} - \dots, \qquad b = \frac12 - \frac{t^2}{24} + \frac{t^4}{720} - \dots$$
#
# Written in $t^2$ the series take no square root and divide by nothing: on Jets at $\phi = 0$ they give
# $a = 1$, $b = \tfrac12$, zero derivatives, and $\partial\,\mathrm{Exp} / \partial \phi_k = [e_k]_\times$
# exactly. `course.factorgraph.jetmath.so3_exp` uses them below $t^2 = 10^{-10}$; the branch is chosen
# by the value, and the derivative follows the branch taken (as Ceres' Jets do with an `if`). The figure
# shows what the closed form of $b$ does in floating point: its value cancels ($1 - \cos t$ leaves it
# a relative error of about $\epsilon / t^2$), and the derivative a Jet would carry through it cancels
# far worse. The table after it evaluates $\mathrm{Exp}$ on your Jets at $\phi = 0$, by the closed form alone
# and with the series.

# %% id="figure-series"
display(Image(plot.to_png(chapter7.series_figure())))

# %% id="zero-angle"
with todo_as_one_line():
    print(chapter7.zero_angle_table(chapter7.exercise("jets", IMPL).Jet))

# %% [markdown] id="chain-md"
# **The chain rule, seen.** On one edge of chapter 6 (random poses, a residual rotation of 0.4 rad), your
# Jets give three things: the derivative of the residual in the 24 stored numbers of both poses (seeded
# directly), the derivative of the retraction at 0, and the tangent Jacobians seeded through the
# retraction. The product of the first two is the third, and the retraction's derivative is the one
# derived above: `SE3.plus_jacobian`'s closed form. Seeding the stored values with it gives the same
# Jacobians, with no retraction on Jets.

# %% id="chain-rule"
edge = chapter7.se3_edge(seed=0, residual_angle=0.4)  # z, x_i, x_j stored (1, 12); T_i, T_j as (t, R)
with todo_as_one_line():
    print(chapter7.chain_rule_text(chapter7.chain_rule(edge, chapter7.exercise("jets", IMPL).Jet), edge))

# %% [markdown] id="plus-jacobian-md"
# **Each kind's seed, printed.** What the factor graph hands your `tangent_jacobians` for a variable is its
# kind's `plus_jacobian(x)`, $P = \partial\, \mathrm{vec}(x \boxplus \delta) / \partial \delta$ at $\delta = 0$
# (Ceres' `Manifold::PlusJacobian`). For SE(2), moved by addition, $P = I_3$: the stored numbers are the
# tangent coordinates, and a plain seed is the right one. For SE(3), the $12 \times 6$ derived above: rows
# 0-2 (the translation) hold $R$ in the $\rho$ columns, rows 3-11 (R row by row) hold
# $\partial R / \partial \phi_k = R\,[e_k]_\times$ in column $3 + k$, and the rest is zero. Each is checked
# against central differences of its retraction at $\delta = 0$.

# %% id="plus-jacobian"
print(chapter7.plus_jacobian_text(chapter7.plus_jacobian_study()))

# %% id="hint-tangent"
hint("tangent_jacobians", 1)

# %% [markdown] id="tangent-check-md"
# **Check your `tangent_jacobians` where you work**, on the same edge, seeded with the poses'
# plus-Jacobians: its two $6 \times 6$ blocks against central differences through the retraction
# (`plus="se3"`: exactly $T \boxplus \delta$), each wrong entry named by its block.

# %% id="tangent-check"
with todo_as_one_line():
    Jet = chapter7.exercise("jets", IMPL).Jet
    tangent_jacobians = chapter7.exercise("autodiff_factor", IMPL).tangent_jacobians
    plus_jacobians = [SE3.plus_jacobian(edge.x_i), SE3.plus_jacobian(edge.x_j)]  # (1, 12, 6) each
    r, (A, B) = tangent_jacobians(edge.residual, plus_jacobians, [edge.x_i, edge.x_j], Jet)
    check_jacobian(edge.error, [edge.T_i, edge.T_j], J=[A[0], B[0]], plus="se3", names=["T_i", "T_j"], rows="se3")

# %% id="check-autodiff"
check("autodiff_factor")

# %% [markdown] id="linearisation-md"
# ## 4. The generic linearisation (exercise `factor_linearisation`)
#
# A graph holds $N$ variables of several kinds, variable $v$ with tangent size $d_v$: the whole step
# $\delta$ has $n = \sum_v d_v$ entries, and variable $v$'s is the slice starting at the offset
# $o_v = d_0 + \dots + d_{v-1}$. Its factors have types; a type fixes the kinds of its slots, its residual
# size $m$ and its residual code. The cost is $\chi^2 = \sum_f e_f^\top \Omega_f e_f$, and each factor
# linearises as $e_f(x \boxplus \delta) \approx e_f + \sum_a J_{f,a}\, \delta_{v(f, a)}$, slot $a$ on
# variable $v(f, a)$.
#
# **Whitening.** An information matrix is symmetric positive definite, so it has a Cholesky factor,
# $\Omega = L L^\top$, and
#
# $$e^\top \Omega\, e = e^\top L L^\top e = |L^\top e|^2 .$$
#
# With the whitened residual $r = L^\top e$ and Jacobians $\tilde J = L^\top J$, the cost is a plain sum of
# squares, $H = \sum \tilde J^\top \tilde J$ and $b = \sum \tilde J^\top r$: the assembly needs no
# $\Omega$, and every factor type, whatever its $m$ and its noise, looks the same to it. (The framework
# whitens each group in one batched product, `course.factorgraph.noise`. A group may also carry one of
# chapter 4's robust losses, `graph.add_many(..., loss=("huber", 2.0))`: its whitened $r$ and $\tilde J$
# are then reweighted as chapter 4 does, and the assembly still sees plain squares.)
#
# **Groups.** All factors of one type share their code and their sizes, so the framework evaluates a type
# once for all its $M$ factors: residuals $(M, m)$ and Jacobian blocks $(M, m, d_a)$, one Jet evaluation
# instead of $M$ calls of Python.
#
# **The pattern.** Factor $f$'s whitened Jacobian is zero but in its variables' columns, so
# $\tilde J_f^\top \tilde J_f$ is zero but for the blocks $\tilde J_{f,a}^\top \tilde J_{f,c}$
# ($d_a \times d_c$: rectangular where the kinds differ) at rows of $v(f, a)$ and columns of $v(f, c)$,
# for every pair of slots; and $b$ gets $\tilde J_{f,a}^\top r_f$ at the rows of $v(f, a)$. Summed over
# the factors, block $(u, v)$ of $H$ can be nonzero only on the diagonal or where a factor joins $u$ and
# $v$: the pattern depends on the keys alone. As in chapters 2 and 6, find it once and let every
# linearisation compute numbers and scatter them; what is new is the mixed sizes (a pose has 3, a
# landmark 2; a BAL camera 9, a point 3), the offsets that follow from them, factors of one or several
# slots, and a slot pair whose variables come in the other order, so that its block falls below the
# diagonal. $H$ is symmetric and the solver reads its upper triangle. Fixed variables are held still as in
# chapters 2 and 6.
#
# The figure: the pattern of $H$ of a short path of six SE(2) poses (odometry between neighbours) that
# sees three landmarks (2D points) by range and bearing, each pose the two nearest.

# %% id="figure-pattern"
path_graph = chapter7.mixed_graph()
display(Image(plot.to_png(chapter7.pattern_figure(path_graph))))

# %% id="hint-assembler"
hint("BlockSparseAssembler", 1)

# %% [markdown] id="path-solve-md"
# **Your three pieces together.** Gauss-Newton on that graph from a perturbed start (the poses off by
# centimetres, the landmarks by decimetres; the measurements are exact, so the minimum is $\chi^2 = 0$), with
# your Jets, your `tangent_jacobians` and your assembler; scipy's sparse LU solves each step, so that no
# other chapter's exercise is needed here.

# %% id="path-solve"
with todo_as_one_line():
    _, run = chapter7.solve(path_graph, IMPL)
    print(chapter7.run_line(run, f"{path_graph.num_variables} variables, {path_graph.num_factors} factors"))

# %% id="check-linearisation"
check("factor_linearisation")

# %% [markdown] id="experiments-md"
# # Experiments
#
# The chapters' problems as factor graphs: chapter 2's intel (729 poses, 3070 edges; the only graph of
# the small setting) and, in the full setting, chapter 6's sphere2500 (2500 poses, 4949 edges) and
# chapter 4's ladybug-49 (49 cameras, 7776 points, 31843 observations). Each is built from the chapter's
# own data by
# `course.problems.<family>.factor_graph.as_factor_graph`: one variable per pose (camera, point), one
# factor per edge (observation), the chapter's information, fixed poses and start.
#
# `SMALL = True` (set by `python -m notebooks.build --execute --small`, and by the tests) runs intel
# alone and one round of each timing; the full setting runs all three, five rounds each (several
# minutes). Set `IMPL = "exercises"` to run your own pieces through all of it.
#
# ## 1. Automatic against analytic Jacobians
#
# At each graph's start: the factor graph's Jacobians by Jets (`autodiff`) and by central differences
# (`numeric`, step $10^{-5}$ through the retraction) against the chapter's own analytic Jacobians
# (`pose_graph_fast`, `pose_graph_3d`, `bundle_adjustment`), the largest difference per factor relative
# to that factor's largest entry.

# %% id="agreement"
print(chapter7.agreement_table(chapter7.jacobian_agreement(GRAPHS, IMPL)))

# %% [markdown] id="minimum-md"
# ## 2. The same minimum
#
# Levenberg-Marquardt (Nielsen's rule) from the same start: ours with the analytic Jacobians, the factor
# graph with automatic ones and with central differences.

# %% id="minimum"
for name in [g for g in GRAPHS if g != "ladybug-49"]:  # ladybug-49's solves: the benchmark below
    try:
        runs = chapter7.solve_runs(name, IMPL)
    except DatasetError as exc:
        print(f"{name}: skipped ({str(exc).splitlines()[0]})")
        continue
    print(compare.format_table(runs, title=name))
    print(chapter7.minimum_line(runs))
    print()

# %% [markdown] id="cost-md"
# ## 3. What automatic derivatives cost
#
# `python -m course benchmark --autodiff`: the median time of one linearisation (the Jacobians, $H$ and
# $b$) and of one iteration of a whole solve, ours against the factor graph's, the runs interleaved so
# that the machine's load falls on all alike. On ladybug-49 the factor graph eliminates the points first,
# as chapter 4 does, but from the $H$ its generic assembly stores (`course.factorgraph.schur_elimination`: any
# kind of variable that no factor joins to another of its kind, here the points), where chapter 4 keeps
# $H$ as its blocks; so the linearisation's ratio is the automatic differentiation's and the generic
# assembly's together. There the 50 iterations stop short of the minimum: the two paths step alike to
# rounding for ten iterations, then part (by $10^{-6}$ at step 20; nothing is fixed, and the scene's seven
# free directions leave $H$ nearly singular, so the two computations round differently along them).
# In the small setting one round: the times are noisy; and GTSAM with the custom factors
# (`gtsam-custom`) is timed on its linearisation alone, as on ladybug-49 (its five iterations on intel
# take seconds).

# %% id="cost"
with todo_as_one_line():
    benchmark_autodiff.main(repeats=REPEAT, impl=IMPL, graphs=GRAPHS, custom_solves=not SMALL)


# %% [markdown] id="new-factor-md"
# ## 4. A new factor in five lines
#
# A robot drives a loop of 80 poses; its odometry drifts, and every eighth pose gets a position fix (a
# GPS-like measurement of $(x, y)$, standard deviation 0.5 m). The fix is a new factor on one SE(2) pose,
# $e = (x, y) - z$. Its Jacobian is not written anywhere: its residual, written once for arrays and Jets,
# is all the graph needs. The graph has nothing fixed: the fixes hold it in place.

# %% id="gps-factor"
def gps(z, x):  # the residual, once for arrays and Jets: the pose's position against the fix
    return x[..., :2] - z


GPS = FactorType("gps_se2", (SE2,), 2, gps)  # the kinds of its variables, and its size
drive = chapter7.gps_drive(seed=1)
graph = chapter7.odometry_graph(drive)  # the poses at the dead reckoning and the odometry; nothing fixed
graph.add_many(GPS, drive.gps_keys, drive.gps, np.eye(2) / drive.gps_sigma**2)

# %% id="gps-solve"
solved = None
with todo_as_one_line():
    problem, run = chapter7.solve(graph, IMPL)
    solved = run.params.reshape(-1, 3)
    print(chapter7.run_line(run, f"{graph.num_variables} poses, {graph.num_factors} factors"))
    _, (J,) = problem.factor_jacobians(run.params, list(graph.groups).index("gps_se2"))
    print(f"the GPS factor's Jacobian at pose {int(drive.gps_keys[1, 0])}, by your Jets:\n{J[1]}")
display(Image(plot.to_png(chapter7.drive_figure(drive, solved))))

# %% [markdown] id="range-only-md"
# ## 5. A new problem from the library: range-only SLAM
#
# The same loop of 80 poses, with no position fixes: four radio beacons stand at places nobody surveyed
# well (their first guesses are off by metres), and at every pose the robot measures its distance to each
# beacon within 14 m, standard deviation 0.1 m. Nothing in the graph is new code: the library's
# `prior(SE2)`, `between(SE2)` and `RANGE_2D`, and `Vector(2)` variables for the beacons
# (`chapter7.range_only_graph`, fifteen lines). The unknowns are the 80 poses and the 4 beacons, 248
# numbers.
#
# **The range factor.** With $d = l - t$ the beacon seen from the pose's position,
# $e = |d| - z$. Its derivative: $\partial |d| / \partial d = d^\top / |d|$, the unit vector towards the
# beacon, so
#
# $$J_{\text{pose}} = \begin{pmatrix} -\dfrac{d^\top}{|d|} & 0 \end{pmatrix} \ (1 \times 3), \qquad
#   J_{\text{beacon}} = \dfrac{d^\top}{|d|} \ (1 \times 2):$$
#
# a range says nothing of the heading (its column is 0: the heading comes from the odometry), and nothing
# of the direction across the line of sight. One range puts the beacon on a circle around the pose; the
# poses along the path draw many circles, and the beacon sits where they cross. That is why this problem
# is **not convex** in the beacons: circles from a nearly straight stretch of path cross twice, in the
# beacon's place and in its mirror image across the path, so the error has more than one minimum, and
# which one a solve ends in depends on its start and on its steps. A start within a metre or two of the
# truth, and a path that turns, are what make it well posed here. ($|d|$ at $d = 0$ is the cone of
# section 3: `jetmath.sqrt` gives 0 for both the value and the derivative there; a robot never stands on
# its beacon.)
#
# **The gauge.** Ranges and odometry are unchanged if the whole scene moves or turns: three free
# directions. The prior on the first pose (what GTSAM users write where chapter 2 fixed a pose) removes
# them, so nothing is fixed and Gauss-Newton or Levenberg-Marquardt sees a definite $H$.
#
# **Against GTSAM's own factors.** The same graph, from the same start, in GTSAM's native C++ factors:
# `PriorFactorPose2`, `BetweenFactorPose2`, `RangeFactor2D` (a `Pose2` to a `Point2`), with
# `noiseModel.Gaussian.Information` of our information (`course.backends.factorgraph.gtsam_native`). Its
# pose errors are SE(2)'s log map, ours chapter 2's edge error: the two agree to first order and differ
# by second-order terms, so the minima are a hair apart; both solutions are scored by our $\chi^2$, which
# ours minimises, so ours ends at GTSAM's or below. The times are the solves alone, the faster of three.

# %% id="range-only"
ranging = chapter7.range_only()  # seed=4; try range_only(seed=2, survey_sigma=1.0) (question 6)
range_runs = None
with todo_as_one_line():
    range_runs = chapter7.range_only_runs(ranging, IMPL)
    print(chapter7.range_only_table(ranging, range_runs))

# %% [markdown] id="questions-md"
# ## Questions
#
# Answer from the runs and figures of this notebook (in the quick setting, intel).
#
# **Question 1.** Read the smallest error of forward and of central differences, and the step where each
# is reached, off the figure of section 2. Derive both optimal steps and errors from the two error terms,
# with the constants, and compare. Then run `chapter7.step_study(IMPL, shift=1000.0)` (the same edge, its
# poses moved 1000 m along x and y): which term changes, by how much should the best errors grow, and what
# happens to your Jets' error?
#
# **Question 2.** `jetmath.so3_exp` switches to the series below $t = 10^{-5}$, but the right panel of
# section 3's figure shows the closed form's derivative of $b$ losing all its digits near $t = 10^{-4}$.
# How large can the resulting error in $\partial\,\mathrm{Exp} / \partial \phi$ be just above the switch
# ($b$ multiplies $[\phi]_\times^2$)? Where in this course do Jets meet $\mathrm{Exp}$ at a small angle that
# is not 0? Where would you put the switch for Jets, and how many terms of the series would it need?
#
# **Question 3.** In the benchmark, how much longer does one linearisation with Jets take than the
# analytic one on intel? A Jet of the SE(2) edge carries $k = 6$ derivatives beside each value: if every
# operation cost $k + 1$ times as much, what ratio would you expect, and why is the measured one
# different? What would central differences cost in residual evaluations, and why is `ours-numeric` not
# that much slower?
#
# **Question 4.** The SE(2) retraction here is plain addition; chapter 6 moved SE(3) poses on the right.
# Suppose SE(2) poses were moved on the right too, $(t + R(\theta)\rho,\ \theta + \varphi)$. How do the
# tangent Jacobians change (the chain rule)? Does Gauss-Newton take different steps, and does it end at
# another minimum? Does Levenberg-Marquardt with Nielsen's $\lambda I$, and with Marquardt's
# $\lambda\, \mathrm{diag}(H)$?
#
# **Question 5.** The drive of experiment 4 has no fixed pose, yet Gauss-Newton solves it; chapter 2's
# graphs needed one. Why? How many fixes does the drive need at the least, and what goes wrong with one?
# Compare the solution's distance from the truth with the odometry's and with the fixes' own noise.
#
# **Question 6.** In experiment 5, how many iterations and how much time did ours and GTSAM take, and why
# can the two minima differ at all when both graphs hold the same measurements? Run
# `chapter7.range_only(seed=2, survey_sigma=1.0)` through `chapter7.range_only_runs`: where does each end,
# and what does the beacons' error say happened? Why does a range factor's Jacobian have a zero column for
# the heading, and which factors make the heading observable?

# %% [markdown] tags=["answer"] id="answer-1"
# *Your answer to question 1.*

# %% [markdown] tags=["answer"] id="answer-2"
# *Your answer to question 2.*

# %% [markdown] tags=["answer"] id="answer-3"
# *Your answer to question 3.*

# %% [markdown] tags=["answer"] id="answer-4"
# *Your answer to question 4.*

# %% [markdown] tags=["answer"] id="answer-5"
# *Your answer to question 5.*

# %% [markdown] tags=["answer"] id="answer-6"
# *Your answer to question 6.*
