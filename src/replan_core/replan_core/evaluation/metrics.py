"""Run metrics from recorded time series (plain arrays): falls, distance, velocity tracking."""

from __future__ import annotations

import itertools
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
    """Mean body-frame velocity (vx, vy, wz) over [start, end]: each step between two samples
    is expressed in the body frame of its mid heading and the steps are summed (the body
    velocity integrated), so a walk that turns reads its speed along the arc. The chord of the
    displacement, used before, read a 0.05 m/s walk turning at 0.2 rad/s over 18 s as 0.027
    m/s (test_metrics.py)."""
    inside = np.flatnonzero((times >= start) & (times <= end))
    if len(inside) < 2:
        return None
    span = times[inside[-1]] - times[inside[0]]
    if span <= 0:
        return None
    yaw_unwrapped = np.unwrap(yaws[inside])
    steps = np.diff(positions[inside, :2], axis=0)                   # world, m
    mid = 0.5 * (yaw_unwrapped[1:] + yaw_unwrapped[:-1])             # rad
    c, s = np.cos(mid), np.sin(mid)
    vx = float(np.sum(c * steps[:, 0] + s * steps[:, 1]) / span)    # m/s, body x
    vy = float(np.sum(-s * steps[:, 0] + c * steps[:, 1]) / span)   # m/s, body y
    wz = float((yaw_unwrapped[-1] - yaw_unwrapped[0]) / span)        # rad/s
    return vx, vy, wz


def _cycle_leg(touchdowns: list[tuple[float, int]], start: float,
               end: float) -> list[float]:
    """The touchdown times within [start, end] (s) of the leg whose first to last touchdown
    there spans the longest (the earliest leg on a tie); [] without any."""
    best: list[float] = []
    for leg in sorted({leg for _, leg in touchdowns}):
        times = sorted(t for t, other in touchdowns if other == leg and start <= t <= end)
        if len(times) >= 2 and (not best or times[-1] - times[0] > best[-1] - best[0]):
            best = times
    return best


def whole_cycles(touchdowns: list[tuple[float, int]], start: float,
                 end: float) -> tuple[float, float, int] | None:
    """The longest span within [start, end] (s) from a touchdown of one leg to a later one of
    the same leg, and the crawl cycles in it: ``(t0, t1, cycles)``, or None without two.

    A crawl's trunk sways and surges with its cycle, so a velocity averaged over a span that is
    not whole cycles keeps part of that swing (HyQ sideways at 0.1 m/s read 0.079 to 0.108 m/s
    over 3 s windows). touchdowns: (time s, leg), one per step (``executed_steps``'
    actual touchdowns, not contact edges: a stance foot whose load flickers around the
    threshold has edges too).
    """
    times = _cycle_leg(touchdowns, start, end)
    return (times[0], times[-1], len(times) - 1) if times else None


def cycle_velocities(times: np.ndarray, positions: np.ndarray, yaws: np.ndarray,
                     touchdowns: list[tuple[float, int]], start: float,
                     end: float) -> list[dict]:
    """The mean body velocity over each whole crawl cycle within [start, end] (s), in time
    order: ``{'start_s', 'end_s', 'velocity': [vx, vy, wz]}`` (m/s, rad/s), from one touchdown
    of a leg to its next (the leg of ``whole_cycles``). After a set-point change the first
    cycles show how the trunk gets to the new speed; the last ones are its steady state."""
    return _cycles_between(times, positions, yaws, _cycle_leg(touchdowns, start, end))


def leg_cycle_velocities(times: np.ndarray, positions: np.ndarray, yaws: np.ndarray,
                         touchdowns: list[tuple[float, int]], start: float,
                         end: float) -> list[dict]:
    """The whole cycles within [start, end] (s) opened by each leg: ``{'leg', 'cycles'}``
    (``cycles`` as ``cycle_velocities``' rows, from each touchdown of that leg to its next),
    legs in the order of their first touchdown there. The legs land a step apart, so each
    leg's first cycle starts at a different point of the way to a new speed: one leg's cycles
    alone can show a lag and miss the catch-up that follows it, or the reverse."""
    rows = []
    for leg in sorted({leg for _, leg in touchdowns}):
        legs_times = sorted(t for t, other in touchdowns if other == leg and start <= t <= end)
        cycles = _cycles_between(times, positions, yaws, legs_times)
        if cycles:
            rows.append({'leg': int(leg), 'cycles': cycles})
    return sorted(rows, key=lambda row: row['cycles'][0]['start_s'])


