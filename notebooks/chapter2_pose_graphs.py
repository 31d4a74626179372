# %% [markdown] id="title"
# # Chapter 2: 2D pose graphs, Gauss-Newton and the sparse solve
#
# A pose graph has poses $x_i = (t_i, \theta_i)$ and edges $(i, j)$ that measure pose $j$
# in the frame of pose $i$: $z_{ij} = (t_{ij}, \theta_{ij})$ with information
# $\Omega_{ij}$. Gauss-Newton computes every edge's error with its Jacobians, assembles the
# normal equations of the whole graph, solves them and moves the poses. This chapter builds that
# iteration piece by piece, then makes it fast: the solve sparse, the edges vectorised. The
# chapter is a lesson in this order:
#
# 1. **Theory**, derived: the SE(2) edge error and the chain rule to its Jacobians (exercise
#    `pose_graph_edge`); Gauss-Newton on a graph, the blocks of J and H, and the gauge freedom
#    (exercise `pose_graph_assembly`); Cholesky, fill-in and the sparse solve (exercise
#    `sparse_solve`); the whitened residual a Ceres cost function returns (exercise
#    `ceres_edge_cost`); all edges at once, assembled into a pattern found once (exercise
#    `pose_graph_fast`). After each exercise's theory, a cell `check("...")` grades it here, with the
#    same sandboxed judge and public checks as `python -m autograder --only ...`; where you derive a
#    Jacobian, a cell first shows you how to check it yourself with `course.check_jacobian`.
# 2. **Experiments**: Gauss-Newton on intel; the dense against the sparse solve, on intel and as the
#    graph grows; every method and back end on every named dataset, and who converges on mit; where
#    the time of an iteration goes.
# 3. **Written questions.**
#
# Stuck on a derivation? `hint("edge_error_and_jacobians", 1)` (or `python -m autograder hint
# NAME LEVEL` in a terminal) gives the approach, level 2 the key identity, level 3 the result.
#
# Conventions, everywhere in this chapter: a pose maps body to world, $p_w = R(\theta)\, p_b + t$,
# with $R(\theta) = \begin{bmatrix} \cos\theta & -\sin\theta \\ \sin\theta & \cos\theta \end{bmatrix}$;
# a pose is moved by plain addition of a step $(\Delta x, \Delta y, \Delta\theta)$, the angle
# wrapped to $[-\pi, \pi)$; pose $p$ owns rows and columns $3p, 3p+1, 3p+2$ of $H$ and $b$; an edge
# adds $e^\top \Omega e$ to $\chi^2$, $H = J^\top \Omega J$, $b = J^\top \Omega e$, and the step solves
# $H \Delta x = -b$ (as in chapter 1).
#
# `SMALL = True` (set by `python -m notebooks.build --execute --small`, and by the tests)
# runs the quick setting: the scaling up to 200 poses and the table on `w100` and
# `manhattan:200` only. The full setting (`make notebooks`) takes a few minutes, most of
# it on `w10000`. Set `IMPL = "exercises"` to run your own code through all of it.

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
from IPython.display import Image, Markdown, display

from autograder.lesson import check, hint
from course import check_jacobian
from course.app import benchmark, compare, plot
from course.notebook_helpers import chapter2
from course.notebook_helpers.common import load, median_time, one_thread, outcome, ran, time_split, where
from course.problems.posegraph import dataset as datasets
from course.problems.posegraph.problem import PoseGraphProblem
from course.solver import minimize

# "solutions", "exercises" or a path to your own copy (python -m notebooks.build --impl sets it);
# by default this tree's own: "exercises" in a student tree
IMPL = os.environ.get("COURSE_IMPL") or (
    "solutions" if (root / "solutions" / "__init__.py").is_file() else "exercises")
# runs per (back end, method); the table keeps the median-time run (--small sets 1)
REPEAT = int(os.environ.get("COURSE_NOTEBOOK_REPEAT", "5"))
# 1: the quick setting (small graphs; the tests run it, --small sets it); else the full one
SMALL = os.environ.get("COURSE_NOTEBOOK_SMALL", "0") == "1"
print(f"implementation: {IMPL}; setting: {'quick' if SMALL else 'full'}")

