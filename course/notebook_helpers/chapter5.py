"""Chapter 5's lesson: the figures of its theory, and what its cells need to check your work where you write it.

Preintegration (exercise ``imu_preintegration``), on the samples between two keyframes of a simulation
(:func:`keyframe_interval`, an :class:`Interval`):

* :func:`preintegration_study` (a :class:`PreintegrationStudy`: ``.figure()``, ``.report()``): the
  preintegrated covariance growing with the time since keyframe i, and the error of the first-order
  bias correction against integrating again;
* :func:`bias_jacobian_setup`: ``f(b_g, b_a) = (Log(Delta R(b^)^T Delta R(b)), Delta v(b), Delta p(b))``
  (9,) through your ``preintegrate`` and your bias Jacobians at ``b^`` (9, 3) each, for ``check_jacobian``;
* :func:`residual_setup`: your ``imu_factor_residual`` as a function of the 8 variables it depends on,
  and the analytic Jacobian the window uses (``course.problems.vio.imu_jacobians``), for ``check_jacobian``.

The window and marginalisation (exercise ``marginalisation``):

* :func:`window_graph_figure`: the window's factor graph, then after its oldest keyframe leaves,
  with a prior and without;
* :func:`marginal_figure`: marginalising, conditioning on and dropping one variable of a 2-D Gaussian;
* :func:`marginal_report`: your ``marginalise`` against the inverse of the covariance's kept block.

:func:`todo_as_a_line` wraps a cell that calls your code: an unwritten TODO prints one line naming it.
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator
from dataclasses import dataclass
from typing import Any

import numpy as np

from course.app import plot
from course.core import impl as impl_loader
from course.core.impl import not_implemented_reason
from course.geometry.so3 import so3_exp, so3_log
from course.notebook_helpers.lesson import JacobianSetup
from course.problems.vio.imu_jacobians import imu_jacobian
from course.problems.vio.sim import VioSim
from course.problems.vio.window import FIRST_SIGMAS

#: camera frames per keyframe (as the window takes them: 0.25 s at 20 Hz)
KEYFRAME_EVERY = 5


@contextlib.contextmanager
def todo_as_a_line(then: str = "write it, then run this cell again") -> Iterator[None]:
    """Run the ``with`` block; an unwritten exercise (``NotImplementedError``) ends it with one
    printed line, ``not run: not implemented: TODO module.function (write it, ...)``, not a traceback."""
    try:
        yield
    except NotImplementedError as exc:
        print(f"not run: {not_implemented_reason(exc)} ({then})")


def _module(impl: Any, name: str) -> Any:
    return impl_loader.load(impl).module(name)


# ---------------------------------------------------------------- preintegration


@dataclass(frozen=True)
class Interval:
    """The IMU samples of one stretch of a simulation: ``gyro``, ``accel`` (N + 1, 3) measured,
    ``dt`` (s, the sample period), the true biases at its start ``bias_gyro``, ``bias_accel`` (3,),
    the noise densities, ``gravity`` (3,), and the true ``state_i``, ``state_j`` = (R (3, 3), v (3,),
    p (3,)) at its ends (``t_i``, ``t_j``)."""

    gyro: np.ndarray
    accel: np.ndarray
    dt: float
    bias_gyro: np.ndarray
    bias_accel: np.ndarray
    gyro_noise: float
    accel_noise: float
    gravity: np.ndarray
    state_i: tuple
    state_j: tuple
    t_i: float
    t_j: float

    def preintegrate(self, module: Any, bias_gyro=None, bias_accel=None, samples: int | None = None) -> Any:
        """``module.preintegrate`` of the first ``samples`` intervals (all by default) at the given biases
        (the true ones at the start by default)."""
        n = len(self.gyro) - 1 if samples is None else samples
        return module.preintegrate(self.gyro[:n + 1], self.accel[:n + 1], self.dt,
                                   self.bias_gyro if bias_gyro is None else bias_gyro,
                                   self.bias_accel if bias_accel is None else bias_accel,
                                   self.gyro_noise, self.accel_noise)


def keyframe_interval(sim: VioSim, keyframe: int = 1, keyframes: int = 1) -> Interval:
    """The samples from keyframe ``keyframe`` to keyframe ``keyframe + keyframes`` of ``sim`` (a keyframe
    every :data:`KEYFRAME_EVERY` camera frames, as the window takes them)."""
    frames = sim.frame_imu_index[::KEYFRAME_EVERY]
    if keyframe + keyframes >= len(frames):
        raise ValueError(f"{sim.name} has {len(frames)} keyframes: no keyframe {keyframe + keyframes}")
    a, b = int(frames[keyframe]), int(frames[keyframe + keyframes])

    def state(k):
        return sim.rotations[k], sim.velocities[k], sim.positions[k]

    return Interval(sim.gyro[a:b + 1], sim.accel[a:b + 1], float(sim.dt), sim.bias_gyro[a].copy(),
                    sim.bias_accel[a].copy(), sim.gyro_noise, sim.accel_noise, np.asarray(sim.gravity, dtype=float),
                    state(a), state(b), float(sim.imu_times[a]), float(sim.imu_times[b]))


def _block_sigmas(cov: np.ndarray) -> np.ndarray:
    """``sqrt(trace)`` of the three 3x3 diagonal blocks of a (9, 9) covariance: the rms length of
    the rotation (rad), velocity (m/s) and position (m) error."""
    return np.sqrt([np.trace(cov[k:k + 3, k:k + 3]) for k in (0, 3, 6)])


#: the names and units of the three increments, in the order of the error state
INCREMENTS = (("Delta R", "rad"), ("Delta v", "m/s"), ("Delta p", "m"))
#: a fixed direction of the bias changes in :func:`preintegration_study`
BIAS_DIRECTION = np.array([1.0, -2.0, 1.5]) / np.linalg.norm([1.0, -2.0, 1.5])


def correction_errors(module: Any, interval: Interval, delta_gyro, delta_accel) -> np.ndarray:
    """(3,): how far the first-order correction of the increments for a bias change
    ``(delta_gyro, delta_accel)`` (3,) each lands from integrating again at the new biases:
    ``|Log(Delta R'^T Delta R(b))|`` (rad), ``|Delta v' - Delta v(b)|``, ``|Delta p' - Delta p(b)|``,
    with ``Delta R' = Delta R Exp(dR/dbg d_g)``, ``Delta v' = Delta v + dv/dbg d_g + dv/dba d_a``, ...
    (the corrections the ``imu_preintegration`` docstring defines)."""
    d_g, d_a = np.asarray(delta_gyro, dtype=float), np.asarray(delta_accel, dtype=float)
    pre = interval.preintegrate(module)
    new = interval.preintegrate(module, interval.bias_gyro + d_g, interval.bias_accel + d_a)
    R1 = pre.delta_R @ so3_exp(pre.dR_dbg @ d_g)
    v1 = pre.delta_v + pre.dv_dbg @ d_g + pre.dv_dba @ d_a
    p1 = pre.delta_p + pre.dp_dbg @ d_g + pre.dp_dba @ d_a
    return np.array([np.linalg.norm(so3_log(R1.T @ new.delta_R)), np.linalg.norm(v1 - new.delta_v),
                     np.linalg.norm(p1 - new.delta_p)])


@dataclass
class PreintegrationStudy:
    """What :func:`preintegration_study` measured with one implementation's ``preintegrate``.

    ``times`` (T,) s since keyframe i and ``sigmas`` (T, 3) the rms 1-sigma of the rotation (rad),
    velocity (m/s) and position (m) error there (``sqrt(trace)`` of each 3x3 block of the covariance);
    ``interval`` the seconds of one keyframe interval, ``noise`` (3,) the three 1-sigmas at its end;
    ``sizes`` (S,) rad/s the gyroscope bias changes along :data:`BIAS_DIRECTION` and ``errors`` (S, 3) the
    error of the first-order correction of each increment over one keyframe interval
    (:func:`correction_errors`); ``accel_only`` the largest error of an accelerometer bias change alone
    (up to 0.5 m/s^2); ``name`` the simulation's."""

    name: str
    times: np.ndarray
    sigmas: np.ndarray
    interval: float
    noise: np.ndarray
    sizes: np.ndarray
    errors: np.ndarray
    accel_only: float

    def slopes(self) -> np.ndarray:
        """(3,): the least-squares slope of log(sigma) against log(t), per increment."""
        return np.array([np.polyfit(np.log(self.times), np.log(self.sigmas[:, k]), 1)[0] for k in range(3)])

    def crossings(self) -> np.ndarray:
        """(3,): the gyroscope bias change (rad/s) at which the correction's error reaches the 1-sigma of
        the noise, per increment (log-log interpolation; inf when it stays below)."""
        out = np.full(3, np.inf)
        for k in range(3):
            above = np.flatnonzero(self.errors[:, k] >= self.noise[k])
            if len(above) and above[0] > 0:
                a, b = above[0] - 1, above[0]
                x, y = np.log(self.sizes[[a, b]]), np.log(self.errors[[a, b], k])
                out[k] = float(np.exp(x[0] + (np.log(self.noise[k]) - y[0]) * (x[1] - x[0]) / (y[1] - y[0])))
            elif len(above):
                out[k] = float(self.sizes[0])
        return out

    def report(self) -> str:
        """The slopes, the 1-sigmas after one keyframe interval, and where the correction reaches the noise."""
        slopes, cross = self.slopes(), self.crossings()
        lines = [f"{'increment':14} {'slope of sigma(t)':>18} {'sigma at ' + format(self.interval, '.2f') + ' s':>16} "
                 f"{'correction error = noise at |d b_g|':>36}"]
        for k, (name, unit) in enumerate(INCREMENTS):
            where = f"{cross[k]:.2g} rad/s" if np.isfinite(cross[k]) else f"above {self.sizes[-1]:g} rad/s"
            lines.append(f"{name + ' (' + unit + ')':14} {slopes[k]:18.2f} {self.noise[k]:16.2e} {where:>36}")
        lines.append(f"an accelerometer bias change alone (up to 0.5 m/s^2): correction error at most "
                     f"{self.accel_only:.1e}")
        lines.append(f"(the window's prior on the first keyframe's gyroscope bias: sigma {FIRST_SIGMAS[9]:g} rad/s)")
        return "\n".join(lines)

    def figure(self) -> Any:
        """Two panels: (left) ``sigmas`` against ``times``, log-log, with guides of slope 1/2 and 3/2 and
        the keyframe interval marked; (right) ``errors`` against ``sizes``, log-log, with a guide of slope 2
        and the three 1-sigmas of the noise dashed."""
        fig = plot.figure(12.0, 4.6)
        left, right = fig.subplots(1, 2)
        times, sigmas = self.times, self.sigmas
        for k, (name, unit) in enumerate(INCREMENTS):
            left.loglog(times, sigmas[:, k], marker=".", color=f"C{k}", label=f"{name} ({unit})")
        for slope, style in ((0.5, ":"), (1.5, "--")):  # guides a third below the curves they follow
            guide = sigmas[-1, 0 if slope == 0.5 else 2] / 3.0 * (times / times[-1]) ** slope
            left.loglog(times, guide, style, color="0.4", linewidth=1, label=f"slope {slope:g} (a guide)")
        left.axvline(self.interval, color="k", linewidth=0.6)
        left.text(self.interval, left.get_ylim()[0] * 2, " one keyframe interval", fontsize=8)
        left.set_xlabel("time since keyframe i (s)")
        left.set_ylabel("1-sigma of the error (rms over the 3 axes)")
        left.set_title(f"the covariance of the preintegrated increments ({self.name})", fontsize=10)
        left.grid(True, which="both", alpha=0.3)
        left.legend(fontsize=8)
        for k, (name, unit) in enumerate(INCREMENTS):
            right.loglog(self.sizes, np.maximum(self.errors[:, k], 1e-18), marker=".", color=f"C{k}",
                         label=f"{name}: first order against integrated again ({unit})")
            right.axhline(self.noise[k], color=f"C{k}", linestyle="--", linewidth=1)
        right.loglog(self.sizes, self.errors[-1].max() / 3.0 * (self.sizes / self.sizes[-1]) ** 2, ":",
                     color="0.4", linewidth=1, label="slope 2 (a guide)")
        right.plot([], [], "k--", linewidth=1, label="dashed: the 1-sigma of the noise, same colour")
        right.plot([], [], " ", label=f"an accelerometer bias change alone: at most {self.accel_only:.1e}")
        right.set_xlabel("|change of the gyroscope bias| (rad/s)")
        right.set_ylabel("error of the corrected increment")
        right.set_title(f"correcting for a new bias over one keyframe interval ({self.interval:.2f} s)", fontsize=10)
        right.grid(True, which="both", alpha=0.3)
        right.legend(fontsize=7, loc="upper left")
        return fig


def preintegration_study(sim: VioSim, impl: Any = "solutions", keyframe: int = 1,
                         horizon: int = 4) -> PreintegrationStudy:
    """Measure, with ``impl``'s ``preintegrate`` on ``sim`` from keyframe ``keyframe``, the covariance's
    growth over ``horizon`` keyframe intervals (30 lengths, log-spaced) and the first-order bias
    correction over one, for gyroscope bias changes from 1e-5 to 1 rad/s (a :class:`PreintegrationStudy`).
    Raises ``NotImplementedError`` while ``preintegrate`` is a TODO."""
    module = _module(impl, "imu_preintegration")
    long = keyframe_interval(sim, keyframe, horizon)
    one = keyframe_interval(sim, keyframe, 1)
    counts = np.unique(np.geomspace(1, len(long.gyro) - 1, 30).astype(int))
    sigmas = np.array([_block_sigmas(long.preintegrate(module, samples=int(n)).covariance) for n in counts])
    sizes = np.geomspace(1e-5, 1.0, 21)
    errors = np.array([correction_errors(module, one, s * BIAS_DIRECTION, np.zeros(3)) for s in sizes])
    accel_only = max(float(correction_errors(module, one, np.zeros(3), s * BIAS_DIRECTION).max())
                     for s in (1e-3, 0.05, 0.5))
    return PreintegrationStudy(sim.name, counts * long.dt, sigmas, one.t_j - one.t_i,
                               _block_sigmas(one.preintegrate(module).covariance), sizes, errors, accel_only)


#: the rows of :func:`bias_jacobian_setup`'s ``f``, named for ``check_jacobian``'s report
INCREMENT_ROWS = [("Log(delta R)", slice(0, 3)), ("delta v", slice(3, 6)), ("delta p", slice(6, 9))]




def bias_jacobian_setup(interval: Interval, impl: Any = "solutions") -> JacobianSetup:
    """Your bias Jacobians as a Jacobian to check: ``f(b_g, b_a)`` (9,) is
    ``(Log(Delta R(b^)^T Delta R(b)), Delta v(b), Delta p(b))`` from your ``preintegrate`` at the biases
    ``b = (b_g, b_a)``; at ``b = b^`` (the interval's true biases) its Jacobian is, by the definition of
    the bias Jacobians, ``J = [[dR/dbg, 0], [dv/dbg, dv/dba], [dp/dbg, dp/dba]]`` (9, 6), which your
    ``preintegrate`` returns. Raises ``NotImplementedError`` while it is a TODO."""
    module = _module(impl, "imu_preintegration")
    pre = interval.preintegrate(module)
    R0 = np.asarray(pre.delta_R)

    def f(b_g, b_a):
        new = interval.preintegrate(module, b_g, b_a)
        return np.concatenate([so3_log(R0.T @ new.delta_R), new.delta_v, new.delta_p])

    J_g = np.vstack([pre.dR_dbg, pre.dv_dbg, pre.dp_dbg])
    J_a = np.vstack([np.zeros((3, 3)), pre.dv_dba, pre.dp_dba])
    return JacobianSetup(f, [interval.bias_gyro.copy(), interval.bias_accel.copy()], [J_g, J_a],
                         ["vector", "vector"], ["b_g", "b_a"], INCREMENT_ROWS)


#: the variables of :func:`residual_setup`'s ``f`` and how each moves (``check_jacobian``'s ``plus``)
RESIDUAL_NAMES = ["R_i", "p_i", "v_i", "b_g,i", "b_a,i", "R_j", "p_j", "v_j"]
RESIDUAL_SPACES = ["so3", "vector", "vector", "vector", "vector", "so3", "vector", "vector"]
RESIDUAL_ROWS = [("r_R", slice(0, 3)), ("r_v", slice(3, 6)), ("r_p", slice(6, 9))]
#: where each variable's columns sit in the analytic (9, 30) Jacobian (tangent order dphi, dp, dv, db_g, db_a; i then j)
RESIDUAL_COLUMNS = [slice(0, 3), slice(3, 6), slice(6, 9), slice(9, 12), slice(12, 15), slice(15, 18), slice(18, 21),
                    slice(21, 24)]


def residual_setup(interval: Interval, impl: Any = "solutions", seed: int = 0) -> JacobianSetup:
    """Your ``imu_factor_residual`` as ``f(R_i, p_i, v_i, b_g, b_a, R_j, p_j, v_j)`` (9,), with the
    preintegration of ``interval`` by your ``preintegrate``, at the interval's true states moved a
    little (``seed``: about 0.02 rad, 0.05 m/s, 0.05 m, and biases 0.01 off ``b^``, so that every
    term of the residual is at work), and the window's analytic Jacobian of it
    (``course.problems.vio.imu_jacobians.imu_jacobian`` at your residual's rotation rows), one (9, 3)
    block per variable.
    Raises ``NotImplementedError`` while ``preintegrate`` or ``imu_factor_residual`` is a TODO."""
    module = _module(impl, "imu_preintegration")
    pre = interval.preintegrate(module)
    rng = np.random.default_rng(seed)
    (R_i, v_i, p_i), (R_j, v_j, p_j) = interval.state_i, interval.state_j
    R_i, R_j = R_i @ so3_exp(0.02 * rng.standard_normal(3)), R_j @ so3_exp(0.02 * rng.standard_normal(3))
    p_i, p_j = p_i + 0.05 * rng.standard_normal(3), p_j + 0.05 * rng.standard_normal(3)
    v_i, v_j = v_i + 0.05 * rng.standard_normal(3), v_j + 0.05 * rng.standard_normal(3)
    b_g = interval.bias_gyro + 0.01 * rng.standard_normal(3)
    b_a = interval.bias_accel + 0.01 * rng.standard_normal(3)
    g = interval.gravity

    def f(R_i, p_i, v_i, b_g, b_a, R_j, p_j, v_j):
        return module.imu_factor_residual((R_i, v_i, p_i), (R_j, v_j, p_j), pre, (b_g, b_a), g)

    r = f(R_i, p_i, v_i, b_g, b_a, R_j, p_j, v_j)  # a TODO raises here, before the checker's report
    s_i = np.r_[so3_log(R_i), p_i, v_i, b_g, b_a]
    s_j = np.r_[so3_log(R_j), p_j, v_j, b_g, b_a]
    J = imu_jacobian(s_i, s_j, tuple(pre), g, np.asarray(r, dtype=float)[0:3])
    x = [R_i, p_i, v_i, b_g, b_a, R_j, p_j, v_j]
    return JacobianSetup(f, x, [J[:, c] for c in RESIDUAL_COLUMNS], RESIDUAL_SPACES, RESIDUAL_NAMES, RESIDUAL_ROWS)


# ---------------------------------------------------------------- the window and marginalisation


def _node(ax: Any, xy, text: str, colour: str, square: bool = False) -> None:
    marker = "s" if square else "o"
    ax.plot(*xy, marker=marker, markersize=20 if not square else 13, color=colour, zorder=3)
    ax.text(*xy, text, ha="center", va="center", fontsize=8, color="white", zorder=4)


def window_graph_figure() -> Any:
    """Three panels of a small window's factor graph (five keyframes x0..x4, six landmarks l0..l5):
    the window (the oldest keyframe x0, its factors and the landmark l0 only it sees in red); after x0
    leaves with a prior (one factor, the black square, on every variable x0 shared a factor with:
    x1, l1, l2, its edges orange); after x0 leaves without a prior (its factors gone, x1's pose held
    by an anchor). A line from a keyframe to a landmark is a reprojection, between keyframes an IMU factor."""
    frames = 5
    xs = np.arange(frames, dtype=float)
    lm_x = np.array([-0.3, 0.6, 1.4, 2.2, 3.1, 3.9])
    sees = {0: [0, 1, 2], 1: [1, 2, 3], 2: [2, 3, 4], 3: [3, 4, 5], 4: [4, 5]}
    only_x0 = [lm for lm in sees[0] if all(lm not in sees[f] for f in range(1, frames))]
    shared = [lm for lm in sees[0] if lm not in only_x0]
    fig = plot.figure(15.0, 3.6)
    axes = fig.subplots(1, 3)
    titles = ("the window: x0 leaves next\n(red: x0, its factors, and l0 that only x0 sees)",
              "after, with a prior: one factor on x1, l1 and l2\n(orange): all three coupled to each other",
              "after, without a prior: x0's factors are gone;\nx1's pose held where it is (an anchor)")
    for panel, ax in enumerate(axes):
        gone = panel > 0
        for f in range(frames):
            if gone and f == 0:
                continue
            for lm in sees[f]:
                if gone and lm in only_x0:
                    continue
                red = f == 0
                ax.plot([xs[f], lm_x[lm]], [0.0, 1.5], color="tab:red" if red else "0.6", linewidth=1, zorder=1)
        for f in range(frames - 1):
            if gone and f == 0:
                continue
            ax.plot(xs[f:f + 2], [0.0, 0.0], color="tab:red" if f == 0 else "k", linewidth=3, zorder=2)
        for lm in range(len(lm_x)):
            if gone and lm in only_x0:
                continue
            _node(ax, (lm_x[lm], 1.5), f"l{lm}", "tab:red" if lm in only_x0 else "tab:green")
        for f in range(frames):
            if gone and f == 0:
                continue
            _node(ax, (xs[f], 0.0), f"x{f}", "tab:red" if f == 0 else "tab:blue")
        if panel == 1:
            centre = (0.35, 0.75)
            for target in [(xs[1], 0.0)] + [(lm_x[lm], 1.5) for lm in shared]:
                ax.plot([centre[0], target[0]], [centre[1], target[1]], color="tab:orange", linewidth=2, zorder=1)
            _node(ax, centre, "", "k", square=True)
            ax.text(centre[0] - 0.15, centre[1], "prior ", ha="right", va="center", fontsize=8)
        if panel == 2:
            ax.plot([xs[1] - 0.45, xs[1]], [-0.45, 0.0], color="tab:purple", linewidth=2, zorder=1)
            _node(ax, (xs[1] - 0.45, -0.45), "", "tab:purple", square=True)
            ax.text(xs[1] - 0.6, -0.45, "anchor ", ha="right", va="center", fontsize=8)
        ax.set_xlim(-1.2, frames - 0.4)
        ax.set_ylim(-0.8, 2.0)
        ax.set_axis_off()
        ax.set_title(titles[panel], fontsize=9)
    return fig


@dataclass(frozen=True)
class TwoVariables:
    """A two-variable linear-Gaussian problem: ``x_m`` (to remove) and ``x_k`` (kept), with a prior
    on ``x_m`` (mean ``z_m``, sigma ``s_m``), a relative measurement ``x_k - x_m = z_rel`` (sigma
    ``s_rel``) and a weak direct one on ``x_k`` (mean ``z_k``, sigma ``s_k``)."""

    z_m: float = 0.0
    s_m: float = 1.0
    z_rel: float = 1.0
    s_rel: float = 0.5
    z_k: float = 2.5
    s_k: float = 2.0

    def system(self) -> tuple[np.ndarray, np.ndarray]:
        """The information matrix H (2, 2) and vector ``eta`` (2,), ``H x = eta`` at the mean, of (x_m, x_k):
        each factor ``(a^T x - z)^2 / s^2`` adds ``a a^T / s^2`` to H and ``a z / s^2`` to eta."""
        H, eta = np.zeros((2, 2)), np.zeros(2)
        for row, z, s in (((1.0, 0.0), self.z_m, self.s_m), ((-1.0, 1.0), self.z_rel, self.s_rel),
                          ((0.0, 1.0), self.z_k, self.s_k)):
            a = np.asarray(row)
            H += np.outer(a, a) / s**2
            eta += a * z / s**2
        return H, eta


def marginal_densities(problem: TwoVariables) -> dict:
    """``{name: (mean, sigma)}`` of ``x_k`` three ways, in the scalar elimination of the lesson:
    ``marginal`` (eliminate ``x_m``: information ``h_kk - h_km^2 / h_mm``), ``conditional`` (``x_m``
    held at its estimate: information ``h_kk``), ``dropped`` (``x_m``'s factors forgotten: ``x_k``'s own
    factor alone); and ``joint`` the mean of (x_m, x_k) and its covariance (2, 2)."""
    H, eta = problem.system()
    mean = np.linalg.solve(H, eta)
    info = H[1, 1] - H[1, 0] * H[0, 1] / H[0, 0]
    return {"joint": (mean, np.linalg.inv(H)), "marginal": (mean[1], 1.0 / np.sqrt(info)),
            "conditional": (mean[1], 1.0 / np.sqrt(H[1, 1])), "dropped": (problem.z_k, problem.s_k)}


def marginal_figure(problem: TwoVariables | None = None) -> Any:
    """Two panels of :class:`TwoVariables`: (left) the joint density's 1-, 2- and 3-sigma ellipses in
    (x_m, x_k) and the line on which conditioning holds x_m; (right) the density of x_k marginalised,
    conditioned and dropped (:func:`marginal_densities`), each sigma in its legend."""
    problem = problem or TwoVariables()
    d = marginal_densities(problem)
    mean, cov = d["joint"]
    fig = plot.figure(12.0, 4.4)
    left, right = fig.subplots(1, 2)
    values, vectors = np.linalg.eigh(cov)
    angle = np.linspace(0.0, 2.0 * np.pi, 200)
    circle = np.stack([np.cos(angle), np.sin(angle)])
    for level in (1, 2, 3):
        ring = mean[:, None] + level * vectors @ (np.sqrt(values)[:, None] * circle)
        left.plot(ring[0], ring[1], color="C0", linewidth=1.5 if level == 1 else 0.8)
    left.axvline(mean[0], color="C1", linestyle="--", label="conditioning: x_m held at its estimate")
    left.plot(*mean, "k+", markersize=10, label="the joint mean")
    left.set_xlabel("x_m (removed)")
    left.set_ylabel("x_k (kept)")
    left.set_title("the joint density of (x_m, x_k): 1, 2, 3 sigma", fontsize=10)
    left.set_aspect("equal", adjustable="datalim")
    left.legend(fontsize=8, loc="lower right")
    grid = np.linspace(mean[1] - 5.0, mean[1] + 5.0, 400)
    for name, colour, style in (("marginal", "C0", "-"), ("conditional", "C1", "--"), ("dropped", "C2", ":")):
        m, s = d[name]
        density = np.exp(-0.5 * ((grid - m) / s) ** 2) / (s * np.sqrt(2.0 * np.pi))
        right.plot(grid, density, style, color=colour, linewidth=2, label=f"{name}: mean {m:.2f}, sigma {s:.2f}")
    right.set_xlabel("x_k")
    right.set_ylabel("density")
    right.set_title("what the kept variable knows after x_m leaves", fontsize=10)
    right.legend(fontsize=8)
    return fig


def marginal_report(impl: Any = "solutions", n: int = 7, remove=(5, 1), seed: int = 0) -> str:
    """Your ``marginalise`` on a random positive definite H (n, n) and b (n,), removing ``remove``
    (not sorted, not contiguous), against two facts of the Gaussian it stands for:
    the prior's information is the inverse of the kept block of the covariance ``H^-1``, and the
    prior's minimiser ``-H_prior^-1 b_prior`` is the kept part of the whole system's ``-H^-1 b``.
    Raises ``NotImplementedError`` while ``marginalise`` is a TODO."""
    module = _module(impl, "marginalisation")
    rng = np.random.default_rng(seed)
    A = rng.standard_normal((2 * n, n))
    H, b = A.T @ A, rng.standard_normal(n)
    remove = np.asarray(remove, dtype=np.int64)
    keep = np.setdiff1d(np.arange(n), remove)
    H_prior, b_prior = module.marginalise(H, b, remove)
    H_prior, b_prior = np.asarray(H_prior, dtype=float), np.asarray(b_prior, dtype=float)
    if H_prior.shape != (len(keep), len(keep)) or b_prior.shape != (len(keep),):
        return (f"marginalise returned H_prior {H_prior.shape} and b_prior {b_prior.shape}: expected "
                f"({len(keep)}, {len(keep)}) and ({len(keep)},), the kept indices {keep.tolist()} in order")
    cov = np.linalg.inv(H)
    lines = [f"H ({n} x {n}) positive definite, removing {remove.tolist()}, keeping {keep.tolist()}:"]
    for what, yours, truth in (
            ("H_prior against inv(inv(H)[kept, kept])", H_prior, np.linalg.inv(cov[np.ix_(keep, keep)])),
            ("the prior's minimiser against the kept part of H's", -np.linalg.lstsq(H_prior, b_prior, rcond=None)[0],
             -np.linalg.solve(H, b)[keep])):
        err = float(np.max(np.abs(yours - truth))) / max(1.0, float(np.max(np.abs(truth))))
        lines.append(f"  {what}: largest relative difference {err:.1e} ({'OK' if err < 1e-8 else 'WRONG'})")
    return "\n".join(lines)