def _cycles_between(times: np.ndarray, positions: np.ndarray, yaws: np.ndarray,
                    cycle_times: list[float]) -> list[dict]:
    """``cycle_velocities``' rows between each pair of consecutive ``cycle_times`` (s)."""
    rows = []
    for t0, t1 in itertools.pairwise(cycle_times):
        v = achieved_velocity(times, positions, yaws, t0, t1)
        if v is not None:
            rows.append({'start_s': float(t0), 'end_s': float(t1),
                         'velocity': [float(x) for x in v]})
    return rows


def steady_velocity(cycles: list[dict], last: int) -> list[float] | None:
    """(vx, vy, wz) over the ``last`` whole cycles of ``cycle_velocities``' rows (the
    duration-weighted mean, i.e. the velocity integrated over their span): the steady state
    once the trunk has got to the speed; None with fewer cycles."""
    if last < 1 or len(cycles) < last:
        return None
    tail = cycles[-last:]
    weights = np.array([c['end_s'] - c['start_s'] for c in tail])
    mean = np.average(np.array([c['velocity'] for c in tail]), axis=0, weights=weights)
    return [float(x) for x in mean]


def tracking_errors(times: np.ndarray, positions: np.ndarray, yaws: np.ndarray,
                    segments: list[Segment], settle: float,
                    touchdowns: list[tuple[float, int]] | None = None,
                    steady_cycles: int = 2) -> list[dict]:
    """Per commanded segment: commanded and achieved velocity, after ``settle`` s. With the
    true ``touchdowns`` ((time s, leg), as ``whole_cycles``), also the velocity over the whole
    crawl cycles after the settling (``achieved_cycles``, its span ``cycles_span_s`` and
    ``cycles``: the crawl's sway averaged out), the velocity of each whole cycle from the
    segment's start (``cycle_velocities``) and the steady state over its last
    ``steady_cycles`` cycles (``achieved_steady``; None with fewer), and each leg's whole
    cycles (``leg_cycle_velocities``). After a set-point change the trunk takes a few cycles
    to get to the new speed (it falls behind its feet while it accelerates); an average from
    ``settle`` s on keeps part of that."""
    rows = []
    for seg in segments:
        start = min(seg.start + settle, seg.start + 0.5 * (seg.end - seg.start))
        achieved = achieved_velocity(times, positions, yaws, start, seg.end)
        row = {'start_s': seg.start, 'end_s': seg.end, 'commanded': list(seg.command),
               'achieved': list(achieved) if achieved else None}
        span = whole_cycles(touchdowns, start, seg.end) if touchdowns else None
        cycles = achieved_velocity(times, positions, yaws, span[0], span[1]) if span else None
        if touchdowns is not None:
            per_cycle = cycle_velocities(times, positions, yaws, touchdowns, seg.start,
                                         seg.end)
            row.update(achieved_cycles=list(cycles) if cycles else None,
                       cycles_span_s=[span[0], span[1]] if cycles else None,
                       cycles=span[2] if cycles else 0,
                       cycle_velocities=per_cycle,
                       leg_cycle_velocities=leg_cycle_velocities(
                           times, positions, yaws, touchdowns, seg.start, seg.end),
                       achieved_steady=steady_velocity(per_cycle, steady_cycles),
                       steady_cycles=steady_cycles)
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


# ------------------------------------------------------------------------------------------
# Measured balance, estimator and touchdown metrics (the realistic robot, docs/realism.md)


def _convex_hull(points: np.ndarray) -> np.ndarray:
    """Counter-clockwise convex hull of (n, 2) points (monotone chain; n is at most 4 here)."""
    pts = sorted(map(tuple, points))
    if len(pts) <= 2:
        return np.array(pts)

    def cross(o, a, b):
        return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])

    lower: list = []
    for p in pts:
        while len(lower) >= 2 and cross(lower[-2], lower[-1], p) <= 0:
            lower.pop()
        lower.append(p)
    upper: list = []
    for p in reversed(pts):
        while len(upper) >= 2 and cross(upper[-2], upper[-1], p) <= 0:
            upper.pop()
        upper.append(p)
    return np.array(lower[:-1] + upper[:-1])


