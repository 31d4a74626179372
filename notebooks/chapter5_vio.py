# %% [markdown] id="title"
# # Chapter 5: a sliding-window visual-inertial back end
#
# A camera alone sees neither the scale of its motion nor which way is down; an IMU (a gyroscope
# and an accelerometer) sees both, but integrated alone it drifts within seconds. A
# visual-inertial back end fuses them: keyframes linked by IMU factors and landmarks seen by
# the camera, in a window of the last few keyframes that slides along the trajectory. The
# chapter is a lesson in this order:
#
# 1. **Theory**, derived: IMU preintegration (exercise `imu_preintegration`, function
#    `preintegrate`): the increments that need neither the start state nor gravity, the
#    discrete recursion, the error state and its covariance, the bias Jacobians; the IMU factor
#    and what each of its 15 rows compares (`imu_factor_residual`); the sliding window;
#    marginalisation as a Schur complement, the prior as a linear factor, fill-in, and why
#    the prior's linearisation point matters (exercise `marginalisation`). After each
#    exercise's theory, a cell `check("...")` grades it here, with the same sandboxed judge and
#    public checks as `python -m autograder --only ...`; where you derive a Jacobian, a cell
#    before it runs the course's Jacobian checker, `check_jacobian`, on your own function.
# 2. **Experiments**: our window with the prior, our window without, our batch and, where gtsam
#    is installed, GTSAM's batch and fixed-lag smoother, on the same simulation: the fill-in of
#    H, the window's cost and the prior's size over time, the pose error over time; then the
#    source's evaluation on EuRoC MH_05.
# 3. **Written questions.**
#
# Stuck on a derivation? `hint("preintegrate", 1)` (or `python -m autograder hint NAME LEVEL`)
# gives the approach, level 2 the key identity, level 3 the result.
#
# Conventions, as everywhere in the course: residuals are whitened, so
# $\chi^2 = \sum_k \lVert r_k\rVert^2$, $H = J^\top J$, $b = J^\top r$, and a step solves
# $H\,\delta = -b$. $R = R_{wb}$ rotates body coordinates into the world's, and a rotation moves
# on the right, $R \leftarrow R \operatorname{Exp}(\delta\phi)$; $[x]_\times$ is the skew matrix
# ($[x]_\times y = x \times y$), $\operatorname{Exp}$ and $\operatorname{Log}$ map between
# $\mathbb{R}^3$ and SO(3); gravity is $g = (0, 0, -9.81)$ m/s$^2$ in the world.
#
# `SMALL = True` (set by `python -m notebooks.build --execute --small`, and by the tests)
# runs a 4-second simulation (`vio-sim:4:0`, 17 keyframes); the full setting runs `vio-sim:12:0`
# (49 keyframes). Either takes well under a minute (the runs' own times are in section 5).
# With `IMPL = "exercises"` your `imu_preintegration` and `marginalisation` go through the
# lesson's cells, the windows and the batch; until they are written, those cells say
# which TODO stops them, and GTSAM's runs and the EuRoC section run all the same.

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
from course.app import plot
from course.notebook_helpers import chapter5
from course.notebook_helpers.vio import (
    ape_curves,
    ape_figure,
    ape_table,
    fill_in,
    fill_in_figure,
    fill_in_report,
    mh05_table,
    not_run_note,
    prior_size_report,
    run_estimators,
    runs_report,
    window_cost_figure,
)
from course.problems.vio.sim import load_vio_sim

# "solutions", "exercises" or a path to your own copy (python -m notebooks.build --impl sets it);
# by default this tree's own: "exercises" in a student tree
IMPL = os.environ.get("COURSE_IMPL") or (
    "solutions" if (root / "solutions" / "__init__.py").is_file() else "exercises")
# 1: the quick setting (a 4-second simulation; the tests run it, --small sets it); else the full one
SMALL = os.environ.get("COURSE_NOTEBOOK_SMALL", "0") == "1"
# the simulation: "vio-sim:SECONDS:SEED" (course.problems.vio.sim)
NAME = "vio-sim:4:0" if SMALL else "vio-sim:12:0"
# keyframes in the window
WINDOW = 10
# the solve whose H section 6 shows: solve k holds k + 2 keyframes, so WINDOW - 2 is the first full
# window (its H has no prior yet); a later one shows a window that already holds a prior
FILL_AT = WINDOW - 2
sim = load_vio_sim(NAME)  # the theory's cells use its IMU samples too

