# %% [markdown] id="title"
# # Chapter 3b: where the solve starts
#
# Gauss-Newton (and every other local method) converges, at best, to the minimum whose
# basin holds its start. Chapters 2 and 3 started every solve from the poses in the file,
# which compose the odometry: their drift grows along the whole trajectory, and on mit
# (chi2 4.4e9 at the start) Gauss-Newton ends in a local minimum. This chapter computes
# two other starts (your `exercises/initialisation.py`). It is a lesson in this order:
#
# 1. **Theory**, derived: why the start matters (the cost is non-convex through the rotations
#    alone); the spanning-tree start, composing the measurements along a breadth-first tree
#    (exercise `initialisation.spanning_tree_poses`); the chordal relaxation of the rotations, a
#    linear least-squares problem, and the projection back to rotations
#    (`initialisation.chordal_rotations`); the translations given the rotations, a second linear
#    problem (`initialisation.chordal_translations`). Cells `check("...")` grade your
#    `initialisation.py` here, with the same sandboxed judge and public checks as
#    `python -m autograder --only initialisation`.
# 2. **Experiments**: the basin of convergence on mit, from the file's poses and from the chordal
#    start; every start (file, tree, chordal) on every public graph with our Gauss-Newton,
#    Levenberg-Marquardt (type 3) and dogleg; the time to solution, the initialisation included,
#    against g2o and GTSAM from the file's poses.
# 3. **Written questions.**
#
# Stuck on a derivation? `hint("chordal_rotations", 1)` (or `python -m autograder hint NAME
# LEVEL`) gives the approach, level 2 the key identity, level 3 the result.
#
# Conventions, as in chapter 2: a pose is $x_i = (t_i, \theta_i)$, $R_i = R(\theta_i)$; the edge
# from $i$ to $j$ measures $z_{ij} = (t_{ij}, \theta_{ij})$, pose $j$ seen from pose $i$, with error
#
# $$e_{ij} = \begin{pmatrix} R_{ij}^\top \big(R_i^\top (t_j - t_i) - t_{ij}\big) \\
# \mathrm{wrap}(\theta_j - \theta_i - \theta_{ij}) \end{pmatrix},
# \qquad \chi^2 = \sum_k e_k^\top \Omega_k\, e_k ;$$
#
# angles are wrapped to $[-\pi, \pi)$, and one pose, the anchor, is held at its file pose (the gauge).
# `SMALL = True` (set by `python -m notebooks.build --execute --small`, and by the tests) runs the
# experiments' quick setting on generated graphs (`manhattan:N`, and `w100` where gtsam brings it);
# the theory's figures use `manhattan:200` in both settings. Set `IMPL = "exercises"` to run your
# own initialisers through all of it.

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
from course.app.starts import INITIALISERS
from course.notebook_helpers import chapter3b
from course.notebook_helpers.common import (
    basin_figure,
    initialiser_table,
    load,
    not_run_note,
    time_to_solution_table,
)
from course.problems.posegraph import dataset as datasets

# "solutions", "exercises" or a path to your own copy (python -m notebooks.build --impl sets it);
# by default this tree's own: "exercises" in a student tree
IMPL = os.environ.get("COURSE_IMPL") or (
    "solutions" if (root / "solutions" / "__init__.py").is_file() else "exercises")
# runs per (back end, method); the tables keep the median-time run (--small sets 1)
REPEAT = int(os.environ.get("COURSE_NOTEBOOK_REPEAT", "5"))
# 1: the quick setting (small graphs; the tests run it, --small sets it); else the full one
SMALL = os.environ.get("COURSE_NOTEBOOK_SMALL", "0") == "1"