def _segment_distance(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> float:
    ab = b - a
    length2 = float(ab @ ab)
    s = 0.0 if length2 == 0.0 else min(max(float((p - a) @ ab) / length2, 0.0), 1.0)
    return float(np.linalg.norm(p - (a + s * ab)))


def polygon_margin(point: np.ndarray, vertices: np.ndarray) -> float:
    """Signed distance (m) of a point to the convex hull of ``vertices`` (n, 2): positive
    inside (distance to the nearest edge), negative outside; a segment or a single point has
    no inside (0 on it, negative off it)."""
    hull = _convex_hull(np.asarray(vertices, dtype=float))
    p = np.asarray(point, dtype=float)
    if len(hull) == 0:
        return -np.inf
    if len(hull) == 1:
        return -float(np.linalg.norm(p - hull[0]))
    if len(hull) == 2:
        return -_segment_distance(p, hull[0], hull[1])
    inside = True
    distance = np.inf
    for a, b in zip(hull, np.roll(hull, -1, axis=0), strict=True):
        edge = b - a
        if edge[0] * (p[1] - a[1]) - edge[1] * (p[0] - a[0]) < 0.0:
            inside = False
        distance = min(distance, _segment_distance(p, a, b))
    return float(distance if inside else -distance)


def cop_margins(feet: np.ndarray, forces: np.ndarray, min_normal_force: float = 1.0
                ) -> tuple[np.ndarray, np.ndarray]:
    """Measured centre of pressure and its margin in the polygon of the feet in contact.

    feet, forces: (n, 4, 3) true foot positions and ground reaction forces (world); a foot is in
    contact when its normal (z) force exceeds ``min_normal_force`` N. The CoP is the
    normal-force-weighted mean of the contact feet (flat-ground approximation). Returns the CoP
    (n, 2) and the margin (n,) m (negative = outside; NaN when no foot carries load).
    """
    n = len(feet)
    cop = np.full((n, 2), np.nan)
    margin = np.full(n, np.nan)
    for k in range(n):
        fz = forces[k, :, 2]
        loaded = fz > min_normal_force
        if not np.any(loaded):
            continue
        xy = feet[k, loaded, :2]
        cop[k] = fz[loaded] @ xy / fz[loaded].sum()
        margin[k] = polygon_margin(cop[k], xy)
    return cop, margin


def estimator_errors(times: np.ndarray, estimated: np.ndarray, true: np.ndarray,
                     estimated_velocity: np.ndarray, true_velocity: np.ndarray) -> dict:
    """Errors of an estimated base trajectory against the truth at the same stamps.

    estimated, true: (n, 3) positions (m); *_velocity: (n, 3) world linear velocities (m/s).
    """
    if len(times) == 0:
        return {}
    xy = np.linalg.norm(estimated[:, :2] - true[:, :2], axis=1)
    velocity = np.linalg.norm(estimated_velocity - true_velocity, axis=1)
    walked = float(np.sum(np.linalg.norm(np.diff(true[:, :2], axis=0), axis=1)))
    return {'samples': len(times), 'xy_error_end_m': float(xy[-1]),
            'xy_error_max_m': float(xy.max()),
            'xy_drift_fraction': float(xy[-1] / walked) if walked > 0.05 else None,
            'z_error_max_m': float(np.abs(estimated[:, 2] - true[:, 2]).max()),
            'velocity_rmse_mps': float(np.sqrt(np.mean(velocity ** 2))),
            'path_length_m': walked}


def touchdown_timing(touchdowns: list[tuple[float, int]],
                     planned: list[tuple[float, int, float, float]]
                     ) -> tuple[np.ndarray, np.ndarray]:
    """Actual minus planned touchdown time (s) of each executed step, and the actual times.

    touchdowns: (time, leg) of each true touchdown edge (a stance foot whose load flickers
    around the threshold has edges too). planned: (plan stamp, leg, planned lift-off, planned
    touchdown) of each step of each published plan. A step was executed if it lifted off
    before the next plan was made; its actual touchdown is the first edge of its leg after half
    its planned swing and before its planned touchdown plus the planned swing (a step with no
    such edge is left out).
    """
    matched = [(actual, actual - touchdown) for _, _, touchdown, actual in
               executed_steps(touchdowns, planned) if actual is not None]
    return (np.array([error for _, error in matched]),
            np.array([actual for actual, _ in matched]))


def peaks_around(times: np.ndarray, values: np.ndarray, events: np.ndarray,
                 before: float = 0.1, after: float = 0.3) -> np.ndarray:
    """Peak-to-peak excursion of ``values`` in [event - before, event + after] per event."""
    out = []
    for t in events:
        inside = (times >= t - before) & (times <= t + after)
        if np.count_nonzero(inside) >= 2:
            window = values[inside]
            out.append(float(window.max() - window.min()))
    return np.array(out)


def planned_zmp_at(times: np.ndarray, plans: list[tuple[float, np.ndarray, np.ndarray]]
                   ) -> np.ndarray:
    """The planned ZMP (n, 2) at ``times`` from the newest plan made at or before each time.

    plans: (plan stamp, sample times (m,), ZMP samples (m, 2)) in any order; between samples
    the LIP plan's ZMP is linear (the CoM acceleration is, under constant jerk). NaN where no
    plan exists yet.
    """
    out = np.full((len(times), 2), np.nan)
    plans = sorted(plans, key=lambda p: p[0])
    starts = np.array([p[0] for p in plans])
    for i, (stamp, sample_times, zmp) in enumerate(plans):
        end = starts[i + 1] if i + 1 < len(plans) else np.inf
        inside = (times >= stamp - 1e-9) & (times < end - 1e-9)
        if np.any(inside) and len(sample_times):
            out[inside, 0] = np.interp(times[inside], sample_times, zmp[:, 0])
            out[inside, 1] = np.interp(times[inside], sample_times, zmp[:, 1])
    return out


def flag_intervals(times: np.ndarray, flags: np.ndarray) -> list[tuple[float, float]]:
    """The (start, end) times of the runs of True in a sampled boolean series: from the first
    true sample of a run to the first false sample after it (the last time if none)."""
    flags = np.asarray(flags, dtype=bool)
    if len(flags) == 0:
        return []
    edges = np.diff(flags.astype(np.int8))
    starts = list(np.flatnonzero(edges == 1) + 1)
    ends = list(np.flatnonzero(edges == -1) + 1)
    if flags[0]:
        starts.insert(0, 0)
    out = [(float(times[s]), float(times[e])) for s, e in zip(starts, ends, strict=False)]
    if len(starts) > len(ends):
        out.append((float(times[starts[-1]]), float(times[-1])))
    return out


def executed_steps(touchdowns: list[tuple[float, int]],
                   planned: list[tuple[float, int, float, float]]
                   ) -> list[tuple[int, float, float, float | None]]:
    """The executed steps and their actual touchdowns, by the rule of ``touchdown_timing``:
    (leg, planned lift-off, planned touchdown, actual touchdown or None if no edge matched),
    in plan order. Arguments as for ``touchdown_timing``."""
    by_leg: dict[int, list[float]] = {}
    for t, leg in touchdowns:
        by_leg.setdefault(leg, []).append(t)
    for times in by_leg.values():
        times.sort()
    stamps = sorted({p[0] for p in planned})
    next_plan = dict(zip(stamps, [*stamps[1:], np.inf], strict=False))
    out: list[tuple[int, float, float, float | None]] = []
    for stamp, leg, liftoff, touchdown in sorted(planned, key=lambda p: (p[0], p[2])):
        if liftoff >= next_plan[stamp] - 1e-9:
            continue
        swing = touchdown - liftoff
        actual = next((t for t in by_leg.get(leg, [])
                       if liftoff + 0.5 * swing < t <= touchdown + swing), None)
        out.append((int(leg), float(liftoff), float(touchdown), actual))
    return out


# ------------------------------------------------------------------------------------------
# Experiment metrics (scripts/experiments.sh, docs/results.md)


def settle_time(times: np.ndarray, positions: np.ndarray, yaws: np.ndarray, segment: Segment,
                window: float = 1.0, tolerance: float = 0.1) -> float | None:
    """Seconds from the start of ``segment`` until the velocity, averaged over the trailing
    ``window`` (s; a crawl's velocity swings within each step), is within ``tolerance`` of the
    segment's set-point; None if it never is before the segment ends.

    Within tolerance: the planar velocity error is at most ``tolerance`` times the commanded
    planar speed, and, if a yaw rate is commanded, the yaw-rate error at most ``tolerance``
    times it. The window's delay (about window / 2) is part of the figure.
    """
    vx, vy, wz = segment.command
    speed = float(np.hypot(vx, vy))
    if speed == 0.0 and wz == 0.0:
        return None
    inside = np.flatnonzero((times >= segment.start) & (times <= segment.end))
    for i in inside:
        t = float(times[i])
        if t - window < times[0]:
            continue
        achieved = achieved_velocity(times, positions, yaws, t - window, t)
        if achieved is None:
            continue
        linear_ok = np.hypot(achieved[0] - vx, achieved[1] - vy) <= tolerance * speed
        yaw_ok = wz == 0.0 or abs(achieved[2] - wz) <= tolerance * abs(wz)
        if linear_ok and yaw_ok:
            return t - segment.start
    return None


def triangle_inradius(vertices: np.ndarray) -> float:
    """Radius (m) of the circle inscribed in the triangle of (3, 2) ``vertices``: 2 area /
    perimeter; 0 for a degenerate triangle."""
    a, b, c = np.asarray(vertices, dtype=float)[:, :2]
    area = 0.5 * abs((b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]))
    perimeter = np.linalg.norm(b - a) + np.linalg.norm(c - b) + np.linalg.norm(a - c)
    return float(2.0 * area / perimeter) if perimeter > 0 else 0.0


