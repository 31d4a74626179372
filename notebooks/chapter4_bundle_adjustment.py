# %% [markdown] id="title"
# # Chapter 4: bundle adjustment
#
# Bundle adjustment refines $C$ cameras and $P$ points from $K$ observations of the points
# in the images: the back end of structure from motion, and of visual SLAM once the map has
# landmarks. It is the largest least-squares problem of the course (ladybug-49: 23769
# unknowns, 63686 residuals), and it is solved in seconds because of its structure. The
# chapter is a lesson in this order:
#
# 1. **Theory**, derived: the BAL camera model; its Jacobians by the chain rule, through a
#    perturbation of the angle-axis vector (exercise `bundle_adjustment`, function
#    `reprojection_residuals_and_jacobians`), checked where you work with the course's Jacobian
#    checker `check_jacobian`; the block sparsity of J and H (`normal_equations`); the Schur
#    complement (`schur_solve`); robust costs as reweighted least squares (exercise
#    `robust_kernels`); the gauge freedom (exercise `gauge`); the parallel assembly (exercise
#    `parallel_assembly`). After each exercise's theory, a cell `check("...")` grades it here,
#    with the same sandboxed judge and public checks as `python -m autograder --only ...`.
# 2. **Experiments**: ours against the peers (Ceres through pycolmap, GTSAM, scipy) per
#    iteration and per second; a problem with fewer residuals than unknowns; points behind the
#    camera; dense against Schur; robust kernels against outliers; the parallel assembly's speed-up.
# 3. **Written questions.**
#
# Stuck on a derivation? `hint("reprojection_residuals_and_jacobians", 1)` (or
# `python -m autograder hint NAME LEVEL`) gives the approach, level 2 the key identity, level 3
# the result.
#
# Conventions, as everywhere in the course: residuals are predicted minus observed (pixels),
# $\chi^2 = \sum_k \lVert r_k\rVert^2$ (Ceres and the BAL files report the cost
# $\tfrac12 \sum_k \lVert r_k\rVert^2$, half of it), $H = J^\top J$, $g = J^\top r$, and a step
# solves $(H + D)\,\delta = -g$ with $D$ the damping. The state is
# $x = (\text{cameras}, \text{points})$, cameras first, $9C + 3P$ unknowns, and *every* unknown,
# the angle-axis vector too, moves by plain addition, $x \leftarrow x + \delta$.
# $[v]_\times$ is the skew matrix ($[v]_\times u = v \times u$), $\operatorname{Exp}$ the exponential map
# of SO(3).
#
# `SMALL = True` (set by `python -m notebooks.build --execute --small`, and by the tests)
# runs the quick setting: synthetic problems (`bal-synthetic:CAMERAS:POINTS`) instead of
# ladybug-49, few iterations, in well under a minute. The full setting takes a few minutes,
# most of them on ladybug-49 (every solver for 100 iterations) and the parallel timings. Set
# `IMPL = "exercises"` to run your own `bundle_adjustment`, `robust_kernels`,
# `parallel_assembly` and `gauge` through all of it; until they are written, the cells that
# need them say which TODO stops them, and the peers' runs go on without them.

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
from course import check_jacobian
from course.app import benchmark_bal, compare, parallel_speedup, plot
from course.notebook_helpers import chapter4
from course.notebook_helpers.bal import (
    behind_camera_detail,
    cost_figure,
    dense_vs_schur,
    dense_vs_schur_figure,
    dense_vs_schur_table,
    focal_length_table,
    gauge_figure,
    gauge_report,
    iteration_limit_table,
    kernel_figure,
    load,
    minimum_reached,
    mirror_points,
    neighbours_only,
    openmp_table,
    per_iteration_table,
    rank_report,
    size_sweep_figure,
    sparsity_counts,
    sparsity_figure,
)
from course.notebook_helpers.lesson import todo_as_one_line
from course.problems.bal import outliers
from course.problems.bal.dataset import load_bal

# "solutions", "exercises" or a path to your own copy (python -m notebooks.build --impl sets it);
# by default this tree's own: "exercises" in a student tree
IMPL = os.environ.get("COURSE_IMPL") or (
    "solutions" if (root / "solutions" / "__init__.py").is_file() else "exercises")
# runs per timing; the tables keep the median (--small sets 1)
REPEAT = int(os.environ.get("COURSE_NOTEBOOK_REPEAT", "5"))
# 1: the quick setting (synthetic problems; the tests run it, --small sets it); else the full one
SMALL = os.environ.get("COURSE_NOTEBOOK_SMALL", "0") == "1"
# our Levenberg-Marquardt (type 3) and dogleg, Ceres' LM and dogleg, GTSAM's LM, scipy's trf
METHODS = ["lm-type3", "dogleg", "levenberg-marquardt", "trf"]

