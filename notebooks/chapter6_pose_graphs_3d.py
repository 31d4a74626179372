# %% [markdown] id="title"
# # Chapter 6: pose graphs in 3D
#
# A pose is now $T = (R, t) \in SE(3)$: three angles and three coordinates, and the angles do not
# live in a vector space. This chapter carries chapter 2's Gauss-Newton over to that curved space,
# and then meets two problems chapter 2's graphs hid: where to start (the chordal relaxation) and
# what to do with loop closures that are wrong (robust costs, graduated non-convexity). The chapter
# is a lesson in this order:
#
# 1. **Theory**, derived: rotations and poses as manifolds, the exponential and the logarithm,
#    perturbations on the left and on the right, the right Jacobian; the SE(3) edge error and the
#    chain rule to its Jacobians, the retraction (exercise `pose_graph_3d`); the normal equations in
#    6x6 blocks and their sparsity (exercise `pose_graph_3d_assembly`); the chordal relaxation
#    (exercise `chordal_3d`); robust costs and GNC (exercise `gnc`). After each exercise's theory, a
#    cell `check("...")` grades it here, with the same sandboxed judge and public checks as
#    `python -m autograder --only ...`; where you derive a Jacobian, a cell first shows you how to
#    check it yourself with `course.check_jacobian`.
# 2. **Experiments**: every back end from the file's poses and from the chordal start, the
#    trajectories, the spectrum of rotation errors, wrong loop closures.
# 3. **Written questions.**
#
# Stuck on a derivation? `hint("gnc", 1)` (or `python -m autograder hint NAME LEVEL` in a
# terminal) gives the approach, level 2 the key identity, level 3 the result.
#
# Conventions, everywhere in this chapter: a pose maps body to world, $x_w = R\, x_b + t$; the
# tangent vector of a pose is $\delta = (\rho, \phi)$, **translation first** (as in g2o files;
# GTSAM puts the rotation first); the course perturbs on the **right**, $T \boxplus \delta =
# (R\,\mathrm{Exp}(\phi),\ t + R\rho)$; $[\phi]_\times$ is the skew matrix with $[\phi]_\times v = \phi
# \times v$; an edge $i \to j$ with information $\Omega$ adds $e^\top \Omega e$ to $\chi^2$,
# $H = J^\top \Omega J$, $b = J^\top \Omega e$, the step solves $H \delta = -b$.

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
from course.app import compare, outliers3d, plot
from course.notebook_helpers import chapter6
from course.notebook_helpers.chapter6 import todo_as_one_line
from course.notebook_helpers.common import not_run_note
from course.notebook_helpers.posegraph3d import (
    load3d,
    outlier_table,
    poses_figure,
    residual_angles,
    rotation_spectrum,
)
from course.problems.posegraph3d import robust
from course.problems.posegraph3d.initialise import initialise
from course.problems.posegraph3d.outliers import odometry, with_wrong_loop_closures
from course.problems.posegraph3d.problem import unpack

SMALL = os.environ.get("COURSE_NOTEBOOK_SMALL") == "1"
# "solutions", "exercises" or a path to your own copy (python -m notebooks.build --impl sets it);
# by default this tree's own: "exercises" in a student tree
IMPL = os.environ.get("COURSE_IMPL") or ("solutions" if (root / "solutions").is_dir() else "exercises")
GRAPHS = ["smallGrid3D"] if SMALL else ["sphere2500", "torus3D"]
LESSON_GRAPH = "smallGrid3D"  # the theory's figures, in either setting
print(f"implementation: {IMPL}; graphs: {', '.join(GRAPHS)}; the theory's figures: {LESSON_GRAPH}")
lesson_graph = load3d(LESSON_GRAPH)  # None (saying why) where the data folder is missing

