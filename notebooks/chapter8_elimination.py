# %% [markdown] id="title"
# # Chapter 8: elimination, orderings, the Bayes tree, marginal covariances and incremental smoothing
#
# Every back end so far solved $H\,\delta = -b$ by a sparse Cholesky factorization it did not look inside,
# and returned a point estimate only. This chapter opens the factorization: solving a linear factor graph
# is **eliminating its variables one at a time**, each leaving a conditional on the variables it touched
# and a new factor on them; the order of elimination decides how much fill the factor $R$ gets; and $R$,
# the square-root information, gives the **marginal covariances** (GTSAM's `Marginals`, Ceres'
# `Covariance`) without the dense inverse. Grouped into cliques, the conditionals form the **Bayes tree**,
# the data structure of GTSAM's incremental smoother iSAM2: a new measurement changes only the cliques on
# the paths from its variables to the root, and the smoother re-eliminates those alone. The chapter is a
# lesson in this order:
#
# 1. **Theory**, derived: eliminating one variable from its adjacent factors by QR or by completing the
#    square (exercise `elimination`), the Bayes net it leaves and the solution by back-substitution; the
#    elimination game, fill, the elimination tree and a greedy minimum-degree ordering (exercise
#    `orderings`); the Bayes tree's cliques (exercise `bayes_tree`); the covariance recursion on $R$'s
#    pattern (exercise `marginal_covariances`); what an update changes in the tree, fluid relinearisation
#    and the partial state update (exercise `incremental_update`). After each
#    exercise's theory, a cell `check("...")` grades it here, with the same sandboxed judge and public
#    checks as `python -m autograder --only ...`; before it, a cell checks your code where you work.
# 2. **Experiments**: the fill of intel (in the full setting also M3500) under four orderings, yours among
#    them; every pose's marginal covariance on intel by your recursion, against the dense inverse; intel fed
#    one pose per step to the smoother built on your pieces, against GTSAM's `ISAM2`.
# 3. **Written questions.**
#
# Stuck on a derivation? `hint("elimination", 1)` (or `python -m autograder hint NAME LEVEL` in a terminal)
# gives the approach, level 2 the key identity, level 3 the result.
#
# Conventions, everywhere in this chapter: a linear(ised) factor adds $\|A\,x - b\|^2$ to the cost,
# **whitened** (its noise folded into $A$ and $b$), with $x$ the stacked variables it touches; this is
# GTSAM's and the textbook's form (Dellaert and Kaess, *Factor Graphs for Robot Perception*, chapter 3).
# The Gauss-Newton step of the earlier chapters is the case $A = J$, $b = -r$. A variable $v$ has $d_v$
# unknowns; the information is $\Lambda = A^\top A$, the information vector $\eta = A^\top b$.

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

from IPython.display import Image, display

from autograder.lesson import check, hint
from course.app import plot
from course.core.errors import DatasetError
from course.notebook_helpers import chapter8
from course.notebook_helpers.chapter8 import todo_as_one_line

SMALL = os.environ.get("COURSE_NOTEBOOK_SMALL") == "1"
# "solutions", "exercises" or a path to your own copy (python -m notebooks.build --impl sets it);
# by default this tree's own: "exercises" in a student tree
IMPL = os.environ.get("COURSE_IMPL") or ("solutions" if (root / "solutions").is_dir() else "exercises")
GRAPHS = ["intel"] if SMALL else ["intel", "m3500"]
print(f"implementation: {IMPL}; graphs: {', '.join(GRAPHS)}")