# %% [markdown] id="camera-md"
# # Theory
#
# ## 1. The BAL camera model
#
# In the BAL convention (`course/problems/bal/dataset.py`) camera $c$ has 9 unknowns: the
# angle-axis vector $w$ of its rotation, its translation $t$, its focal length $f$ and its radial
# distortion $k_1, k_2$. Point $p$ has 3, its position $X$ in the world. Observation $k$ is the
# pixel $z_k$ where camera $c_k$ sees point $p_k$; the prediction goes through three stages.
#
# **Into the camera's frame.** $P = R(w)\,X + t$. The rotation by the angle $\theta = \lVert w\rVert$
# about the axis $n = w / \theta$ is the exponential of the skew matrix $W = [w]_\times$,
# $R(w) = \operatorname{Exp}(w) = \sum_{j \ge 0} W^j / j!$. For a unit axis,
# $n \times (n \times (n \times v)) = -\,n \times v$, so $W^3 = -\theta^2 W$: every odd power of $W$ is
# $(-\theta^2)^j\,W$ and every even one (from the second) is $(-\theta^2)^j\,W^2$. Collecting the two series,
#
# $$R(w) = I + \Big(\sum_{j\ge0} \frac{(-\theta^2)^j}{(2j+1)!}\Big) W
#        + \Big(\sum_{j\ge0} \frac{(-\theta^2)^j}{(2j+2)!}\Big) W^2
#        = I + \frac{\sin\theta}{\theta}\, W + \frac{1-\cos\theta}{\theta^2}\, W^2 ,$$
#
# Rodrigues' formula. Both coefficients are smooth, even functions of $\theta$: near 0 their series
# ($1 - \theta^2/6$, $1/2 - \theta^2/24$) replace the quotients, so that $w = 0$ never divides by zero.
#
# **The projection.** A BAL camera looks down its $-z$ axis: a point in front of it has $P_z < 0$.
# The ray from the camera's centre through $P$ meets the plane $z = -1$ at $P / (-P_z)$, whose
# first two coordinates are the normalised image point
#
# $$p = -P_{xy} / P_z .$$
#
# Every point of that ray, $\alpha P$ for $\alpha \ne 0$, has the same $p$: also $-P$, the mirror
# image through the centre, *behind* the camera (the left panel below; experiment 3 meets it).
#
# **Distortion and focal length.** A real lens bends rays radially: $p$ is scaled along its ray by
# a factor that depends on its distance from the centre of the image only,
# $d = 1 + k_1 \lVert p\rVert^2 + k_2 \lVert p\rVert^4$ (the right panel: $k_1 < 0$ pulls the corners
# in, barrel; $k_1 > 0$ pushes them out, pincushion), and the focal length converts to pixels
# (BAL's image coordinates are centred). The residual of observation $k$ is
#
# $$r_k = f\,d\,p - z_k \in \mathbb{R}^2, \qquad
#   \chi^2 = \sum_k \lVert r_k \rVert^2 \quad(\text{the BAL cost is } \tfrac12 \chi^2).$$

# %% id="figure-camera"
display(Image(plot.to_png(chapter4.camera_model_figure())))

# %% [markdown] id="jacobian-md"
# ## 2. The Jacobians, by the chain rule (exercise `bundle_adjustment`)
#
# Observation $k$ depends on 12 unknowns, the 9 of its camera and the 3 of its point, so its two
# rows of $J$ hold two blocks: $J_{\text{cam}}$ ($2 \times 9$, columns $w, t, f, k_1, k_2$) and
# $J_{\text{point}}$ ($2 \times 3$). The residual is a composition of the stages above,
#
# $$(w, t, X) \xrightarrow{\;P = R(w) X + t\;} P \in \mathbb{R}^3 \xrightarrow{\;p = -P_{xy}/P_z\;} p \in \mathbb{R}^2
#   \xrightarrow{\;f\,d(p)\,p\;} \hat z \in \mathbb{R}^2 ,$$
#
# so each block is a product of the stages' Jacobians:
#
# $$\frac{\partial r}{\partial X} = A\,\frac{\partial P}{\partial X}, \quad
#   \frac{\partial r}{\partial t} = A\,\frac{\partial P}{\partial t}, \quad
#   \frac{\partial r}{\partial w} = A\,\frac{\partial P}{\partial w}, \qquad
#   A = \frac{\partial \hat z}{\partial p}\,\frac{\partial p}{\partial P} \quad (2 \times 3),$$
#
# with $A$ computed once per observation, while $f, k_1, k_2$ enter only the last stage
# ($\partial r / \partial f$, $\partial r / \partial k_1$, $\partial r / \partial k_2$ directly from $f\,d\,p$).
# $P$ is affine in $t$ and linear in $X$: $\partial P / \partial t = I$ and $\partial P / \partial X = R(w)$.
# $\partial p / \partial P$ ($2 \times 3$) is the quotient rule on $-P_x / P_z$ and $-P_y / P_z$ (each row
# depends on $P_z$ too); $\partial \hat z / \partial p$ ($2 \times 2$) is the product rule on the scalar
# $f\,d$ times the vector $p$, where $d$ depends on $p$ through $\lVert p\rVert^2 = p^\top p$. Those
# three are yours to write out.
#
# **A perturbation of the angle-axis.** The hard stage is $\partial (R(w) X) / \partial w$. Rotations
# compose by multiplication, and $R(w + \delta w) \ne R(w)\,R(\delta w)$ unless $\delta w$ is parallel to $w$. What
# holds to first order is that a change of the angle-axis vector is a small rotation applied on the
# right, through a $3 \times 3$ matrix that depends on $w$, the *right Jacobian* of SO(3):
#
# $$R(w + \delta w) = R(w)\,\operatorname{Exp}\big(J_r(w)\,\delta w\big) + O(\lVert\delta w\rVert^2),
#   \qquad J_r(0) = I$$
#
# (`course.geometry.so3.right_jacobian`; its closed form is in the hints).
#
# **The derivative of a rotated point.** For a small rotation on the right,
# $\operatorname{Exp}(\phi) = I + [\phi]_\times + O(\lVert\phi\rVert^2)$, and
# $[\phi]_\times X = \phi \times X = -X \times \phi = -[X]_\times \phi$, so
#
# $$R\,\operatorname{Exp}(\phi)\,X = R X - R\,[X]_\times\,\phi + O(\lVert\phi\rVert^2), \qquad
#   \frac{\partial\, R \operatorname{Exp}(\phi) X}{\partial \phi}\Big|_{\phi = 0} = -R\,[X]_\times .$$
#
# Chain this with the perturbation above to get $\partial (R(w) X) / \partial w$. Taking $-R[X]_\times$ itself
# for it is the classic slip: it is the derivative for an update $R \leftarrow R \operatorname{Exp}(\delta)$,
# not for $w \leftarrow w + \delta w$. The figure is the *Taylor test* of three candidates $D$ for the
# derivative at $\lVert w\rVert = 2$ rad: the error $\lVert R(w + e u) X - R(w) X - e\,D u\rVert$ falls like
# $e^2$ (slope 2) only for the true derivative; a wrong one leaves a first-order error (slope 1).