# %% [markdown] id="imu-md"
# # Theory
#
# ## 1. IMU preintegration
#
# ### What the IMU measures
#
# At 200 Hz the gyroscope measures the body's angular velocity and the accelerometer its
# *specific force*, the acceleration minus gravity, both in the body frame, each with a slowly
# drifting bias and white noise:
#
# $$\tilde\omega = \omega_b + b_g + n_g, \qquad \tilde a = R^\top (a_w - g) + b_a + n_a .$$
#
# (At rest $a_w = 0$ and the accelerometer reads $-R^\top g$: 9.81 m/s$^2$ *up*.) The noises
# have densities $\sigma_g$ (rad/s/$\sqrt{\text{Hz}}$) and $\sigma_a$ (m/s$^2$/$\sqrt{\text{Hz}}$).
# Solving for the motion, $\omega_b = \tilde\omega - b_g - n_g$ and
# $a_w = R(\tilde a - b_a - n_a) + g$, and holding the samples constant over an interval
# $dt$, the state moves from sample $k$ to $k+1$ by
#
# $$R_{k+1} = R_k \operatorname{Exp}\big((\tilde\omega_k - b_g)\,dt\big), \quad
#   v_{k+1} = v_k + g\,dt + R_k(\tilde a_k - b_a)\,dt, \quad
#   p_{k+1} = p_k + v_k\,dt + \tfrac12 g\,dt^2 + \tfrac12 R_k(\tilde a_k - b_a)\,dt^2 .$$
#
# Between two keyframes $i$ and $j$ (0.25 s apart here: 50 intervals) this is the IMU's
# prediction of $x_j$ from $x_i$. But every $R_k$ depends on $R_i$: each time the optimiser
# moves $R_i$, the 50 steps would have to be integrated again, for every keyframe pair, at every
# iteration. Preintegration removes that dependence.
#
# ### Increments that need neither the start nor gravity
#
# Write every rotation relative to the first, $R_k = R_i\,\Delta R_{ik}$ with
# $\Delta R_{ik} = \prod_{l=i}^{k-1} \operatorname{Exp}(w_l\,dt_l)$ and $w_l = \tilde\omega_l - b_g$
# (the noise left out for now), and $\bar a_k = \tilde a_k - b_a$. Summing the velocity
# updates from $i$ to $j$ and taking $R_i$ out of the sum:
#
# $$v_j = v_i + g\,\Delta t_{ij} + R_i\,\Delta v_{ij}, \qquad
#   \Delta v_{ij} := \sum_{k=i}^{j-1} \Delta R_{ik}\,\bar a_k\,dt_k .$$
#
# The positions: summing the updates $p_{k+1} - p_k$ from $i$ to $j$,
#
# $$p_j - p_i = \sum_k v_k\,dt_k + \tfrac12 g\sum_k dt_k^2 + \tfrac12\sum_k R_k\bar a_k\,dt_k^2;$$
#
# put in $v_k = v_i + g\,(t_k - t_i) + R_i\,\Delta v_{ik}$ (the line above, from $i$ to $k$) and use the
# telescoping sum
#
# $$\sum_k \big((t_k - t_i)\,dt_k + \tfrac12 dt_k^2\big)
#   = \sum_k \tfrac12\big((t_{k+1} - t_i)^2 - (t_k - t_i)^2\big) = \tfrac12 \Delta t_{ij}^2 :$$
#
# $$p_j = p_i + v_i\,\Delta t_{ij} + \tfrac12 g\,\Delta t_{ij}^2 + R_i\,\Delta p_{ij}, \qquad
#   \Delta p_{ij} := \sum_{k=i}^{j-1} \big(\Delta v_{ik}\,dt_k + \tfrac12 \Delta R_{ik}\,\bar a_k\,dt_k^2\big),
#   \qquad R_j = R_i\,\Delta R_{ij}.$$
#
# The states and gravity stay outside the sums; $\Delta R_{ij}, \Delta v_{ij}, \Delta p_{ij}$ hold
# only the samples and the biases, so they are computed once per keyframe pair, whatever the
# optimiser does to $x_i$ and $x_j$. They are not a rotation, velocity change and
# displacement in the world: they are those of the body in frame $i$, with gravity's part
# taken out, as if the body fell freely.
#
# ### The discrete recursion: Euler and the midpoint
#
# The sums above are a recursion from $(\Delta R, \Delta v, \Delta p) = (I, 0, 0)$:
#
# $$\Delta R_{k+1} = \Delta R_k \operatorname{Exp}(w_k\,dt_k), \qquad
#   \Delta v_{k+1} = \Delta v_k + a_k\,dt_k, \qquad
#   \Delta p_{k+1} = \Delta p_k + \Delta v_k\,dt_k + \tfrac12 a_k\,dt_k^2,$$
#
# where the rate $w_k$ and the rotated acceleration $a_k$ stand for the interval. *Euler*
# (Forster et al., GTSAM) takes its left end, $w_k = \tilde\omega_k - b_g$,
# $a_k = \Delta R_k(\tilde a_k - b_a)$. The *midpoint* scheme (the exercise; VINS-Mono) averages
# both ends: $w_k = \tfrac12(\tilde\omega_k + \tilde\omega_{k+1}) - b_g$ and
# $a_k = \tfrac12\big(\Delta R_k(\tilde a_k - b_a) + \Delta R_{k+1}(\tilde a_{k+1} - b_a)\big)$. Why it is
# better: for a smooth $f$, $\int_0^h f = h f(0) + \tfrac12 h^2 f'(0) + O(h^3)$; the left end
# $h f(0)$ misses the second term (an error $O(h^2)$ per interval), while
# $\tfrac12 h\,(f(0) + f(h)) = h f(0) + \tfrac12 h^2 f'(0) + O(h^3)$ keeps it: the same samples,
# one order more.
#
# ### Noise: the error state, and one step of it
#
# The increments above are computed from noisy samples. Define their errors against the
# increments of noise-free samples, on the right for the rotation as everywhere:
#
# $$\Delta R^{\text{true}}_k = \Delta R_k \operatorname{Exp}(\delta\phi_k), \qquad
#   \Delta v^{\text{true}}_k = \Delta v_k + \delta v_k, \qquad
#   \Delta p^{\text{true}}_k = \Delta p_k + \delta p_k,$$
#
# $\delta_k = (\delta\phi_k, \delta v_k, \delta p_k) \in \mathbb{R}^9$, $\delta_0 = 0$. The noise of interval
# $k$, $\eta_k = (\eta_g, \eta_a)$, enters where the biases do: the true rate is $w_k - \eta_g$, and
# every $\tilde a_\cdot - b_a$ is $\tilde a_\cdot - b_a - \eta_a$. Put the true quantities into the
# three updates: each new error is a smooth function of $\delta_k$ and $\eta_k$, zero at zero, so
# to first order
#
# $$\delta_{k+1} = A_k\,\delta_k + B_k\,\eta_k, \qquad
#   A_k = \frac{\partial \delta_{k+1}}{\partial \delta_k}\ (9 \times 9), \quad
#   B_k = \frac{\partial \delta_{k+1}}{\partial \eta_k}\ (9 \times 6).$$
#
# The velocity and position rows come straight from their updates, which are linear. Write the
# error of the scheme's rotated acceleration as $a^{\text{true}}_k = a_k + \delta a_k$, with
# $\delta a_k = D_\phi\,\delta\phi_k + D_g\,\eta_g + D_a\,\eta_a$ to first order; subtracting the computed
# updates from the true ones,
#
# $$\delta v_{k+1} = \delta v_k + \delta a_k\,dt_k, \qquad
#   \delta p_{k+1} = \delta p_k + \delta v_k\,dt_k + \tfrac12\,\delta a_k\,dt_k^2 .$$
#
# What is left, and is the exercise: the rotation's row (how $\delta\phi_{k+1}$ depends on
# $\delta\phi_k$ and $\eta_g$) and the three derivatives $D_\phi, D_g, D_a$ of $a_k$, for the midpoint
# scheme (and, optionally, Euler). The tools, each from the series of $\operatorname{Exp}$:
#
# * the **right Jacobian** $J_r(x)$ of SO(3) is defined by
#   $\operatorname{Exp}(x + d) = \operatorname{Exp}(x)\operatorname{Exp}(J_r(x)\,d) + O(d^2)$
#   (`course.geometry.so3.right_jacobian`);
# * **moving a rotation error through a rotation**: $R\,[x]_\times R^\top = [R x]_\times$ for any rotation
#   $R$, so $R \operatorname{Exp}(x) R^\top = \operatorname{Exp}(R x)$, i.e.
#   $\operatorname{Exp}(x)\,R = R \operatorname{Exp}(R^\top x)$;
# * **first order**: $\operatorname{Exp}(x) = I + [x]_\times + O(x^2)$, and $[x]_\times y = -[y]_\times x$
#   (so a rotation error acting on a vector becomes a matrix acting on the error).
#
# ### The covariance
#
# $\eta_k$ is independent of $\delta_k$ (which holds only $\eta_0 .. \eta_{k-1}$), both have zero mean,
# so the cross terms of $E[\delta_{k+1}\delta_{k+1}^\top]$ vanish:
#
# $$\Sigma_{k+1} = A_k \Sigma_k A_k^\top + B_k Q_k B_k^\top, \qquad \Sigma_0 = 0 .$$
#
# $Q_k$ is the covariance of the noise *averaged over the interval*: a white noise of density
# $\sigma$ has $E[n(t)\,n(s)] = \sigma^2 \delta_D(t - s)$ ($\delta_D$ Dirac's), so its average over $dt$
# has variance $\frac{1}{dt^2}\int_0^{dt}\!\int_0^{dt} \sigma^2\delta_D(t - s)\,ds\,dt = \sigma^2/dt$, and
# $Q_k = \operatorname{diag}(\sigma_g^2 I_3, \sigma_a^2 I_3)/dt_k$ (the simulation draws each sample's noise
# with that variance). The rotation error gathers one independent gyroscope error per interval,
# of variance of order $\sigma_g^2 dt$: a random walk, whose spread grows like $\sqrt t$; the
# position integrates the velocity's error once more.
#
# ### A bias that changes: the bias Jacobians
#
# The increments are computed at the bias estimate $\hat b$ of their moment. The optimiser then
# moves the bias to $\hat b + \delta b$; integrating again would cost the 50 steps we saved. But a
# bias change enters every step exactly as a noise would ($w_k - \delta b_g$, $\tilde a - \hat b_a - \delta b_a$):
# it is a noise $\eta_k = \delta b$ that is the same at every step. So the increments at
# $\hat b + \delta b$ differ from ours by an error that follows, to first order, the same recursion,
# $\delta_{k+1} = A_k\delta_k + B_k\,\delta b$; with $\delta_k = J_k\,\delta b$,
#
# $$J_{k+1} = A_k J_k + B_k, \qquad J_0 = 0,$$
#
# and $J$ (9 x 6) stacks the bias Jacobians $\partial\Delta R/\partial b_g$ (as a right perturbation),
# $\partial\Delta v/\partial b_g$, $\partial\Delta v/\partial b_a$, $\partial\Delta p/\partial b_g$,
# $\partial\Delta p/\partial b_a$ ($\partial\Delta R/\partial b_a = 0$: the rotation never sees the
# accelerometer). The factor then corrects the increments to first order,
# $\Delta R\operatorname{Exp}(\frac{\partial\Delta R}{\partial b_g}\delta b_g)$,
# $\Delta v + \frac{\partial\Delta v}{\partial b_g}\delta b_g + \frac{\partial\Delta v}{\partial b_a}\delta b_a$ and
# so on. $\Delta v$ and $\Delta p$ are *linear* in $b_a$ (the rotations do not depend on it), so for
# the accelerometer's bias the correction is exact; the gyroscope's enters through
# $\operatorname{Exp}$, and the correction's error is of second order in $\delta b_g$.
#
# The figure below measures both with your `preintegrate` (its covariance and its bias
# Jacobians), from keyframe 1 of the simulation: left, the 1-sigma of each increment's error
# against the time since keyframe $i$; right, over one keyframe interval, the error of the
# first-order correction against integrating again at the new bias, as the gyroscope bias
# change grows, beside the noise's 1-sigma (dashed). The table under it gives the slopes and
# where each correction error reaches the noise.