# %% [markdown] id="why-md"
# ## 1. Why the start matters
#
# Look at where $\chi^2$ is nonlinear. Hold every orientation $\theta$ fixed: then $R_i$ and $R_{ij}$
# are constant matrices, the translation error $R_{ij}^\top R_i^\top (t_j - t_i) - R_{ij}^\top t_{ij}$
# is *affine* in the positions, the angle error does not involve them, and $\chi^2$ is a convex
# quadratic in the positions: one linear solve finds its minimum (section 4). All the nonlinearity
# enters through the rotations. Now turn one orientation $\theta_i$ with everything else fixed: the
# vector $R_i^\top (t_j - t_i)$ of each edge leaving $i$ goes round a circle, so its contribution to
# $\chi^2$ is a trigonometric polynomial in $\theta_i$ (terms in $\cos\theta_i$ and $\sin\theta_i$, and in
# $2\theta_i$ when $\Omega_{tt}$ is not a multiple of the identity), and the wrapped angle errors are
# periodic too: $\chi^2$ is $2\pi$-periodic in each orientation. A convex function of one variable
# that is periodic is constant, so $\chi^2$ is not convex: besides its minimum it can have other
# stationary points (local minima, saddles), and Gauss-Newton, which only sees the quadratic model
# at its current point, converges to the one whose basin holds its start.
#
# Which starts lie in the basin of the minimum? Odometry composes measurements: a heading error on
# one edge rotates every pose after it, and independent heading errors add up along the chain like
# a random walk (variance growing with the number of edges composed). Below, on `manhattan:200`, the
# minimum $x^\star$ is bent as dead reckoning with a constant gyro bias would bend it: each of the
# 199 relative headings along the chain turned by drift / 199, the last pose's heading off by the
# drift. Left: $\chi^2$ of each drifted start (grey; not a convex function of the drift), and where
# Gauss-Newton ends from it. Right: one start outside the basin, and the stationary point
# Gauss-Newton stops at, over the minimum.

# %% id="figure-drift"
drift = chapter3b.drift_basin(datasets.load_dataset("manhattan:200"), IMPL)  # needs chapter 2's pieces
if drift is not None:
    display(Image(plot.to_png(drift)))

# %% [markdown] id="drift-md"
# Gauss-Newton comes back to the minimum (759.354) from every drift in $[-3.53, 3.53]$ rad (up to
# 0.0178 rad per edge), and from larger drifts stops at $\chi^2$ between 5.42e+05 and 5.57e+06, where
# its steps no longer reduce the cost: the start decides the answer. A good initialiser puts every
# orientation close enough to the minimum's; the positions then follow (section 4).

# %% [markdown] id="tree-md"
# ## 2. The spanning-tree start
#
# A spanning tree of the graph (N poses, M edges) has N - 1 of its edges and joins the anchor to
# every pose by exactly one path. Set the anchor's pose, then every other pose from its parent in
# the tree, by the parent edge's measurement:
#
# $$x_v = x_u \oplus z_{uv} \qquad \text{where } (t, \theta) \oplus (t', \theta') =
# \big(t + R(\theta)\, t',\; \mathrm{wrap}(\theta + \theta')\big) .$$
#
# Then the relative pose of $x_v$ seen from $x_u$ is exactly $z_{uv}$, so that edge's error is
# zero: **the tree start satisfies its N - 1 tree edges exactly**, and its $\chi^2$ is carried by the
# M - N + 1 edges left out (the loop closures the tree does not use). An edge written in the other
# direction, $z_{vu}$ ($u$ seen from $v$), gives $x_v = x_u \oplus z_{vu}^{-1}$, with the inverse
# $z^{-1}$ the relative pose for which $z \oplus z^{-1} = (0, 0, 0)$: derive it from the composition
# above.
#
# **Which tree?** Each composition adds its measurement's noise, and, as in section 1, the heading
# error of a pose is the sum of the heading errors along its path: its variance grows with the number
# of edges on the path. A breadth-first search from the anchor reaches every pose through the fewest
# possible edges, for all poses at once: the smallest accumulated drift a tree allows. The file's
# poses are usually the depth-first tree along the odometry, where pose k sits k edges from the
# anchor.
#
# The figure: the file's poses of `manhattan:200` coloured by their place along the chain, and your
# tree start coloured by hops from the anchor, the edges it does not satisfy in red.

# %% id="figure-tree"
tree = chapter3b.tree_start(datasets.load_dataset("manhattan:200"), IMPL)
if tree is not None:
    display(Image(plot.to_png(tree)))

# %% id="hint-tree"
hint("spanning_tree_poses", 1)  # level 1, the approach; 2 gives the key identity, 3 the result

# %% id="check-tree"
check("initialisation.spanning_tree_poses")