# %% [markdown] id="so3-md"
# ## 1. Rotations and poses as manifolds
#
# A rotation is a $3 \times 3$ matrix with $R^\top R = I$ and $\det R = 1$. These matrices form
# $SO(3)$, a curved three-dimensional surface in the nine-dimensional space of matrices: the sum of
# two rotations is no rotation, and Gauss-Newton's update $x + \delta$ makes no sense for them. What
# saves us is that near any rotation the surface looks like $\mathbb{R}^3$.
#
# **The tangent space.** Differentiate $R(s)^\top R(s) = I$ along a curve through $R(0) = I$:
# $\dot R^\top + \dot R = 0$. The velocities at the identity are the skew-symmetric matrices, three
# numbers each:
#
# $$[\phi]_\times = \begin{bmatrix} 0 & -\phi_3 & \phi_2 \\ \phi_3 & 0 & -\phi_1 \\ -\phi_2 & \phi_1 & 0
#   \end{bmatrix}, \qquad [\phi]_\times v = \phi \times v .$$
#
# **The exponential map.** Turning at the constant rate $\phi$ in the body's own axes for one unit of
# time, $\dot R = R\,[\phi]_\times$ from $R(0) = I$, gives the matrix exponential
# $\mathrm{Exp}(\phi) = \sum_k [\phi]_\times^k / k!$. Write $\phi = \theta u$ with $|u| = 1$. From
# $[u]_\times^2 = u u^\top - I$ and $[u]_\times u = 0$ follows $[u]_\times^3 = -[u]_\times$, so every power
# folds back onto $[u]_\times$ or $[u]_\times^2$; collecting the odd terms
# ($\theta - \theta^3/3! + \dots = \sin\theta$) and the even ones ($\theta^2/2! - \theta^4/4! + \dots =
# 1 - \cos\theta$):
#
# $$\mathrm{Exp}(\theta u) = I + \sin\theta\,[u]_\times + (1 - \cos\theta)\,[u]_\times^2
#   \qquad \text{(Rodrigues' formula).}$$
#
# **The logarithm** inverts it for $\theta \in [0, \pi]$. Take the trace ($\mathrm{tr}[u]_\times = 0$,
# $\mathrm{tr}[u]_\times^2 = -2$): $\mathrm{tr} R = 1 + 2\cos\theta$ gives the angle; the antisymmetric
# part $(R - R^\top)/2 = \sin\theta\,[u]_\times$ gives the axis, and $\mathrm{Log}(R) = \theta u$. Near
# $\theta = 0$ the division by $\sin\theta$ takes its series; near $\pi$, $\sin\theta$ carries no
# digits of $u$, and the symmetric part $(R + R^\top)/2 - \cos\theta\, I = (1 - \cos\theta)\, u u^\top$
# gives the axis instead (`course.geometry.so3.log_many` does both).
#
# **Poses.** $T = (R, t)$ acts as $x_w = R\,x_b + t$; composing and inverting,
#
# $$T_a T_b = (R_a R_b,\ R_a t_b + t_a), \qquad T^{-1} = (R^\top,\ -R^\top t) .$$
#
# A pose has six tangent coordinates $\delta = (\rho, \phi)$, translation first.
#
# **Three identities** used in every derivation below, each a line from the definitions:
#
# 1. $[a]_\times b = -[b]_\times a$ (a cross product changes sign when its factors swap);
# 2. $R\,[\phi]_\times R^\top = [R\phi]_\times$ (because $R(\phi \times v) = (R\phi) \times (Rv)$), hence
#    $R\,\mathrm{Exp}(\phi)\,R^\top = \mathrm{Exp}(R\phi)$ and $\mathrm{Exp}(\phi)\,R = R\,\mathrm{Exp}(R^\top \phi)$:
#    a perturbation moves through a rotation by rotating its vector;
# 3. $\mathrm{Exp}(\phi)^\top = \mathrm{Exp}(-\phi)$, and $\mathrm{Exp}(\phi) = I + [\phi]_\times + O(|\phi|^2)$.

# %% [markdown] id="perturbation-md"
# ### 1.1 Perturbations: on the left or on the right
#
# To differentiate a function of a rotation we move the rotation by a small one and keep the
# first-order change. There are two ways to put the small rotation: on the **left**,
# $R \leftarrow \mathrm{Exp}(\phi)\,R$ ($\phi$ in the world's axes), or on the **right**,
# $R \leftarrow R\,\mathrm{Exp}(\phi)$ ($\phi$ in the body's own axes). By identity 2,
# $R\,\mathrm{Exp}(\phi) = \mathrm{Exp}(R\phi)\,R$: a right perturbation $\phi$ is the left perturbation
# $R\phi$, and Jacobians taken one way and the other differ by that factor $R$.
#
# *Worked example:* $f(R) = R\,v$ (a body vector in the world's axes).
# On the right: $R\,\mathrm{Exp}(\phi)\, v \approx Rv + R[\phi]_\times v = Rv - R[v]_\times \phi$, so
# $\partial f / \partial\phi = -R[v]_\times$.
# On the left: $\mathrm{Exp}(\phi)\,Rv \approx Rv + [\phi]_\times Rv = Rv - [Rv]_\times \phi$, so
# $\partial f / \partial\phi = -[Rv]_\times = -R[v]_\times R^\top$: the right one times $R^\top$, as
# identity 2 says.
#
# **The course perturbs on the right**, the translation too, in the pose's own axes:
#
# $$T \boxplus \delta = (R\,\mathrm{Exp}(\phi),\ t + R\rho) .$$
#
# A pose graph's measurements and their noise are expressed in the frame of the pose that
# measured them, and so is a right perturbation; g2o's `VertexSE3` and GTSAM's `Pose3` move their
# poses on the right as well (GTSAM rotation first). The figure shows the difference on one pose: on the
# left a small rotation swings the pose about the world's origin (far away, a small angle is a
# large displacement); on the right it turns the pose where it stands.

# %% id="figure-perturbations"
display(Image(plot.to_png(chapter6.perturbation_figure())))