# %% id="figure-taylor"
display(Image(plot.to_png(chapter4.rotation_taylor_figure())))

# %% id="hint-jacobians"
hint("reprojection_residuals_and_jacobians", 1)  # level 1, the approach; 2 the key identity, 3 the result

# %% [markdown] id="jacobian-check-md"
# **Check your Jacobians where you work.** `course.check_jacobian(f, x, J, plus=...)` moves each
# variable along each of its coordinates, takes central differences of `f` and compares them with
# your `J` entry by entry; a wrong entry is reported with its block (`d y / d camera w`: the row
# of the residual, the variable and its part). Here on one observation of a small synthetic
# scene, whose camera is rotated by about 2 rad (far from $w = 0$, where a missing $J_r$ goes
# unnoticed), with your `reprojection_residuals_and_jacobians`; then once more with one entry
# spoilt on purpose, to show what a slip looks like. (`chapter4.CAMERA` names a camera's 9
# columns $w, t, f, k_1, k_2$; both variables move by plain addition.) Use it the same way on
# your own cases: $w = 0$ exactly, $\lVert w\rVert$ near $\pi$, strong distortion.

# %% id="jacobian-check"
scene = load_bal("bal-synthetic:6:40")
k = chapter4.generic_observation(scene)  # the first observation whose camera is rotated by about 2 rad
print(chapter4.observation_line(scene, k))
with todo_as_one_line():
    f, x, J, plus, names, rows = chapter4.observation_setup(scene, k, IMPL)  # your function, on this observation
    check_jacobian(f, x, J=J, plus=plus, names=names, rows=rows)
    print("\nwhat a slip looks like (the sign of J_cam[1, 2], d y / d w_z, flipped):")
    slip = J[0].copy()
    slip[1, 2] *= -1.0
    check_jacobian(f, x, J=[slip, J[1]], plus=plus, names=names, rows=rows)

# %% id="check-jacobians"
check("bundle_adjustment.reprojection_residuals_and_jacobians")

# %% [markdown] id="blocks-md"
# ## 3. The block sparsity of J and H: the arrow
#
# Stack the $K$ residuals into $r$ ($2K$) and the unknowns into $x$ ($9C + 3P$). The two rows of
# observation $k$ in $J$ are zero except for $J_{\text{cam},k}$ in the 9 columns of camera $c_k$ and
# $J_{\text{point},k}$ in the 3 of point $p_k$: 24 nonzeros in rows of length $9C + 3P$. Write $J_k$ for
# those two rows. Then
#
# $$H = J^\top J = \sum_k J_k^\top J_k, \qquad g = J^\top r = \sum_k J_k^\top r_k, \qquad
#   \chi^2 = \sum_k \lVert r_k\rVert^2 ,$$
#
# and each $J_k^\top J_k$ has four nonzero blocks: $J_{\text{cam},k}^\top J_{\text{cam},k}$ at $(c_k, c_k)$,
# $J_{\text{point},k}^\top J_{\text{point},k}$ at $(p_k, p_k)$, $J_{\text{cam},k}^\top J_{\text{point},k}$ at
# $(c_k, p_k)$ and its transpose at $(p_k, c_k)$. Summed over the observations, with the cameras first,
#
# $$H = \begin{bmatrix} U & W \\ W^\top & V \end{bmatrix}, \quad
#   U = \operatorname{blockdiag}(U_c)\ (9 \times 9 \text{ each}), \quad
#   V = \operatorname{blockdiag}(V_p)\ (3 \times 3 \text{ each}), \quad
#   W: \text{a } 9 \times 3 \text{ block } W_k \text{ at } (c_k, p_k),$$
#
# where $U_c$ sums over camera $c$'s observations and $V_p$ over point $p$'s (the docstring of
# `normal_equations` has each sum). No term couples two cameras, nor two points: $U$ and $V$ are
# block diagonal, and only a camera and a point it sees share a block. Drawn, $H$ is an *arrow*: a
# long diagonal of $P$ small blocks $V_p$, and the cameras' rows and columns along its border ($U$ and
# $W$; the middle panels below, cameras left of and above the dashed line). The pattern depends on
# the observation indices alone, not on the values: the table counts it without forming anything,
# so it also runs on ladybug-49, where J and H are a fraction of a percent full.
#
# The figure: two small synthetic problems at their start. Top: cameras on a ring around the scene,
# each point seen by 2 to 5 cameras chosen at random, so that nearly every pair of cameras shares a
# point. Bottom: the same kind of scene with only the observations by the point's own camera and its
# two neighbours on the ring (`neighbours_only`), the covisibility of a camera moving along a path.
# The right panels, $S$, are the subject of section 4.

# %% id="sparsity"
ring = load_bal("bal-synthetic:6:40")
path = neighbours_only(load_bal("bal-synthetic:12:120"), window=1)
with todo_as_one_line():
    display(Image(plot.to_png(sparsity_figure([ring, path], IMPL))))  # the nonzeros of your Jacobians
for problem in (ring, path, load("ladybug-49")):
    if problem is not None:
        print(sparsity_counts(problem))
        print()

# %% id="check-normal-equations"
check("bundle_adjustment.normal_equations")