# %% [markdown] id="edge-md"
# ## 1. The edge error and its Jacobians
#
# **Poses as rigid motions.** The pose $x = (t, \theta)$ maps a point from the robot's (body) frame
# to the world, $p_w = R(\theta)\, p_b + t$. Applying $x_b$ first and then $x_a$ gives the
# composition, and solving $p_w = R p_b + t$ for $p_b$ gives the inverse:
#
# $$x_a \circ x_b = \big(t_a + R_a t_b,\ \theta_a + \theta_b\big), \qquad
#   x^{-1} = \big(-R^\top t,\ -\theta\big) .$$
#
# (In 2D, $R(\alpha) R(\beta) = R(\alpha + \beta)$: rotations compose by adding their angles, in
# either order.) Pose $j$ seen from pose $i$ is $x_i^{-1} \circ x_j = \big(R_i^\top (t_j - t_i),\
# \theta_j - \theta_i\big)$, and that is what an edge measures: $z_{ij} \approx x_i^{-1} \circ x_j$
# (odometry between consecutive poses, a scan match for a loop closure).
#
# **The error.** The measurement puts pose $j$ at $\hat x_j = x_i \circ z_{ij} = (t_i + R_i t_{ij},\
# \theta_i + \theta_{ij})$. The error is where pose $j$ really is, seen from that prediction:
#
# $$e_{ij} = \hat x_j^{-1} \circ x_j = \Big(R(\theta_i + \theta_{ij})^\top \big(t_j - t_i - R_i t_{ij}\big),\
#   \theta_j - \theta_i - \theta_{ij}\Big) .$$
#
# Split the rotation, $R(\theta_i + \theta_{ij})^\top = R_{ij}^\top R_i^\top$, and use $R_i^\top R_i = I$
# on the last term:
#
# $$e_t = R_{ij}^\top \big(R_i^\top (t_j - t_i) - t_{ij}\big), \qquad
#   e_\theta = \mathrm{wrap}(\theta_j - \theta_i - \theta_{ij}) .$$
#
# $e_{ij} = 0$ exactly when pose $j$ is where the measurement puts it. The angles are defined up
# to $2\pi$, so the angle error is wrapped to $[-\pi, \pi)$: the smallest turn between the two
# headings. $e_t$ is the position error in the predicted pose's own axes: its rows mean "ahead" and
# "to the left", which is how the information $\Omega_{ij}$ of a scan match is expressed. In the
# figure, the red arrow is the translation error drawn in the world; $e_t$ is that arrow in the
# dashed pose's axes.

# %% id="figure-edge"
display(Image(plot.to_png(chapter2.edge_figure(*chapter2.example_edge()))))

# %% [markdown] id="update-md"
# ### 1.1 Why the poses are updated by plain addition here
#
# Gauss-Newton linearises the error, $e(x + \Delta x) \approx e(x) + J\,\Delta x$, so it needs a
# meaning for "$x + \Delta x$". For a 2D pose, $(x, y, \theta)$ are coordinates of the whole space of
# poses, $\mathbb{R}^2 \times S^1$: three numbers for three degrees of freedom, with no singular
# point. Adding $\Delta\theta$ to $\theta$ turns the pose by $\Delta\theta$, and because 2D rotations
# commute, $R(\theta + \Delta\theta) = R(\theta) R(\Delta\theta) = R(\Delta\theta) R(\theta)$: the turn
# is the same whether we think of it in the body's axes or in the world's. The only catch, the
# angle's period, is taken care of by wrapping after the update. So
#
# $$x \leftarrow x + \Delta x, \quad \theta \leftarrow \mathrm{wrap}(\theta)$$
#
# is a valid update, and the Jacobians are ordinary partial derivatives of $e$ by the six numbers
# $(x_i, y_i, \theta_i, x_j, y_j, \theta_j)$. (Moving the translation in the body's axes,
# $t \leftarrow t + R\,\Delta t$, as the exponential map of SE(2) does to first order, is just as
# valid: it gives other Jacobians, related to these by an invertible $3 \times 3$ matrix per pose,
# and the same minimum.) In 3D (chapter 6) none of this holds: rotations do not commute, three angles have
# singular points, and the update becomes $R\,\mathrm{Exp}(\phi)$.

# %% [markdown] id="chain-md"
# ### 1.2 The chain rule to the Jacobians
#
# Write the error as a function of the six coordinates, the measurement held constant:
#
# $$e_t = R_{ij}^\top R(\theta_i)^\top (t_j - t_i) - R_{ij}^\top t_{ij}, \qquad
#   e_\theta = \theta_j - \theta_i - \theta_{ij} - 2\pi k ,$$
#
# where the wrap subtracts $2\pi k$ with an integer $k$ that is constant except where the angle
# error crosses $\pm\pi$ (a set of measure zero: the derivative is taken away from it).
#
# * $e_t$ is **linear in $t_i$ and $t_j$**: a constant matrix times $t_j - t_i$. Its derivative by
#   $t_j$ is that matrix, by $t_i$ its negative.
# * $e_t$ does **not depend on $\theta_j$**, and $e_\theta$ not on $t_i$ or $t_j$.
# * $e_t$ depends on $\theta_i$ **only through $R(\theta_i)^\top$**. By the chain rule,
#
# $$\frac{\partial e_t}{\partial \theta_i}
#   = R_{ij}^\top \left[\frac{d R(\theta)^\top}{d\theta}\right]_{\theta_i} (t_j - t_i) .$$
#
# **The derivative of a rotation's transpose.** Differentiate $R(\theta)$ entry by entry:
#
# $$\frac{dR}{d\theta} = \begin{bmatrix} -\sin\theta & -\cos\theta \\ \cos\theta & -\sin\theta \end{bmatrix}
#   = R(\theta)\, S, \qquad S = \begin{bmatrix} 0 & -1 \\ 1 & 0 \end{bmatrix} = R(\pi/2) ,$$
#
# the rotation turned a quarter further. Transposing (the derivative of a transpose is the
# transpose of the derivative):
#
# $$\frac{d R^\top}{d\theta} = \Big(\frac{dR}{d\theta}\Big)^\top = S^\top R(\theta)^\top
#   = \begin{bmatrix} -\sin\theta & \cos\theta \\ -\cos\theta & -\sin\theta \end{bmatrix} .$$
#
# Read it geometrically: $S^\top v = (v_2, -v_1)$ turns $v$ by $-90°$. Turning pose $i$ by a small
# $d\theta$ turns every vector *seen from it* by $-d\theta$, so $R_i^\top (t_j - t_i)$ moves
# perpendicular to itself, at a rate equal to its length.
#
# **Your turn** (exercise `pose_graph_edge`): write $A_{ij} = \partial e_{ij} / \partial x_i$ and
# $B_{ij} = \partial e_{ij} / \partial x_j$, each $3 \times 3$ with rows $(e_t, e_\theta)$ and
# columns $(x, y, \theta)$ of the pose, from the pieces above: a $2 \times 2$ translation block, a
# $2 \times 1$ column for the angle, a $1 \times 2$ and a $1 \times 1$ block for the angle error.
# Then write `edge_error_and_jacobians` in `exercises/pose_graph_edge.py`.