# %% [markdown] id="right-jacobian-md"
# ### 1.2 The right Jacobian
#
# Rotations do not commute, so $\mathrm{Exp}(\phi + \delta) \ne \mathrm{Exp}(\phi)\,\mathrm{Exp}(\delta)$.
# To first order in $\delta$ there is a matrix $J_r(\phi)$, the **right Jacobian**, with
#
# $$\mathrm{Exp}(\phi + \delta) \approx \mathrm{Exp}(\phi)\,\mathrm{Exp}\big(J_r(\phi)\,\delta\big) .$$
#
# *Derivation.* Let $F(s) = \mathrm{Exp}(-s\phi)\,\mathrm{Exp}(s(\phi + \delta))$, $F(0) = I$. Differentiating,
# $F'(s) = \mathrm{Exp}(-s\phi)\,[\delta]_\times\,\mathrm{Exp}(s(\phi + \delta))$, and to first order in
# $\delta$ the last factor may be taken at $\delta = 0$: $F'(s) \approx \mathrm{Exp}(-s\phi)\,[\delta]_\times\,
# \mathrm{Exp}(s\phi) = [\mathrm{Exp}(-s\phi)\,\delta]_\times$ (identity 2). Integrating from 0 to 1,
#
# $$\mathrm{Exp}(-\phi)\,\mathrm{Exp}(\phi + \delta) = F(1)
#   \approx I + \Big[\int_0^1 \mathrm{Exp}(-s\phi)\,ds\ \delta\Big]_\times , \qquad \text{so}$$
#
# $$J_r(\phi) = \int_0^1 \mathrm{Exp}(-s\phi)\, ds
#   = I - \frac{1 - \cos\theta}{\theta^2}[\phi]_\times + \frac{\theta - \sin\theta}{\theta^3}[\phi]_\times^2 ,$$
#
# integrating Rodrigues' formula term by term ($\int_0^1 \sin(s\theta)\,ds = (1 - \cos\theta)/\theta$,
# $\int_0^1 (1 - \cos s\theta)\,ds = 1 - \sin\theta/\theta$). Its inverse is again of the form
# $I + a[\phi]_\times + b[\phi]_\times^2$ (a power series in $[u]_\times$ folds back onto these two);
# multiplying out $J_r J_r^{-1} = I$ with $[u]_\times^3 = -[u]_\times$ and solving for $a$, $b$:
#
# $$J_r^{-1}(\phi) = I + \tfrac12 [\phi]_\times
#   + \Big(\frac{1}{\theta^2} - \frac{1 + \cos\theta}{2\theta\sin\theta}\Big)[\phi]_\times^2$$
#
# (given: `course.geometry.so3.right_jacobian_inverse_many`). It stays finite up to $\theta = \pi$, where the
# coefficient is $1/\pi^2$; but $(1 + \cos\theta)/\sin\theta$ is $0/0$ there and cancels near it, so the code
# writes it $1/\tan(\theta/2)$.
# Setting $\varepsilon = J_r(\phi)\,\delta$ in the first display and taking the Log gives what a
# rotation *error* needs:
#
# $$\mathrm{Log}\big(\mathrm{Exp}(\phi)\,\mathrm{Exp}(\varepsilon)\big) \approx \phi + J_r^{-1}(\phi)\,\varepsilon .$$
#
# A Log moved on the right by a small $\varepsilon$ changes by $J_r^{-1}(\phi)\,\varepsilon$, not by $\varepsilon$.
# (On the left, $J_l(\phi) = J_r(-\phi)$ plays the same part.) The figure measures how much that
# matters: the error of the two first-order forms, relative to $|\varepsilon|$, as the angle
# $|\phi|$ grows.

# %% id="figure-right-jacobian"
display(Image(plot.to_png(chapter6.right_jacobian_figure())))

