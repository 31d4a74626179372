"""Chapter 5's sliding-window VIO back end: the problem's Jacobians, and the comparison of the
window with the marginalisation prior, the window that drops old frames, and the batch."""

import numpy as np
import pytest

from course import vio_window as vw
from course.problems.vio import VioProblem
from course.vio_sim import load_vio_sim

#: the analytic reprojection and the central-difference IMU Jacobians against central
#: differences of the whole residual (whitened units; entries reach 1e5)
JACOBIAN_TOL = 1e-5
#: the issue's criterion: with the prior within 20% of the batch's APE rmse
BATCH_MARGIN = 1.20


def _small_problem():
    sim = load_vio_sim("vio-sim:2:0")
    kfs = vw._Keyframes(sim, 5)
    frame_ids = list(range(4))
    states = {k: kfs.truth(k) for k in frame_ids}
    import solutions.imu_preintegration as imu

    preints = {k: kfs.preintegrate(imu, k, states[k]) for k in frame_ids[:-1]}
    points = {}
    lm_ids = vw._add_landmarks(sim, kfs, frame_ids, states, points)
    data = vw._data(sim, kfs, frame_ids, lm_ids, preints, [])  # no frame prior: its Jacobian is first-order
    return VioProblem(np.array([states[f] for f in frame_ids]), sim.landmarks[lm_ids], data, loss=None)


def test_the_jacobian_matches_central_differences():
    problem = _small_problem()
    x = problem.retract(problem.x0, 1e-3 * np.random.default_rng(0).standard_normal(problem.n))
    r, J, _ = problem.residual_and_jacobian(x)
    J = J.toarray()
    step = 1e-6
    numeric = np.zeros_like(J)
    for col in range(problem.n):
        h = np.zeros(problem.n)
        h[col] = step
        numeric[:, col] = (problem.residual_and_jacobian(problem.retract(x, h))[0]
                           - problem.residual_and_jacobian(problem.retract(x, -h))[0]) / (2 * step)
    assert np.abs(J - numeric).max() <= JACOBIAN_TOL * max(1.0, np.abs(J).max())
    assert problem.chi2(x) == pytest.approx(float(r @ r), rel=1e-12)


@pytest.mark.slow
def test_the_prior_beats_dropping_and_is_near_the_batch():
    results = vw.compare("vio-sim:12:0")
    print("\n" + vw.format_comparison(results))
    with_prior, without, batch = (results[k]["rmse"] for k in results)
    assert with_prior < without
    assert with_prior <= BATCH_MARGIN * batch