# %% id="figure-preintegration"
with chapter5.todo_as_a_line():  # a TODO in your preintegrate is one line here, not a traceback
    study = chapter5.preintegration_study(sim, IMPL)
    display(Image(plot.to_png(study.figure())))
    print(study.report())

# %% [markdown] id="preintegrate-check-md"
# **Check where you work.** The bias Jacobians are the one derivative `preintegrate` returns, and
# a numerical one is easy to take: computed by your own `preintegrate` at the biases $b$,
#
# $$f(b_g, b_a) = \big(\operatorname{Log}(\Delta R(\hat b)^\top \Delta R(b)),\ \Delta v(b),\ \Delta p(b)\big)
#   \quad\text{has at } b = \hat b \text{ the Jacobian}\quad
#   \begin{bmatrix} \partial\Delta R/\partial b_g & 0 \\
#   \partial\Delta v/\partial b_g & \partial\Delta v/\partial b_a \\
#   \partial\Delta p/\partial b_g & \partial\Delta p/\partial b_a\end{bmatrix}$$
#
# by the definition above. `check_jacobian(f, x, J=...)` takes central differences of `f` and compares
# them entry by entry with your `J`; a wrong block of $A_k$ or $B_k$ shows in the block it
# spoils, named in the report (e.g. `d delta v / d b_g`). It does not test the covariance: the
# `check` cell does.

