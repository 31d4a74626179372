# %% [markdown] id="title"
# # Chapter 4: bundle adjustment
#
# Bundle adjustment refines $C$ cameras and $P$ points from $K$ observations of the points
# in the images. In the BAL convention (`course/problems/bal/dataset.py`) camera $c$ has 9 unknowns (the
# angle-axis vector $w$, the translation $t$, the focal length $f$ and the radial distortion
# $k_1, k_2$), point $p$ has 3, and observation $k$ of point $p_k$ by camera $c_k$ gives the
# residual (pixels)
#
# $$P = R(w)\,X + t, \qquad p = -P_{xy} / P_z, \qquad
#   r_k = f\,(1 + k_1 \lVert p\rVert^2 + k_2 \lVert p\rVert^4)\, p - z_k,$$
#
# and the cost is $\tfrac12 \sum_k \lVert r_k\rVert^2$ (the course's chi2 is twice that).
# The Jacobian J is $(2K, 9C + 3P)$, but each observation's two rows touch only 12 columns:
# the 9 of its camera and the 3 of its point. So $H = J^T J$ has the block form
#
# $$H = \begin{bmatrix} U & W \\ W^T & V \end{bmatrix}, \quad
#   U = \mathrm{blockdiag}(U_c)\ (9 \times 9 \text{ each}), \quad
#   V = \mathrm{blockdiag}(V_p)\ (3 \times 3 \text{ each}), \quad
#   W: \text{one } 9 \times 3 \text{ block per observation},$$
#
# and since $V$ is $P$ independent $3 \times 3$ blocks, the points can be eliminated
# (your `schur_solve`): the reduced camera system
#
# $$S\,\delta_c = -g_c + W V^{-1} g_p, \qquad S = U - W V^{-1} W^T \ (9C \times 9C), \qquad
#   \delta_p = V^{-1} (-g_p - W^T \delta_c).$$
#
# This notebook runs, in turn:
#
# 1. the sparsity of J, H and S;
# 2. the cost per iteration and per second of ours and the peers (Ceres through pycolmap,
#    GTSAM, scipy) on ladybug-49 and on a synthetic problem, the time per iteration, and how
#    ours and Ceres' grow from 10k to 300k observations;
# 3. dubrovnik-3-7, a problem with fewer residuals than unknowns: what its rank deficiency
#    does to every solver;
# 4. the points that start behind the camera, and each peer's answer to them;
# 5. the time of one step, dense against Schur, as the number of points grows;
# 6. the robust kernels' weight curves, and what they do to a problem with 10% outliers;
# 7. the parallel assembly's speed-up, next to the source's OpenMP table;
# 8. the gauge: the 7 zero eigenvalues of H; then two written questions.
#
# `SMALL = True` (set by `python -m notebooks.build --execute --small`, and by the tests)
# runs the quick setting: synthetic problems (`bal-synthetic:CAMERAS:POINTS`) instead of
# ladybug-49, few iterations, in well under a minute. The full setting takes a few minutes,
# most of them on ladybug-49 (every solver for 100 iterations) and the parallel timings. Set
# `IMPL = "exercises"` to run your own `bundle_adjustment`, `robust_kernels`,
# `parallel_assembly` and `gauge` through all of it.

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

from course.app import benchmark_bal, compare, parallel_speedup, plot
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

# %% [markdown] id="sparsity-md"
# ## 1. The sparsity of J, H and S
#
# Two small synthetic problems, at their start. Top: cameras on a ring around the scene,
# each point seen by 2 to 5 cameras chosen at random, so that nearly every pair of cameras
# shares a point. Bottom: the same kind of scene with only the observations by the point's
# own camera and its two neighbours on the ring (`neighbours_only`), the covisibility of a
# camera moving along a path. In J each observation's two rows hold a $2 \times 9$ block in
# its camera's columns and a $2 \times 3$ block in its point's. In H, U and V are block
# diagonal and W has one $9 \times 3$ block per observation. S has a $9 \times 9$ block
# $(c, d)$ exactly when cameras $c$ and $d$ see a common point: dense on the ring, banded
# along the path. The table counts the structural nonzeros (from the indices alone, so it
# also runs on ladybug-49, where the data folder exists): J and H are a fraction of a
# percent full, S is small but mostly full. That is why `schur_solve` factors S densely
# (up to $9C = 1000$) and why the elimination of the points, not the factorization, is most
# of a step.

# %% id="sparsity"
ring = load_bal("bal-synthetic:6:40")
path = neighbours_only(load_bal("bal-synthetic:12:120"), window=1)
display(Image(plot.to_png(sparsity_figure([ring, path], IMPL))))
for problem in (ring, path, load("ladybug-49")):
    if problem is not None:
        print(sparsity_counts(problem))
        print()

# %% [markdown] id="costs-md"
# ## 2. Cost per iteration and per second
#
# Every solver from the problem's own start, the gauge fixed as each peer fixes it (ours
# and Ceres: camera 0's pose and one coordinate of camera 1; GTSAM: soft priors on camera 0
# and point 0), at most `ITERATIONS` iterations: our Levenberg-Marquardt and dogleg with
# the Schur complement, Ceres' (C++, through pycolmap), GTSAM's Levenberg-Marquardt and
# scipy's `least_squares` recipe (trf; one "iteration" is one evaluation of the residuals).
# The table's chi2 is ours, over all observations, at each solver's result (section 4 puts
# each peer's own cost beside it). The figure plots each back end's *own* cost, the one it
# minimizes, so the curves of Ceres and GTSAM on ladybug-49 do not count the observations
# they set aside (section 4). On the synthetic problem every solver reaches the same
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
    runs[name] = compare.run_bal(problem, impl=IMPL, methods=METHODS, max_iterations=ITERATIONS)
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
sweep = benchmark_bal.size_sweep(sizes, repeats=min(REPEAT, 3), iterations=2 if SMALL else 5, impl=IMPL)
print(benchmark_bal.format_sweep(sweep))
display(Image(plot.to_png(size_sweep_figure(sweep))))

