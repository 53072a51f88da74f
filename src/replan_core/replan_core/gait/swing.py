"""Swing-foot trajectory: lift-off position to foothold, apex ``height`` above the higher end.

Horizontal: a quintic (minimum-jerk) blend, zero velocity and acceleration at both ends, over the
whole swing or its first ``horizontal_fraction``. Vertical: two quintic pieces, up to the apex at
mid-swing and down to the target, each with zero velocity and acceleration at its ends, so z is
C2 as well.

A haptic swing aims below its foothold (the controller's ``touchdown_depth``) and so meets the
ground before its planned touchdown, at ``ground_crossing_fraction`` of the swing. Its horizontal
blend ends there: a blend over the whole swing left the foot short of its foothold by what it
still had to travel (Go1, realistic profile: 6-7 mm of a 0.105 m stride, the crawl 6-9 % slow
until the velocity feedback made it up, docs/gait.md, "Response to a set-point change").

The whole-body controller tracks this trajectory; after ``t_touchdown`` it holds the target (in
haptic mode the controller itself keeps pushing the foot down until contact is sensed, see
docs/gait.md).
"""

from __future__ import annotations

import numpy as np


def _quintic(s: float) -> tuple[float, float, float]:
    """Minimum-jerk blend 10 s^3 - 15 s^4 + 6 s^5 on [0, 1] and its first two derivatives."""
    s = min(max(s, 0.0), 1.0)
    return (s**3 * (10.0 - 15.0 * s + 6.0 * s * s),
            30.0 * s * s * (1.0 - s) ** 2,
            60.0 * s * (1.0 - s) * (1.0 - 2.0 * s))


def swing_trajectory(start, target, t_liftoff: float, t_touchdown: float, height: float,
                     t: float, horizontal_fraction: float = 1.0,
                     ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Foot position (3,), velocity (3,) and acceleration (3,) at sim time ``t`` (world, m, s).

    Before ``t_liftoff`` the foot is at ``start``; after ``t_touchdown`` at ``target`` (zero
    velocity and acceleration). The apex, at mid-swing, is ``height`` above max(start z,
    target z). The horizontal blend takes the first ``horizontal_fraction`` (0, 1] of the swing
    and then holds the target's x, y.
    """
    if not 0.0 < horizontal_fraction <= 1.0:
        raise ValueError(f'horizontal_fraction must be in (0, 1], got {horizontal_fraction}')
    p0 = np.asarray(start, dtype=float).reshape(3)
    p1 = np.asarray(target, dtype=float).reshape(3)
    zero = np.zeros(3)
    duration = t_touchdown - t_liftoff
    if duration <= 0.0 or t >= t_touchdown:
        return p1.copy(), zero.copy(), zero.copy()
    if t <= t_liftoff:
        return p0.copy(), zero.copy(), zero.copy()
    s = (t - t_liftoff) / duration
    horizontal = duration * horizontal_fraction          # s, the horizontal blend's length
    b, db, ddb = _quintic(s / horizontal_fraction)       # constant past its end
    pos = p0 + (p1 - p0) * b
    vel = (p1 - p0) * db / horizontal
    acc = (p1 - p0) * ddb / horizontal**2
    # z: up to the apex over the first half, down over the second (each half is a quintic).
    apex = max(p0[2], p1[2]) + height
    half = 0.5 * duration
    if s < 0.5:
        z_from, z_to, sigma = p0[2], apex, s * 2.0
    else:
        z_from, z_to, sigma = apex, p1[2], s * 2.0 - 1.0
    bz, dbz, ddbz = _quintic(sigma)
    pos[2] = z_from + (z_to - z_from) * bz
    vel[2] = (z_to - z_from) * dbz / half
    acc[2] = (z_to - z_from) * ddbz / half**2
    return pos, vel, acc


def ground_crossing_fraction(start_z: float, target_z: float, height: float,
                             depth: float) -> float:
    """The fraction of a swing, in (0.5, 1], at which a swing from ``start_z`` aimed ``depth``
    (m) below ``target_z`` (as ``swing_trajectory`` to ``target_z - depth`` with apex ``height``)
    passes ``target_z`` on its way down: 1.0 for ``depth <= 0``. Bisection on the descent's
    quintic (monotonic), to 1e-12 of the swing."""
    if depth <= 0.0:
        return 1.0
    aim = target_z - depth
    apex = max(start_z, aim) + height
    share = (apex - target_z) / (apex - aim)     # of the descent, done at the crossing
    if share <= 0.0:
        return 0.5                               # the target lies above the apex
    low, high = 0.0, 1.0
    for _ in range(40):
        middle = 0.5 * (low + high)
        if _quintic(middle)[0] < share:
            low = middle
        else:
            high = middle
    return 0.5 + 0.5 * high
