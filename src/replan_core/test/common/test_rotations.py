"""rotations.py against the rotation matrix, on seeded random quaternions."""

import numpy as np
import pytest

from replan_core.common import rotations

RNG = np.random.default_rng(7)
QUATERNIONS = [q / np.linalg.norm(q) for q in RNG.normal(size=(20, 4))]


@pytest.mark.parametrize('q', QUATERNIONS)
def test_rotate_and_its_inverse_agree_with_the_matrix(q):
    v = RNG.normal(size=3)
    matrix = rotations.quaternion_to_matrix(q)
    np.testing.assert_allclose(rotations.rotate(q, v), matrix @ v, atol=1e-12)
    np.testing.assert_allclose(rotations.rotate(rotations.conjugate(q), v), matrix.T @ v,
                               atol=1e-12)


@pytest.mark.parametrize('q', QUATERNIONS)
def test_multiply_composes_rotations(q):
    other = QUATERNIONS[0]
    product = rotations.multiply(q, other)
    np.testing.assert_allclose(rotations.quaternion_to_matrix(product),
                               rotations.quaternion_to_matrix(q)
                               @ rotations.quaternion_to_matrix(other), atol=1e-12)


def test_normalized_and_yaw():
    yaw = 0.7
    q = 3.0 * np.array([0.0, 0.0, np.sin(yaw / 2), np.cos(yaw / 2)])
    unit = rotations.normalized(q)
    assert np.linalg.norm(unit) == pytest.approx(1.0, abs=1e-15)
    assert rotations.yaw_of(unit) == pytest.approx(yaw, abs=1e-12)
