"""``Log`` on Jets and in JAX at and near a half turn: value and derivative right at every angle.

The reference derivative is the closed form ``d Log(R0 Exp(d)) / dd at 0 = J_r(phi)^-1`` with
``J_r^-1 = I + [phi]/2 + (1/t^2 - cot(t/2) / (2 t)) [phi]^2`` (``cot(t/2) = (1 + cos t) / sin t``, written
so that it stays accurate through pi), and ``course.geometry``'s log the reference value.
"""

import numpy as np
import pytest
from conftest import needs

from course.core import impl as impl_loader
from course.factorgraph import BETWEEN_SE3, SE3, FactorGraph, FactorGraphProblem, jetmath
from course.geometry.so3 import skew, so3_exp, so3_log

GAPS = (1.0, 1e-3, 1e-5, 1e-7, 0.0)  # pi minus the angle
AXIS = np.array([0.3, -0.5, 0.8]) / np.linalg.norm([0.3, -0.5, 0.8])


def _jr_inverse(phi):
    t = np.linalg.norm(phi)
    W = skew(phi)
    return np.eye(3) + 0.5 * W + (1.0 / t**2 - 1.0 / (np.tan(t / 2.0) * 2.0 * t)) * (W @ W)


def _rotations(gap):
    """A rotation by pi - gap, its inverse, and a small and a right-angle one (the other branches in one batch)."""
    R = so3_exp((np.pi - gap) * AXIS)
    return np.stack([R, R.T, so3_exp(1e-6 * AXIS), so3_exp(0.5 * np.pi * AXIS[::-1])])


@pytest.mark.parametrize("gap", GAPS)
def test_log_on_jets_is_right_at_and_near_pi(gap):
    Jet = impl_loader.load("solutions").module("jets").Jet
    R0 = _rotations(gap)
    out = jetmath.so3_log(R0 @ jetmath.so3_exp(Jet.seed(np.zeros((len(R0), 3)), 0, 3)))
    for k, R in enumerate(R0):
        phi = so3_log(R)
        np.testing.assert_allclose(out.value[k], phi, rtol=0, atol=4e-15)
        np.testing.assert_allclose(out.grad[k], _jr_inverse(phi), rtol=0, atol=4e-15)
    assert np.linalg.norm(out.value[0]) == pytest.approx(np.pi - gap, abs=4e-15)


@pytest.mark.parametrize("gap", GAPS)
def test_log_on_arrays_is_right_at_and_near_pi_one_at_a_time_too(gap):
    R = _rotations(gap)
    np.testing.assert_allclose(jetmath.so3_log(R), [so3_log(m) for m in R], rtol=0, atol=4e-15)
    np.testing.assert_allclose(jetmath.so3_log(R[0]), so3_log(R[0]), rtol=0, atol=4e-15)


@needs("jax")
@pytest.mark.parametrize("gap", GAPS)
def test_log_in_jax_is_right_at_and_near_pi(gap):
    import jax
    import jax.numpy as jnp

    from course.backends.factorgraph import jax_factors

    for R in _rotations(gap):
        phi = so3_log(R)

        def moved(d, R=R):
            return jax_factors.so3_log(R @ jax_factors.so3_exp(d))

        np.testing.assert_allclose(np.asarray(moved(jnp.zeros(3))), phi, rtol=0, atol=4e-15)
        np.testing.assert_allclose(np.asarray(jax.jacfwd(moved)(jnp.zeros(3))), _jr_inverse(phi), rtol=0, atol=4e-15)


def _half_turn_graph():
    """Two poses, the second turned by pi about an axis, an identity between them: chi2 = pi^2 whatever
    the rotation's sign (a log that takes sin t = 0 for a small angle gives about 0). No translation:
    GTSAM's Pose3 error is the twist ``Logmap``, which mixes rotation into the translation part."""
    graph = FactorGraph("half turn")
    identity = np.concatenate([np.zeros(3), np.eye(3).ravel()])
    graph.add_variable("x0", SE3, identity)
    graph.fix("x0")
    graph.add_variable("x1", SE3, np.concatenate([np.zeros(3), so3_exp(np.pi * AXIS).ravel()]))
    graph.add(BETWEEN_SE3, ["x0", "x1"], identity)
    return graph


def test_a_between_factor_at_a_half_turn_costs_pi_squared():
    problem = FactorGraphProblem(_half_turn_graph())
    assert problem.chi2(problem.x0) == pytest.approx(np.pi**2, rel=1e-15)


@needs("gtsam")
def test_a_between_factor_at_a_half_turn_reports_gtsams_chi2():
    import gtsam

    R = gtsam.Rot3(so3_exp(np.pi * AXIS))
    factor = gtsam.BetweenFactorPose3(0, 1, gtsam.Pose3(), gtsam.noiseModel.Unit.Create(6))
    values = gtsam.Values()
    values.insert(0, gtsam.Pose3())
    values.insert(1, gtsam.Pose3(R, np.zeros(3)))
    problem = FactorGraphProblem(_half_turn_graph())
    assert problem.chi2(problem.x0) == pytest.approx(2.0 * factor.error(values), rel=1e-12)