# %% id="hint-edge"
hint("edge_error_and_jacobians", 1)  # level 1, the approach; 2 gives the key identity, 3 the result

# %% [markdown] id="checker-md"
# **Check where you work.** Before the grader, check your Jacobians against central differences of
# your own error with `course.check_jacobian`. Give it the function, the variables as a list (here
# the two poses, moved by plain addition: `plus="se2"`) and your Jacobians, one per variable; it
# moves each coordinate by $\pm 10^{-6}$, compares every entry and, when one is off, prints the
# worst entries and the block they sit in (which rows of $e$, which pose, translation or
# rotation). The second call shows what a slip looks like: one entry of $A$ changed by 0.1.

# %% id="jacobian-check"
x_i, x_j, z_ij = chapter2.example_edge()
with chapter2.todo_as_one_line():  # an unwritten exercise prints one line naming its TODO
    edge = chapter2.exercise("pose_graph_edge", IMPL).edge_error_and_jacobians
    e, A, B = edge(x_i, x_j, z_ij)
    check_jacobian(lambda x_i, x_j: edge(x_i, x_j, z_ij)[0], [x_i, x_j], J=[A, B], plus="se2",
                   names=["x_i", "x_j"], rows="se2")
    slip = A.copy()
    slip[1, 2] += 0.1  # a slip in the angle's column of A
    check_jacobian(lambda x_i, x_j: edge(x_i, x_j, z_ij)[0], [x_i, x_j], J=[slip, B], plus="se2",
                   names=["x_i", "x_j"], rows="se2")

# %% id="check-edge"
check("pose_graph_edge")

# %% [markdown] id="assembly-md"
# ## 2. Gauss-Newton on a graph
#
# Stack the $N$ poses into $x \in \mathbb{R}^{3N}$ and the $M$ edge errors into $e \in \mathbb{R}^{3M}$;
# $\Omega = \mathrm{blockdiag}(\Omega_1, \dots, \Omega_M)$. The cost is
#
# $$\chi^2(x) = \sum_{k=1}^{M} e_k(x)^\top \Omega_k\, e_k(x) = e^\top \Omega e .$$
#
# Linearise every edge $k$ from pose $i$ to pose $j$ at once:
# $e_k(x + \Delta x) \approx e_k + A_k \Delta x_i + B_k \Delta x_j = e_k + J_k \Delta x$, with the
# block row
#
# $$J_k = \big[\, 0 \ \cdots\ 0 \ \ A_k \ \ 0 \ \cdots\ 0 \ \ B_k \ \ 0 \ \cdots\ 0 \,\big] \quad (3 \times 3N),$$
#
# $A_k$ in pose $i$'s three columns and $B_k$ in pose $j$'s. Exactly as in chapter 1, the
# linearised cost is a quadratic in $\Delta x$ whose minimiser solves $H \Delta x = -b$, now with
#
# $$H = J^\top \Omega J = \sum_k J_k^\top \Omega_k J_k, \qquad b = J^\top \Omega e = \sum_k J_k^\top \Omega_k e_k .$$
#
# **Which blocks one edge touches.** The $(p, q)$ block of $J_k^\top \Omega_k J_k$ is
# $J_k[:, p]^\top\, \Omega_k\, J_k[:, q]$, where $J_k[:, p]$ is block column $p$ of $J_k$: it is zero
# unless both $p$ and $q$ are $i$ or $j$. So one edge adds to **four** $3 \times 3$ blocks of $H$,
# $(i, i)$, $(i, j)$, $(j, i)$, $(j, j)$, and to **two** 3-blocks of $b$, $i$ and $j$; what it adds
# to each is the exercise (multiply out the block products). Summed over the edges,
# $H_{pq} \neq 0$ only where $p = q$ or an edge joins $p$ and $q$: **the block pattern of $H$ is the
# graph's adjacency matrix plus the diagonal.** It depends on the edges alone, not on $x$: it is
# the same in every iteration. In the figure, the loop closure 12 (red) fills block row 12 of $J$
# at poses 1 and 9, and the blocks $(1,1)$, $(1,9)$, $(9,1)$, $(9,9)$ of $H$.

