"""Linear inverted pendulum (LIP) with piecewise-constant jerk, eq. (1)-(3), and its lifting
over a horizon, eq. (4)-(5).

One horizontal axis is described here; X and Y use the same matrices. The state of an axis is
``(position m, velocity m/s, acceleration m/s^2)``, the input is the jerk (m/s^3), constant over
each interval of ``dt`` seconds, and the output is the ZMP (m).

Indexing: ``x_0`` is the initial state (the actual state at the re-plan time), jerk ``u_k``
acts on ``[k dt, (k+1) dt)``, k = 0..N-1, and the lifted predictions give the states and the ZMP
at the samples k = 1..N (the paper numbers the same quantities from 1).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from replan_core.common.types import GRAVITY


def lip_matrices(dt: float, com_height: float, gravity: float = GRAVITY
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Discrete model eq. (3): ``x_{k+1} = A x_k + B u_k``, ``z_k = Cz x_k``.

    Returns ``A`` (3, 3), ``B`` (3,) and ``Cz`` (3,).
    """
    if dt <= 0.0 or com_height <= 0.0 or gravity <= 0.0:
        raise ValueError('dt, com_height and gravity must be positive')
    A = np.array([[1.0, dt, dt**2 / 2.0],
                  [0.0, 1.0, dt],
                  [0.0, 0.0, 1.0]])
    B = np.array([dt**3 / 6.0, dt**2 / 2.0, dt])
    Cz = np.array([1.0, 0.0, -com_height / gravity])          # eq. (1): z = x - h/g xdd
    return A, B, Cz


def step(state: np.ndarray, jerk: float | np.ndarray, dt: float) -> np.ndarray:
    """Integrate eq. (2) over one interval of constant jerk.

    ``state`` is (3,) or (3, k) (k axes side by side); ``jerk`` a scalar or (k,).
    """
    p, v, a = state
    return np.array([p + v * dt + a * dt**2 / 2.0 + jerk * dt**3 / 6.0,
                     v + a * dt + jerk * dt**2 / 2.0,
                     a + jerk * dt])


def zmp(state: np.ndarray, com_height: float, gravity: float = GRAVITY) -> np.ndarray:
    """ZMP of eq. (1) from a state (3,) or states (..., 3)."""
    state = np.asarray(state, dtype=float)
    return state[..., 0] - com_height / gravity * state[..., 2]


@dataclass
class LiftedLip:
    """Prediction matrices of one axis over N samples, eq. (4)-(5).

    ``X = S0 @ x0 + Su @ U`` stacks the states x_1..x_N (3N,), ``Z = Z0 @ x0 + Zu @ U`` the ZMP
    z_1..z_N (N,). ``P*``, ``V*``, ``Acc*`` are the position, velocity and acceleration rows of
    the state prediction.
    """

    dt: float
    n: int
    com_height: float
    gravity: float
    S0: np.ndarray        # (3N, 3)
    Su: np.ndarray        # (3N, N), lower block-triangular
    Z0: np.ndarray        # (N, 3)
    Zu: np.ndarray        # (N, N), lower triangular

    @property
    def P0(self) -> np.ndarray:
        return self.S0[0::3]

    @property
    def Pu(self) -> np.ndarray:
        return self.Su[0::3]

    @property
    def V0(self) -> np.ndarray:
        return self.S0[1::3]

    @property
    def Vu(self) -> np.ndarray:
        return self.Su[1::3]

    @property
    def Acc0(self) -> np.ndarray:
        return self.S0[2::3]

    @property
    def Accu(self) -> np.ndarray:
        return self.Su[2::3]


def lift(n: int, dt: float, com_height: float, gravity: float = GRAVITY) -> LiftedLip:
    """Build the lifted prediction eq. (4) and the ZMP prediction eq. (5) for ``n`` samples."""
    if n < 1:
        raise ValueError('the horizon needs at least one sample')
    A, B, Cz = lip_matrices(dt, com_height, gravity)
    S0 = np.zeros((3 * n, 3))
    Su = np.zeros((3 * n, n))
    Ak = np.eye(3)
    AkB = [B]                                 # A^j B for j = 0..n-1
    for _ in range(1, n):
        AkB.append(A @ AkB[-1])
    for k in range(n):
        Ak = A @ Ak                           # A^(k+1)
        S0[3 * k:3 * k + 3] = Ak
        for j in range(k + 1):                # x_{k+1} depends on u_j through A^(k-j) B
            Su[3 * k:3 * k + 3, j] = AkB[k - j]
    Z0 = S0.reshape(n, 3, 3).transpose(0, 2, 1) @ Cz           # (n, 3): Cz A^(k+1)
    Z0 = np.ascontiguousarray(Z0)
    Zu = np.einsum('i,kij->kj', Cz, Su.reshape(n, 3, n))
    return LiftedLip(dt=dt, n=n, com_height=com_height, gravity=gravity,
                     S0=S0, Su=Su, Z0=Z0, Zu=Zu)


def rollout(x0: np.ndarray, jerks: np.ndarray, dt: float) -> np.ndarray:
    """States x_0..x_N (N+1, 3) from eq. (2) iterated step by step."""
    out = np.empty((len(jerks) + 1, 3))
    out[0] = x0
    for k, u in enumerate(jerks):
        out[k + 1] = step(out[k], u, dt)
    return out