# %% [markdown] id="edge-md"
# ## 2. The SE(3) edge, its Jacobians and the retraction (exercise `pose_graph_3d`)
#
# The edge $i \to j$ measures $Z = (R_z, t_z)$, pose $j$ seen from pose $i$. If the poses agreed with
# it, $T_i Z = T_j$; the error measures the discrepancy $D = Z^{-1} T_i^{-1} T_j$ (the identity when
# they agree). With the composition and inverse rules of section 1,
#
# $$T_i^{-1} T_j = \big(R_i^\top R_j,\ R_i^\top (t_j - t_i)\big), \qquad
#   D = \big(R_z^\top R_i^\top R_j,\ R_z^\top (R_i^\top (t_j - t_i) - t_z)\big),$$
#
# and the course's error takes $D$'s translation and the Log of its rotation, translation first:
#
# $$e = \begin{bmatrix} e_t \\ e_\phi \end{bmatrix}
#     = \begin{bmatrix} R_z^\top (d - t_z) \\ \mathrm{Log}(R_z^\top R_i^\top R_j) \end{bmatrix} \in \mathbb{R}^6,
#   \qquad d = R_i^\top (t_j - t_i) .$$
#
# (GTSAM's `BetweenFactor<Pose3>` takes the full SE(3) logarithm of $D$, whose translation part
# $V(\phi)^{-1} D_t$ equals ours to first order; g2o's `EdgeSE3` takes the vector part of $D_R$'s
# quaternion, $\sin(\theta/2)\,u$, about half our rotation part. The experiments come back to it.)
#
# **The chain rule through the perturbations.** The Jacobians the solver needs are
#
# $$A = \frac{\partial\, e(T_i \boxplus \delta_i,\ T_j)}{\partial \delta_i}\Big|_{\delta_i = 0}, \qquad
#   B = \frac{\partial\, e(T_i,\ T_j \boxplus \delta_j)}{\partial \delta_j}\Big|_{\delta_j = 0}
#   \qquad (6 \times 6 \text{ each}),$$
#
# each in four $3 \times 3$ blocks: rows $e_t$, $e_\phi$; columns $\rho$, $\phi$. The recipe, for one
# pose at a time:
#
# 1. substitute $R \to R\,\mathrm{Exp}(\phi)$, $t \to t + R\rho$ into $d$ and into $R_z^\top R_i^\top R_j$;
# 2. keep first order: $\mathrm{Exp}(\pm\phi) \approx I \pm [\phi]_\times$, drop products of $\rho$ and $\phi$;
# 3. for $e_t$, a vector, bring each $\phi$ to the right with identity 1 and read off the matrix that
#    multiplies $\rho$ and the one that multiplies $\phi$;
# 4. for $e_\phi$, a Log, do not expand the Log: move the small rotation to the right end of the
#    product with identity 2 (and 3 for a transpose), then use $\mathrm{Log}(\mathrm{Exp}(e_\phi)\,
#    \mathrm{Exp}(\varepsilon)) \approx e_\phi + J_r^{-1}(e_\phi)\,\varepsilon$ from section 1.2.
#
# The perturbation of $T_j$ is the easier one: it already sits at the right end of
# $R_z^\top R_i^\top R_j$. That of $T_i$ enters transposed and on the left. Derive both; then write
# `edge_errors_and_jacobians` in `exercises/pose_graph_3d.py`, vectorised over the M edges
# (`course.geometry.so3` gives `skew`, `exp_many`, `log_many`, `right_jacobian_inverse_many`).
#
# **The retraction and Gauss-Newton on the manifold.** Near the current poses $x$, the cost is a
# function of the $6N$ numbers $\delta$ through $x \boxplus \delta$, an ordinary vector space: linearise
# each edge, $e_k(x \boxplus \delta) \approx e_k + A_k \delta_i + B_k \delta_j$, minimise the quadratic
# model as in chapter 2 ($H\delta = -b$), and move every pose by its own $\delta$:
# $T \leftarrow T \boxplus \delta = (R\,\mathrm{Exp}(\phi),\ t + R\rho)$, the **retraction**. It stays
# on $SE(3)$ whatever the step (the rotation part is a product of rotations), gives back $T$ at
# $\delta = 0$, and its derivative there is the identity, which is all the linearisation used.
# (SE(3)'s own exponential, $T\,\mathrm{Exp}(\delta^\wedge) = (R\,\mathrm{Exp}(\phi),\ t + R\,V(\phi)\rho)$ with
# $V(\phi) = I + O(|\phi|)$, agrees with it to first order: the same Jacobians and the same minimum.)
# `retract` in the same file is this update for N poses at once. One pose stays fixed: moving
# every pose by the same transformation changes no $T_i^{-1} T_j$, so without it $H$ is singular.

# %% id="hint-edge"
hint("pose_graph_3d.edge_errors_and_jacobians", 1)  # level 1, the approach; 2 the key identity, 3 the result

# %% [markdown] id="jacobian-check-md"
# **Check your Jacobians where you work.** `course.check_jacobian(f, x, J, plus=...)` moves each
# variable along every tangent direction through the course's retraction (`plus="se3"`: exactly
# $T \boxplus \delta$), takes central differences of `f` and compares them with your `J`, entry by
# entry; a wrong entry is reported with its block (`d rotation / d T_i rotation`, ...). Here, on
# one generic edge (residual rotation 0.5 rad) with your `edge_errors_and_jacobians`, and then with one
# entry of your $B$ spoilt on purpose, to show what a slip looks like. Use it the same way on your own
# test cases (an edge near $\theta = \pi$, edges written from $j$ to $i$).

# %% id="jacobian-check"
edge = chapter6.random_edge(seed=0, residual_angle=0.5)  # T_i, T_j and Z, each (t (3,), R (3, 3))
print(f"one edge, residual rotation {edge.residual_angle:.2f} rad")


def edge_error(T_i, T_j):
    """Your e (6,) of the one edge i -> j between the poses T_i = (t_i, R_i) and T_j = (t_j, R_j)."""
    return pose_graph_3d.edge_errors_and_jacobians(*edge.arguments(T_i, T_j))[0][0]


with todo_as_one_line():
    pose_graph_3d = chapter6.exercise("pose_graph_3d", IMPL)
    _, A, B = pose_graph_3d.edge_errors_and_jacobians(*edge.arguments())  # A, B: (1, 6, 6)
    check_jacobian(edge_error, [edge.T_i, edge.T_j], J=[A[0], B[0]], plus="se3", names=["T_i", "T_j"], rows="se3")
    print("\nwhat a slip looks like (B[4, 5] off by 0.1):")
    slip = B[0].copy()
    slip[4, 5] += 0.1
    check_jacobian(edge_error, [edge.T_i, edge.T_j], J=[A[0], slip], plus="se3", names=["T_i", "T_j"], rows="se3")

