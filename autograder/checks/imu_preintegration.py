"""Checks of ``imu_preintegration`` (chapter 5): the midpoint preintegration between two
keyframes (its deltas, their covariance, their bias Jacobians) and the residual of an IMU
factor, each graded alone.

Public inputs: ``preintegrate`` on 60 intervals (0.3 s at 200 Hz) of the simulated loop
(``course.problems.vio.sim``, noisy samples, biases near the truth) and on 25 intervals of fast,
random motion with a ``dt`` per interval; ``imu_factor_residual`` with the reference's
preintegration of those windows, states near the truth (R_i far from I) or random, the bias
at the linearisation point or off it, and a rotation residual of pi - 1e-4; ``preintegrate`` also on
one interval alone and on 5 intervals at a rate exactly 0. Hidden inputs: other windows, seeds and perturbations
of the same kinds. The midpoint scheme (the default) is graded on both windows, the Euler scheme
(``scheme="euler"``) on the fast one.
"""

from functools import cache

import numpy as np

from autograder.checks import Call, Verdict
from autograder.checks.common import check, failed, values
from autograder.checks.edges import Edge
from autograder.feedback import call_fields, compare

MODULES = ("imu_preintegration",)
PRE = "imu_preintegration.preintegrate"
RES = "imu_preintegration.imu_factor_residual"
FIELDS = ("delta_R", "delta_v", "delta_p", "delta_t", "covariance", "dR_dbg", "dv_dbg", "dv_dba", "dp_dbg",
          "dp_dba", "bias_gyro", "bias_accel")
GRAVITY = np.array([0.0, 0.0, -9.81])

# ---------------------------------------------------------------- inputs


def _so3_exp(phi):
    theta = float(np.linalg.norm(phi))
    W = np.array([[0.0, -phi[2], phi[1]], [phi[2], 0.0, -phi[0]], [-phi[1], phi[0], 0.0]])
    if theta < 1e-12:
        return np.eye(3) + W
    return np.eye(3) + np.sin(theta) / theta * W + (1 - np.cos(theta)) / theta**2 * (W @ W)


@cache
def windows(seed=None) -> tuple:
    """Two windows of IMU samples, each a dict: ``args`` of ``preintegrate``, ``where``, and
    for the simulated one the true states at its ends (``state_i``, ``state_j``)."""
    from course.problems.vio.sim import simulate

    rng = np.random.default_rng(83 if seed is None else [seed, 571])
    sim = simulate(6.0, int(rng.integers(0, 10_000)) if seed is not None else 11)
    i = 1000 if seed is None else int(rng.integers(700, 1100))
    j = i + 60
    bg = sim.bias_gyro[i] + rng.normal(0.0, 0.002, 3)
    ba = sim.bias_accel[i] + rng.normal(0.0, 0.02, 3)
    sim_window = {
        "args": (sim.gyro[i:j + 1], sim.accel[i:j + 1], sim.dt, bg, ba, sim.gyro_noise, sim.accel_noise),
        "where": f"on 60 intervals (0.3 s, dt = {sim.dt:g}) of the simulated loop {sim.name} from t = {i * sim.dt:g} s",
        "state_i": (sim.rotations[i], sim.velocities[i], sim.positions[i]),
        "state_j": (sim.rotations[j], sim.velocities[j], sim.positions[j]),
    }
    n = 25
    gyro = rng.normal(0.0, 1.5, (n + 1, 3))
    accel = rng.normal(0.0, 3.0, (n + 1, 3)) + np.array([0.0, 0.0, 9.81])
    dt = rng.uniform(0.004, 0.006, n)
    fast = {
        "args": (gyro, accel, dt, rng.normal(0.0, 0.05, 3), rng.normal(0.0, 0.2, 3), 0.01, 0.1),
        "where": f"on {n} intervals of fast random motion (|omega| about 2.6 rad/s) with a dt per interval",
        "state_i": (_so3_exp(rng.normal(0.0, 1.0, 3)), rng.normal(0.0, 2.0, 3), rng.normal(0.0, 5.0, 3)),
        "state_j": None,
    }
    return sim_window, fast


@cache
def edge_windows(seed=None) -> tuple:
    """The edges: one interval (N = 1, two samples, dt a number), and 5 intervals whose gyro samples all
    equal the gyro bias (the rate exactly 0: Exp and J_r at 0)."""
    rng = np.random.default_rng(85 if seed is None else [seed, 573])
    gravity_up = np.array([0.0, 0.0, 9.81])
    one = {"args": (rng.normal(0.0, 1.5, (2, 3)), rng.normal(0.0, 3.0, (2, 3)) + gravity_up, 0.005,
                    rng.normal(0.0, 0.05, 3), rng.normal(0.0, 0.2, 3), 0.01, 0.1),
           "where": "on one interval (N = 1: two samples, dt = 0.005)"}
    bias = rng.normal(0.0, 0.05, 3)
    still = {"args": (np.tile(bias, (6, 1)), rng.normal(0.0, 3.0, (6, 3)) + gravity_up, rng.uniform(0.004, 0.006, 5),
                      bias, rng.normal(0.0, 0.2, 3), 0.01, 0.1),
             "where": "on 5 intervals whose gyro samples all equal the gyro bias (the rate exactly 0)"}
    return one, still