# %% [markdown] id="chordal-md"
# ## 3. The chordal relaxation of the rotations
#
# A planar rotation is fixed by its first column:
#
# $$R(\theta) = \begin{pmatrix} c & -s \\ s & c \end{pmatrix}, \qquad
# v = R(\theta)\, e_1 = \begin{pmatrix} c \\ s \end{pmatrix}, \qquad c^2 + s^2 = 1 ,$$
#
# so the rotations are the points $v$ of the unit circle. The orientation part of an edge says
# $R_j = R_i R_{ij}$. Take the first column of both sides, and use that planar rotations commute
# ($R_i R_{ij} = R_{ij} R_i$): $v_j = R_i R_{ij} e_1 = R_{ij} R_i e_1 = R(\theta_{ij})\, v_i$. Measure the
# disagreement of an edge by
#
# $$|v_j - R(\theta_{ij})\, v_i|^2 = |v_j|^2 + |v_i|^2 - 2\, v_j^\top R(\theta_{ij}) v_i = 2 - 2\cos\phi,
# \qquad \phi = \mathrm{wrap}(\theta_j - \theta_i - \theta_{ij}),$$
#
# the squared length of the chord between two points of the circle at angle $\phi$ (hence *chordal*;
# the Frobenius distance $\lVert R_j - R_i R_{ij} \rVert_F^2$ is twice it). Near $\phi = 0$ it is
# $\phi^2$, the pose graph's own angle cost; for large errors it stays at most 4 (left panel below).
#
# On the circle the problem is as non-convex as before: the circle is not a convex set. The
# **relaxation** drops the constraint $|v_k| = 1$ and minimizes
#
# $$\sum_k w_k\, |v_j - R(\theta_{ij})\, v_i|^2 \qquad
# \text{over the free } v \in \mathbb{R}^2 \text{ of every pose but the anchor}, \quad w_k = \Omega_k[2, 2] .$$
#
# Each residual is now *linear* in the unknowns, so this is a linear least-squares problem: one
# sparse system of normal equations, no iteration, no start. The anchor's $v$ is held at
# $(\cos\theta_a, \sin\theta_a)$: without it $v = 0$ is a minimum, and every common rotation of all
# the $v$ another one (the gauge). Derive the Jacobians of one edge's residual with respect to $v_i$
# and $v_j$, the $2 \times 2$ blocks they add to the normal equations, and the elimination of the
# anchor: that is `chordal_rotations`.
#
# **The projection back.** The relaxed $v_k$ is not a unit vector. The nearest rotation: minimize
# $|u - v|^2 = 1 + |v|^2 - 2\, u^\top v$ over unit vectors $u$, i.e. maximize $u^\top v$, which by
# Cauchy-Schwarz is largest at $u = v / |v|$: $\theta_k = \mathrm{atan2}(s_k, c_k)$. Its length says how
# well the neighbours agree: one free orientation whose anchored neighbours each "vote" for a unit
# vector $R(\theta_{ij}) v_i$ is relaxed to a point inside the circle, near it when the votes agree and
# far inside when they disagree (middle and right panels); at $v = 0$ the angle is undetermined.

# %% id="figure-relaxation"
display(Image(plot.to_png(chapter3b.relaxation())))


# %% [markdown] id="jacobian-md"
# ### Check your Jacobians where you derive them
#
# Before assembling anything, check the Jacobians of one edge's relaxed residual
# $r(v_i, v_j) = v_j - R(\theta_{ij})\, v_i$ with `course.check_jacobian`: write the $J_i$ and $J_j$ you
# derived in `my_edge_jacobians` below (a function of $\theta_{ij}$) and run the cell. It compares
# them, entry by entry, with central differences of $r$ at a random $(v_i, v_j)$, and names the block
# of any wrong entry. The same function checks any Jacobian you derive:
# `check_jacobian(f, [x1, x2], J=[J1, J2], plus="se2")` moves poses as chapter 2 does.

# %% id="check-jacobian"
def my_edge_jacobians(theta_ij):
    """Your (J_i, J_j), (2, 2) each, of r = v_j - R(theta_ij) v_i."""
    raise NotImplementedError("TODO my_edge_jacobians: write the J_i and J_j you derived")


chapter3b.check_relaxed_jacobians(my_edge_jacobians)

# %% id="hint-rotations"
hint("chordal_rotations", 1)