# %% id="check-edge"
check("pose_graph_3d")

# %% [markdown] id="assembly-md"
# ## 3. The normal equations in 6x6 blocks (exercise `pose_graph_3d_assembly`)
#
# Stack the M edges' errors into $e$ ($6M$) and their Jacobians into $J$ ($6M \times 6N$): block row $k$
# of $J$ is zero except for $A_k$ in the columns of pose $i$ and $B_k$ in those of pose $j$. With the
# block-diagonal $\Omega$,
#
# $$H = J^\top \Omega J = \sum_k J_k^\top \Omega_k J_k, \qquad b = J^\top \Omega e = \sum_k J_k^\top \Omega_k e_k,
#   \qquad \chi^2 = \sum_k e_k^\top \Omega_k e_k ,$$
#
# and since $J_k$ has only two non-zero blocks, $J_k^\top \Omega_k J_k$ has only four: at $(i, i)$,
# $A^\top \Omega A$; at $(i, j)$, $A^\top \Omega B$ (and its transpose at $(j, i)$); at $(j, j)$,
# $B^\top \Omega B$. $J_k^\top \Omega_k e_k$ puts $A^\top \Omega e$ at pose $i$ and $B^\top \Omega e$ at
# pose $j$. So $H$ has a non-zero $6 \times 6$ block on its diagonal and one wherever an edge joins
# two poses: its **pattern depends on the graph alone**, not on the poses. Every iteration changes the
# values, never the places.
#
# That is what the assembly exploits, as in chapter 2 but in $6 \times 6$ blocks. $H$ is symmetric, so
# only its upper triangle is stored (compressed sparse columns, the diagonal included): per edge the 21
# entries on and above the diagonal of $A^\top \Omega A$, the 36 of $A^\top \Omega B$ (or of its
# transpose, when $i > j$ puts that block below the diagonal) and the 21 of $B^\top \Omega B$, 78 in
# all. Where each of them lands in $H$'s list of non-zeros is a question about the graph: answer it
# **once**, in the constructor. Then each iteration is a few batched products and one scatter-add
# (several edges share a diagonal block: their contributions add). A fixed pose keeps an identity
# diagonal block and zero rows, columns and $b$: its step is zero.
#
# The sparse Cholesky factorization that solves $H\delta = -b$ reuses the pattern too: the ordering and
# the symbolic factorization are done once. The ordering matters: eliminating a pose connects all its
# neighbours, and the factor $L$ fills in. The figure shows it on smallGrid3D, in
# $6 \times 6$ blocks (a pose graph's $L$ has the same pattern whatever the poses), and the table what
# random wrong loop closures (section 5) do to it.

# %% id="figure-sparsity"
if lesson_graph is not None:
    display(Image(plot.to_png(chapter6.sparsity_figure(lesson_graph))))
    print(chapter6.fill_in_table([lesson_graph, with_wrong_loop_closures(lesson_graph, 0.2, seed=1)]))

# %% id="hint-assembly"
hint("pose_graph_3d_assembly", 1)

# %% id="check-assembly"
check("pose_graph_3d_assembly")