# %% id="hint-preintegrate"
hint("preintegrate", 1)  # level 1, the approach; 2 gives the key identities, 3 the result

# %% id="jacobian-preintegrate"
interval = chapter5.keyframe_interval(sim, keyframe=1)  # the 51 samples from keyframe 1 to keyframe 2
with chapter5.todo_as_a_line():
    f, b_hat, J, plus, names, rows = chapter5.bias_jacobian_setup(interval, IMPL)  # your preintegrate
    check_jacobian(f, b_hat, J=J, plus=plus, names=names, rows=rows)

# %% id="check-preintegrate"
check("imu_preintegration.preintegrate")

# %% [markdown] id="factor-md"
# ## 2. The IMU factor: what its 15 rows compare
#
# Between consecutive keyframes $i$ and $j$ the window has one IMU factor. Its first nine rows
# are `imu_factor_residual`: for the true states and noise-free samples, section 1 gave three
# relations between $x_i$, $x_j$ and the increments; the residual measures how far the current
# states are from satisfying them. Solve each relation for its increment (what the states say
# it is) and compare with the one measured:
#
# * **rows 0-2, the rotation**: the rotation the states imply between frames $i$ and $j$ against the
#   preintegrated $\Delta R_{ij}$, as a tangent vector (a $\operatorname{Log}$): three numbers, zero when
#   they agree, where the difference of the matrices would be nine numbers for three degrees of
#   freedom;
# * **rows 3-5, the velocity**: the velocity change the states imply in frame $i$, gravity's part
#   removed, against $\Delta v_{ij}$;
# * **rows 6-8, the position**: likewise against $\Delta p_{ij}$.
#
# The increments are first corrected from the biases they were computed at, $\hat b$, to the
# current estimate $b_i$ of keyframe $i$, to first order with the bias Jacobians
# ($\delta b = b_i - \hat b$). To first order the nine rows at the true states are the error state
# $\delta$, so they have the covariance $\Sigma$ of section 1; the window whitens them,
# $L^\top r$ with $L L^\top = \Sigma^{-1}$, so that their $\chi^2$ is $r^\top\Sigma^{-1} r$ and a row that
# the IMU measures well weighs more.
#
# * **rows 9-14, the biases' random walk**: the biases drift,
#   $b_j = b_i + \sigma_{\text{walk}}\sqrt{\Delta t_{ij}}\;n$, so the factor also holds
#   $(b_{g,j} - b_{g,i})/(\sigma_{g,\text{walk}}\sqrt{\Delta t_{ij}})$ and the same for $b_a$ (6 rows, whitened).
#
# So 15 rows, touching the 30 tangent coordinates of $x_i$ and $x_j$ (the residual does not use
# $b_j$; the walk does). The exercise is to write the nine rows, with the corrections.
#
# **Check where you work.** The window does not differentiate your residual: it uses analytic
# Jacobians (`course/problems/vio/imu_jacobians.py`, derived there with the tools of section 1).
# They are right only for the function they differentiate, so a residual that is another
# function (a transposed rotation, gravity's sign, a correction left out) makes the window's
# steps wrong without an error. The cell after the hint moves each of the 8 variables your
# residual depends on ($R_i$ and $R_j$ on the right, the others added), at states a little off the
# truth, and compares central differences of *your* residual with those Jacobians, block by block.

