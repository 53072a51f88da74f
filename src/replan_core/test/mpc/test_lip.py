"""LIP model eq. (1)-(3) and its lifting eq. (4)-(5)."""

import numpy as np
import pytest

from replan_core.mpc.lip import lift, lip_matrices, rollout, step, zmp

DT, H, G = 0.04, 0.55, 9.81


def test_matrices_match_eq3():
    A, B, Cz = lip_matrices(DT, H, G)
    x = np.array([0.1, -0.2, 0.3])
    u = 1.7
    np.testing.assert_allclose(A @ x + B * u, step(x, u, DT), atol=1e-15)
    assert Cz @ x == pytest.approx(x[0] - H / G * x[2], abs=1e-15)


@pytest.mark.parametrize('n', [1, 5, 200])
def test_lifted_prediction_equals_iterated_eq2(n):
    rng = np.random.default_rng(3)
    L = lift(n, DT, H, G)
    x0 = rng.normal(size=3)
    u = rng.normal(scale=2.0, size=n)
    states = rollout(x0, u, DT)                             # eq. (2) step by step
    lifted = (L.S0 @ x0 + L.Su @ u).reshape(n, 3)           # eq. (4)
    np.testing.assert_allclose(lifted, states[1:], rtol=0, atol=1e-9)
    np.testing.assert_allclose(L.Z0 @ x0 + L.Zu @ u, zmp(states[1:], H, G),
                               rtol=0, atol=1e-9)           # eq. (5)
    np.testing.assert_allclose(L.P0 @ x0 + L.Pu @ u, states[1:, 0], atol=1e-9)
    np.testing.assert_allclose(L.V0 @ x0 + L.Vu @ u, states[1:, 1], atol=1e-9)
    np.testing.assert_allclose(L.Acc0 @ x0 + L.Accu @ u, states[1:, 2], atol=1e-9)


def test_zu_lower_triangular():
    L = lift(50, DT, H, G)
    assert np.all(np.triu(L.Zu, 1) == 0.0)
    assert L.Zu.shape == (50, 50) and L.Z0.shape == (50, 3)


def test_invalid_parameters_raise():
    with pytest.raises(ValueError):
        lip_matrices(0.0, H, G)
    with pytest.raises(ValueError):
        lift(0, DT, H, G)