# %% [markdown] id="chordal-md"
# ## 4. Where to start: the chordal relaxation (exercise `chordal_3d`)
#
# Gauss-Newton on poses converges to the minimum near its start. The file's poses are the odometry
# composed, and their drift puts large rotation errors on the loop closures (section 2 of the
# experiments): a poor start. The chordal relaxation (Carlone, Tron, Daniilidis and Dellaert, ICRA 2015)
# computes a start from the measurements alone, by two *linear* least-squares problems.
#
# **Rotations first.** Measure the disagreement of an edge's rotations by the chordal distance
# $\|R_j - R_i R_z\|_F^2$ instead of the squared angle. For two rotations $\theta$ apart,
# $\|R_a - R_b\|_F^2 = \mathrm{tr}\big((R_a - R_b)^\top (R_a - R_b)\big) = 6 - 2\,\mathrm{tr}(R_a^\top R_b)
# = 4(1 - \cos\theta) = 8\sin^2(\theta/2)$: twice the squared angle for small $\theta$, and less for large
# ones (the left panel below). The problem
#
# $$\min_{R_1 \dots R_N \in SO(3)} \sum_k w_k \|R_j - R_i R_z\|_F^2$$
#
# is quadratic in the entries of the $R$'s; only the constraint $R \in SO(3)$ makes it hard. **Drop it**
# (relax): then each edge's residual is linear in the nine entries. Row $a$ of $R_j = R_i R_z$ reads, for
# the rows $r^a$ of the $R$'s written as column vectors, $r_j^a = R_z^\top r_i^a$, and
# $\|R_j - R_i R_z\|_F^2 = \sum_{a=1}^{3} \|r_j^a - R_z^\top r_i^a\|^2$: three independent linear
# least-squares problems with the same matrix, one per row $a$, each residual with Jacobians
# $-R_z^\top$ (on $r_i^a$) and $I$ (on $r_j^a$). Its normal equations are assembled in $3 \times 3$ blocks
# exactly as in section 3. A global rotation of all the $R$'s changes no residual, so one pose, the
# anchor, is held at a given rotation and its unknowns move to the right-hand side.
#
# **Then project.** The solution's $3 \times 3$ matrices $M_k$ are not rotations (right panel: on a
# noisy graph they shrink towards zero away from the anchor, where the measurements disagree most).
# The nearest rotation in the Frobenius norm solves $\min_R \|R - M\|_F^2 = \|M\|_F^2 + 3 - 2\,
# \mathrm{tr}(R^\top M)$, i.e. maximises $\mathrm{tr}(R^\top M)$. With the singular value decomposition
# $M = U S V^\top$ ($s_1 \ge s_2 \ge s_3 \ge 0$), $\mathrm{tr}(R^\top U S V^\top) = \mathrm{tr}(S\, Q)$ with
# $Q = V^\top R^\top U$, an orthogonal matrix, so $|Q_{kk}| \le 1$ and
#
# $$\mathrm{tr}(S\,Q) = \sum_k s_k Q_{kk} \le \sum_k s_k ,$$
#
# with equality at $Q = I$, i.e. $R = U V^\top$. That is a rotation when $\det(U V^\top) = +1$. When it is
# $-1$, $U V^\top$ is a reflection, and $R \in SO(3)$ forces $\det Q = \det(V^\top)\det(U) = -1$: $Q = I$
# is out of reach, and some $Q_{kk}$ must give way. Which $Q$ of determinant $-1$ maximises
# $\sum_k s_k Q_{kk}$, and so which rotation is nearest, is for you to settle in `project_to_so3`.
#
# **Translations given the rotations.** With the rotations fixed, $e_t = R_z^\top (R_i^\top (t_j - t_i) - t_z)
# = (R_i R_z)^\top (t_j - t_i - R_i t_z)$ is linear in the positions, and $e_t^\top \Omega_{tt} e_t =
# r^\top W r$ with the world-frame residual $r = t_j - t_i - R_i t_z$ and
# $W = (R_i R_z)\,\Omega_{tt}\,(R_i R_z)^\top$: a second sparse linear least-squares problem in $3 \times 3$
# blocks, the anchor's position given.

# %% id="figure-chordal"
display(Image(plot.to_png(chapter6.chordal_figure(lesson_graph, IMPL))))

# %% id="hint-chordal"
hint("chordal_3d", 1)

# %% id="check-chordal"
check("chordal_3d")

# %% [markdown] id="gnc-md"
# ## 5. Wrong loop closures: robust costs and graduated non-convexity (exercise `gnc`)
#
# A place recogniser that mistakes one corridor for another adds a loop closure that is simply wrong.
# Least squares pulls on it as hard as it is wrong: $s_k = e_k^\top \Omega_k e_k$ enters the cost
# unbounded. A **robust cost** $\sum_k \rho(s_k)$ caps the pull. Its stationary points satisfy
#
# $$\nabla_x \sum_k \rho(s_k) = \sum_k \rho'(s_k)\, \nabla_x s_k = 0 ,$$
#
# which are also the stationary points of the *weighted* least-squares cost $\sum_k w_k s_k$ with the
# weights frozen at $w_k = \rho'(s_k)$: solve with weights, recompute the weights, repeat (iteratively
# reweighted least squares; chapter 4's kernels weight each residual's gradient by the same $\rho'(s_k)$
# inside every Gauss-Newton step).
# The most decisive cost is the truncated least squares (TLS), $\rho(s) = \min(s, \bar c^2)$: an edge
# whose $s$ exceeds the threshold $\bar c^2$ costs a constant and pulls not at all ($w = 0$), the others
# count fully ($w = 1$). Here $\bar c^2 = 16.81$, the 0.99 quantile of $\chi^2$ with 6 degrees of freedom:
# a right edge exceeds it once in a hundred. But TLS is not convex: started from the least-squares
# solution, where the wrong edges have dragged the right ones out of place, its weights pick the
# wrong edges to trust.
#
# **Graduated non-convexity** (Yang, Antonante, Tzoumas and Carlone, RA-L 2020) replaces $\rho$ by a
# family $\rho_\mu$ that is nearly convex at one end of the control $\mu$ and is $\rho$ at the other,
# and follows the minimum along $\mu$, one weighted least-squares solve per step. For TLS ($\mu$ from near 0 upwards),
# in terms of $s$:
#
# $$\rho_\mu(s) = \begin{cases} s & s \le \frac{\mu}{\mu + 1}\bar c^2 \\
#   2\sqrt{\bar c^2 \mu(\mu + 1)\, s} - \mu(\bar c^2 + s)
#     & \frac{\mu}{\mu + 1}\bar c^2 \le s \le \frac{\mu + 1}{\mu}\bar c^2 \\
#   \bar c^2 & s \ge \frac{\mu + 1}{\mu}\bar c^2 \end{cases}$$
#
# For small $\mu$ the middle piece covers almost everything and, in the residual $r = \sqrt{s}$, is
# nearly proportional to $|r|$ (its concave part, $-\mu r^2$, is of order $\mu$ against the $\sqrt{\mu}$
# of the linear one): nearly convex, like a Huber cost. As $\mu \to \infty$ both bounds close on
# $\bar c^2$ and $\rho_\mu \to \min(s, \bar c^2)$. For Geman-McClure,
# $\rho_\mu(s) = \mu \bar c^2 s / (\mu \bar c^2 + s)$, nearly least squares for large $\mu$
# and Geman-McClure's own cost at $\mu = 1$.
#
# **The weights.** For both, GNC's weights are those of the reweighting above, taken on the surrogate:
# $w = \rho_\mu'(s)$ (Black and Rangarajan's outlier process gives the same: $\rho_\mu(s) =
# \min_{w \in [0, 1]} w s + \Phi_\mu(w)$, and by the envelope theorem $\rho_\mu'(s)$ is the minimising
# $w$). Differentiate each piece; the TLS weight is 1, then falls continuously, then is 0. Write
# `tls_weights` and `gm_weights`.
#
# **The schedule** (`gnc`). Start with least squares (all weights 1). If even the worst edge has
# $s_{\max} \le \bar c^2$, nothing is an outlier. Otherwise start TLS at $\mu_0 = \bar c^2 / (2 s_{\max} - \bar c^2)$:
# then $\frac{\mu_0 + 1}{\mu_0}\bar c^2 = 2 s_{\max}$, the zero-weight zone begins beyond every
# residual, and no edge is dropped before the surrogate has been followed; multiply $\mu$ by 1.4 per round
# until every weight is 0 or 1. Geman-McClure starts at $\mu_0 = 2 s_{\max} / \bar c^2$ (then $\mu_0 \bar c^2 \ge 2s$
# for every edge: nearly least squares) and divides by 1.4 down to 1. The odometry edges are known
# inliers (weight 1 throughout): they keep the graph connected whatever the weights do.
#
# The figure shows the two families. The cell after it checks your weights the way section 2 checked
# the Jacobians: since $\rho_\mu$ acts on each $s_k$ alone, the Jacobian of $(\rho_\mu(s_k))_k$ is the
# diagonal matrix of the weights.