# %% [markdown] id="schur-md"
# ## 4. The Schur complement: eliminate the points
#
# A damped step solves $(H + D)\,\delta = -g$, $9C + 3P$ unknowns (ladybug-49: 23769, a dense $H$ of
# 4.5 GB in the table above). Split the step and the gradient into cameras and points and take the
# damping into $U$ and $V$ (it is diagonal, so they stay block diagonal):
#
# $$\begin{bmatrix} U & W \\ W^\top & V \end{bmatrix}
#   \begin{bmatrix} \delta_c \\ \delta_p \end{bmatrix} = -\begin{bmatrix} g_c \\ g_p \end{bmatrix} .$$
#
# **Block elimination.** This is Gaussian elimination done by blocks. The second block row,
# $W^\top \delta_c + V \delta_p = -g_p$, gives the points' step once the cameras' is known,
#
# $$\delta_p = V^{-1}\,(-g_p - W^\top \delta_c) \qquad \text{(back-substitution)},$$
#
# and putting it into the first block row, $U \delta_c + W \delta_p = -g_c$, leaves a system in the
# cameras alone, the **reduced camera system**:
#
# $$\underbrace{(U - W V^{-1} W^\top)}_{S\ (9C \times 9C)}\ \delta_c = -g_c + W V^{-1} g_p .$$
#
# $S$ is the Schur complement of $V$ in $H + D$; it is symmetric positive definite when $H + D$ is
# (for any $\delta_c \ne 0$, $\delta_c^\top S \delta_c$ is the quadratic form of $H + D$ at
# $(\delta_c, -V^{-1} W^\top \delta_c)$).
#
# **Why the points, and why it is cheap.** $V$ is block diagonal, so
# $V^{-1} = \operatorname{blockdiag}(V_p^{-1})$: $P$ independent $3 \times 3$ inverses, $O(P)$ work where a
# dense matrix of that size costs $O((3P)^3)$. (A $V_p$ is invertible when point $p$ is seen from two
# places at least, or damped: one observation gives it rank 2.) Eliminating the cameras instead would
# leave a $3P \times 3P$ system, and in bundle adjustment $P \gg C$. What remains to factor is $S$, of
# size $9C$; the rest of the step is $O(K)$ products of small blocks.
#
# **The structure of S.** $W V^{-1} W^\top$ couples two cameras only through a point they both see ($V^{-1}$
# is block diagonal: it never mixes two points). So $S$ has a nonzero $9 \times 9$ block exactly where
# two cameras see a common point: the covisibility graph
# (the right panels of the figure above: dense on the ring, banded along the path). That is why
# `schur_solve` factors $S$ densely when it is small or mostly full, and why forming $S$, not
# factoring it, is most of a step on a problem like ladybug-49 (experiments 1 and 4).
#
# In `schur_solve` you write this with the blocks: which $W_k$ pairs add into which block of $S$,
# how the right-hand side and the back-substitution gather per camera and per point, no dense
# matrix of size $9C + 3P$ and no Python loop over observations.

# %% id="hint-schur"
hint("schur_solve", 1)

# %% id="check-bundle-adjustment"
check("bundle_adjustment")

# %% [markdown] id="robust-md"
# ## 5. Robust costs: reweighted least squares (exercise `robust_kernels`)
#
# Least squares trusts every residual: a wrong match 50 pixels off costs 2500 and pulls on the
# solution with a force that grows with it (the gradient $2 J_k^\top r_k$). A robust kernel $\rho$
# replaces each observation's squared norm $s_k = \lVert r_k\rVert^2$ (or $r_k^\top \Omega_k r_k$) by
# $\rho(s_k)$:
#
# $$F(x) = \sum_k \rho\big(s_k(x)\big), \qquad \rho(s) = s + O(s^2)\ \text{near } 0 \quad(\rho(0) = 0,\ \rho'(0) = 1),$$
#
# so that an inlier costs what it costs without a kernel.
#
# **The gradient is a weighted one.** By the chain rule,
# $\nabla F = \sum_k \rho'(s_k)\,\nabla s_k = \sum_k \rho'(s_k)\, 2 J_k^\top r_k$. A weighted least-squares cost
# $\sum_k w_k s_k$ with *fixed* weights has the gradient $\sum_k w_k\, 2 J_k^\top r_k$: the two agree at $x$
# when $w_k = \rho'(s_k(x))$. So a stationary point of the robust cost is a stationary point of the
# least-squares problem weighted by $\rho'$ at that point, and **iteratively reweighted least squares**
# (IRLS) finds it: compute the weights at the current estimate, take a Gauss-Newton step of the
# weighted problem ($H = \sum_k w_k J_k^\top J_k$), repeat. How hard a residual pulls is its
# *influence*, $\partial \rho / \partial \lVert r\rVert = 2 \lVert r\rVert\,\rho'(s)$: for least squares it grows
# without bound.
#
# **Triggs' correction.** IRLS freezes the weight during the step and so ignores that the weight
# changes with the residual. The exact second derivative of one term, $\rho(s(e))$ as a function of
# the residual $e$, has by the chain and the product rule two parts:
#
# $$\nabla_e^2\, \rho(s(e)) = \rho'(s)\,\nabla_e^2 s + \rho''(s)\,\nabla_e s\,\nabla_e s^\top .$$
#
# The first is the reweighted curvature; the second is a rank-one term along $\nabla_e s$, the
# direction of the residual, where it changes the curvature by a multiple of $\rho''$ (negative for
# every kernel below: less curvature). Substitute $s = e^\top \Omega e$, halve as $\chi^2$'s
# $H = J^\top \Omega J$ is halved, and keep only first derivatives of $e$ (Gauss-Newton): that is
# `robust_information` (Triggs et al., 1999, section 4.3). Along the residual the corrected
# curvature becomes $\rho' + 2\rho'' s$ (in the metric of $\Omega$); where that is not positive, the
# corrected $H$ could be indefinite and the step go uphill, so `robust_information` keeps IRLS's
# first-order weight $\rho'$ there.
#
# **Three kernels** (scale $a$, in pixels of $\lVert r\rVert$; their definitions are in the module's
# docstring, Ceres' scaled forms):
#
# * **Huber**: $\rho = s$ up to $s = a^2$, then $2a\sqrt{s} - a^2$, linear in $\lVert r\rVert$: convex (one
#   minimum), and an outlier's influence is bounded but never vanishes;
# * **Cauchy**: $\rho = a^2 \log(1 + s/a^2)$, logarithmic in $\lVert r\rVert$: the influence *redescends*,
#   falls back towards 0 far out; no longer convex;
# * **Tukey** (biweight): $\rho = \tfrac{a^2}{3}\big(1 - (1 - s/a^2)^3\big)$ up to $a^2$, then the constant
#   $a^2/3$: beyond $a$ a residual has no influence at all, wherever it comes from, at the start too.
#
# Derive $\rho'$ and $\rho''$ in $s$ (not in $\lVert r\rVert$) for each. The first figure plots your kernels at
# the scales of experiment 5 (Huber and Cauchy at $a = 2.45$ pixels, the 95% quantile of an inlier's
# $\lVert r\rVert$ with 1-pixel noise, Tukey at 4.5): left the cost, right the weight $\rho'$ (solid) and the
# corrected curvature $\rho' + 2\rho'' s$ (dashed): zero beyond the scale for Huber, negative beyond it for
# Cauchy, and for Tukey negative already from $a/\sqrt{5}$. The second runs IRLS with your weights on
# the smallest problem there is, one unknown measured 50 times, 10 of them wrong (around 12 instead
# of 0): the least-squares mean is pulled to 2.7; each kernel starts there.