# %% id="hint-residual"
hint("imu_factor_residual", 1)

# %% id="jacobian-residual"
with chapter5.todo_as_a_line():
    f, x, J, plus, names, rows = chapter5.residual_setup(interval, IMPL)  # your residual, the window's Jacobian
    check_jacobian(f, x, J=J, plus=plus, names=names, rows=rows)

# %% id="check-imu"
check("imu_preintegration")

# %% [markdown] id="window-md"
# ## 3. The sliding window
#
# A keyframe $i$ has the state $x_i = (R_i, p_i, v_i, b_{g,i}, b_{a,i})$: its rotation,
# position and velocity in the world frame and the biases of the gyroscope and the
# accelerometer. It moves by 15 tangent coordinates
# $\delta x_i = (\delta\phi, \delta p, \delta v, \delta b_g, \delta b_a)$, the rotation on the
# right (`course/problems/vio/problem.py`); a landmark is a point $X_l \in \mathbb{R}^3$. The
# keyframes are every 5th camera frame of the simulation (`course/problems/vio/sim.py`: 0.25 s
# apart); the window holds the last 10 of them and the landmarks that two of them see, and its
# cost is
#
# $$\chi^2(x) = \lVert e_0 + J\,(x \boxminus \bar x)\rVert^2
#   + \sum_i \lVert r^{\mathrm{IMU}}_{i,i+1}(x_i, x_{i+1})\rVert^2_{\Sigma_{i,i+1}^{-1}}
#   + \sum_{(i,l)} \rho\big(\lVert \pi(x_i, X_l) - z_{il}\rVert^2 / \sigma^2\big):$$
#
# the marginalisation prior (linear about its linearisation point $\bar x$, section 4), the IMU
# factors between consecutive keyframes (section 2, with the biases' random walk) and the
# reprojections of the landmarks through the pinhole camera $\pi$ (one pixel of noise, a
# Cauchy kernel $\rho$); the first keyframe also has a prior at the true start. The state puts
# the frames first, then the landmarks, so that in $H\,\delta = -b$ the frames' block is block
# tridiagonal (an IMU factor joins a keyframe to the next), the landmarks' block is block
# diagonal, and each observation puts one $15 \times 3$ block between its keyframe and its
# landmark.
#
# The data cannot see 4 directions (`course.problems.vio.problem.gauge_directions`): a
# translation of everything, and a rotation of everything about gravity (yaw). Roll and pitch
# are seen through gravity (the accelerometer's 9.81 m/s$^2$ says where down is), the scale
# through the accelerometer (the camera alone would not), but nothing says where the world's
# origin is or which way it faces about the vertical.
#
# When the window is full, the oldest keyframe leaves, with the landmarks no other keyframe
# sees. The window *with a prior* keeps what their factors said about the rest (section 4); the
# window *without* a prior (`"drop"`) forgets it, measurements included, and holds the new
# oldest keyframe's pose at its current estimate (an anchor). The figure: a window of five
# keyframes, before and after its oldest leaves, both ways.

# %% id="figure-window"
display(Image(plot.to_png(chapter5.window_graph_figure())))

