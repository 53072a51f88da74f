"""Swing-foot trajectory: lift-off position to foothold, apex ``height`` above the higher end.

Horizontal: a quintic (minimum-jerk) blend, zero velocity and acceleration at both ends.
Vertical: two quintic pieces, up to the apex at mid-swing and down to the target, each with zero
velocity and acceleration at its ends, so z is C2 as well. The whole-body controller tracks this
trajectory; after ``t_touchdown`` it holds the target (in haptic mode the controller itself keeps
pushing the foot down until contact is sensed, see docs/gait.md).
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
                     t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Foot position (3,), velocity (3,) and acceleration (3,) at sim time ``t`` (world, m, s).

    Before ``t_liftoff`` the foot is at ``start``; after ``t_touchdown`` at ``target`` (zero
    velocity and acceleration). The apex, at mid-swing, is ``height`` above max(start z,
    target z).
    """
    p0 = np.asarray(start, dtype=float).reshape(3)
    p1 = np.asarray(target, dtype=float).reshape(3)
    zero = np.zeros(3)
    duration = t_touchdown - t_liftoff
    if duration <= 0.0 or t >= t_touchdown:
        return p1.copy(), zero.copy(), zero.copy()
    if t <= t_liftoff:
        return p0.copy(), zero.copy(), zero.copy()
    s = (t - t_liftoff) / duration
    b, db, ddb = _quintic(s)
    pos = p0 + (p1 - p0) * b
    vel = (p1 - p0) * db / duration
    acc = (p1 - p0) * ddb / duration**2
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
