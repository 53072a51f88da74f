"""How the trunk travels between its footholds (the velocity term's "faster motion"),
read from a run's bag after the run; the run's own metrics give the speed and the rise time,
not how the trunk gets there.

From the truth (``/ground_truth/odom``, ``/ground_truth/contacts``), over a window of a
straight walk whose set-point points along ``direction`` (body frame), each tick's progress
is the base's horizontal displacement since the tick before, projected on that direction
turned by the base's yaw (m):
- ``swing_travel_share``: the progress made while a foot is off the ground (fewer than four
  debounced contacts) over all progress. A crawl's four-feet phases are a third of its time;
  a trunk that stops while a leg swings makes less than ``swing_time_share`` of its travel
  then, one that keeps moving makes about that share.
- ``swing_time_share``: the share of the window's ticks with a foot off the ground.
- ``backward_travel_m``: the sum of the negative progress: how far the trunk moved back,
  against the set-point, over the window.
- ``stride_length_m``: the mean distance between successive true touchdowns (rising contact
  flags) of the same foot inside the window.
- ``progress_m``: the net progress over the window.

Nothing here shapes a run, so the run cache does not depend on it.
"""

from __future__ import annotations

import itertools
import math
from pathlib import Path

import numpy as np

from replan_core.common.rotations import yaw_of
from replan_experiments.push_effects import cached_from_bag, read_truth


def motion_from_states(base: dict, contacts: dict, start: float, end: float,
                       direction=(1.0, 0.0)) -> dict | None:
    """The module docstring's measures over ``start`` to ``end`` (s), from the states by stamp:
    ``base`` stamp -> BaseState, ``contacts`` stamp -> ContactState (both the truth);
    ``direction``: the set-point's direction in the body frame. None if the states do not
    cover the window or the trunk made no progress along the direction."""
    stamps = np.array(sorted(t for t in set(base) & set(contacts) if start <= t <= end))
    along = np.asarray(direction, dtype=float).reshape(2)
    if len(stamps) < 3 or not np.linalg.norm(along) > 0:
        return None
    along = along / np.linalg.norm(along)
    progress, swinging = [], []
    for before, now in itertools.pairwise(stamps):
        yaw = yaw_of(base[now].quaternion)
        cos, sin = math.cos(yaw), math.sin(yaw)
        heading = np.array([cos * along[0] - sin * along[1], sin * along[0] + cos * along[1]])
        step = np.asarray(base[now].position)[:2] - np.asarray(base[before].position)[:2]
        progress.append(float(heading @ step))
        swinging.append(int(np.count_nonzero(contacts[now].contact)) < 4)
    progress_arr, swing_arr = np.array(progress), np.array(swinging, dtype=bool)
    total = float(progress_arr.sum())
    if not total > 0:
        return None
    strides = []
    last_touchdown: dict[int, np.ndarray] = {}
    for t in stamps:
        c = contacts[t]
        for leg in np.flatnonzero(np.asarray(c.touchdown, dtype=bool)):
            foot = np.asarray(c.foot_position)[leg, :2]
            if leg in last_touchdown:
                strides.append(float(np.linalg.norm(foot - last_touchdown[leg])))
            last_touchdown[leg] = foot
    return {'swing_travel_share': round(float(progress_arr[swing_arr].sum()) / total, 4),
            'swing_time_share': round(float(swing_arr.mean()), 4),
            'backward_travel_m': round(float(-progress_arr[progress_arr < 0].sum()), 5),
            'stride_length_m': round(float(np.mean(strides)), 4) if strides else None,
            'progress_m': round(total, 4),
            'motion_window_s': [round(float(start), 4), round(float(end), 4)]}


def cached_motion_effects(folder: Path, start: float, end: float,
                          direction=(1.0, 0.0)) -> dict | None:
    """``motion_from_states`` of the run in ``folder`` (its bag in ``folder/bag``), kept in
    ``folder/motion_effects.json`` for the same window and direction; None without a bag."""
    key = {'start': float(start), 'end': float(end),
           'direction': [float(v) for v in direction]}

    def compute(bag: Path) -> dict | None:
        base, contacts = read_truth(bag)
        return motion_from_states(base, contacts, start, end, direction)
    return cached_from_bag(folder, 'motion_effects.json', key, compute)