# %% id="figure-blocks"
display(Image(plot.to_png(chapter2.block_structure_figure(datasets.load_dataset("manhattan:12"), edge=12))))

# %% [markdown] id="gauge-md"
# ### 2.1 The gauge freedom: why one pose is fixed
#
# Every error compares two poses with each other: $e_{ij} = (x_i \circ z_{ij})^{-1} \circ x_j$.
# Move the whole graph by one rigid motion $g$, $x_p \leftarrow g \circ x_p$ for every pose $p$:
#
# $$(g \circ x_i \circ z_{ij})^{-1} \circ (g \circ x_j)
#   = (x_i \circ z_{ij})^{-1} \circ g^{-1} \circ g \circ x_j = e_{ij} .$$
#
# No error changes, so $\chi^2$ is constant along a three-parameter family of motions through every
# $x$. Differentiating along that family at $g = $ identity gives three directions $v$ with
# $J v = 0$. In our coordinates they are: along $x$, $v = (1, 0, 0,\ 1, 0, 0,\ \dots)$; along $y$,
# likewise; and the turn about the world's origin, $t_p \leftarrow R(\alpha) t_p$,
# $\theta_p \leftarrow \theta_p + \alpha$, whose derivative at $\alpha = 0$ is $(\,S t_p,\ 1) =
# (-y_p, x_p, 1)$ for every pose $p$ (the $S$ of section 1.2). Then $H v = J^\top \Omega J v = 0$:
# **$H$ is singular**, of rank at most $3N - 3$. The normal equations have infinitely many solutions
# (one step plus any rigid motion), and a Cholesky factorisation meets a zero pivot, or, after
# rounding, a tiny one that gives a huge step.
#
# **Fixing pose 0** means $\Delta x_0 = 0$: delete its three columns from $J$. What remains, $H'$
# (the rows and columns of the free poses), is positive definite when the graph is connected: a
# direction $v'$ with $J' v' = 0$ keeps every edge's relative pose to first order, so, edge by edge
# from pose 0 along paths of the graph, it moves every pose rigidly with pose 0, which does not
# move: $v' = 0$. The exercise keeps the $3N \times 3N$ layout instead of deleting: zero pose 0's
# rows and columns of $H$ and its entries of $b$, and put the identity on its diagonal block. Then
# $\Delta x_0 = 0$ and the other rows are exactly $H' \Delta x' = -b'$. Fixing a pose does not change
# the minimum of $\chi^2$, only chooses in which frame the answer is written: it **fixes the gauge**.
#
# The table moves `manhattan:30` along the three motions ($|J v|$ at the rounding level of the
# central differences, against about 2 for a random direction); the figure shows H's spectrum:
# three eigenvalues at rounding level with every pose free, none once pose 0 is fixed.

# %% id="figure-gauge"
gauge_graph = datasets.load_dataset("manhattan:30")
print(chapter2.gauge_table(gauge_graph))
display(Image(plot.to_png(chapter2.gauge_figure(gauge_graph))))

# %% [markdown] id="assembly-exercise-md"
# **Your turn** (exercise `pose_graph_assembly`): write `assemble_normal_equations` in
# `exercises/pose_graph_assembly.py`, a loop over the edges that adds each edge's blocks to a dense
# $H$ and $b$ (and its $e^\top \Omega e$ to $\chi^2$), then fixes the poses in `fixed`. Its check gives
# it reference edge errors and Jacobians, so it does not need your `pose_graph_edge` to be right.

# %% id="hint-assembly"
hint("assemble_normal_equations", 1)

# %% id="check-assembly"
check("pose_graph_assembly")

