"""``course.geometry.so3``'s functions of K rotations agree with their one-rotation forms on every branch.

The vectorised ``exp_many``, ``right_jacobian_many`` and ``right_jacobian_inverse_many`` evaluate each
coefficient on its own branch (the series below ``SMALL_ANGLE``, the closed form above) and build the
3x3 matrices entry by entry; here they are compared, in one call holding both branches and in calls of
one branch alone, with ``so3_exp``, ``right_jacobian`` and the inverse of ``right_jacobian``. Just above
``SMALL_ANGLE`` the closed forms cancel (``1 - cos t``, ``t - sin t``), and numpy's sine and cosine of an array
differ from those of one number by an ulp or two: there the two agree to 1e-12, not to rounding.
"""

import numpy as np
import pytest

from course.geometry.so3 import (
    SMALL_ANGLE,
    exp_many,
    log_many,
    right_jacobian,
    right_jacobian_inverse_many,
    right_jacobian_many,
    so3_exp,
)

ANGLES = [0.0, 1e-12, 1e-9, 0.5 * SMALL_ANGLE, SMALL_ANGLE * (1 - 1e-9), SMALL_ANGLE, 2 * SMALL_ANGLE, 1e-3, 0.3,
          1.0, 2.5, np.pi - 1e-3]


def _vectors(angles, seed=0):
    axes = np.random.default_rng(seed).normal(size=(len(angles), 3))
    return axes / np.linalg.norm(axes, axis=1, keepdims=True) * np.asarray(angles)[:, None]


@pytest.mark.parametrize("angles, atol", [(ANGLES, 1e-12), ([a for a in ANGLES if a < SMALL_ANGLE], 2e-15),
                                          ([a for a in ANGLES if a >= SMALL_ANGLE], 1e-12)],
                         ids=["mixed", "small", "large"])
def test_vectorised_functions_are_the_one_rotation_ones(angles, atol):
    phi = _vectors(angles)
    np.testing.assert_allclose(exp_many(phi), [so3_exp(p) for p in phi], rtol=0, atol=atol)
    np.testing.assert_allclose(right_jacobian_many(phi), [right_jacobian(p) for p in phi], rtol=0, atol=atol)
    inverse = [np.linalg.inv(right_jacobian(p)) for p in phi]
    np.testing.assert_allclose(right_jacobian_inverse_many(phi), inverse, rtol=0, atol=10 * atol)


def test_exp_many_is_a_rotation_and_log_many_its_inverse():
    phi = _vectors(ANGLES * 2, seed=1)  # more than so3.FEW: log_many's vectorised path
    R = exp_many(phi)
    np.testing.assert_allclose(R @ R.transpose(0, 2, 1), np.broadcast_to(np.eye(3), R.shape), rtol=0, atol=1e-15)
    np.testing.assert_allclose(np.linalg.det(R), 1.0, rtol=0, atol=1e-14)
    np.testing.assert_allclose(log_many(R), phi, rtol=0, atol=1e-12)


@pytest.mark.parametrize("gap", [1e-3, 1e-5, 1e-7, 1e-9, 0.0])
def test_right_jacobian_inverse_is_right_at_and_near_pi(gap):
    """``J_r^-1`` is finite at pi (its coefficient is ``1 / pi^2`` there): near it ``(1 + cos t) / sin t``
    cancels (``1 + cos t`` keeps a relative error of about ``eps / gap^2``) where ``1 / tan(t / 2)`` does not."""
    phi = _vectors([np.pi - gap, np.pi - gap], seed=2)
    inverse = [np.linalg.inv(right_jacobian(p)) for p in phi]
    np.testing.assert_allclose(right_jacobian_inverse_many(phi), inverse, rtol=0, atol=4e-15)
