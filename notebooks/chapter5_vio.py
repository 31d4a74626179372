# %% [markdown] id="title"
# # Chapter 5: a sliding-window visual-inertial back end
#
# A keyframe $i$ has the state $x_i = (R_i, p_i, v_i, b_{g,i}, b_{a,i})$: its rotation,
# position and velocity in the world frame and the biases of the gyroscope and the
# accelerometer. It moves by 15 tangent coordinates
# $\delta x_i = (\delta\phi, \delta p, \delta v, \delta b_g, \delta b_a)$, the rotation on the
# right, $R_i \leftarrow R_i \operatorname{Exp}(\delta\phi)$ (`course/problems/vio/problem.py`); a
# landmark is a point $X_l \in \mathbb{R}^3$. The keyframes are every 5th camera frame of the
# simulation (`course/problems/vio/sim.py`: 0.25 s apart); the window holds the last 10 of them and
# the landmarks that two of them see, and its cost is
#
# $$\chi^2(x) = \lVert e_0 + J\,(x \boxminus \bar x)\rVert^2
#   + \sum_i \lVert r^{\mathrm{IMU}}_{i,i+1}(x_i, x_{i+1})\rVert^2_{\Sigma_{i,i+1}^{-1}}
#   + \sum_{(i,l)} \rho\big(\lVert \pi(x_i, X_l) - z_{il}\rVert^2 / \sigma^2\big):$$
#
# the marginalisation prior (linear about its linearisation point $\bar x$), the IMU factors
# between consecutive keyframes (your `imu_preintegration`, with the biases' random walk)
# and the reprojections of the landmarks through the pinhole camera $\pi$ (one pixel of
# noise, a Cauchy kernel $\rho$); the first keyframe also has a prior at the true start. The
# state puts the frames first, then the landmarks, so that in $H\,\delta = -b$ the frames'
# block is block tridiagonal (an IMU factor joins a keyframe to the next), the landmarks'
# block is block diagonal, and each observation puts one $15 \times 3$ block between its
# keyframe and its landmark.
#
# When the window is full, the oldest keyframe leaves, with the landmarks no other keyframe
# sees. With $m$ the variables removed and $k$ those kept, your `marginalisation.marginalise`
# replaces them by the Schur complement, and `prior_residual` writes it as a residual
# $e_0 + J\,\delta_k$ with $J^T J = H^\ast$, $J^T e_0 = b^\ast$:
#
# $$H = \begin{bmatrix} H_{mm} & H_{mk} \\ H_{km} & H_{kk} \end{bmatrix}, \qquad
#   H^\ast = H_{kk} - H_{km} H_{mm}^{-1} H_{mk}, \qquad b^\ast = b_k - H_{km} H_{mm}^{-1} b_m.$$
#
# $H_{km} H_{mm}^{-1} H_{mk}$ couples every two kept variables that shared a factor with a
# removed one: the fill-in. The prior carries only what the removed variables' factors said,
# so it is built from those factors alone (the others stay in the window as factors). Two
# more points (`course/problems/vio/window.py`):
#
# * the prior is linear about $\bar x$, while the factors are relinearised at each new
#   estimate; the factors on the prior's keyframes take their Jacobians at $\bar x$ too
#   (first estimates), so that prior and factors agree on what the data cannot see;
# * the data cannot see 4 directions (`course.problems.vio.problem.gauge_directions`): a translation
#   of everything, and a rotation of everything about gravity (yaw); roll and pitch are seen
#   through gravity, the scale through the accelerometer. Each new prior is projected off
#   these 4 directions, and the window is held by an anchor on its oldest keyframe's
#   position and yaw.
#
# The window *without* a prior (`"drop"`) forgets what leaves, measurements included, and
# holds the new oldest keyframe's pose at its current estimate.
#
# This notebook runs, in turn:
#
# 1. the estimators: the window with the prior, the window without, the batch (every
#    keyframe in one problem, the same factors, no marginalisation), and, where gtsam is
#    installed, GTSAM's batch and its fixed-lag smoother (`course/backends/vio/gtsam.py`);
# 2. the fill-in of H before and after a marginalisation;
# 3. the window's cost and the prior's size over time;
# 4. the absolute pose error (APE) over time, and the table of errors and times;
# 5. the source's evaluation on EuRoC MH_05; then two written questions.
#
# `SMALL = True` (set by `python -m notebooks.build --execute --small`, and by the tests)
# runs a 4-second simulation (`vio-sim:4:0`, 17 keyframes) in well under a minute; the full
# setting runs `vio-sim:12:0` (49 keyframes) in one to two minutes, most of it in our two
# windows. With `IMPL = "exercises"` your `imu_preintegration` and `marginalisation` go through
# the windows and the batch; until they are written, sections 2 to 4 say which TODO stops
# them, and GTSAM's runs and section 5 run all the same.

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

from course.app import plot
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
# the solve whose H section 2 shows: solve k holds k + 2 keyframes, so WINDOW - 2 is the first full
# window (its H has no prior yet); a later one shows a window that already holds a prior
FILL_AT = WINDOW - 2

# %% [markdown] id="runs-md"
# ## 1. The runs
#
# Each estimator on the same simulation, once: our window with the prior (keeping the H of
# solve `FILL_AT` for section 2), our window without a prior, our batch started from the
# first window's estimate, GTSAM's batch (Levenberg-Marquardt from its own IMU propagation
# of the true start) and GTSAM's `BatchFixedLagSmoother` holding the same window of 10
# keyframes. Ours use the dogleg (`course.solver.minimize`); a solve is one call of the
# minimizer on one window. The last column is each run's wall time, everything included
# (the windows' preintegration, triangulation and marginalisation).

# %% id="runs"
estimates = run_estimators(NAME, IMPL, keep_hessians_at=FILL_AT, window=WINDOW)
print(runs_report(estimates))

# %% [markdown] id="fill-md"
# ## 2. The fill-in of H
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
# ## 3. The window's cost and the prior's size over time
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
# look at how much of the window it covers, against the orange block of section 2.

# %% id="cost"
if estimates.prior is not None:
    display(Image(plot.to_png(window_cost_figure(estimates.prior, WINDOW))))
    print(prior_size_report(estimates.prior, WINDOW))
else:
    print(not_run_note(estimates, "the window with the prior"))

# %% [markdown] id="ape-md"
# ## 4. The absolute pose error over time
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
# ## 5. EuRoC MH_05: the source's evaluation
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
# ## Written questions
#
# Answer in the cells below, in a few sentences each. Use the figures above (those of the
# full setting where they differ).
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

# %% [markdown] tags=["answer"] id="answer-1"
# **Your answer to question 1:** *(double-click to edit)*

# %% [markdown] tags=["answer"] id="answer-2"
# **Your answer to question 2:** *(double-click to edit)*