# %% id="kernels"
with todo_as_one_line():
    display(Image(plot.to_png(kernel_figure(outliers.DEFAULT_LOSSES, IMPL))))

# %% id="figure-irls"
location = chapter4.location_data()  # 40 samples N(0, 1), 10 outliers N(12, 2^2)
with todo_as_one_line():
    irls = chapter4.irls_location(location, outliers.DEFAULT_LOSSES[:4], IMPL)  # your kernels' weights rho'
    display(Image(plot.to_png(chapter4.irls_figure(location, irls))))

# %% id="hint-robust"
hint("robust_kernels", 1)

# %% id="check-robust"
check("robust_kernels")

# %% [markdown] id="gauge-md"
# ## 6. The gauge freedom (exercise `gauge`)
#
# Move the whole scene by a similarity, $X \mapsto k\,Q X + s$ (a rotation $Q$, a shift $s$, a scale
# $k > 0$), and move every camera with it, so that it sees each point where it saw it before: in the
# camera's frame, $R' X' + t'$ must equal $R X + t$ for a rotation or a shift of the scene, and $k$ times
# it for a scaling, which the projection $p = -P_{xy}/P_z$ divides out; $f, k_1, k_2$ do not move.
# Every residual is then unchanged: the cost cannot tell the two scenes apart, and its minimum is
# not a point but a 7-dimensional family (3 rotations, 3 translations, 1 scale).
#
# **The null space of H.** Take a one-parameter family of such moves, e.g. the rotation of the
# scene by the angle $\varepsilon$ about axis $u_a$, $X(\varepsilon) = \operatorname{Exp}(\varepsilon u_a) X$, with the
# cameras moved along, and differentiate the state at $\varepsilon = 0$: $n = dx/d\varepsilon$ ($9C + 3P$). No
# residual changes along it to first order, $J n = 0$, hence
#
# $$n^\top H n = \lVert J n\rVert^2 = 0 \quad\Longrightarrow\quad H n = 0
#   \qquad (H \text{ is positive semi-definite}),$$
#
# and the 7 directions (your `gauge_directions`, the columns of $N$, $(9C + 3P) \times 7$) span 7 zero
# eigenvalues of $H$. Undamped Gauss-Newton meets a singular system: any multiple of $n$ can be added
# to a step. For each move, derive the change of every point and of every camera's $w$ and $t$ from
# the condition above (the camera's rotation changes by a small rotation on the right: section 2's
# $J_r$ converts it into a change of $w$, through its inverse).
#
# There are three remedies: **fix the gauge** by holding 7 unknowns
# (`BundleAdjustmentProblem(fix_gauge=True)` holds camera 0's pose and one coordinate of camera 1:
# their rows and columns of $H$ become unit rows), **damp** ($H + \lambda D$ is positive definite: what
# Levenberg-Marquardt does anyway), or **priors** (GTSAM's soft priors on camera 0 and point 0). Below,
# the spectrum of $H$ at the start of a small synthetic problem: with the gauge free, 7 eigenvalues sit
# at rounding level, far below the rest; with the gauge fixed, the plateau of 7 equal eigenvalues at 1
# over the largest, and none is zero. The text checks your $N$ where you work: $J N = 0$, and span($N$)
# is the span of $H$'s 7 lowest eigenvectors. (Experiment 2 meets a problem with more null directions
# than the gauge.)

# %% id="gauge"
small_scene = load_bal("bal-synthetic:5:40")
with todo_as_one_line():
    print(gauge_report(small_scene, IMPL))  # your gauge_directions against your Jacobians
    display(Image(plot.to_png(gauge_figure(small_scene, IMPL))))

# %% id="hint-gauge"
hint("gauge_directions", 1)

# %% id="check-gauge"
check("gauge")

