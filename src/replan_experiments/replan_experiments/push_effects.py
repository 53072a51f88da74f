"""What a push (held for seconds, or one short one) does to the support over the steps that
follow it, read from a run's bag after the run: the degeneration the paper's
foothold correction (V.B) is about, which the run's own metrics do not hold.

From the truth (``/ground_truth/odom``, ``/ground_truth/contacts``), over the window from the
push's start to ``horizon`` s after its end:
- ``trunk_shift_max_m``: the largest lateral shift of the trunk relative to its feet (body y of
  the base minus the centroid of the four feet, against its mean over the ``baseline`` s
  before the push): how far the push moved the body over its feet.
- ``capture_margin_min_m``: the least signed distance of the capture point (base xy plus its
  velocity over omega = sqrt(g / z), the LIP's; the base stands for the CoM) to the edges of
  the polygon of the feet in contact (negative: outside); ``com_margin_min_m`` the same for the
  base itself; ``capture_margin_p5_m`` the 5th percentile over the three- and four-foot ticks.
- ``foot_offset_change_m``: the mean over the window, and over the legs, of |the body-y offset
  of a foot from the base| minus that offset's mean before the push: how far the feet left
  their places about the hips (the hips are fixed in the body).

The bag is read once; nothing here shapes a run, so the run cache does not depend on it.
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable
from pathlib import Path

import numpy as np

from replan_core.common.rotations import yaw_of
from replan_core.common.types import GRAVITY
from replan_core.evaluation.metrics import polygon_margin

_TOPICS = ('/ground_truth/odom', '/ground_truth/contacts')


def read_truth(bag: Path):
    """Base and contact states of the truth by stamp (stamp order), read as the run's own
    analysis reads them (one per stamp)."""
    from replan_experiments.analysis import first_per_stamp, true_contacts
    from replan_ros.messages.odom import base_state_from_odom
    from replan_ros.recording.bag_read import read_messages
    data = read_messages(bag, _TOPICS)
    base = {state.stamp: state for state in first_per_stamp(
        base_state_from_odom(msg) for _, msg in data.get('/ground_truth/odom', []))}
    return base, true_contacts(data)


def push_effects(bag: Path, push_start: float, push_duration: float, horizon: float = 6.0,
                 baseline: float = 2.0) -> dict | None:
    """The module docstring's measures for the push at ``push_start`` (s) lasting
    ``push_duration`` (s); None if the bag lacks the truth over the window."""
    base, contacts = read_truth(bag)
    return effects_from_states(base, contacts, push_start, push_duration, horizon, baseline)


def effects_from_states(base: dict, contacts: dict, push_start: float, push_duration: float,
                        horizon: float = 6.0, baseline: float = 2.0) -> dict | None:
    """``push_effects`` from the states by stamp: ``base`` stamp -> BaseState, ``contacts``
    stamp -> ContactState (both the truth)."""
    stamps = np.array(sorted(set(base) & set(contacts)))
    if not len(stamps):
        return None
    end = push_start + push_duration + horizon
    before = stamps[(stamps >= push_start - baseline) & (stamps < push_start)]
    window = stamps[(stamps >= push_start) & (stamps <= end)]
    if len(before) < 2 or len(window) < 2 or stamps[-1] < end - 1e-6:
        return None

    def body_y(t: float) -> tuple[float, np.ndarray]:
        """Body y of the base about the feet's centroid, and of each foot about the base."""
        b, c = base[t], contacts[t]
        yaw = yaw_of(b.quaternion)
        side = np.array([-math.sin(yaw), math.cos(yaw)])     # body y in the world
        feet = np.asarray(c.foot_position)[:, :2]
        trunk = float(side @ (np.asarray(b.position)[:2] - feet.mean(axis=0)))
        return trunk, (feet - np.asarray(b.position)[:2]) @ side

    ref = [body_y(t) for t in before]
    trunk_ref = float(np.mean([r[0] for r in ref]))
    feet_ref = np.mean([np.abs(r[1]) for r in ref], axis=0)
    shifts, offsets, capture, com = [], [], [], []
    for t in window:
        trunk, feet_y = body_y(t)
        shifts.append(abs(trunk - trunk_ref))
        offsets.append(np.abs(feet_y) - feet_ref)
        c = contacts[t]
        in_contact = np.asarray(c.contact, dtype=bool)
        if in_contact.sum() < 3:
            continue
        polygon = np.asarray(c.foot_position)[in_contact, :2]
        b = base[t]
        height = float(b.position[2] - np.asarray(c.foot_position)[in_contact, 2].mean())
        omega = math.sqrt(GRAVITY / max(height, 1e-3))
        xy = np.asarray(b.position)[:2]
        point = xy + np.asarray(b.linear_velocity)[:2] / omega
        capture.append(polygon_margin(point, polygon))
        com.append(polygon_margin(xy, polygon))
    if not capture:
        return None
    return {'trunk_shift_max_m': round(float(max(shifts)), 4),
            'capture_margin_min_m': round(float(min(capture)), 4),
            'capture_margin_p5_m': round(float(np.percentile(capture, 5)), 4),
            'com_margin_min_m': round(float(min(com)), 4),
            'foot_offset_change_m': round(float(np.mean(np.abs(offsets))), 4),
            'window_s': [round(float(push_start), 4), round(float(end), 4)]}


def cached_push_effects(folder: Path, push_start: float, push_duration: float,
                        horizon: float = 6.0) -> dict | None:
    """``push_effects`` of the run in ``folder`` (its bag in ``folder/bag``), kept in
    ``folder/push_effects.json`` for the same push and horizon; None without a bag."""
    key = {'push_start': push_start, 'push_duration': push_duration, 'horizon': horizon}
    return cached_from_bag(folder, 'push_effects.json', key,
                           lambda bag: push_effects(bag, push_start, push_duration, horizon))


def cached_from_bag(folder: Path, name: str, key: dict,
                    compute: Callable[[Path], dict | None]) -> dict | None:
    """What ``compute`` reads from the bag of the run in ``folder`` (``folder/bag``), kept in
    ``folder/name`` with ``key`` (what it was computed for) and read from there while the key
    is the same; None without a bag."""
    cache = folder / name
    if cache.exists():
        try:
            stored = json.loads(cache.read_text())
            if stored.get('key') == key:
                return stored.get('effects')
        except (OSError, ValueError):
            pass
    bag = folder / 'bag'
    if not bag.exists():
        return None
    effects = compute(bag)
    cache.write_text(json.dumps({'key': key, 'effects': effects}))
    return effects