# %% [markdown] id="cholesky-md"
# ## 3. Solving $H \Delta x = -b$: Cholesky, fill-in and the sparse factorisation
#
# **Cholesky.** A symmetric positive definite $H$ factors as $H = L L^\top$ with $L$ lower
# triangular. Split off the first row and column and compare the two sides block by block:
#
# $$\begin{bmatrix} h_{11} & h^\top \\ h & H_{22} \end{bmatrix} =
#   \begin{bmatrix} l_{11} & 0 \\ l & L_{22} \end{bmatrix}
#   \begin{bmatrix} l_{11} & l^\top \\ 0 & L_{22}^\top \end{bmatrix}
#   = \begin{bmatrix} l_{11}^2 & l_{11} l^\top \\ l_{11} l & l l^\top + L_{22} L_{22}^\top \end{bmatrix} ,$$
#
# so $l_{11} = \sqrt{h_{11}}$, $l = h / l_{11}$, and $L_{22} L_{22}^\top = H_{22} - h h^\top / h_{11}$: the
# rest is the Cholesky factor of what is left after **eliminating** the first variable (the Schur
# complement, positive definite again). Repeat on it. Then $L y = -b$ (forward substitution) and
# $L^\top \Delta x = y$ (back substitution) give the step. For a dense $n \times n$ matrix this costs
# about $n^3/3$ operations, whatever its zeros.
# ($LDL^\top$ is the same with a unit-diagonal $L$ and a diagonal $D$: no square roots. qdldl
# computes it.)
#
# **Fill-in.** Eliminating variable $k$ subtracts $h h^\top / h_{kk}$: every pair of rows where
# column $k$ has entries gets an entry, zero in $H$ or not. On the graph: **eliminating a pose joins
# all its remaining neighbours to each other.** The entries of $L$ that $H$ does not have are the
# fill-in. The order of elimination decides it. A star (one hub joined to $n - 1$ leaves) makes it
# plain: hub first, and every pair of leaves is joined, $L$ is dense; hub last, and no leaf has a
# second neighbour when it goes, $L$ has no fill at all. In a pose graph eliminated in trajectory
# order, the odometry chain alone fills nothing (each pose has one later neighbour), but a loop
# closure from pose $a$ back to pose $c < a$ survives the elimination of $c$ as an entry between
# $c + 1$ and $a$, then $c + 2$ and $a$, and so on: every pose between $c$ and $a$ ends up joined to
# $a$. Fill-reducing
# orderings choose the order from the pattern: **minimum degree** eliminates, at each step, a node
# with the fewest neighbours (AMD approximates the degrees to do it fast); nested dissection splits
# the graph by small separators and eliminates the separators last. Finding the best order is
# NP-hard; these heuristics are good.
#
# **Symbolic once, numeric every iteration.** The pattern of $L$ depends only on the pattern of
# $H$ and the order, never on the values (the figure's patterns come from the edges alone). So a
# sparse factorisation has two phases: the **analysis** (the ordering; the elimination tree, whose
# parent of column $k$ is the first row below the diagonal of column $k$ of $L$; the pattern and
# the memory of $L$) and the **numeric factorisation** (the values). $H$'s pattern is fixed by the
# edges, so the analysis is done once and each iteration (and each damping $\lambda$ tried by LM)
# redoes only the numeric part, whose cost is about $\sum_k c_k^2$, $c_k$ the entries of column $k$
# of $L$ below its diagonal (the `flops` of the table).
#
# **Why CSC, and why the upper triangle.** Compressed sparse column storage keeps three arrays:
# `data` (the values, column after column), `indices` (the row of each value) and `indptr`
# (column $k$ is `data[indptr[k]:indptr[k+1]]`). A factorisation works a column (or a row) at a
# time, and CSC hands it one column as one contiguous slice. $H$ is symmetric, so half of it is all
# of it: storing both halves doubles the memory and the assembly's work, and lets the two halves
# disagree. qdldl reads the upper triangle, diagonal included, in CSC: column $k$ of the upper
# triangle is row $k$ of the lower one, exactly what its up-looking $LDL^\top$ needs to compute row
# $k$ of $L$. The pattern of a CSC matrix is its pair (`indptr`, `indices`), explicit zeros
# included: the analysis can be reused as long as that pair is the same.
#
# The figure factors the pattern of `manhattan:100` (whose loop closures join poses far apart in
# time): in file order $L$ has 28446 entries, ten times the 2634 of $H$'s upper triangle; in
# qdldl's AMD order, 6936. The table adds `manhattan:500` and intel (when the data folder is there).

# %% id="figure-fill-in"
fill_graphs = [datasets.load_dataset("manhattan:100"), datasets.load_dataset("manhattan:500")]
intel = load("intel")  # None (and a line saying why) without the data folder
print(chapter2.fill_in_table(fill_graphs + ([intel] if intel is not None else [])))
display(Image(plot.to_png(chapter2.fill_in_figure(fill_graphs[0]))))

# %% [markdown] id="sparse-exercise-md"
# **Your turn** (exercise `sparse_solve`, in `exercises/sparse_solve.py`): `dense_solve`, the dense
# Cholesky solve of section 3 (the reference point of the experiments); `upper_triangle_csc`, the
# upper triangle of a symmetric matrix as CSC; and `SparseCholeskySolver`, which runs qdldl's
# analysis on the first call and only its numeric factorisation on later calls with the same
# pattern, and analyses again when the pattern changes.

# %% id="hint-sparse"
hint("sparse_solve", 1)

# %% id="check-sparse"
check("sparse_solve")

# %% [markdown] id="ceres-md"
# ## 4. The whitened residual: one edge as Ceres takes it
#
# Ceres minimises $\tfrac{1}{2} \sum_k |f_k(x)|^2$, where $f_k$ is what a cost function returns for
# residual block $k$: it has no weights. Our terms are $e^\top \Omega e$. Factor the information,
# $\Omega = U^\top U$ (for example $U$ upper triangular, from the Cholesky factorisation
# $\Omega = L L^\top$ with $U = L^\top$; any square root works). Then
#
# $$e^\top \Omega e = e^\top U^\top U e = |U e|^2 ,$$
#
# so the residual $r = U e$ gives Ceres' cost $\tfrac{1}{2}\chi^2$ (Ceres reports half our $\chi^2$).
# It is called **whitened** because, when $e$ is Gaussian with covariance $\Sigma = \Omega^{-1}$, $U e$
# has covariance $U \Sigma U^\top = U (U^\top U)^{-1} U^\top = I$: unit-variance, uncorrelated residuals,
# which is what an unweighted least-squares solver assumes.
#
# **Its Jacobians.** $U$ is a constant, so by the chain rule
#
# $$\frac{\partial r}{\partial x_i} = U \frac{\partial e}{\partial x_i}, \qquad
#   \frac{\partial r}{\partial x_j} = U \frac{\partial e}{\partial x_j} ,$$
#
# and Gauss-Newton on $r$ builds $J_r^\top J_r = J^\top U^\top U J = J^\top \Omega J$ and
# $J_r^\top r = J^\top \Omega e$: the same $H$ and $b$ as section 2. Ceres solves the same normal
# equations (its LM adds damping).
#
# **The interface.** Ceres calls `Evaluate(parameters, residuals, jacobians)` with
# `parameters[0]` $= x_i$ and `parameters[1]` $= x_j$; you fill `residuals` (3 values) in place, and,
# unless `jacobians` is None (Ceres wants residuals only), each `jacobians[k]` that is not None
# (a constant block, such as the fixed pose, gets None) as a flat array of 9, row-major: entry
# $(r, c)$ at index $3r + c$. Return True. Ceres calls it from C++ once per edge and evaluation, so
# each call's Python overhead counts: write the arithmetic in scalars (`math.cos`, products of
# floats) rather than small numpy matrices, and remember that 2D rotations compose by adding angles.