# %% [markdown] id="eliminate-md"
# ## 1. Eliminating one variable (exercise `elimination`)
#
# Take a variable $x$ ($d_x$ unknowns) and the factors that touch it. Stack their rows: the columns of $x$
# form $A_x$ ($m \times d_x$), the columns of the other variables those factors touch, its **separator**
# $s$, form $A_s$ ($m \times d_s$), and their right-hand sides $b$ ($m$). Their part of the cost is
#
# $$f(x, s) = \|A_x x + A_s s - b\|^2 .$$
#
# No other factor involves $x$. So for any $s$ the best $x$ can be found from these rows alone, and the
# cost that is left, as a function of $s$, is a new factor on the separator: $x$ is **eliminated**.
# The aim is to split $f$ exactly into two sums of squares,
#
# $$f(x, s) = \|R\,x + S\,s - d\|^2 + \|A'\,s - b'\|^2 + c ,$$
#
# with $R$ ($d_x \times d_x$) upper triangular and invertible and $c \ge 0$ a constant. The first term is
# zero at $x = R^{-1}(d - S s)$ for every $s$: it is the **conditional** $p(x \mid s) \propto
# \exp(-\tfrac12 \|R x + S s - d\|^2)$, a Gaussian whose mean moves linearly with $s$. The second term
# is the new factor on $s$, and $c$ is the part of the cost no choice of $x$ and $s$ removes.
#
# **Two ways to the split.** An orthogonal $Q$ does not change a norm, $\|Q^\top v\| = \|v\|$, so
# $f$ is unchanged when the augmented matrix $[A_x \mid A_s \mid b]$ is replaced by $Q^\top$ times it.
# Choose $Q$ so that the first $d_x$ columns become upper triangular (a QR factorization, column by
# column), and read the split off the rows. Or complete the square in $x$: with $\Lambda = [A_x\
# A_s]^\top [A_x\ A_s]$ and $\eta = [A_x\ A_s]^\top b$, write $f$ as a quadratic in $x$ and $s$ and
# factor its $xx$ block. Both give the same conditional up to the signs of $R$'s rows (QR does not fix
# them); derive what $R$, $S$, $d$ and the new factor are in each, and what the new factor's information
# is (`exercises/elimination.py`). Mind the case where the separator's part is singular: with $m = d_x$ rows
# no information is left for $s$.

# %% id="hint-elimination"
hint("elimination", 1)  # level 1, the approach; 2 the key identity, 3 the result

# %% [markdown] id="elimination-check-md"
# **Check your elimination where you work.** The cell below takes a linear graph of three 2-vectors
# ($x_0$ with a prior, odometry $x_0$-$x_1$ and $x_1$-$x_2$, a loop $x_0$-$x_2$ and a one-row measurement of
# $x_2$), stacks the four factors that touch $x_0$ and eliminates it with your function. It then tests the
# split itself at five random points $(x, s)$: the difference between the two sides must be one constant
# $c \ge 0$, whatever $x$ and $s$ are; no reference answer is used.

# %% id="elimination-check"
with todo_as_one_line():
    elimination = chapter8.exercise("elimination", IMPL)
    chapter8.elimination_check(elimination)

# %% id="check-elimination"
check("elimination")

# %% [markdown] id="bayes-net-md"
# **Eliminating every variable.** After $x_0$ is gone its factors are replaced by the new one on its
# separator, and the graph is smaller by one variable; eliminate the next, and so on. What is left is a
# chain of conditionals, one per variable, each on variables eliminated later: a **Bayes net**,
#
# $$p(x_0, \dots, x_{n-1}) \propto \prod_v p(x_v \mid \mathrm{sep}(v)) .$$
#
# The last variable eliminated has an empty separator; its conditional is its marginal. Solving is then
# **back-substitution** in reverse order, $x_v = R_v^{-1}(d_v - S_v\,x_{\mathrm{sep}(v)})$. Stacked in the
# elimination order, the rows $[R_v\ S_v]$ are exactly the rows of the upper-triangular factor $R$ of
# $\Lambda = R^\top R$ (up to their signs): sparse Cholesky *is* variable elimination, a variable's block
# row holding its separator's columns. The cell below eliminates the small graph in two orders with your
# function and compares the back-substituted solution with numpy's dense least squares.

# %% id="bayes-net"
with todo_as_one_line():
    print(chapter8.bayes_net_table(elimination))

# %% [markdown] id="orderings-md"
# ## 2. Orderings and fill (exercise `orderings`)
#
# What an elimination does to the graph does not depend on the numbers. Eliminating $v$ replaces its
# factors by one factor on its separator: afterwards **every two variables of the separator share a
# factor**, and where they did not before, the graph gains an edge, a **fill** edge. The separators,
# and so the pattern of $R$ (variable $v$'s block row holds $\mathrm{sep}(v)$), are found by playing this
# **elimination game** on the graph alone; it is the symbolic analysis a sparse Cholesky does before it
# computes a number (CHOLMOD's `analyze`, GTSAM's `Ordering` and symbolic elimination).
#
# The parent of $v$ in the **elimination tree** is the variable of its separator eliminated first: the
# next variable whose elimination $v$'s new factor reaches. A root has an empty separator; a graph of
# several components has a root per component. The tree's height bounds how deep a change travels, and
# its shape is the skeleton of the Bayes tree to come.
#
# **The ordering decides the fill.** Eliminating a landmark seen from three poses joins the three poses
# (three fill edges at most); eliminating a pose first joins everything it saw. Finding the ordering with
# the least fill is NP-hard; the greedy **minimum degree** rule eliminates, at each step, the variable
# with the fewest neighbours in the current graph (fill included), so that the clique it leaves is small.
# AMD and COLAMD (SuiteSparse: what CHOLMOD, g2o, Ceres and GTSAM use) are approximate, much faster forms of
# the same rule. Write both functions (`exercises/orderings.py`): the elimination game under a given
# ordering, and the greedy minimum degree, ties to the smallest index.