# %% id="figure-surrogates"
display(Image(plot.to_png(chapter6.surrogate_figure())))

# %% id="weights-check"
s, c2 = np.array([0.5, 3.0, 9.0, 14.0, 30.0, 80.0]), 16.81  # squared residuals; c2 as in section 5
with todo_as_one_line():
    gnc = chapter6.exercise("gnc", IMPL)
    check_jacobian(lambda s: chapter6.tls_surrogate(s, 0.3, c2), s, J=np.diag(gnc.tls_weights(s, 0.3, c2)),
                   names=["s"])
    check_jacobian(lambda s: chapter6.gm_surrogate(s, 3.0, c2), s, J=np.diag(gnc.gm_weights(s, 3.0, c2)),
                   names=["s"])

# %% id="hint-gnc"
hint("gnc", 1)

# %% id="check-gnc"
check("gnc")

# %% [markdown] id="experiments-md"
# # Experiments
#
# Every final $\chi^2$ below is ours, on every back end's solution. The peers' errors differ from ours:
# g2o's `EdgeSE3` writes the rotation part as the vector part of $D_R$'s quaternion,
# $\sin(\theta/2)\,u$, about half ours, so the g2o files' rotation information is for that error (4x the
# angle's), and the reader converts it; GTSAM's `BetweenFactor<Pose3>` is $\mathrm{Logmap}(D)$, rotation
# first.
#
# `SMALL = True` (set by `python -m notebooks.build --execute --small`, and by the tests) runs the quick
# setting: `smallGrid3D` (125 poses; its residual rotations at the minimum reach 49 degrees: a hard
# graph), the outliers on it at 20%. The full setting runs `sphere2500` and `torus3D`, the outliers on
# `sphere2500` at 10%, 20% and 50% (tens of minutes). Set `IMPL = "exercises"` to run your own pieces
# through all of it.

# %% [markdown] id="compare-md"
# ## 1. Every back end, from the file's poses and from the chordal start
#
# Gauss-Newton only: the per-iteration cost and the number of iterations are the point here
# (`python -m course compare NAME --init chordal` runs every method).

# %% id="compare"
solved = {}  # name -> (graph, chordal start, our Gauss-Newton run from it), for the figures below
for name in GRAPHS:
    graph = load3d(name)
    if graph is None:
        continue
    for init in ("file", "chordal"):
        runs = compare.run_posegraph3d(graph, impl=IMPL, methods=["gauss-newton"], init=init,
                                       unimplemented="row")
        print(compare.format_table(runs, title=f"{name} from {init}: {graph.num_poses} poses, "
                                               f"{graph.num_edges} edges{not_run_note(runs)}"))
        print()
        if init == "chordal" and not runs[0].not_run:
            solved[name] = (graph, initialise(graph, "chordal", IMPL)[0], runs[0])

# %% id="trajectories"
if not solved:
    print("no Gauss-Newton run of ours from the chordal start above: no trajectories, no spectrum below")