# %% [markdown] id="ceres-checker-md"
# **Check where you work**: `cost.evaluate(x_i, x_j)` runs your `Evaluate` as Ceres does and returns
# the residuals and both Jacobians; compare $r$ with $U e$ from the definition, then the Jacobians
# with central differences of your residuals.

# %% id="ceres-jacobian-check"
with chapter2.todo_as_one_line():  # an unwritten exercise prints one line naming its TODO
    U = np.linalg.cholesky(np.diag([400.0, 100.0, 2500.0])).T  # Omega = U^T U
    cost = chapter2.exercise("ceres_edge_cost", IMPL).SE2EdgeCost(z_ij, U)
    r, (J_i, J_j) = cost.evaluate(x_i, x_j)
    print("your r:", np.round(np.ravel(r), 6), " U e from the definition:",
          np.round(U @ chapter2.edge_error(x_i, x_j, z_ij), 6))
    check_jacobian(lambda x_i, x_j: cost.evaluate(x_i, x_j)[0], [x_i, x_j], J=[J_i, J_j], plus="se2",
                   names=["x_i", "x_j"], rows="se2")

# %% [markdown] id="ceres-exercise-md"
# **Your turn** (exercise `ceres_edge_cost`): write `SE2EdgeCost` in `exercises/ceres_edge_cost.py`:
# in `__init__` keep what does not change between calls, in `Evaluate` the rest.

# %% id="hint-ceres"
hint("SE2EdgeCost", 1)

# %% id="check-ceres"
check("ceres_edge_cost")

# %% [markdown] id="fast-md"
# ## 5. All edges at once
#
# The per-edge loop of `pose_graph_assembly` pays the Python interpreter for every small operation
# of every edge, and allocates a dense $3N \times 3N$ matrix: on intel it is far slower than the same
# arithmetic done for all edges at once (the last experiment measures how much).
# Two changes make the linearisation fast:
#
# **Vectorise over the edges.** Gather the two poses of every edge, `poses[edges_i]` and
# `poses[edges_j]` ($M \times 3$ each), compute the cosines and sines once as arrays of $M$, and fill
# the errors ($M \times 3$) and the Jacobians ($M \times 3 \times 3$ stacks) entry by entry: each formula
# of section 1 becomes one numpy operation over all $M$ edges instead of $M$ Python operations.
#
# **Assemble into a pattern found once.** Edge $k$ contributes $J_k^\top \Omega_k J_k$ restricted to
# its two poses, the $6 \times 6$ matrix $[A_k\ B_k]^\top \Omega_k [A_k\ B_k]$. It is symmetric: its 21
# entries on and above the diagonal say everything. Entry $(a, c)$ of it lands in $H$ at the global
# row and column $(d_a, d_c)$, with $d = (3i, 3i+1, 3i+2, 3j, 3j+1, 3j+2)$, and belongs to the upper
# triangle only if $d_a \le d_c$; where pose $i$ comes after pose $j$ it is stored at its mirror.
# **These positions depend on the edges alone** (section 2), so they are computed once, when the
# solver is built: the pattern of $H$ (the distinct positions, in CSC order) and, for each of the
# $21 M$ contributions, its slot in `H.data`. Each iteration then costs two batched products for the
# $6 \times 6$ blocks and one scatter-add of the $21 M$ values into their slots, in C: several edges share
# the diagonal blocks of a pose, so values that land in the same slot must add, as
# `np.bincount(slots, weights)` does (`np.bincount([0, 2, 0], [1.0, 2.0, 3.0])` is `[4, 0, 2]`), where
# a fancy-indexed `data[slots] += values` would keep only one of them.
#
# **Check where you work**: the checker takes stacks too. Below, edge $k$ of `manhattan:30` joins row
# $k$ of `X_i` to row $k$ of `X_j` (`chapter2.edges_apart` calls your function that way), so each
# edge's poses can be moved on their own; your `A` and `B`, $(M, 3, 3)$, are the diagonal blocks of
# the Jacobians by `X_i` and `X_j`.