# %% [markdown] id="assembly-md"
# ## 7. The parallel assembly (exercise `parallel_assembly`)
#
# $U$, $V$, $g$ and $\chi^2$ are sums over the observations (section 3), so they can be summed in
# parts: split the $K$ observations into $n$ contiguous chunks $[b_i, b_{i+1})$, assemble each chunk's
# partial sums $U^{(i)}, V^{(i)}, g^{(i)}, \chi^{2\,(i)}$ on its own thread, and add the parts:
# $U = \sum_i U^{(i)}$, and so on ($W$ has one block per observation: the chunks' $W$ are concatenated
# in observation order). Threads, not processes: numpy releases the interpreter's lock inside its
# large calls, and threads share the Jacobians where processes would copy them (the module's
# docstring measures both).
#
# **The sum in a fixed order.** Floating-point addition is commutative but not associative:
# $(a + b) + c$ and $a + (b + c)$ can differ in the last bit. So the parallel sums equal the serial ones
# only to rounding (about $10^{-16}$ relative), and they depend on the chunks. What they must not
# depend on is the number of workers, nor which thread finishes first: a result that changes from run
# to run makes a bug impossible to reproduce and a test flaky. Hence the chunks are fixed by their
# number alone (`chunk_bounds`: contiguous, sizes that differ by at most one), and the partial sums
# are added in chunk order, the order of submission, never in the order the threads complete. (By
# default there is one chunk per worker, so changing the workers changes the chunks; pass `chunks`
# to keep them.) The table runs your `normal_equations_parallel` with a fixed number of chunks on 1, 2
# and 4 workers, three times each: the same bits every time, and a difference from the serial
# assembly that is zero for one chunk and rounding otherwise. (Whether the threads make it faster is
# experiment 6.)

# %% id="sum-order"
with todo_as_one_line():
    print(chapter4.sum_order_table(load_bal("bal-synthetic:20:3000:3"), IMPL))  # your parallel assembly

# %% id="hint-parallel"
hint("parallel_assembly", 1)

# %% id="check-parallel"
check("parallel_assembly")

# %% [markdown] id="experiments-md"
# # Experiments
#
# The theory's pieces at work on whole problems: our Levenberg-Marquardt and dogleg with the Schur
# complement against the peers on the same problems and starts, a problem whose minimum is not
# unique, the points behind a camera, the price of a dense step, robust kernels against outliers and
# the parallel assembly's speed-up. Until your `bundle_adjustment` is written, our rows say which
# TODO stops them and the peers run all the same.

# %% [markdown] id="costs-md"
# ## 1. Cost per iteration and per second
#
# Every solver from the problem's own start, the gauge fixed as each peer fixes it (ours
# and Ceres: camera 0's pose and one coordinate of camera 1; GTSAM: soft priors on camera 0
# and point 0), at most `ITERATIONS` iterations: our Levenberg-Marquardt and dogleg with
# the Schur complement, Ceres' (C++, through pycolmap), GTSAM's Levenberg-Marquardt and
# scipy's `least_squares` recipe (trf; one "iteration" is one evaluation of the residuals).
# The table's chi2 is ours, over all observations, at each solver's result (experiment 3 puts
# each peer's own cost beside it). The figure plots each back end's *own* cost, the one it
# minimizes, so the curves of Ceres and GTSAM on ladybug-49 do not count the observations
# they set aside (experiment 3). On the synthetic problem every solver reaches the same
# minimum (GTSAM's slightly above: its priors on camera 0 and point 0 pull them towards the
# start); look at how many iterations each takes and how long one iteration is. On
# ladybug-49 (49 cameras, 7776 points, 31843 observations, start cost 850912.46) look for
# where each curve flattens, and which solvers end close to each other. An LM with the
# Schur complement on the all-observations cost reaches about 13344.24 (13344.2407 after
# 500 iterations, `course.app.benchmark_bal.MINIMA`): the last line says when ours is within
# 1e-6 of it. (Quick setting: the synthetic problem only.)

# %% id="costs"
ITERATIONS = 20 if SMALL else 100
runs = {}
for name in (["bal-synthetic:10:300"] if SMALL else ["bal-synthetic:30:3000", "ladybug-49"]):
    problem = load(name)
    if problem is None:
        continue
    # a pair stopped by a TODO of yours is a row naming it; the peers run all the same
    runs[name] = compare.run_bal(problem, impl=IMPL, methods=METHODS, max_iterations=ITERATIONS, unimplemented="row")
    print(compare.format_table(runs[name], f"{problem.name}: {problem.num_cameras} cameras, {problem.num_points} "
                                            f"points, {problem.num_observations} observations, at most "
                                            f"{ITERATIONS} iterations"))
    display(Image(plot.to_png(cost_figure(runs[name], f"{problem.name}: each back end's own cost"))))
    print(minimum_reached(problem.name, runs[name]))

# %% [markdown] id="per-iteration-md"
# ### Time per iteration
#
# The figure's seconds come from one run each. Here each back end runs 10 iterations (scipy:
# 2 evaluations) from the start, `min(REPEAT, 3)` times, interleaved, and the table keeps the
# median time per iteration (`course.app.benchmark_bal.per_iteration`), on ladybug-49 (quick
# setting: 5 iterations on the synthetic problem). Ours evaluates the Jacobians and assembles U, V, W in
# numpy, sums S's reduction term over the camera pairs in a compiled pass (numba, where installed:
# `course.solver.schur_reduction`) and factors S with scipy; Ceres does all of it in C++ (one thread); GTSAM
# linearizes one factor at a time and eliminates with its own ordering; scipy differentiates
# by finite differences (one evaluation per group of independent columns) and solves with
# LSMR.