for name, (graph, start, ours) in solved.items():
    t_final, _ = unpack(ours.params)
    fig = poses_figure([("file's poses", graph.t), ("chordal start", start.t), ("Gauss-Newton", t_final)], title=name)
    display(Image(plot.to_png(fig)))

# %% [markdown] id="spectrum-md"
# ## 2. The spectrum of rotation errors
#
# Each edge's residual rotation $|\mathrm{Log}(R_z^T R_i^T R_j)|$, sorted: at the file's
# poses the drift of the odometry shows as large residuals on the loop closures; the
# chordal start removes most of them before any Gauss-Newton step.

# %% id="spectrum"
for name, (graph, start, ours) in solved.items():
    curves = [("file's poses", residual_angles(graph, graph.t, graph.R)),
              ("chordal start", residual_angles(graph, start.t, start.R)),
              ("Gauss-Newton", residual_angles(graph, *unpack(ours.params)))]
    for label, angles in curves:
        print(f"{name} {label:14} median {float(np.median(angles)):.4f} deg, max {float(angles.max()):.3f} deg")
    display(Image(plot.to_png(rotation_spectrum(curves, title=name))))

# %% [markdown] id="outliers-md"
# ## 3. Wrong loop closures
#
# A share of the loop closures is replaced by random ones (two random poses, a random
# rotation, a translation as wide as the graph), each claiming the replaced edge's
# information. Every method starts from the chordal start of the corrupted graph; an edge
# counts as rejected when its weight (GNC) is below 0.5 or its $e^T \Omega e$ (least squares,
# Cauchy) above the threshold $\bar c^2 = 16.81$ (chi-square, 6 degrees of freedom, 0.99).
# Errors are against the truth where it is known (the gtsam wheel's sphere2500), else against
# our solution of the graph without outliers. The row "oracle LS" is least squares on the
# corrupted graph with its wrong closures removed (known here, never in practice): the best
# any method can do with the right closures that are left, and the bar GNC is held to.

# %% id="outliers"
name, shares = ("smallGrid3D", (0.2,)) if SMALL else ("sphere2500", (0.1, 0.2, 0.5))
if load3d(name) is not None:
    with todo_as_one_line():
        rows, label = outliers3d.run(name, shares, seed=1, impl=IMPL)
        print(f"{name}: errors against {label}; threshold c2 = {robust.C2_6DOF_99:.2f} on e^T Omega e")
        print(outlier_table(rows))

# %% [markdown] id="gnc-weights-md"
# ### GNC's weights, round by round
#
# Our GNC again on smallGrid3D with 20% wrong closures (the same seed as the table), recording the
# weights of every round: each line is one loop closure (the odometry keeps weight 1). Round 0 is least
# squares; the next rounds follow the surrogate as $\mu$ moves.

# %% id="gnc-weights"
if lesson_graph is not None:
    corrupted = with_wrong_loop_closures(lesson_graph, 0.2, seed=1)
    with todo_as_one_line():
        gnc_runs = [robust.gnc(corrupted, surrogate, IMPL) for surrogate in ("tls", "gm")]
        display(Image(plot.to_png(chapter6.gnc_weights_figure(gnc_runs, corrupted.outliers, odometry(corrupted)))))
        print(chapter6.gnc_rounds_table(gnc_runs, corrupted.outliers, odometry(corrupted)))

# %% [markdown] id="questions-md"
# ## Questions
#
# Answer from the runs and figures of this notebook (in the quick setting, smallGrid3D).
#
# **Question 1.** The g2o files give a rotation information of about 400 where the gtsam
# wheel's copy of sphere2500 gives 100. Which error is each number for, and what goes wrong
# if a solver uses the file's number with the angle error?
#
# **Question 2.** GNC rejects the wrong loop closures that least squares keeps. Why does it
# need the odometry as known inliers, and what does the first, unweighted solve contribute?
#
# **Question 3.** The figure of section 1.2 shows the error made by taking $J_r^{-1}$ as the
# identity. The residual rotations of smallGrid3D reach 49 degrees at the minimum (experiment 2).
# About how wrong would the rotation rows of $A$ and $B$ be on those edges? Would Gauss-Newton with
# these Jacobians still stop at the same minimum? (What does a fixed point of its iteration satisfy?
# What does $J_r^{-1}(e_\phi)^\top$ do to the vector $e_\phi$ itself, and what does the answer need
# of the rotation block of $\Omega$?)
#
# **Question 4.** The chordal start has a far lower $\chi^2$ than the file's poses and saves
# Gauss-Newton iterations (experiment 1), yet its median residual rotation is *smaller* than at the
# minimum (experiment 2). How can a start have smaller rotation residuals than the minimum of
# $\chi^2$? What does the right panel of the chordal figure (singular values far below 1 away from
# the anchor) say about the relaxed problem on this graph?
#
# **Question 5.** In the fill-in table of section 3, how many blocks does the minimum-degree
# ordering save against the file order, and what do the wrong loop closures add? Why does a wrong
# closure between two random poses cost more in the factorization than a right closure between
# neighbours of the grid, and why then does GNC's inner problem leave out an edge whose weight is
# 0, rather than keep it with weight 0?

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
