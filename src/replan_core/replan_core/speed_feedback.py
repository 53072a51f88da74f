"""Velocity feedback in foot placement: the stride correction that makes the crawl walk at the
commanded speed (issue 31; docs/gait.md, "Velocity feedback").

Why. Each first foothold of a plan is the leg's actual foot plus one reference stride
(``gait.compute_footholds``). A foot that lands short (a haptic touchdown ends the swing at
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
or a zero set-point clears ``c``.

ROS-free and clock-free: times are the re-plan stamps (s).
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass

import numpy as np


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
        if self._samples and (sample.t <= self._samples[-1].t or not np.array_equal(
                self._samples[-1].setpoint, sample.setpoint)):
            self._samples.clear()                # a new set-point (c kept), or a new run
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
        start = min(self._samples, key=lambda s: abs(sample.t - s.t - self.window))
        measured = mean_body_velocity(start, sample)
        error = sample.setpoint[:2] - measured         # m/s, body frame
        if float(np.hypot(*error)) > self.max_error:
            return self.correction               # a disturbance: not integrated
        dt = sample.t - self._samples[-2].t
        c = self.correction + self.gain * error * dt
        norm = float(np.hypot(*c))
        if norm > self.limit:
            c *= self.limit / norm
        self.correction = c
        return self.correction