# %% id="per-iteration"
name = "bal-synthetic:10:300" if SMALL else "ladybug-49"
if load(name) is not None:
    iterations = 5 if SMALL else 10
    with todo_as_one_line():
        timings = benchmark_bal.per_iteration(name, repeats=min(REPEAT, 3), iterations=iterations, impl=IMPL,
                                              scipy_evaluations=2)
        print(per_iteration_table(timings, f"{name}: milliseconds per iteration, median of {min(REPEAT, 3)} "
                                           f"(scipy: per evaluation); ours is lm-type3, the gauge fixed"))

# %% [markdown] id="sweep-md"
# ### How the cost grows
#
# The same measurement on `bal-synthetic` problems from about 10,000 to 300,000 observations
# (`course.app.benchmark_bal.size_sweep`: 20 to 400 cameras, each point seen by 2 to 5 random
# ones, 5 iterations, `min(REPEAT, 3)` runs; quick setting: three tiny problems). Each camera
# shares points with more others as the cameras multiply, so S fills in: past 100 cameras it is
# nearly dense, and `schur_solve` then factorizes it densely (`DENSE_FILL`), as a sparse
# factorization of a dense matrix does the same work with more bookkeeping. Does the ratio
# grow with the size? Where does the fixed cost of a Python iteration show?

# %% id="sweep"
sizes = ((4, 30), (10, 300), (20, 900)) if SMALL else benchmark_bal.SWEEP
with todo_as_one_line():
    sweep = benchmark_bal.size_sweep(sizes, repeats=min(REPEAT, 3), iterations=2 if SMALL else 5, impl=IMPL)
    print(benchmark_bal.format_sweep(sweep))
    display(Image(plot.to_png(size_sweep_figure(sweep))))

# %% [markdown] id="rank-md"
# ## 2. dubrovnik-3-7: fewer residuals than unknowns
#
# dubrovnik-3-7 (it ships with gtsam) has 3 cameras and 7 points: 48 unknowns, and 19
# observations: 38 residuals. J has at most 38 independent rows, so at least 10 directions
# change no residual to first order: 7 of them are the gauge (theory, section 6), and fixing the
# gauge (7 unknowns held) still leaves at least 3. With more unknowns than equations the
# residuals can generally all be made zero, along a whole family of solutions: the cost
# has no unique minimum, and no solver can be said to converge *to* it. Below, every
# solver with growing iteration limits: a cost that keeps falling with more iterations, or
# that stops at zero (up to rounding) on a different point for each solver. The last table
# shows the focal lengths of each result: a similarity of the scene (the gauge) leaves $f$
# unchanged, so different $f$ at zero cost are different minima, not one minimum in two
# gauges. Compare iterations and trends here, not final costs. (Skipped where gtsam is not
# installed.)

# %% id="rank"
dubrovnik = load("dubrovnik-3-7")
if dubrovnik is not None:
    with todo_as_one_line():
        print(rank_report(dubrovnik, IMPL))
        print()
        table, last = iteration_limit_table(dubrovnik, IMPL, (5, 20, 100) if SMALL else (10, 50, 200, 1000), METHODS)
        print(table)
        print()
        print(focal_length_table(dubrovnik, last))

# %% [markdown] id="behind-md"
# ## 3. Points behind the camera
#
# A point is in front of a BAL camera when $P_z < 0$. The projection $p = -P_{xy} / P_z$ is
# unchanged when $P$ becomes $-P$: the formula sees a point behind the camera exactly where
# it sees its mirror image through the camera's centre, in front. ladybug-49 starts with 31
# observations (of 10 points, every one of their observations) behind their cameras. The
# BAL cost counts them like any other, and each peer has its own answer (each module's
# docstring in `course/backends/` says more):
#
# * **Ceres through pycolmap** deletes, before it solves, every observation whose point is
#   behind its camera, and the points left with fewer than two observations: it solves a
#   smaller problem (on ladybug-49: 31812 observations), and during the solve its cost scores
#   an observation that crosses behind the camera zero;
# * **GTSAM** keeps them, but `GeneralSFMFactor` scores an observation behind its camera zero
#   (with zero Jacobians) while it stays there (its LM on ladybug-49 stalls near 14629 after
#   about 400 iterations, where our cost of its result is much higher);
# * **scipy's recipe** and **ours** keep them and apply the BAL formula as it stands.
#
# So the peers' own costs are costs of different problems. The table below shows each run's
# final cost by our formula over all observations beside the peer's own, how many
# observations have their point behind the camera at the start and at the result, and what
# the peer removed. A point that crosses the camera's plane during a solve that scores it
# zero pulls on nothing and can end anywhere: look at the Ceres dogleg's row on ladybug-49,
# where one point ends on a camera's plane and our formula puts its residual out of all
# proportion. (Quick setting, or without the data folder: the synthetic problem with 4
# points mirrored through the centre of one of their cameras, `mirror_points`, so that they
# start behind that camera with an unchanged residual there.)

# %% id="behind"
if "ladybug-49" in runs:
    problem, behind_runs = load_bal("ladybug-49"), runs["ladybug-49"]
else:
    problem = mirror_points(load_bal("bal-synthetic:10:300"), 4)
    behind_runs = compare.run_bal(problem, impl=IMPL, methods=METHODS, max_iterations=ITERATIONS,
                                  unimplemented="row")
    print(compare.format_table(behind_runs, f"{problem.name}, at most {ITERATIONS} iterations"))
    print()
print(behind_camera_detail(problem))
print()
print(compare.format_bal(behind_runs))