# %% id="hint-orderings"
hint("symbolic_elimination", 1)  # and hint("minimum_degree_ordering", 1)

# %% [markdown] id="game-md"
# **The elimination game, seen.** Six poses around a loop and two landmarks, each seen from three poses;
# on the left in the natural order (the poses first), on the right in your minimum-degree order. Each
# node shows its index and, after `#`, when it is eliminated; the dashed red edges are your fill.

# %% id="figure-game"
with todo_as_one_line():
    orderings = chapter8.exercise("orderings", IMPL)
    display(Image(plot.to_png(chapter8.game_figure(orderings))))

# %% id="check-orderings"
check("orderings")

# %% [markdown] id="bayes-tree-md"
# ## 3. The Bayes tree (exercise `bayes_tree`)
#
# The Bayes net of section 1 has one conditional per variable, $p(x_v \mid \mathrm{sep}(v))$. Many of them
# belong together: when $v$'s separator is exactly the variables of the conditional it points to (that
# one's frontal variables and its separator), the two are one joint conditional on a smaller set, a
# **clique**. The **Bayes tree** groups the conditionals into such cliques, a clique $p(F \mid S)$ holding
# its *frontal* variables $F$ and its *separator* $S$, each clique's separator inside its parent's variables
# (the *running intersection*). It is the form GTSAM's `ISAM2` keeps: a new measurement changes only the
# cliques on the paths from the variables it touches to the root, so an incremental update re-eliminates
# that top of the tree alone.
#
# Build it from the conditionals in **reverse** elimination order (Kaess et al., iSAM2, 2012, Algorithm 2):
# a conditional with an empty separator starts a root; otherwise take the clique holding its separator's
# first-eliminated variable as a frontal, and either add the conditional to it (when the separator is
# that clique's frontals and separator, exactly) or hang a new clique under it. Work out why the first
# eliminated separator variable is the right parent, why equality (not inclusion) is the test, and what
# a clique's separator is when it holds several frontals (`exercises/bayes_tree.py`).

# %% id="hint-bayes-tree"
hint("bayes_tree", 1)

# %% [markdown] id="bayes-tree-check-md"
# **Check your Bayes tree where you work.** The cell below eliminates the elimination game's graph in your
# minimum-degree order, builds the tree with your `bayes_tree`, prints each clique as `frontals :
# separator` indented under its parent, and tests what every Bayes tree satisfies.

# %% id="bayes-tree-check"
with todo_as_one_line():
    bayes = chapter8.exercise("bayes_tree", IMPL)
    chapter8.bayes_tree_check(orderings, bayes)

# %% id="check-bayes-tree"
check("bayes_tree")

# %% [markdown] id="marginals-md"
# ## 4. Marginal covariances (exercise `marginal_covariances`)
#
# The estimate's covariance is $\Sigma = \Lambda^{-1}$, and a variable's **marginal** covariance is its
# diagonal block $\Sigma_{vv}$: what gating a loop closure, planning or reporting an uncertainty needs.
# Note that $(\Lambda_{vv})^{-1}$ is *not* it: that is the covariance of $v$ with every other variable
# held at its estimate (the conditional), far too small on a long trajectory. The dense inverse costs
# $O(n^3)$ time and $O(n^2)$ memory; the square-root information $R$ ($\Lambda = R^\top R$) gives the
# blocks at the cost of the factorization.
#
# From $\Sigma = R^{-1} R^{-\top}$: $R\,\Sigma = R^{-\top}$. The right side is lower triangular with the
# diagonal $1 / R_{ii}$. Read row $i$ of this identity in the columns $j \ge i$, and derive a recursion
# for $\Sigma_{ij}$ from the entries $\Sigma_{kj}$ with $k > i$, run from the last row up. Which entries
# $\Sigma_{kj}$ does row $i$ need, if $R$'s row $i$ holds only the entries of $i$'s separator? Show that
# they lie in $R$'s pattern again when that pattern is a Cholesky factor's (fill included), so that the
# recursion never leaves it: computing $\Sigma$ on $R$'s pattern alone gives every marginal
# (Golub and Plemmons; Kaess and Dellaert's covariance recovery, which GTSAM's `Marginals` builds on).
# For the joint marginal of a few variables, solve for their columns of $\Sigma$ only. Write both
# (`exercises/marginal_covariances.py`).