# %% id="check-rotations"
check("initialisation.chordal_rotations")

# %% [markdown] id="translations-md"
# ## 4. The translations given the rotations
#
# With the orientations $\theta$ from the relaxation held fixed, the translation error of an edge,
#
# $$e_t = R_{ij}^\top \big(R_i^\top (t_j - t_i) - t_{ij}\big),$$
#
# is a constant matrix times $t_j - t_i$, minus a constant vector: affine in the positions. So
# $\sum_k e_{t,k}^\top\, \Omega_{tt,k}\, e_{t,k}$, with $\Omega_{tt}$ the translation block of the
# information, is a convex quadratic in the positions, and its minimum is one linear least-squares
# solve (the anchor's position held, the gauge of translations). It is the *exact* minimum over
# positions for these rotations: Gauss-Newton on this sub-problem would stop after one step.
# Derive it: pull the rotations out of $e_t$ so that each edge's term reads $r_k^\top W_k\, r_k$ with a
# residual $r_k$ in the world frame, $t_j - t_i$ minus a constant, and a $2 \times 2$ weight $W_k$; then
# assemble and solve the normal equations as for the rotations. That is `chordal_translations`.
#
# The cross terms $\Omega_k[:2, 2]$ between translation and rotation are ignored here: the rotations
# are fixed, and keeping them would pull the positions by the rotation errors left over from
# section 3 (the usual two-stage approximation). The chordal start is the pair (rotations,
# positions); the solver that follows sees the full information and corrects both.

# %% id="hint-translations"
hint("chordal_translations", 1)

# %% id="check-initialisation"
check("initialisation")

# %% [markdown] id="experiments-md"
# # Experiments
#
# This part runs:
#
# 1. the basin of convergence: mit from the file's poses and from the chordal start;
# 2. every start (file, tree, chordal) on every public graph, with our Gauss-Newton,
#    Levenberg-Marquardt (type 3) and dogleg;
# 3. the time to solution, the initialisation included, against g2o and GTSAM from the
#    file's poses.
#
# The full setting takes about a minute, most of it on `w10000`.

# %% [markdown] id="basin-md"
# ## The basin of convergence
#
# mit (808 poses, 827 edges: few loop closures to correct a long drift) from the file's
# poses and from the chordal start: each row shows the start (grey) and where our
# Gauss-Newton ends from it (blue). From the file it converges, by its own test, to a
# local minimum (chi2 about 770); from the chordal start, in a few iterations, to the
# lowest minimum any of our runs finds (about 41.16). Both are minima: what differs is
# the basin the start lies in. (Quick setting, or without the data folder:
# `manhattan:300`, where both starts reach the same minimum.)

# %% id="basin"
g = load("manhattan:300" if SMALL else "mit")
if g is None:
    g = datasets.load_dataset("manhattan:300")
    display(Markdown("**The data folder is missing here**: the generated `manhattan:300` stands in for "
                     "mit below; the figures in the text do not apply to it."))
starts = chapter3b.basin_starts(g, IMPL)  # {start: (poses, our Gauss-Newton's run)}, or None at a TODO
if starts is not None:
    display(Image(plot.to_png(basin_figure(starts, f"{g.name}: {g.num_poses} poses, {g.num_edges} edges"))))

# %% [markdown] id="table-md"
# ## Every initialiser on every public graph
#
# For each graph and each start (`file`, `tree`, `chordal`): the start's chi2, the
# initialisation's own time, and for our Gauss-Newton, Levenberg-Marquardt type 3 and
# dogleg the iterations (100: stopped at the limit), the final chi2 and `lowest`: whether
# it ends within 1e-6 (relative) of the lowest final chi2 of all nine runs on that graph.
# A low start chi2 is not the point: a start is good when it lies in the basin of that
# lowest minimum. Missing data files are skipped with the reason; a start or method whose
# exercise is not written yet is a line naming its TODO.

# %% id="table"
METHODS = ["gauss-newton", "lm-type3", "dogleg"]
names = ["manhattan:200", "w100"] if SMALL else ["intel", "intel-g2o", "m3500", "mit", "csail", "fr079", "w10000"]
tables = {}
for name in names:
    graph = load(name)
    if graph is None:
        continue
    tables[name] = [r for init in INITIALISERS for r in compare.run_posegraph(
        graph, impl=IMPL, methods=METHODS, backends=["ours"], init=init, unimplemented="row")]