def support_inradius_after(times: np.ndarray, feet: np.ndarray, in_contact: np.ndarray,
                           start: float, steps: int = 3) -> float | None:
    """Least inradius (m) of the support triangle (exactly three feet in contact) from ``start``
    until ``steps`` swings have begun and ended, the paper's measure of how a push degenerates
    the support polygons; None if no three-foot support occurs in that span.

    times (n,), feet (n, 4, 3) foot positions, in_contact (n, 4) bool.
    """
    three = np.count_nonzero(in_contact, axis=1) == 3
    after = times >= start
    starts = np.flatnonzero(after[1:] & three[1:] & ~three[:-1]) + 1
    end = times[-1]
    if len(starts) > steps:
        end = times[starts[steps]]              # the start of the (steps+1)-th swing
    chosen = np.flatnonzero(after & three & (times < end))
    if len(chosen) == 0:
        return None
    return float(min(triangle_inradius(feet[i][in_contact[i]]) for i in chosen))


def rise_time(times: np.ndarray, positions: np.ndarray, yaws: np.ndarray, before: Segment,
              after: Segment, window: float = 1.0, fraction: float = 0.9,
              settle: float = 2.0, achieved_after=None) -> float | None:
    """Seconds from a set-point change until the velocity, averaged over the trailing
    ``window``, has covered ``fraction`` of the way from what was achieved before the change
    to what is achieved after it: how promptly the change is followed, apart from any
    steady-state offset of the achieved velocity from the set-point. Each component whose
    set-point changed must have got there (vx, vy in m/s, wz in rad/s); None if one never
    does before ``after`` ends, or if the achieved velocities cannot be measured.

    Achieved before: the mean over the last ``settle`` s of ``before``; after:
    ``achieved_after`` (vx, vy, wz) if given (the steady state over whole cycles,
    ``tracking_errors``' ``achieved_steady``), else the mean from ``settle`` s into ``after``
    to its end, which keeps part of the trunk's acceleration and so reads a lower target.
    """
    v0 = achieved_velocity(times, positions, yaws, max(before.start, before.end - settle),
                           before.end)
    v1 = (tuple(achieved_after) if achieved_after is not None else achieved_velocity(
        times, positions, yaws, min(after.start + settle, 0.5 * (after.start + after.end)),
        after.end))
    if v0 is None or v1 is None:
        return None
    changed = [k for k in range(3) if abs(after.command[k] - before.command[k]) > 1e-9]
    if not changed:
        return None
    goal = {k: v0[k] + fraction * (v1[k] - v0[k]) for k in changed}
    rising = {k: v1[k] > v0[k] for k in changed}
    inside = np.flatnonzero((times > after.start) & (times <= after.end))
    for i in inside:
        t = float(times[i])
        if t - window < times[0]:
            continue
        v = achieved_velocity(times, positions, yaws, t - window, t)
        if v is not None and all((v[k] >= goal[k]) if rising[k] else (v[k] <= goal[k])
                                 for k in changed):
            return t - after.start
    return None