# %% [markdown] id="marginal-md"
# ## 4. Marginalisation: the Schur complement
#
# ### Eliminating the removed variables
#
# About the current estimate, the window's cost is, to second order (half of the linearised
# $\chi^2$, the course's convention),
#
# $$c(\delta) = \tfrac12\,\delta^\top H\,\delta + b^\top\delta + \text{const}.$$
#
# Split $\delta$ into the variables to remove, $\delta_m$, and those kept, $\delta_k$. Whatever
# $\delta_k$ is, the removed variables' measurements still hold, and the best the removed
# variables can do is the minimum over $\delta_m$: the kept variables should carry the cost
#
# $$c^\ast(\delta_k) = \min_{\delta_m} c(\delta_m, \delta_k).$$
#
# For a Gaussian this is exactly the marginal: $e^{-c}$ integrated over $\delta_m$ is
# $e^{-c^\ast}$ times a constant (the integral of a Gaussian in $\delta_m$ whose covariance
# $H_{mm}^{-1}$ does not depend on $\delta_k$). Do the minimisation for one removed scalar variable
# $m$, with $h_{mm} > 0$ its diagonal entry, $h_{km}$ the column of $H$ that couples it to the
# kept ones and $H_{kk}$ the kept block:
#
# $$c = \tfrac12 h_{mm}\,\delta_m^2 + \delta_m\,(h_{km}^\top\delta_k + b_m)
#   + \tfrac12\,\delta_k^\top H_{kk}\,\delta_k + b_k^\top\delta_k .$$
#
# A parabola in $\delta_m$: its minimum is at $\delta_m = -(h_{km}^\top\delta_k + b_m)/h_{mm}$, where it
# is $-(h_{km}^\top\delta_k + b_m)^2 / (2h_{mm})$. Expanding the square,
#
# $$c^\ast(\delta_k) = \tfrac12\,\delta_k^\top\Big(H_{kk} - \frac{h_{km}h_{km}^\top}{h_{mm}}\Big)\delta_k
#   + \Big(b_k - \frac{h_{km}\,b_m}{h_{mm}}\Big)^\top\delta_k + \text{const}:$$
#
# one step of Gaussian elimination: each kept row of $(H \mid b)$ loses the multiple of row $m$ that
# zeroes its entry in column $m$. Your `marginalise` removes a *block* of variables at once (a
# keyframe's 15 coordinates and the landmarks only it sees), in any order, and $H_{mm}$ may be
# singular (a landmark seen by one ray): derive the block version from the block rows of
# $H\delta = -b$, with the pseudo-inverse of $H_{mm}$ where the scalar has $1/h_{mm}$. The result,
# the Schur complement of $H_{mm}$ in $H$, is also the inverse of the kept block of the covariance:
# $(H^\ast)^{-1} = (H^{-1})_{kk}$ when $H$ is invertible; the cell before the `check` tests your
# function against that.
#
# ### Marginalising is neither conditioning nor forgetting
#
# Two shortcuts are tempting. *Conditioning*, holding $x_m$ fixed at its estimate, keeps $H_{kk}$:
# it treats $x_m$ as known exactly and makes the kept variables overconfident. *Dropping*, forgetting
# $x_m$ with its factors, keeps only the other factors: it throws the information away (the window
# without a prior). The figure shows both for two scalar variables: a prior on $x_m$, a relative
# measurement $x_k - x_m$ and a weak direct one on $x_k$.
#
# ### The prior as a linear factor
#
# The minimiser works with residuals, so the window writes $c^\ast$ as one. Since
#
# $$\tfrac12\lVert e_0 + J\,\delta_k\rVert^2
#   = \tfrac12\,\delta_k^\top J^\top J\,\delta_k + e_0^\top J\,\delta_k + \tfrac12\lVert e_0\rVert^2,$$
#
# this matches $c^\ast$ when $J^\top J = H^\ast$ and $J^\top e_0 = b^\ast$. `prior_residual` builds them from
# the eigen-decomposition $H^\ast = V \operatorname{diag}(s) V^\top$: $J = \operatorname{diag}(\sqrt s)\,V^\top$
# has $J^\top J = H^\ast$, and $e_0 = \operatorname{diag}(1/\sqrt s)\,V^\top b^\ast$ has
# $J^\top e_0 = V V^\top b^\ast = b^\ast$ for a $b^\ast$ in the range of $H^\ast$, keeping only the
# eigenvalues above a relative threshold: the
# prior has as many rows as its rank. Later, at an estimate $x_k$ of the kept variables, its
# residual is $e_0 + J\,(x_k \boxminus \bar x_k)$ (`prior_update`): $J$ stays the one of the
# linearisation point $\bar x$, because the measurements it came from are gone and nothing can
# linearise them again.
#
# ### Fill-in
#
# In $c^\ast$ the entry $(a, b)$ of the kept block changes by $h_{am}h_{mb}/h_{mm}$: nonzero exactly
# when $a$ and $b$ *both* shared a factor with $m$. Every two variables that were neighbours of a
# removed one become coupled, whether or not a factor joined them: the prior is one dense factor
# on all of them (the orange edges of the figure in section 3). Removing a keyframe couples the
# next keyframe (its IMU factor) and every landmark it saw; removing a landmark instead would
# couple every keyframe that saw it, which is why the window removes only the landmarks no other
# keyframe sees (chapter 4 eliminates the points of bundle adjustment the same way, and there the
# camera block fills in). The prior carries only what the removed variables' factors said, so it
# is built from those factors alone: the others stay in the window as factors.
#
# ### The linearisation point: first estimates and the gauge
#
# The prior is linear about $\bar x$; the factors still in the window are linearised again at
# every new estimate. The 4 directions nothing measures (section 3) depend on the state
# (the yaw direction moves every position, velocity and point with it): $N(x)$. The prior's $J$
# is blind along $N(\bar x)$, the relinearised factors along $N(x)$; once $x$ has moved, the sum is
# no longer blind along any of them, and the window "measures" yaw and position from nothing
# but the mismatch, an overconfident and inconsistent estimate. Two remedies
# (`course/problems/vio/window.py`):
#
# * **first-estimate Jacobians** (Huang, Mourikis and Roumeliotis, 2009): evaluate the
#   Jacobians of the factors on the prior's keyframes at $\bar x$ too, so that prior and factors
#   agree on what the data cannot see;
# * what our window does: **project each new prior off the 4 directions**, so that it says
#   nothing along them, and hold the window by an anchor on its oldest keyframe's position and
#   yaw instead.

