"""Run metrics from recorded time series (plain arrays): falls, distance, velocity tracking."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class FallLimits:
    """A run has fallen when the trunk goes below ``min_height`` or tilts past ``max_tilt``."""

    min_height: float = 0.30      # m above the ground (base origin z)
    max_tilt: float = 0.6         # rad, roll or pitch (about 34 deg)


def roll_pitch_yaw(quaternions: np.ndarray) -> np.ndarray:
    """(n, 4) quaternions x, y, z, w -> (n, 3) roll, pitch, yaw (rad, ZYX convention)."""
    x, y, z, w = quaternions.T
    roll = np.arctan2(2 * (w * x + y * z), 1 - 2 * (x * x + y * y))
    pitch = np.arcsin(np.clip(2 * (w * y - z * x), -1.0, 1.0))
    yaw = np.arctan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))
    return np.stack([roll, pitch, yaw], axis=1)


def detect_fall(times: np.ndarray, heights: np.ndarray, rpy: np.ndarray,
                limits: FallLimits) -> tuple[bool, float | None, str]:
    """(fell, first time it happened, why)."""
    too_low = heights < limits.min_height
    tilted = np.maximum(np.abs(rpy[:, 0]), np.abs(rpy[:, 1])) > limits.max_tilt
    bad = np.flatnonzero(too_low | tilted)
    if len(bad) == 0:
        return False, None, ''
    k = bad[0]
    why = (f'trunk height {heights[k]:.3f} m < {limits.min_height} m' if too_low[k]
           else f'tilt {np.degrees(max(abs(rpy[k, 0]), abs(rpy[k, 1]))):.1f} deg > '
                f'{np.degrees(limits.max_tilt):.1f} deg')
    return True, float(times[k]), why


@dataclass(frozen=True)
class Segment:
    start: float                  # s
    end: float                    # s
    command: tuple[float, float, float]   # vx, vy (m/s, body), wz (rad/s)


def command_segments(events: list[tuple[float, tuple[float, float, float]]],
                     end_time: float) -> list[Segment]:
    """Piecewise-constant set-point segments from (time, command) changes; zero before the
    first one."""
    changes = sorted(events, key=lambda e: e[0])
    segments, t0, cmd = [], 0.0, (0.0, 0.0, 0.0)
    for t, new in changes:
        if t > t0:
            segments.append(Segment(t0, min(t, end_time), cmd))
        t0, cmd = t, tuple(float(c) for c in new)
    if end_time > t0:
        segments.append(Segment(t0, end_time, cmd))
    return [s for s in segments if s.end > s.start]


def achieved_velocity(times: np.ndarray, positions: np.ndarray, yaws: np.ndarray,
                      start: float, end: float) -> tuple[float, float, float] | None:
    """Mean body-frame velocity (vx, vy, wz) over [start, end] from the displacement: the
    world displacement is expressed in the frame of the mean heading over the window."""
    inside = np.flatnonzero((times >= start) & (times <= end))
    if len(inside) < 2:
        return None
    i0, i1 = inside[0], inside[-1]
    span = times[i1] - times[i0]
    if span <= 0:
        return None
    yaw_unwrapped = np.unwrap(yaws[inside])
    heading = float(np.mean(yaw_unwrapped))
    d = positions[i1, :2] - positions[i0, :2]
    c, s = np.cos(heading), np.sin(heading)
    body = np.array([c * d[0] + s * d[1], -s * d[0] + c * d[1]]) / span
    wz = (yaw_unwrapped[-1] - yaw_unwrapped[0]) / span
    return float(body[0]), float(body[1]), float(wz)


def tracking_errors(times: np.ndarray, positions: np.ndarray, yaws: np.ndarray,
                    segments: list[Segment], settle: float) -> list[dict]:
    """Per commanded segment: commanded and achieved velocity, after ``settle`` s."""
    rows = []
    for seg in segments:
        start = min(seg.start + settle, seg.start + 0.5 * (seg.end - seg.start))
        achieved = achieved_velocity(times, positions, yaws, start, seg.end)
        row = {'start_s': seg.start, 'end_s': seg.end, 'commanded': list(seg.command),
               'achieved': list(achieved) if achieved else None}
        if achieved is not None:
            err = np.subtract(achieved, seg.command)
            row['error'] = [float(e) for e in err]
            row['linear_error_mps'] = float(np.hypot(err[0], err[1]))
            row['yaw_rate_error_radps'] = float(abs(err[2]))
        rows.append(row)
    return rows


def distance_travelled(positions: np.ndarray) -> tuple[float, float]:
    """(straight-line distance start to end, path length) in the plane, m."""
    if len(positions) < 2:
        return 0.0, 0.0
    straight = float(np.linalg.norm(positions[-1, :2] - positions[0, :2]))
    path = float(np.sum(np.linalg.norm(np.diff(positions[:, :2], axis=0), axis=1)))
    return straight, path


def interval_stats(times: np.ndarray, skip: int = 0) -> dict | None:
    """Median, mean, min and max of the intervals between consecutive ``times`` (s), leaving out
    the first ``skip`` intervals (e.g. the stand at the start); None if none are left."""
    intervals = np.diff(np.sort(np.asarray(times, dtype=float)))[skip:]
    if len(intervals) == 0:
        return None
    return {'median': float(np.median(intervals)), 'mean': float(np.mean(intervals)),
            'min': float(np.min(intervals)), 'max': float(np.max(intervals)),
            'count': len(intervals)}