# %% id="hint-marginals"
hint("marginal_covariances", 1)

# %% [markdown] id="marginals-check-md"
# **Check your recursion where you work.** The cell below solves a generated Manhattan world of 150 poses
# (chapter 2's problem, Gauss-Newton from the file's poses), linearises at the solution (the first pose
# held still), factors $\Lambda$ in your minimum-degree order with $R$ stored on your symbolic pattern, and
# compares your marginal of every pose with the same block of the dense inverse.

# %% id="marginals-check"
with todo_as_one_line():
    marginal_covariances = chapter8.exercise("marginal_covariances", IMPL)
    small_info = chapter8.pose_graph_information("manhattan:150", IMPL)
    print(chapter8.marginals_line(chapter8.marginals_run(small_info, orderings, marginal_covariances)))

# %% id="check-marginals"
check("marginal_covariances")

# %% [markdown] id="incremental-md"
# ## 5. The incremental update (exercise `incremental_update`)
#
# A robot adds a pose and a few measurements every step, and needs the estimate now. Solving from
# scratch each time repeats all the work; iSAM2 (Kaess et al., IJRR 2012) changes only the part of the
# Bayes tree that the new information reaches. Derive which part that is.
#
# A clique's conditional $p(F \mid S)$ came from eliminating its frontals: it summarises the factors whose
# first-eliminated variable is one of its frontals, and the new factors its children passed up on their
# separators. A new factor on the keys $K$ would have been eliminated with the first-eliminated of $K$: which
# clique's conditional changes, and why does its parent's change too? Conclude that an update re-eliminates
# the **top**: the cliques holding a new key as a frontal and everything on their paths to the root. Below
# the top hang the **orphans**, subtrees that did not change: each one enters the re-elimination as the
# factor it passed up on its separator (cached when it was eliminated), and after it, hangs from the new
# clique that its own conditional would join by the rule of section 3 (its separator's first-eliminated
# member, in the *new* ordering).
#
# **Fluid relinearisation.** The tree is linear: each factor was linearised at a point $\bar x$, and the
# tree's solution is a step $\delta$ from it. While a variable's step is small the linearisation is good;
# once its largest entry passes a threshold (GTSAM's `relinearizeThreshold`, 0.01 by default), the variable
# takes its step into its linearisation point and every factor on it is linearised again. Which cliques does
# that change? Not only those holding the variable as a frontal: a factor on it may have been eliminated
# earlier, in a clique that holds the variable in its separator.
#
# **The partial state update.** Back-substitution solves $R\,\delta_F = d - S\,\delta_S$ from the roots down.
# A replaced clique has a new conditional and must be solved; any other clique's answer changes only if its
# separator's steps did. Show that when a clique is not solved again, none of its descendants needs to be
# (a child's separator lies within its parent's variables), so the update can stop there: iSAM2's
# "wildfire", which stops where the change is below a second threshold. Write the four pieces
# (`exercises/incremental_update.py`): `relinearised_keys`, `affected_cliques`, `orphan_parents` and
# `wildfire_update`.

# %% id="hint-incremental"
hint("affected_cliques", 1)

# %% [markdown] id="incremental-check-md"
# **Check your update where you work.** The first cell applies your `affected_cliques` to the Bayes tree of
# section 3 for three kinds of news (a measurement between recent poses, a loop closure, a relinearised pose)
# and tests what the contract states of a top; the second runs your `wildfire_update` on the same tree with
# random conditionals and tests that every recomputed clique satisfies its conditional and every other keeps
# its step.

# %% id="incremental-check"
with todo_as_one_line():
    incremental = chapter8.exercise("incremental_update", IMPL)
    chapter8.affected_check(orderings, bayes, incremental)
    chapter8.wildfire_check(orderings, bayes, incremental)

# %% id="check-incremental"
check("incremental_update")

# %% [markdown] id="experiments-md"
# ## 6. Experiments
#
# Your orderings on real graphs, every pose's marginal covariance on intel, and intel online.

# %% [markdown] id="fill-md"
# **On real graphs.** The table eliminates intel (and M3500 in the full setting) under the natural
# order, your minimum degree, reverse Cuthill-McKee (scipy: it makes the matrix banded, not sparse) and
# AMD (SuiteSparse through cvxopt, where installed), with your `symbolic_elimination` in every row: the
# fill edges, the largest separator, the elimination tree's height, and the nonzeros of $R$ for poses of
# 3 unknowns ($6$ on a diagonal block, $9$ per separator pose). The time is the ordering's alone.