def _pre_calls(seed=None):
    calls = [Call(f"imu_preintegration:{PRE.split('.')[1]}", w["args"], returns=FIELDS, where=w["where"])
             for w in windows(seed)]
    fast = windows(seed)[1]
    return calls + [Call(f"imu_preintegration:{PRE.split('.')[1]}", fast["args"], {"scheme": "euler"}, returns=FIELDS,
                         where=fast["where"] + ", scheme='euler'")] + [
        Call(f"imu_preintegration:{PRE.split('.')[1]}", w["args"], returns=FIELDS, where=w["where"])
        for w in edge_windows(seed)]


@cache
def _reference(seed=None) -> tuple:
    """The reference's preintegration of each window (instructor side: inside a calls builder)."""
    from autograder import reference

    f = reference.solutions_module("imu_preintegration").preintegrate
    return tuple(tuple(np.asarray(x, dtype=float) for x in f(*w["args"])) for w in windows(seed))


def _res_calls(seed=None):
    rng = np.random.default_rng(89 if seed is None else [seed, 577])
    sim_window, fast = windows(seed)
    pre_sim, pre_fast = _reference(seed)
    calls = []

    def moved(state, angle, speed, distance):
        R, v, p = state
        return (R @ _so3_exp(rng.normal(0.0, angle, 3)), v + rng.normal(0.0, speed, 3),
                p + rng.normal(0.0, distance, 3))

    def bias(pre, off):
        return (pre[10] + rng.normal(0.0, 0.01 * off, 3), pre[11] + rng.normal(0.0, 0.1 * off, 3))

    for off, text in ((0.0, "the bias at the linearisation point"), (1.0, "the bias off the linearisation point")):
        state_i = moved(sim_window["state_i"], 0.02, 0.1, 0.1)
        state_j = moved(sim_window["state_j"], 0.05, 0.2, 0.3)
        calls.append(Call(f"imu_preintegration:{RES.split('.')[1]}",
                          (state_i, state_j, pre_sim, bias(pre_sim, off), GRAVITY),
                          where=f"{sim_window['where']}, states near the truth, {text}"))
    state_j = (_so3_exp(rng.normal(0.0, 1.0, 3)), rng.normal(0.0, 2.0, 3), rng.normal(0.0, 5.0, 3))
    calls.append(Call(f"imu_preintegration:{RES.split('.')[1]}",
                      (fast["state_i"], state_j, pre_fast, bias(pre_fast, 1.0), GRAVITY),
                      where=f"{fast['where']}, random states, the bias off the linearisation point"))
    # R_j = R_i Delta R Exp((pi - 1e-4) u): the rotation residual within 1e-3 of pi (the bias at b hat)
    axis = rng.normal(size=3)
    R_i = fast["state_i"][0]
    R_j = R_i @ pre_fast[0] @ _so3_exp(NEAR_PI * axis / np.linalg.norm(axis))
    state_j = (R_j, rng.normal(0.0, 2.0, 3), rng.normal(0.0, 5.0, 3))
    calls.append(Call(f"imu_preintegration:{RES.split('.')[1]}",
                      (fast["state_i"], state_j, pre_fast, (pre_fast[10], pre_fast[11]), GRAVITY),
                      where=f"{fast['where']}, the rotation residual pi - 1e-4 rad, the bias at the linearisation "
                            "point"))
    return calls


#: the angle of the rotation residual near pi
NEAR_PI = np.pi - 1e-4


# ---------------------------------------------------------------- judges

_LABELS = {name: f"{name}[{{}}]" for name in FIELDS} | {"delta_t": "delta_t"}

#: the parts of the residual: (slice, label, cause)
PARTS = {
    "r_R": (slice(0, 3), "r_R[{}]", "r_R = Log(Delta R'^T R_i^T R_j) with Delta R' = Delta R Exp(dR/dbg delta b_g)"),
    "r_v": (slice(3, 6), "r_v[{}]", "r_v = R_i^T (v_j - v_i - g dT) - (Delta v + dv/dbg delta b_g + dv/dba delta b_a)"),
    "r_p": (slice(6, 9), "r_p[{}]", "r_p = R_i^T (p_j - p_i - v_i dT - 1/2 g dT^2) - (Delta p + dp/dbg delta b_g + "
                                    "dp/dba delta b_a)"),
}
RES_RTOL, RES_ATOL = 1e-8, 1e-10