# %% [markdown] id="rank-md"
# ## 3. dubrovnik-3-7: fewer residuals than unknowns
#
# dubrovnik-3-7 (it ships with gtsam) has 3 cameras and 7 points: 48 unknowns, and 19
# observations: 38 residuals. J has at most 38 independent rows, so at least 10 directions
# change no residual to first order: 7 of them are the gauge (section 8), and fixing the
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
    print(rank_report(dubrovnik, IMPL))
    print()
    table, last = iteration_limit_table(dubrovnik, IMPL, (5, 20, 100) if SMALL else (10, 50, 200, 1000), METHODS)
    print(table)
    print()
    print(focal_length_table(dubrovnik, last))

# %% [markdown] id="behind-md"
# ## 4. Points behind the camera
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
    behind_runs = compare.run_bal(problem, impl=IMPL, methods=METHODS, max_iterations=ITERATIONS)
    print(compare.format_table(behind_runs, f"{problem.name}, at most {ITERATIONS} iterations"))
    print()
print(behind_camera_detail(problem))
print()
print(compare.format_bal(behind_runs))

# %% [markdown] id="dense-md"
# ## 5. Dense against Schur as the number of points grows
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
steps = dense_vs_schur(10, point_counts, IMPL, repeat=min(REPEAT, 3))
print(dense_vs_schur_table(steps, 10))
display(Image(plot.to_png(dense_vs_schur_figure(steps, 10))))

# %% [markdown] id="robust-md"
# ## 6. Robust kernels
#
# A kernel replaces an observation's $s = \lVert r\rVert^2$ by $\rho(s)$ (your
# `robust_kernels`): Huber grows linearly beyond its scale $a$, Cauchy logarithmically, and
# Tukey not at all. Gauss-Newton with a kernel weights each observation's information by
# $\rho'(s)$ (solid curves, right): 1 for an inlier, small or zero for an outlier. The corrected
# weight along the residual, $\rho' + 2\rho'' s$ (dashed), turns negative beyond the scale for
# Cauchy and Tukey; where it does, `robust_information` keeps the first-order weight
# $\rho'$ so that H stays positive semi-definite. The scales are those of the experiment
# below: Huber and Cauchy at $a = 2.45$ pixels (the 95% quantile of an inlier's $|r|$ with
# 1-pixel noise), Tukey at 4.5.

# %% id="kernels"
display(Image(plot.to_png(kernel_figure(outliers.DEFAULT_LOSSES, IMPL))))

# %% [markdown] id="outliers-md"
# The experiment (`course.problems.bal.outliers`): a synthetic problem (12 cameras, 300 points, 1-pixel
# noise) with 10% of its observations moved by a further $N(0, 50^2)$ pixels, solved by
# our LM (the gauge fixed, at most 100 iterations) with each loss; the figure of merit is
# the RMS reprojection error of the *inliers* at the solution, against the same problem
# solved without the outliers (first row). Least squares lets the outliers pull the scene
# away from the inliers; look at which kernel brings the inliers' RMS back to the
# outlier-free value (`/ outlier-free` near 1), and at Tukey alone, which also ignores the
# inliers that start far off (10 pixels and more): from Cauchy's solution (the last row) it
# does not.

# %% id="outliers"
reference, rows = outliers.run(12, 300, seed=1, impl=IMPL)
print(outliers.table(reference, rows))

# %% [markdown] id="parallel-md"
# ## 7. The parallel assembly
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

# %% [markdown] id="gauge-md"
# ## 8. The gauge
#
# Rotate, shift or scale the whole scene and move every camera with it: every reprojection
# stays the same. These 7 directions (your `gauge.gauge_directions`, N of shape
# $(9C + 3P, 7)$) are in the null space of J, so $H = J^T J$ has 7 zero eigenvalues and
# undamped Gauss-Newton meets a singular system. Below, the spectrum of H at the start of a
# small synthetic problem: with the gauge free, 7 eigenvalues sit at rounding level, far
# below the rest; with the gauge fixed (`BundleAdjustmentProblem(fix_gauge=True)` holds
# camera 0's pose and one coordinate of camera 1: their rows and columns of H become unit
# rows, the plateau of 7 equal eigenvalues at 1 over the largest), none is zero. The text
# checks that $J N = 0$ and that span(N) is the span of H's 7 lowest eigenvectors.

# %% id="gauge"
small_scene = load_bal("bal-synthetic:5:40")
print(gauge_report(small_scene, IMPL))
display(Image(plot.to_png(gauge_figure(small_scene, IMPL))))

# %% [markdown] id="questions-md"
# ## Written questions
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

# %% [markdown] tags=["answer"] id="answer-1"
# **Your answer to question 1:** *(double-click to edit)*

# %% [markdown] tags=["answer"] id="answer-2"
# **Your answer to question 2:** *(double-click to edit)*