print(initialiser_table(tables, METHODS))

# %% [markdown] id="time-md"
# ## Time to solution
#
# The chordal start costs two sparse factorizations of the size of the problem (the
# rotations: N-1 complex unknowns; the translations: 2(N-1), or N-1 with two right-hand
# sides when every $\Omega_{tt}$ is a multiple of the identity): on `w10000` about one
# Gauss-Newton iteration, on `m3500` (a cheaper iteration) two or three. It pays when it
# saves more iterations than it costs (the first iteration, which also computes the
# fill-reducing ordering, is never among those saved). Below, the time to solution
# (initialisation plus solve, `RunResult.total_seconds`) of our Gauss-Newton from the
# chordal start, against ours, g2o's and GTSAM's Gauss-Newton from the file's poses, on
# the larger graphs (quick setting: `manhattan:1000`). Each solve runs `min(REPEAT, 3)`
# times and keeps its median-time run (once on `w10000`); the initialisation is timed
# once. A peer not installed here is a row saying so.

# %% id="time"
for name in (["manhattan:1000"] if SMALL else ["m3500", "w10000"]):
    graph = load(name)
    if graph is None:
        continue
    repeat = min(REPEAT, 3) if graph.num_poses <= 5000 else 1
    runs = (compare.run_posegraph(graph, impl=IMPL, methods=["gauss-newton"], backends=["ours"],
                                  init="chordal", repeat=repeat, unimplemented="row")
            + compare.run_posegraph(graph, impl=IMPL, methods=["gauss-newton"],
                                    backends=["ours", "g2o", "gtsam"], init="file", repeat=repeat,
                                    unimplemented="row"))
    print(time_to_solution_table(runs, f"{name}: {graph.num_poses} poses, {graph.num_edges} edges, "
                                       f"time to solution{not_run_note(runs)}"))
    print()

# %% [markdown] id="questions-md"
# ## Written questions
#
# Answer in the cells below, in a few sentences each. Use the measurements above.
#
# **Question 1.** On mit the spanning-tree start (chi2 6.2e6) brings Gauss-Newton to the
# lowest minimum (41.16), where the file's poses (4.4e9) leave it at 770.66. On intel-g2o
# the tree start looks far worse than the file's (chi2 1.3e9 against 5.1e6), yet
# Gauss-Newton still converges from it to 215.830, as from the file. Why is the tree
# start good on mit and bad by chi2 on intel-g2o, and why does the start's chi2 say so
# little about where Gauss-Newton ends?
#
# **Question 2.** Why does relaxing the rotations (dropping $c^2 + s^2 = 1$) make the
# rotation problem linear, and why is the translation problem linear once the rotations
# are fixed? What does the relaxation give up, and on what kind of graph would you expect
# the chordal start to be poor?
#
# **Question 3.** In the figure of the relaxation (section 3), the relaxed $v$ has length 0.990 when
# the three votes spread over 0.4 rad and 0.602 when they spread over 2.8 rad; its projected angle
# is 0.7539 rad against the wrapped cost's minimum at 0.6399 rad, where with the closer votes it was
# 0.6059 against 0.6057. Why does disagreement shorten $v$, and why does the projection then move
# away from the wrapped cost's minimum (compare the two costs of the left panel for large errors)?
#
# **Question 4.** In the drift figure (section 1), Gauss-Newton returns to the minimum of
# `manhattan:200` from a drift of up to 3.53 rad spread over the 199 edges of its chain. Would a graph
# ten times as long, with the same heading error per edge, start in the basin? How does a
# breadth-first tree change the drift the farthest pose carries (the hops printed under the
# figure of section 2)?

# %% [markdown] tags=["answer"] id="answer-1"
# **Your answer to question 1:** *(double-click to edit)*

# %% [markdown] tags=["answer"] id="answer-2"
# **Your answer to question 2:** *(double-click to edit)*

# %% [markdown] tags=["answer"] id="answer-3"
# **Your answer to question 3:** *(double-click to edit)*

# %% [markdown] tags=["answer"] id="answer-4"
# **Your answer to question 4:** *(double-click to edit)*