def _part(name):
    sl, label, cause = PARTS[name]

    def judge(ctx):
        triples, failure = call_fields(ctx, failed=failed)
        for index, (call, got, want) in enumerate(triples):
            r, ref = np.asarray(got["value"], dtype=float), np.asarray(want["value"], dtype=float)
            if r.shape != ref.shape:
                return Verdict(0.0, compare(r, ref, "r", RES_RTOL, RES_ATOL, call.where)
                               + " (concatenate([r_R, r_v, r_p]))")
            known = [(np.asarray(value, dtype=float)[sl], why) for value, why in ctx.known(index).get("value", ())]
            text = compare(r[sl], ref[sl], label, RES_RTOL, RES_ATOL, call.where, known, cause)
            if text:
                return Verdict(0.0, text)
        return failure or Verdict(1.0, "ok")

    return judge


def _values(names, rtol, atol, cause):
    return values(names, rtol, atol, cause, _LABELS, atol_scaled=True)


CHECKS = [
    check(PRE, "delta R", 2, _pre_calls, _values(("delta_R",), 1e-9, 1e-12,
          "Delta R_{k+1} = Delta R_k Exp(w_k dt_k), w_k = (omega_k + omega_{k+1}) / 2 - b_g (Euler: omega_k - b_g)")),
    check(PRE, "delta v, delta p and delta t", 3, _pre_calls, _values(("delta_v", "delta_p", "delta_t"), 1e-9, 1e-12,
          "a_k = (Delta R_k (a_k - b_a) + Delta R_{k+1} (a_{k+1} - b_a)) / 2, Delta p += Delta v dt + a_k dt^2 / 2 "
          "with the old Delta v, then Delta v += a_k dt (Euler: a_k = Delta R_k (a_k - b_a))")),
    check(PRE, "covariance", 3, _pre_calls, _values(("covariance",), 1e-7, 1e-12,
          "Sigma_{k+1} = A_k Sigma_k A_k^T + B_k Q_k B_k^T, Q_k = diag(gyro_noise^2 I, accel_noise^2 I) / dt_k")),
    check(PRE, "rotation bias Jacobian dR/dbg", 2, _pre_calls, _values(("dR_dbg",), 1e-8, 1e-12,
          "dR/dbg_{k+1} = E^T dR/dbg_k - J_r(w_k dt) dt (J_{k+1} = A_k J_k + B_k)")),
    check(PRE, "velocity and position bias Jacobians", 3, _pre_calls,
          _values(("dv_dbg", "dv_dba", "dp_dbg", "dp_dba"), 1e-8, 1e-12,
                  "J_{k+1} = A_k J_k + B_k, the rows of v and p: D_phi, D_g, D_a of the scheme's acceleration")),
    check(RES, "rotation residual r_R", 2, _res_calls, _part("r_R")),
    check(RES, "velocity residual r_v", 2, _res_calls, _part("r_v")),
    check(RES, "position residual r_p", 2, _res_calls, _part("r_p")),
]


def _rates(call):
    gyro, bias = np.asarray(call.args[0], dtype=float), np.asarray(call.args[3], dtype=float)
    scheme = call.kwargs.get("scheme", "midpoint")
    return ((gyro[:-1] + gyro[1:]) / 2.0 if scheme == "midpoint" else gyro[:-1]) - bias


def _residual_angle(call) -> float:
    """The angle of Delta R'^T R_i^T R_j (from the inputs)."""
    state_i, state_j, pre, (b_g, _), _ = call.args
    M = (np.asarray(pre[0]) @ _so3_exp(np.asarray(pre[5]) @ (np.asarray(b_g) - np.asarray(pre[10])))).T
    M = M @ np.asarray(state_i[0]).T @ np.asarray(state_j[0])
    sin = np.linalg.norm([M[2, 1] - M[1, 2], M[0, 2] - M[2, 0], M[1, 0] - M[0, 1]]) / 2.0
    return float(np.arctan2(sin, (np.trace(M) - 1.0) / 2.0))


_P_TARGET = f"imu_preintegration:{PRE.split('.')[1]}"
_R_TARGET = f"imu_preintegration:{RES.split('.')[1]}"

EDGES = (
    Edge("preintegrate: one interval (N = 1, two samples)", _P_TARGET, lambda c: len(c.args[0]) == 2),
    Edge("preintegrate: the rate exactly 0 (gyro samples equal to the gyro bias: Exp and J_r at 0)", _P_TARGET,
         lambda c: bool(np.all(_rates(c) == 0.0))),
    Edge("preintegrate: dt a number, and dt one per interval", _P_TARGET, lambda c: np.ndim(c.args[2]) == 0),
    Edge("preintegrate: scheme='euler'", _P_TARGET, lambda c: c.kwargs.get("scheme") == "euler"),
    Edge("imu_factor_residual: the bias at the linearisation point (delta b = 0)", _R_TARGET,
         lambda c: bool(np.all(np.asarray(c.args[3][0]) == np.asarray(c.args[2][10]))
                        and np.all(np.asarray(c.args[3][1]) == np.asarray(c.args[2][11])))),
    Edge("imu_factor_residual: a rotation residual within 1e-3 of pi (pi - 1e-4)", _R_TARGET,
         lambda c: _residual_angle(c) > np.pi - 1e-3),
)