# %% id="fill-table"
with todo_as_one_line():
    try:
        print(chapter8.ordering_table(orderings, GRAPHS))
    except DatasetError as exc:
        print(f"not run: {exc}")

# %% [markdown] id="marginals-intel-md"
# **Marginals on intel.** The same run as the check of section 4 on intel (729 poses): your recursion on
# $R$ against the dense inverse, both timed.

# %% id="marginals-intel"
info = run = None
with todo_as_one_line():
    try:
        info = chapter8.pose_graph_information("intel", IMPL)
        run = chapter8.marginals_run(info, orderings, marginal_covariances)
        print(chapter8.marginals_line(run))
    except DatasetError as exc:
        print(f"not run: {exc}")

# %% [markdown] id="ellipses-md"
# **The uncertainty, seen.** Every tenth pose's position marginal as its 3-sigma ellipse, relative to the
# first pose (held still). Look at where the ellipses grow and where a loop closure shrinks them.

# %% id="figure-ellipses"
if run is not None:
    display(Image(plot.to_png(chapter8.ellipse_figure(info, run["covariances"]))))

# %% [markdown] id="online-md"
# **Online, one pose per step.** Intel (its first 300 poses in the quick setting) fed to the smoother built on
# your five pieces (`course/incremental`: your `elimination` for each group of small cliques, each clique's
# conditional its rows of the call's $R$, your `orderings` and `bayes_tree` for the top's new structure, your
# `incremental_update` for the rest), to GTSAM's `ISAM2` with
# the same relinearisation threshold (0.01, checked every step), and to batch re-solves of the graph so far
# every K steps. Each method starts a new pose from the odometry composed onto its own estimate of the last
# one. The table gives the time per step, the variables relinearised and re-eliminated per step, and the
# final chi2 against the batch minimum; the figure the time of every step. Look for the loop closures.

# %% id="online"
online_result = None
with todo_as_one_line():
    try:
        online_result = chapter8.online_run("intel", IMPL, poses=300 if SMALL else None)
        print(chapter8.online_table(online_result))
    except DatasetError as exc:
        print(f"not run: {exc}")

# %% id="figure-online"
if online_result is not None:
    display(Image(plot.to_png(chapter8.online_figure(online_result))))

# %% [markdown] id="questions-md"
# ## Questions
#
# Answer from the runs and figures of this notebook (in the quick setting, intel).
#
# **Question 1.** In the small graph of section 1, how many rows does the new factor left by eliminating
# $x_0$ have with QR, and how many with the Cholesky route? What is the constant $c$ in each, and why is it
# 0 here? Give a graph in which eliminating a variable leaves no information at all on its separator.
#
# **Question 2.** In the elimination game, why does eliminating a landmark first cost at most three fill
# edges here, while eliminating pose 0 first joins its neighbours? Count the nonzeros of $R$ (in blocks)
# for both orderings of the figure from the separators, and say which ordering a bundle adjustment
# problem's Schur complement (chapter 4) corresponds to.
#
# **Question 3.** In the table of section 2, compare the fill of the natural order with the minimum
# degree's and AMD's on intel. Why is the natural order of a trajectory so much worse here than on a
# simple chain? Why does reverse Cuthill-McKee have less fill than the natural order but more than minimum
# degree? How does the time of your minimum degree compare with AMD's, and why?
#
# **Question 4.** How much longer did the dense inverse take than your recursion on intel? How do both
# grow with the number of poses on a graph like M3500 ($n = 3500$)? Which pose has the largest ellipse,
# and why is it not the last one?
#
# **Question 5.** Read the Bayes tree of section 3 (the game's graph in your minimum-degree order). A new
# measurement between poses 4 and 5 arrives: which cliques does it change (the paths from the cliques
# holding its variables as frontals to the root)? And one between poses 0 and 3? Which variables would an
# incremental update re-eliminate in each case, and why does iSAM2 order the newest variables last?
#
# **Question 6.** In the online table of section 6, how many variables does each smoother relinearise and
# re-eliminate per step, on average, and how does that compare with the number of poses? Where in the
# figure are the slowest steps, and what happened at them (look at the dataset's loop closures)? Compare the
# final chi2 of both smoothers with the batch minimum, and say why neither is at it until the last update is
# iterated. Our smoother is written in Python on top of your functions, GTSAM's in C++: where does the time
# of one of our steps go, and which of your functions is called once per clique?

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