# %% id="figure-marginal"
display(Image(plot.to_png(chapter5.marginal_figure())))

# %% id="hint-marginalise"
hint("marginalise", 1)

# %% id="identity-marginalise"
with chapter5.todo_as_a_line():  # your marginalise on a random H, against the covariance's kept block
    print(chapter5.marginal_report(IMPL))

# %% id="check-marginalisation"
check("marginalisation")

# %% [markdown] id="experiments-md"
# # Experiments
#
# The estimators on one simulation, in turn: the runs (section 5), the fill-in of H before
# and after a marginalisation (6), the window's cost and the prior's size over time (7), the
# absolute pose error over time and the table of errors and times (8), and the source's
# evaluation on EuRoC MH_05 (9).

# %% [markdown] id="runs-md"
# ## 5. The runs
#
# Each estimator on the same simulation, once: our window with the prior (keeping the H of
# solve `FILL_AT` for section 6), our window without a prior, our batch started from the
# first window's estimate, GTSAM's batch (Levenberg-Marquardt from its own IMU propagation
# of the true start) and GTSAM's `BatchFixedLagSmoother` holding the same window of 10
# keyframes. Ours use the dogleg (`course.solver.minimize`); a solve is one call of the
# minimizer on one window. The last column is each run's wall time, everything included
# (the windows' preintegration, triangulation and marginalisation).

# %% id="runs"
estimates = run_estimators(NAME, IMPL, keep_hessians_at=FILL_AT, window=WINDOW)
print(runs_report(estimates))

# %% [markdown] id="fill-md"
# ## 6. The fill-in of H
#
# The window's H at the solution of solve `FILL_AT` (the first with 10 keyframes), and what
# marginalising its oldest keyframe does to it; a black pixel is a nonzero entry, the
# dashed lines part the frames (15 rows each) from the landmarks (3 each). Left: H, the rows
# and columns to remove in red: the oldest keyframe, its IMU factor to the next and its
# reprojections. Middle: the pattern of the Schur complement on the kept variables, $H_{kk}$
# and, in orange, the fill-in: the kept landmarks the removed keyframe saw become coupled
# with each other and with the next keyframe (the other end of its IMU factor), a block
# that was sparse and is now full. Right: the next window's H at its start (a new keyframe,
# its new landmarks, and the prior). The prior belongs on the rows and columns of the
# orange block: it holds what the removed factors said about the kept variables, and the
# factors that stay in the window are in the next window's H already. The last line
# compares the information (the diagonal of H) on the keyframes the removed one was not
# linked to, next window over this one: marginalisation gives them nothing new, so the
# ratio should be about 1 (a little more where the new keyframe adds observations of their
# landmarks); a prior built from the whole window's H counts the factors that stay a
# second time.

# %% id="fill"
if estimates.prior is not None and estimates.prior.hessians:
    fill = fill_in(estimates.prior.hessians)
    display(Image(plot.to_png(fill_in_figure(fill))))
    print(fill_in_report(fill))
else:
    print(not_run_note(estimates, f"the window with the prior (to solve {FILL_AT})"))

# %% [markdown] id="cost-md"
# ## 7. The window's cost and the prior's size over time
#
# One point per solve of the window with the prior, against the time of its newest
# keyframe. Top: $\chi^2$ at the window's solution (robust, the prior's term included).
# While the window fills, every keyframe adds an IMU factor and reprojections, and
# $\chi^2$ grows with them; once it is full, as many measurements leave as arrive, and a
# consistent estimator's $\chi^2$ levels off near the number of residuals minus the number of
# unknowns. Bottom: the prior's size, the tangent dimension of the variables it touches and
# its rows (its rank: at least 4 fewer, the gauge directions projected out; a kept landmark
# the removed keyframe saw once gets no depth from it), beside the window's own
# dimension. It cannot grow without bound (it touches only variables still in the window);
# look at how much of the window it covers, against the orange block of section 6.

# %% id="cost"
if estimates.prior is not None:
    display(Image(plot.to_png(window_cost_figure(estimates.prior, WINDOW))))
    print(prior_size_report(estimates.prior, WINDOW))
