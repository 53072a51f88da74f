"""Velocity feedback in foot placement: the stride correction that makes the crawl walk at the
commanded speed (docs/gait.md, "Velocity feedback").

Why. Each first foothold of a plan is the leg's actual foot plus one reference stride
(``crawl.compute_footholds``). A foot that lands short (a haptic touchdown ends the swing at
first contact, before the foot has reached its target) is a permanent loss: the next stride
starts from where it landed. The trunk follows the feet, so the walk settles a few per cent
below the set-point (-4 to -8 % measured, more while turning).

What. At every re-plan the base position of that tick (the estimate in the realistic profile,
never the truth) is kept; the mean velocity over the last crawl cycle is the displacement
from the re-plan closest to one cycle back (the same leg's touchdown: the crawl's sway
cancels) to this one, in the body frame of the mean heading, corrected
for the arc when the heading turned (chord to arc of a constant turn). Its error against the
set-points in force over the same window drives an integrator: the correction ``c`` (body
frame, m) is added to every stride of the plan,

    c_k = clip(c_{k-1} + gain * (v_set - v_meas) * dt_k, |c| <= limit)       (integral action)

where ``dt_k`` (s) is the time since the previous re-plan. A constant loss of ``d`` m per
stride is compensated at ``c = d``; with ``gain`` = g the remaining error shrinks by about
(1 - g) per cycle. What the integrator must not hold is a disturbance: integral action on
the velocity is position control, and a robot pushed 10 cm sideways would walk the 10 cm back.
So only a window the set-point held through counts, beginning one cycle after the set-point
changed (the trunk's acceleration to a new speed is not wound in: it would overshoot), and a
window whose error exceeds ``max_error`` (m/s: a push, a slip, a stumble; the systematic
losses measured are below 0.015 m/s) leaves the correction as it is. A stand plan, a new run
or a zero set-point clears ``c``; a new set-point keeps each axis of ``c`` scaled with it
where the set-point keeps its sign, and clears it elsewhere (``carried_correction``).

Step timing (``StepTiming``). The larger share of the loss is not short landings but late
ones: a swing's touchdown is sensed a few ticks after its planned time (the foot meets the
ground with its reference's velocity near zero, and the contact is debounced), and each
re-plan times the next steps from the actual touchdown. A stride planned for a 3 s cycle is
then walked in 3.17 s (0.792 s per step measured on the realistic HyQ): 5 % slow whatever the
footholds. ``StepTiming`` measures the step period the robot actually walks (the median of the
intervals between the last cycle's touchdowns) and the foothold planner lays the strides out
for it (``crawl.compute_footholds(stride_time_scale=)``): the footholds are where the reference
trunk will be at the actual touchdowns, not at the planned ones.

Trunk trend (``trunk_trend``). The base pose at the re-plans of the last cycle, one at each
phase of the crawl, gives where the trunk is now without its sway: each moved on to now with
the twist measured over the cycle, and averaged (the sway of the four phases cancels). The
foothold correction places the feet about the hips of that trunk (crawl.GaitParams.
correction_hips), not about the swaying one.

ROS-free and clock-free: times are the touchdown and re-plan stamps (s).
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass

import numpy as np

from replan_core.gait.crawl import ReferenceTrajectory


@dataclass(frozen=True)
class ReplanSample:
    """The state at one re-plan: stamp (s), base xy (m, world), yaw (rad), set-point
    (vx m/s, vy m/s, wz rad/s, body frame)."""

    t: float
    xy: np.ndarray
    yaw: float
    setpoint: np.ndarray


def mean_body_velocity(a: ReplanSample, b: ReplanSample) -> np.ndarray:
    """Mean (vx, vy) (m/s, body frame) from ``a`` to ``b``: the chord turned into the mean
    heading and lengthened to the arc of a constant turn through the same yaw change."""
    dt = b.t - a.t
    if dt <= 0:
        raise ValueError(f'window must have a positive length, got {dt} s')
    dyaw = math.remainder(b.yaw - a.yaw, math.tau)
    heading = a.yaw + 0.5 * dyaw
    chord = b.xy - a.xy
    c, s = math.cos(heading), math.sin(heading)
    body = np.array([c * chord[0] + s * chord[1], -s * chord[0] + c * chord[1]])
    half = 0.5 * abs(dyaw)
    arc_over_chord = half / math.sin(half) if half > 1e-9 else 1.0
    return body * arc_over_chord / dt


def one_cycle_back(samples, t: float, cycle: float) -> ReplanSample:
    """The sample closest to one crawl cycle (``cycle`` s) before ``t``: the same leg's
    touchdown, where the crawl's sway and surge are those of ``t`` (a window from it to ``t``
    cancels them)."""
    return min(samples, key=lambda s: abs(t - s.t - cycle))


def trunk_trend(samples: list[ReplanSample], cycle: float) -> np.ndarray | None:
    """The base xy (m, world) at the newest sample's time without the crawl's sway, from the
    re-plan samples (time order) of the last crawl cycle (``cycle`` s): the twist measured from
    the sample about one cycle back to the newest (the same phase: the sway cancels), each later
    sample moved on to the newest time along it, and their mean (one per phase: the sway
    cancels). None without a cycle of samples (at least two phases), or if the set-point
    changed within it (the trunk is then on its way to the new speed: the measured twist is
    not its motion now)."""
    if not samples:
        return None
    newest = samples[-1]
    # The oldest sample at most a step past one cycle back (the same leg's touchdown).
    window = [s for s in samples if newest.t - s.t <= 1.25 * cycle]
    oldest = one_cycle_back(window, newest.t, cycle)
    later = [s for s in window if s.t > oldest.t]
    span = newest.t - oldest.t
    if len(later) < 2 or span < 0.75 * cycle:
        return None
    if any(not np.array_equal(s.setpoint, newest.setpoint) for s in window if s.t >= oldest.t):
        return None
    vx, vy = mean_body_velocity(oldest, newest)
    wz = math.remainder(newest.yaw - oldest.yaw, math.tau) / span
    twist = np.array([vx, vy, wz])
    moved = [ReferenceTrajectory(s.t, s.xy, s.yaw, twist).pose(newest.t)[0] for s in later]
    return np.mean(moved, axis=0)


def carried_correction(correction: np.ndarray, old_setpoint, new_setpoint) -> np.ndarray:
    """The stride correction (m, body frame) carried over a set-point change: per axis, scaled
    with the set-point when it keeps its sign (a loss grows with the stride), else zero (a
    forward walk's correction has no meaning for a sideways one: carried, it walks the robot
    on along the old direction until the feedback unwinds it)."""
    old = np.asarray(old_setpoint, dtype=float)[:2]
    new = np.asarray(new_setpoint, dtype=float)[:2]
    carried = np.zeros(2)
    same_sign = old * new > 0.0
    carried[same_sign] = correction[same_sign] * new[same_sign] / old[same_sign]
    return carried


class SpeedFeedback:
    """The stride correction of one run (module docstring)."""

    def __init__(self, gain: float, limit: float, window: float, max_error: float) -> None:
        """gain: per cycle (0: off); limit: m, largest correction; window: s, the span the
        velocity is averaged over (one crawl cycle); max_error: m/s, a larger error is a
        disturbance, not integrated."""
        if not (math.isfinite(gain) and gain >= 0):
            raise ValueError(f'velocity feedback gain must be finite, >= 0, got {gain}')
        if not (math.isfinite(limit) and limit >= 0):
            raise ValueError(f'velocity feedback limit must be finite, >= 0, got {limit}')
        if not (math.isfinite(window) and window > 0):
            raise ValueError(f'velocity feedback window must be finite, > 0, got {window}')
        if not (math.isfinite(max_error) and max_error > 0):
            raise ValueError(f'velocity feedback max_error must be finite, > 0, got {max_error}')
        self.max_error = max_error
        self.gain = gain
        self.limit = limit
        self.window = window
        self.correction = np.zeros(2)            # m, body frame, added to every stride
        self._samples: deque[ReplanSample] = deque()
        self._settle_until = -math.inf           # s: no window starts before this

    def reset(self) -> None:
        """Forget the history and the correction (stand, new run, zero set-point)."""
        self.correction = np.zeros(2)
        self._samples.clear()

    def update(self, t: float, xy, yaw: float, setpoint) -> np.ndarray:
        """The correction (m, body frame) for the plan of the re-plan at ``t`` (s), from the
        base xy (m, world) and yaw (rad) of that tick and the set-point it plans for."""
        sample = ReplanSample(float(t), np.asarray(xy, dtype=float)[:2].copy(), float(yaw),
                              np.asarray(setpoint, dtype=float).copy())
        if self.gain == 0.0 or not np.any(sample.setpoint):
            self.reset()
            return self.correction
        if self._samples and sample.t <= self._samples[-1].t:
            self._samples.clear()                # a new run
        elif self._samples and not np.array_equal(self._samples[-1].setpoint, sample.setpoint):
            self.correction = self._limited(carried_correction(
                self.correction, self._samples[-1].setpoint, sample.setpoint))
            self._samples.clear()
        if not self._samples:
            # The trunk accelerates to a new set-point over about one cycle: a window counts
            # only from then on, or the acceleration would be wound into c (overshoot).
            self._settle_until = sample.t + self.window
        if sample.t < self._settle_until:
            self._samples.clear()                # settling: only the newest can start a window
        self._samples.append(sample)
        while sample.t - self._samples[0].t > 1.5 * self.window:
            self._samples.popleft()
        # The window's start: the re-plan closest to one cycle back, i.e. the same leg's
        # touchdown, so the crawl's sway and surge cancel (a start a step off the cycle left
        # them in: the error of one window scattered by +-0.01 m/s, as much as the loss).
        if sample.t - self._samples[0].t < 0.75 * self.window:
            return self.correction               # not a full window yet
        start = one_cycle_back(self._samples, sample.t, self.window)
        measured = mean_body_velocity(start, sample)
        error = sample.setpoint[:2] - measured         # m/s, body frame
        if float(np.hypot(*error)) > self.max_error:
            return self.correction               # a disturbance: not integrated
        dt = sample.t - self._samples[-2].t
        self.correction = self._limited(self.correction + self.gain * error * dt)
        return self.correction

    def _limited(self, c: np.ndarray) -> np.ndarray:
        """``c`` scaled down to the norm ``limit`` if longer."""
        norm = float(np.hypot(*c))
        return c * (self.limit / norm) if norm > self.limit else c


class StepTiming:
    """The step period the crawl actually walks, from its touchdown ticks (module docstring).

    ``touchdown(t)`` at every real touchdown while walking; ``restart()`` when the walk
    (re)starts from a stand, so that standing time never counts as a step. ``scale`` is the
    median of the last ``steps`` touchdown intervals over the planned step period (of those
    known while fewer: from the first interval on; 1.0 before it), clipped to
    ``[1 / max_scale, max_scale]``: the median of a full cycle keeps one forced or stumbled
    touchdown (up to ``max_extension`` late) out of the strides. The first cycle uses what it
    has: strides laid out for the planned period while the steps come earlier made the first
    cycle after a walk-off 6-12 % too fast (HyQ, B1, Go2; docs/gait.md, "Response to a
    set-point change").
    """

    def __init__(self, step_period: float, steps: int, max_scale: float = 1.25) -> None:
        """step_period: s, planned touchdown to touchdown; steps: intervals in the median (one
        crawl cycle); max_scale: the largest stretch (or shrink) of a stride."""
        if not (math.isfinite(step_period) and step_period > 0):
            raise ValueError(f'step period must be finite, > 0, got {step_period}')
        if steps < 1:
            raise ValueError(f'steps must be >= 1, got {steps}')
        if not (math.isfinite(max_scale) and max_scale >= 1.0):
            raise ValueError(f'max_scale must be finite, >= 1, got {max_scale}')
        self.step_period = step_period
        self.max_scale = max_scale
        self._intervals: deque[float] = deque(maxlen=steps)
        self._last: float | None = None          # s, the previous touchdown of this walk

    def restart(self) -> None:
        """The walk starts (again) from a stand: the next touchdown opens no interval."""
        self._last = None

    def touchdown(self, t: float) -> None:
        """A real step touched down at tick ``t`` (s)."""
        t = float(t)
        if self._last is not None and t > self._last:
            self._intervals.append(t - self._last)
        self._last = t

    @property
    def measured_period(self) -> float | None:
        """s, the median touchdown interval of the last cycle (of the intervals known while
        fewer); None before the first."""
        if not self._intervals:
            return None
        return float(np.median(self._intervals))

    @property
    def scale(self) -> float:
        """Measured over planned step period, clipped; 1.0 while not measured."""
        measured = self.measured_period
        if measured is None:
            return 1.0
        return min(max(measured / self.step_period, 1.0 / self.max_scale), self.max_scale)