# %% id="fast-jacobian-check"
fast_graph = datasets.load_dataset("manhattan:30")
X_i, X_j, Z = fast_graph.poses[fast_graph.edges_i], fast_graph.poses[fast_graph.edges_j], fast_graph.measurements
with chapter2.todo_as_one_line():  # an unwritten exercise prints one line naming its TODO
    errors_and_jacobians = chapter2.exercise("pose_graph_fast", IMPL).edge_errors_and_jacobians
    e, A, B = chapter2.edges_apart(errors_and_jacobians, X_i, X_j, Z)
    check_jacobian(lambda X_i, X_j: chapter2.edges_apart(errors_and_jacobians, X_i, X_j, Z)[0], [X_i, X_j],
                   J=[A, B], plus="se2", names=["X_i", "X_j"], rows="se2")

# %% [markdown] id="fast-exercise-md"
# **Your turn** (exercise `pose_graph_fast`, optional but it is what makes the experiments below
# fast): `edge_errors_and_jacobians`, the vectorised errors and Jacobians, and `SparseAssembler`, the
# pattern and slots in `__init__` and the scatter-add in `assemble`. The solver uses them when they
# are written and falls back to the per-edge loop otherwise.

# %% id="hint-fast"
hint("pose_graph_fast", 1)

# %% id="check-fast"
check("pose_graph_fast")

# %% [markdown] id="experiments-md"
# # Experiments
#
# With every piece in place, the experiments run the whole iteration: Gauss-Newton on intel; the
# dense against the sparse solve, on intel and as the graph grows; every method and back end on
# every named dataset, and who converges on mit; where the time of an iteration goes. Set
# `IMPL = "exercises"` in the setup cell to run your own code through all of it.

# %% [markdown] id="intel-md"
# ## Gauss-Newton on intel
#
# intel (TORO format): 729 poses, 3070 edges, odometry as the start. The source write-up
# reports chi2 from 2.05e6 down to 65.40. Without the data folder, the generated
# `manhattan:500` stands in (the cell says so), and those figures do not apply.

# %% id="intel"
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

# %% [markdown] id="dense-md"
# ## Dense against sparse
#
# $H$ is $3N \times 3N$ (2187 x 2187 on intel) but has only the $3 \times 3$ blocks of the
# poses that share an edge. A dense Cholesky factorization costs $O(n^3)$ whatever the
# zeros; a sparse one, after a fill-reducing ordering (AMD), costs in proportion to the
# non-zeros of its factor. `course.app.benchmark.dense_vs_sparse` solves the same Gauss-Newton
# system (at the start) both ways with the implementation's `sparse_solve`, checks that the
# two steps agree, and returns the median times. Both run on one thread here (the sparse
# solver is single-threaded, and a multithreaded BLAS on a shared machine gives erratic
# times; `threadpoolctl`, when installed, sets the limit). The source reported the sparse
# solve about 30 times faster on intel. Per iteration, the rest of the work (errors,
# Jacobians, assembly) is the same for both, so the ratio per iteration is smaller than
# per solve.

# %% id="dense"
with one_thread():  # one BLAS thread (threadpoolctl)
    dense, sparse = benchmark.dense_vs_sparse(graph.name, repeats=REPEAT, impl=IMPL)
print(f"{graph.name}, one solve: dense {1e3 * dense:.1f} ms, sparse {1e3 * sparse:.2f} ms, "
      f"dense/sparse = {dense / sparse:.1f}x (median of {REPEAT}; the source: about 30x on intel)")
sparse_iteration = gn.seconds_per_iteration
dense_iteration = sparse_iteration - sparse + dense
print(f"{graph.name}, one Gauss-Newton iteration: sparse {1e3 * sparse_iteration:.1f} ms (measured), "
      f"dense about {1e3 * dense_iteration:.1f} ms (the same with the dense solve), "
      f"ratio {dense_iteration / sparse_iteration:.1f}x")

# %% [markdown] id="growth-md"
# ## How each grows with the number of poses
#
# The same comparison on generated Manhattan worlds of $N$ poses (`manhattan:N`: a robot
# on a grid, odometry plus loop closures to earlier visits of the same cell, about three
# edges per pose), one thread as above. A dense Cholesky factorization grows like $N^3$
# (for small $N$ the measured slope is lower: BLAS runs faster on bigger matrices); the
# sparse one grows much more slowly, its cost set by the fill-in that the loop closures
# cause. The slopes in the legend are least-squares fits of $\log t$ against $\log N$.

# %% id="growth"
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

display(Image(plot.to_png(chapter2.growth_figure(sizes, dense_t, sparse_t, slopes))))

# %% [markdown] id="table-md"
# ## Every back end on every named dataset
#
# Our five methods and the peers (g2o through g2opy, Ceres through pyceres, GTSAM), same
# start, same fixed pose, at most 100 iterations; `final chi2` is our own error on each
# back end's solution (GTSAM minimizes the SE(2) log-map error, so its minimum differs
# slightly). Missing data files are skipped with the reason. On `w10000` (10 000 poses,
# 64 311 edges; full setting only) Ceres is left out: its cost function is Python, about
# 0.5 s per iteration there, and each pair runs once (an LM run takes 10-25 s); elsewhere
# each pair runs `min(REPEAT, 3)` times and keeps its median-time run. Graphs with ground
# truth (`manhattan:N`) also get the absolute trajectory error.