else:
    print(not_run_note(estimates, "the window with the prior"))

# %% [markdown] id="ape-md"
# ## 8. The absolute pose error over time
#
# Left, per keyframe, the position error after aligning the whole estimate with the ground
# truth by one rotation and one translation (`course.problems.vio.ape.ape`, SE(3), Umeyama's method):
# $e_i = \lVert p^{\mathrm{true}}_i - (R\,p_i + t)\rVert$. Every estimate starts from the true
# first keyframe (its prior), so without alignment (right) the error is the drift from the
# start. A window's estimate of a keyframe is the one it had when it left the window (a
# fixed-lag smoother), the last window's for the others. The batch uses every measurement at
# once: it is the best these factors and data give, and the reference for the windows.
# GTSAM's batch solves the same factors with its own preintegration and its own start; its
# fixed-lag smoother holds the same window and marginalises, into its prior, only the
# factors of the variables it removes. The first table gives the APE rmse and max, the time
# per solve (the batch: one solve) and the iterations per solve; the second, the scale and
# the rmse of a Sim(3) alignment and the last error without alignment. A scale error makes
# the aligned error grow linearly away from the middle of the run (a V): where a curve has
# that shape, the scale (a Sim(3) scale away from 1) dominates its APE. Look at where each
# window's curve leaves the batch's, and at how fast each drifts on the right.

# %% id="ape"
if estimates.truth is not None:
    curves = ape_curves(estimates)
    if curves:
        display(Image(plot.to_png(ape_figure(curves, f"{NAME}: position error per keyframe, SE(3) alignment"))))
    print(ape_table(estimates, curves))
else:
    print(not_run_note(estimates, "the estimators"))

# %% [markdown] id="mh05-md"
# ## 9. EuRoC MH_05: the source's evaluation
#
# The source evaluated its VIO back end on the EuRoC MH_05 sequence and shipped its own
# estimate with the ground truth (the data folder's `euroc_mh05/`: `COURSE_DATA`, or
# `../shared/data` next to this repository). The same APE as above on those two files (pairs
# within 0.01 s, SE(3) alignment), beside evo's figures on the same files and the row the
# source reports for its Levenberg-Marquardt run: what `python -m course ape euroc-mh05`
# prints. Ours equals evo's; the source's row came from another run of its estimator, so
# expect it close, not equal.

# %% id="mh05"
print(mh05_table())

# %% [markdown] id="questions-md"
# # Written questions
#
# Answer in the cells below, in a few sentences each. Use the figures and tables above (those
# of the full setting where they differ).
#
# **Question 1.** Our window projects the 4 unobservable directions (a translation, and a
# rotation about gravity) out of every new prior, and holds the window by an anchor on its
# oldest keyframe instead. Why must a prior that stays linear about its first estimates
# carry no information along these directions once the factors in the window are
# relinearised at new estimates? Say what the directions depend on, what the prior and the
# relinearised factors would then disagree about, and what would happen to the estimate of
# yaw and position if the first keyframe's tight prior were passed on from prior to prior.
#
# **Question 2.** The window without a prior drifts. What does it throw away each time its
# oldest keyframe leaves, which errors can nothing in the next window correct, and why do
# they add up over time? Use the APE curves: where does each window leave the batch, and
# does the prior remove the drift, or only slow it down? Why can no estimator that sees
# only IMU and camera measurements avoid it entirely?
#
# **Question 3.** In the preintegration figure of section 1 (and the table under it), the
# 1-sigma of the rotation and velocity errors grows with a slope of about 1/2 in log-log, the
# position's with about 3/2. Explain both slopes from the covariance recursion: what each
# interval adds, and how the velocity's error feeds the position's. On the right, why is a
# change of the accelerometer bias corrected exactly, while a change of the gyroscope bias leaves
# an error that grows with slope 2? From which gyroscope bias change on would you integrate the
# samples again instead of correcting, and is a window ever likely to need it (compare the
# first keyframe's prior on $b_g$, 0.02 rad/s, in `course/problems/vio/window.py`)?
#
# **Question 4.** In the figure of the two variables (section 4), conditioning on $x_m$ gives
# $x_k$ about half the marginal's sigma and dropping $x_m$'s factors about twice it (read them
# in its legend). Say why each shortcut errs the way it does, and which of the two the window
# without a prior makes when its oldest keyframe leaves (its anchor holds the new oldest
# keyframe's pose where it is): what does that do to the next windows' confidence, and to the
# errors of section 8? What does the prior cost instead: which block of H fills in (section 6)
# and how large does the prior get against the window (section 7)?

# %% [markdown] tags=["answer"] id="answer-1"
# **Your answer to question 1:** *(double-click to edit)*

# %% [markdown] tags=["answer"] id="answer-2"
# **Your answer to question 2:** *(double-click to edit)*

# %% [markdown] tags=["answer"] id="answer-3"
# **Your answer to question 3:** *(double-click to edit)*

# %% [markdown] tags=["answer"] id="answer-4"
# **Your answer to question 4:** *(double-click to edit)*