# %% [markdown] id="dense-md"
# ## 4. Dense against Schur as the number of points grows
#
# One damped step $(H + \lambda\,\mathrm{diag}(H))\,\delta = -g$, $\lambda = 10^{-3}$, on
# synthetic problems with 10 cameras and a growing number of points, solved two ways on one
# BLAS thread (`dense_vs_schur`): a dense Cholesky factorization of the whole
# $(9C + 3P)^2$ matrix (H formed beforehand, not timed), against `schur_solve` from the blocks
# (forming S included). The dense solve grows like $(9C + 3P)^3$, cubic in P once the points
# dominate; at fixed C the Schur solve grows linearly in P (the elimination touches each
# observation once; S stays $90 \times 90$). The last column checks that both give the same
# step. Look at where the two curves cross, and at the growth exponents under the table.

# %% id="dense"
point_counts = [50, 100, 200, 400] if SMALL else [50, 100, 200, 400, 800, 1600]
with todo_as_one_line():
    steps = dense_vs_schur(10, point_counts, IMPL, repeat=min(REPEAT, 3))  # your schur_solve against a dense Cholesky
    print(dense_vs_schur_table(steps, 10))
    display(Image(plot.to_png(dense_vs_schur_figure(steps, 10))))

# %% [markdown] id="outliers-md"
# ## 5. Robust kernels against outliers
#
# The kernels of theory section 5 on a whole problem (`course.problems.bal.outliers`): a
# synthetic problem (12 cameras, 300 points, 1-pixel noise) with 10% of its observations moved
# by a further $N(0, 50^2)$ pixels, solved by our LM (the gauge fixed, at most 100 iterations)
# with each loss; the figure of merit is
# the RMS reprojection error of the *inliers* at the solution, against the same problem
# solved without the outliers (first row). Least squares lets the outliers pull the scene
# away from the inliers; look at which kernel brings the inliers' RMS back to the
# outlier-free value (`/ outlier-free` near 1), and at Tukey alone, which also ignores the
# inliers that start far off (10 pixels and more): from Cauchy's solution (the last row) it
# does not.

# %% id="outliers"
with todo_as_one_line():
    reference, rows = outliers.run(12, 300, seed=1, impl=IMPL)
    print(outliers.table(reference, rows))

# %% [markdown] id="parallel-md"
# ## 6. The parallel assembly's speed-up
#
# The source's table (one solve on EuRoC MH_05, C++ with OpenMP in the assembly of the
# normal equations) says that threads helped Levenberg-Marquardt and hurt the dogleg. Below
# it, ours (`course.app.parallel_speedup`, your `parallel_assembly.normal_equations_parallel`):
# first the assembly alone, serial against threads (`Nw`: N workers) and against forked
# processes (`Np`), then whole step attempts with the serial and the parallel assembly,
# where the column `2w/serial` is the quantity of the source's `speed-up` column, with the
# assembly's share of an attempt and Amdahl's bound. A parallel assembly pays only where the
# assembly is a large part of the time and the work per thread outweighs starting the
# threads and summing their parts; on this machine two cores are shared with everything
# else. (Quick setting: small synthetic problems, one run each.)

# %% id="parallel"
print(openmp_table())
print()
if SMALL:
    parallel_speedup.section(repeats=1, impl=IMPL, problems=("bal-synthetic:8:300:3", "bal-synthetic:20:3000:3"),
                             iteration_problems=("bal-synthetic:20:3000:3",), attempts=3, iteration_repeats=1)
else:
    parallel_speedup.section(repeats=REPEAT, impl=IMPL, iteration_repeats=min(REPEAT, 3))

# %% [markdown] id="questions-md"
# # Written questions
#
# Answer in the cells below, in a few sentences each. Use the measurements above (those of
# the full setting where they differ).
#
# **Question 1.** On ladybug-49 the four back ends report different final costs, and the
# peers' own costs differ from ours at their own results. Why can the BAL projection
# formula not tell a point behind the camera from one in front, and what does each peer's
# answer (delete, score zero, keep) change in the problem it solves? Which costs in the
# tables can be compared with each other, and which answer would you want in a SLAM back
# end, where a new point's first estimate may be behind a camera?
#
# **Question 2.** On dubrovnik-3-7 every solver's cost keeps falling, or stops at zero, and
# the focal lengths of the results differ. Count the residuals and unknowns: why is there
# no unique minimum even with the gauge fixed, and what does that do to a comparison of
# solvers by their final cost? What would you change (in the problem, or in what you
# report) to compare them fairly?
#
# **Question 3.** In experiment 4 the dense step's time grows much faster with the number of
# points than the Schur step's (the growth exponents under its table). Using the derivation of
# theory section 4, say which parts of a Schur step grow with the observations and which with
# the cameras alone, and why the exponents come out as they do. How would the balance change
# for a problem with ten times as many cameras and the same number of observations per camera,
# first when every camera shares points with most others (the ring of the sparsity figure),
# then when each shares points only with its neighbours (the path)?
#
# **Question 4.** In experiment 5, Huber leaves the inliers' RMS about five times its
# outlier-free value, Cauchy brings it back, and Tukey does so only when it starts from Cauchy's
# solution. Explain the three with the weights $\rho'$ and the influence of a residual (the
# kernel figure and the IRLS figure of theory section 5). Why does Tukey from the start fail
# here, when it worked on the 1-D example? What does it suggest for a SLAM back end that must
# start from a rough estimate?
#
# **Question 5.** The table of theory section 7 shows differences from the serial assembly of
# about $10^{-15}$ that do not change with the number of workers. Why are they not zero, why do
# they not depend on the workers, and what would change if the partial sums were added as the
# threads finish? Then, in experiment 6: using the assembly's share of a step attempt and
# Amdahl's bound, explain why two threads barely change the time of a whole step here, while the
# source's C++ Levenberg-Marquardt gained 1.47 times.

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