# %% id="table"
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
    runs = compare.run_posegraph(g, impl=IMPL, backends=backends, repeat=repeat, unimplemented="row")
    tables[name] = ran(runs)  # a peer not installed here is a row of the table only
    print(compare.format_table(runs, title=f"{name}: {g.num_poses} poses, {g.num_edges} edges"))
    if compare.format_ate(runs):
        print(compare.format_ate(runs))
    print()

# %% [markdown] id="mit-md"
# ## Who converges on mit
#
# mit (808 poses, 827 edges) starts from odometry so far off that chi2 is 4.4e9. The cell
# below reads the runs above and says which methods stop by their own convergence test
# within the 100 iterations, after how many, and where they end: a pose graph has local
# minima, and a method may converge to a different one than Gauss-Newton. It then gives
# those that hit the limit up to 2000 iterations. (In the quick setting it reads the last
# graph of the table instead.)

# %% id="mit"
hard = "mit" if "mit" in tables else list(tables)[-1]
runs = tables[hard]
gn_min = next(r.final_chi2 for r in runs if r.backend == "ours" and r.method == "gauss-newton")
groups = {kind: [r for r in runs if outcome(r) == kind] for kind in ("converged", "limit", "failed")}
text = [f"**{hard}** starts at chi2 {runs[0].initial_chi2:.3g}; Gauss-Newton ends at {gn_min:.6g}."]
text.append("Converged (stopped by their own test within the limit): " + ("; ".join(
    f"{r.backend} {r.method} in {r.iterations} iterations to chi2 {r.final_chi2:.6g} ({where(r, gn_min)})"
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
        f"{r.iterations} iterations ({1e3 * r.seconds:.0f} ms) to chi2 {r.final_chi2:.6g} ({where(r, gn_min)})"
        for r in longer) + ".")
display(Markdown("\n\n".join(text)))

# %% [markdown] id="split-md"
# ## Where the time of an iteration goes
#
# Each part of one Gauss-Newton iteration, timed alone at the start of the graph with the
# implementation's own pieces (`pose_graph_fast`: errors and Jacobians of all edges at
# once, then the scatter-add of the edge blocks into the fixed sparsity pattern of H;
# `sparse_solve.SparseCholeskySolver`: numeric factorization and the two triangular
# solves, the ordering and symbolic analysis reused from the first call), against the
# time per iteration measured in the loop. The one-off costs come after: the sparsity
# pattern (once per graph) and the fill-reducing ordering with the symbolic
# factorization (once per pattern). On intel, the per-edge loop of
# `pose_graph_assembly` (a dense H) is timed too, for comparison.

# %% id="split"
for name in (["intel"] if SMALL else ["intel", "w10000"]):
    g = load(name)
    if g is None and name == "intel":
        g = datasets.load_dataset("manhattan:500")
    if g is None:
        continue
    repeat = REPEAT if g.num_poses <= 5000 else max(1, min(REPEAT, 3))
    try:
        parts, once, trial = time_split(g, repeat, IMPL)
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

# %% [markdown] id="questions-md"
# # Written questions
#
# Answer in the cells below, in a few sentences each. Use the measurements above.
#
# **Question 1.** Which step of an iteration takes the most time, and how can it be made
# faster? Name several ways and say what each one saves.
#
# **Question 2.** Which other methods for nonlinear least squares (and nonlinear
# optimization in general) exist besides Gauss-Newton? For each, say in a sentence or two
# how it works and when you would choose it.
#
# **Question 3.** The gauge table of section 2.1 moves `manhattan:30` along three directions that
# leave every error unchanged. Why does the turn's direction depend on where each pose is,
# $(-y_p, x_p, 1)$, while the two translations' do not? What would happen to $H$, and to a Gauss-Newton
# step, if you fixed only the position $(x_0, y_0)$ of pose 0 and left its angle free?
#
# **Question 4.** In the fill-in table of section 3, $L$ in file order has more than four times the
# entries it has in AMD order on `manhattan:100`, and the gap grows with the graph. Where does the
# fill come from in file order (think of what a loop closure does as the poses are eliminated one by
# one)? Why can the ordering and the symbolic analysis be computed once for all iterations, and in
# which situations would they have to be redone?
#
# **Question 5.** Ceres gets the same $H$ and $b$ as ours (section 4) and needs about as many
# iterations, yet in the table of the experiments each of its iterations takes several times longer
# on `w100` and `manhattan:200`. Where does its time go? How does the cost Ceres reports relate to the
# `final chi2` column?

# %% [markdown] tags=["answer"] id="answer-1"
# **Your answer to question 1:** *(double-click to edit)*

# %% [markdown] tags=["answer"] id="answer-2"
# **Your answer to question 2:** *(double-click to edit)*

# %% [markdown] tags=["answer"] id="answer-3"
# **Your answer to question 3:** *(double-click to edit)*

# %% [markdown] tags=["answer"] id="answer-4"
# **Your answer to question 4:** *(double-click to edit)*

# %% [markdown] tags=["answer"] id="answer-5"
# **Your answer to question 5:** *(double-click to edit)*
