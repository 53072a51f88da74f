"""What a run's gait did, step by step, read from its bag: when each touchdown was sensed
against the true contact, the step periods, each whole cycle's speed split into the feet's
strides and the trunk's place over them, each set-point's cycles opened by each leg as the
robots page judges them, the re-plans of that cycle (each
leg's first stride, the CoM plan's travel against the truth's), and the velocity feedback's
stride correction at the end of each set-point (docs/gait.md, "Response to a set-point
change").

    python -m replan_experiments.gait_report RUN_DIR [--after S] [--late S]

RUN_DIR is a run's folder (``scripts/scenario.sh --out``, or a page's run cache): its ``bag``
and ``metrics.json`` (the cycles of ``velocity_tracking``, each leg's among them). It reads a
finished run; no run imports it, so it shapes none.
"""

from __future__ import annotations

import argparse
import itertools
import json
import math
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from replan_core.common.types import LEGS
from replan_core.evaluation.metrics import roll_pitch_yaw
from replan_experiments.analysis import contact_series, true_contacts
from replan_experiments.robots_page import response_axis
from replan_experiments.robots_render import response_misses
from replan_ros.messages.com_plan import com_plan_from_msg
from replan_ros.messages.footholds import footholds_from_msg
from replan_ros.messages.odom import base_state_from_odom
from replan_ros.messages.stamps import stamp_to_sec
from replan_ros.recording.bag_read import TRUTH_TOPIC, read_messages

SENSED_TOPIC = '/contacts'
TRUE_CONTACTS_TOPIC = '/ground_truth/contacts'
DIAGNOSTICS_TOPIC = '/diagnostics'
FOOTHOLDS_TOPIC = '/footholds'
COM_PLAN_TOPIC = '/com_plan'
# s: a touchdown sensed up to this long before the truth's still pairs with it (the truth's
# contact flag is debounced too, sim.debounce_ticks).
PAIR_SLACK = 0.02


@dataclass(frozen=True)
class Sensing:
    """One sensed touchdown: tick (s), leg, and how long after the same foot's true contact it
    was sensed (s; None: no true contact of that foot since its previous sensed touchdown)."""

    t: float
    leg: int
    delay: float | None


def sensing_delays(sensed: list[tuple[float, int]],
                   true: list[tuple[float, int]]) -> list[Sensing]:
    """Pair each sensed touchdown (time s, leg) with the last true touchdown of its foot after
    that foot's previous sensed one, up to ``PAIR_SLACK`` after it."""
    out = []
    previous = dict.fromkeys(range(len(LEGS)), -math.inf)
    for t, leg in sorted(sensed):
        candidates = [tt for tt, ll in true
                      if ll == leg and previous[leg] < tt <= t + PAIR_SLACK]
        out.append(Sensing(t, leg, t - max(candidates) if candidates else None))
        previous[leg] = t + PAIR_SLACK
    return out


@dataclass(frozen=True)
class CycleSplit:
    """One whole cycle along the set-point's direction: its span (s); the trunk's and the feet's
    mean speed in % of the set-point; the trunk minus the mean of the four feet at its start
    and end (m); the trunk minus the reference at its start and end (m)."""

    start: float
    end: float
    trunk_percent: float
    feet_percent: float
    over_feet: tuple[float, float]
    over_reference: tuple[float, float]


def _at(times: np.ndarray, values: np.ndarray, t: float):
    """The sample of ``values`` at the first time at or after ``t`` (the last one past the end)."""
    return values[min(int(np.searchsorted(times, t)), len(times) - 1)]


def cycle_splits(boundaries: list[float], speed: float, direction: np.ndarray,
                 origin: tuple[float, np.ndarray], trunk: tuple[np.ndarray, np.ndarray],
                 feet: tuple[np.ndarray, np.ndarray]) -> list[CycleSplit]:
    """Each whole cycle between consecutive ``boundaries`` (s) along ``direction`` (unit, world
    xy) at the set-point ``speed`` (m/s). ``origin`` (time s, xy m) starts the reference, which
    moves on at the set-point; ``trunk`` (times, xy) and ``feet`` (times, (n, 4, 2) xy) are the
    truth."""
    def along(xy) -> float:
        return float(np.dot(xy, direction))

    def reference(t: float) -> float:
        return along(origin[1]) + speed * (t - origin[0])

    rows = []
    for t0, t1 in itertools.pairwise(boundaries):
        b0, b1 = along(_at(*trunk, t0)), along(_at(*trunk, t1))
        f0, f1 = (along(_at(*feet, t).mean(axis=0)) for t in (t0, t1))
        span = (t1 - t0) * speed
        rows.append(CycleSplit(t0, t1, 100.0 * (b1 - b0) / span, 100.0 * (f1 - f0) / span,
                               (b0 - f0, b1 - f1), (b0 - reference(t0), b1 - reference(t1))))
    return rows


def judged(segment: dict) -> tuple[str, str, list[str]]:
    """A set-point's whole cycles opened by each leg (the run's ``leg_cycle_velocities``), in
    per cent of the set-point, judged as docs/robots.md judges them: the report's line, the
    set-point's axis and what it misses (``robots_render.response_misses``)."""
    axis, cell = response_axis(segment)
    misses = response_misses(cell)
    legs = '; '.join(f'{leg["leg"]} at {leg["start_s"] - segment["start_s"]:.2f} s '
                     + ' '.join(f'{100 * x:.0f}' for x in leg['shares'])
                     for leg in cell['legs'])
    line = (f'  {axis}: each whole cycle opened by each leg, % of the set-point, as '
            f'docs/robots.md judges them: {legs or "none"}'
            + (f' ({", ".join(misses)} off)' if misses else ' (met)'))
    return line, axis, misses


def first_strides(plan, direction: np.ndarray) -> list[tuple[int, float]]:
    """Each leg's first step in the foothold plan ``plan``: (leg, its stride along
    ``direction`` (unit, world xy), m, from the foot where it stands), in touchdown order."""
    first: dict = {}
    for step in plan.steps:
        first.setdefault(step.leg, step)
    feet = np.asarray(plan.initial_feet, dtype=float)
    return [(leg, float(np.dot(step.target[:2] - feet[leg, :2], direction)))
            for leg, step in sorted(first.items(), key=lambda item: item[1].touchdown_time)]


def travel_at(times: np.ndarray, xy: np.ndarray, t0: float, span: float,
              direction: np.ndarray) -> list[float]:
    """Travel (m) along ``direction`` from ``t0`` to ``t0`` plus a quarter, a half, three
    quarters and the whole of ``span`` (s), linear between the samples (``times``, ``xy``)."""
    def along(t: float) -> float:
        return float(np.dot([np.interp(t, times, xy[:, 0]), np.interp(t, times, xy[:, 1])],
                            direction))
    return [along(t0 + f * span) - along(t0) for f in (0.25, 0.5, 0.75, 1.0)]


def _touchdowns(times, touchdown) -> list[tuple[float, int]]:
    """(time s, leg) of every touchdown flag: ``touchdown`` (n, 4) bool at ``times`` (n,) s."""
    return [(float(t), int(leg)) for t, row in zip(times, touchdown, strict=True)
            for leg in np.flatnonzero(row)]


def _decoded(messages, decode) -> list:
    """``decode`` of each (log time, message) pair, in plan-stamp order; messages it refuses
    are left out."""
    plans = []
    for _, msg in messages:
        try:
            plans.append(decode(msg))
        except ValueError:
            continue
    return sorted(plans, key=lambda plan: plan.start_time)


def stride_corrections(diagnostics) -> list[tuple[float, float, float]]:
    """(stamp s, x m, y m) of the gait's velocity-feedback stride correction (body frame), from
    its ``/diagnostics`` messages ((log time, message) pairs), in stamp order."""
    rows = []
    for _, array in diagnostics:
        for status in array.status:
            values = {kv.key: kv.value for kv in status.values}
            if status.name.startswith('gait') and 'stride_correction_x' in values:
                rows.append((stamp_to_sec(array.header.stamp),
                             float(values['stride_correction_x']),
                             float(values['stride_correction_y'])))
    return sorted(rows)


def report(run: Path, after: float, late: float) -> list[str]:
    """The report's lines for the run folder ``run``; touchdowns before ``after`` (s, the
    stand-up) are left out; a sensed touchdown later than ``late`` (s) after its true contact
    counts as late."""
    metrics = json.loads((run / 'metrics.json').read_text())
    data = read_messages(run / 'bag', topics=(TRUTH_TOPIC, SENSED_TOPIC, TRUE_CONTACTS_TOPIC,
                                              DIAGNOSTICS_TOPIC, FOOTHOLDS_TOPIC,
                                              COM_PLAN_TOPIC))
    sensed_series = contact_series(data, SENSED_TOPIC)
    truth = true_contacts(data)              # stamp -> the true contact state, feet included
    odom = sorted((base_state_from_odom(m) for _, m in data.get(TRUTH_TOPIC, [])),
                  key=lambda b: b.stamp)
    if not (odom and sensed_series and truth):
        raise ValueError(f'{run}: the bag holds no {TRUTH_TOPIC}, {SENSED_TOPIC} or '
                         f'{TRUE_CONTACTS_TOPIC}')
    true_times = sorted(truth)
    sensed = _touchdowns(sensed_series['times'], sensed_series['touchdown'])
    true = _touchdowns(true_times, [truth[t].touchdown for t in true_times])
    lines = _sensing_lines(sensing_delays(sensed, true), after, late)
    times = np.array([t for t, _ in sensed if t >= after])
    if len(times) > 1:
        intervals = np.diff(times)
        lines.append(f'intervals between sensed touchdowns after {after:g} s (s): median '
                     f'{np.median(intervals):.3f}, {intervals.min():.3f}-{intervals.max():.3f}')
    trunk = (np.array([b.stamp for b in odom]), np.array([b.position[:2] for b in odom]))
    trunk_velocity = np.array([b.linear_velocity[:2] for b in odom])     # m/s, world
    yaws = roll_pitch_yaw(np.array([b.quaternion for b in odom]))[:, 2]
    feet = (np.array(true_times),
            np.array([np.asarray(truth[t].foot_position)[:, :2] for t in true_times]))
    sensed_times = np.array([t for t, _ in sensed])
    corrections = stride_corrections(data.get(DIAGNOSTICS_TOPIC, []))
    plans = (_decoded(data.get(FOOTHOLDS_TOPIC, []), footholds_from_msg),
             _decoded(data.get(COM_PLAN_TOPIC, []), com_plan_from_msg))
    for segment in metrics.get('velocity_tracking') or []:
        lines += _segment_lines(segment, sensed_times, trunk, trunk_velocity, yaws, feet,
                                plans)
        if any(segment['commanded']):
            lines.append(judged(segment)[0])
        last = next((row for row in reversed(corrections) if row[0] < segment['end_s']), None)
        if any(segment['commanded']) and last is not None and last[0] > segment['start_s']:
            stamp, x, y = last
            lines.append(f'  stride correction at {stamp:.2f} s, the last before '
                         f'{segment["end_s"]:.2f} s: x {1000 * x:+.1f} mm, y {1000 * y:+.1f} mm')
    return lines


def _sensing_lines(delays: list[Sensing], after: float, late: float) -> list[str]:
    kept = [d for d in delays if d.t >= after]
    paired = [d for d in kept if d.delay is not None]
    late_ones = [d for d in paired if d.delay > late]
    prompt = [d for d in paired if d.delay <= late]
    lines = [f'touchdowns sensed after {after:g} s: {len(kept)}; {len(late_ones)} more than '
             f'{1000 * late:.0f} ms after the true contact'
             + (f' ({1000 * min(d.delay for d in late_ones):.0f}-'
                f'{1000 * max(d.delay for d in late_ones):.0f} ms)' if late_ones else '')
             + f', {len(prompt)} within {1000 * late:.0f} ms'
             + (f' (at most {1000 * max(d.delay for d in prompt):.0f} ms)' if prompt else '')
             + ', '
             f'{len(kept) - len(paired)} without a true contact since the foot\'s last one']
    per_leg = ', '.join(
        f'{name} {sum(1 for d in late_ones if d.leg == leg)} of '
        f'{sum(1 for d in kept if d.leg == leg)}' for leg, name in enumerate(LEGS))
    lines.append(f'late per leg: {per_leg}')
    return lines


def _segment_lines(segment: dict, sensed_times: np.ndarray, trunk, trunk_velocity: np.ndarray,
                   yaws: np.ndarray, feet, plans: tuple[list, list] = ([], [])) -> list[str]:
    command = np.asarray(segment['commanded'], dtype=float)
    speed = float(np.hypot(*command[:2]))
    cycles = segment.get('cycle_velocities') or []
    if speed == 0.0 or not cycles:
        return []
    # The reference starts at the first touchdown after the change: the re-plan that saw it
    # (from standing, the first step's).
    after = sensed_times[sensed_times >= segment['start_s']]
    if not len(after):
        return []
    t0 = float(after[0])
    yaw = float(_at(trunk[0], yaws, t0))
    c, s = math.cos(yaw), math.sin(yaw)
    direction = np.array([c * command[0] - s * command[1], s * command[0] + c * command[1]])
    direction /= speed
    boundaries = [cycles[0]['start_s']] + [row['end_s'] for row in cycles]
    lines = [f'set-point ({command[0]:+.3f}, {command[1]:+.3f}, {command[2]:+.3f}) from '
             f'{segment["start_s"]:.2f} s; reference from the touchdown at {t0:.2f} s; per '
             'whole cycle: trunk %, feet %, trunk minus feet (mm), trunk minus reference (mm)']
    for row in cycle_splits(boundaries, speed, direction,
                            (t0, _at(trunk[0], trunk[1], t0)), trunk, feet):
        lines.append(f'  {row.start:6.2f}-{row.end:6.2f} s  {row.trunk_percent:6.1f}  '
                     f'{row.feet_percent:6.1f}  {1000 * row.over_feet[0]:6.1f} -> '
                     f'{1000 * row.over_feet[1]:6.1f}  {1000 * row.over_reference[0]:6.1f} -> '
                     f'{1000 * row.over_reference[1]:6.1f}')
    lines += _replan_lines(t0, boundaries[1] - boundaries[0], speed, direction, trunk, plans)
    inside = (trunk[0] >= boundaries[0]) & (trunk[0] <= boundaries[-1])
    along = trunk_velocity[inside] @ direction                 # m/s
    if len(along):
        lines.append(f'  trunk speed along the set-point over these cycles: {along.min():.3f} '
                     f'to {along.max():.3f} m/s')
    return lines


def _replan_lines(t0: float, span: float, speed: float, direction: np.ndarray, trunk,
                  plans: tuple[list, list]) -> list[str]:
    """The re-plans from the one at ``t0`` (the change's) to one cycle (``span`` s) later:
    each leg's first stride and the CoM plan's travel against the truth's and the set-point's
    (``plans``: the foothold plans and CoM plans of the bag)."""
    footholds, com_plans = plans
    lines = []
    for plan in footholds:
        if not t0 - 1e-6 <= plan.start_time <= t0 + span:
            continue
        strides = ', '.join(f'{LEGS[leg]} {1000 * m:.0f}'
                            for leg, m in first_strides(plan, direction))
        text = f'    {plan.start_time:6.2f} s: {strides}'
        com = next((c for c in com_plans if abs(c.start_time - plan.start_time) < 1e-6), None)
        if com is not None:
            times = com.start_time + com.dt * np.arange(len(com.position))
            planned = travel_at(times, com.position[:, :2], plan.start_time, span, direction)
            true = travel_at(*trunk, plan.start_time, span, direction)
            text += ('; plan ' + ' / '.join(f'{1000 * m:.0f}' for m in planned)
                     + ', truth ' + ' / '.join(f'{1000 * m:.0f}' for m in true)
                     + ', set-point ' + ' / '.join(f'{1000 * speed * f * span:.0f}'
                                                   for f in (0.25, 0.5, 0.75, 1.0)))
        lines.append(text)
    if lines:
        lines.insert(0, '  re-plans in the first cycle: each leg\'s first stride along the '
                        'set-point (mm); the CoM plan\'s travel along it at 1/4, 1/2, 3/4 and '
                        '1 cycle, against the truth\'s and the set-point\'s (mm)')
    return lines


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog='gait_report.sh', description=__doc__.split('\n\n')[0])
    parser.add_argument('run', type=Path, help='a run folder: bag/ and metrics.json')
    parser.add_argument('--after', type=float, default=2.0,
                        help='s: touchdowns before this are left out (the stand-up); default 2')
    parser.add_argument('--late', type=float, default=0.04,
                        help='s after the true contact that makes a sensed touchdown late; '
                             'default 0.04')
    args = parser.parse_args(argv)
    if not (args.run / 'metrics.json').is_file() or not (args.run / 'bag').exists():
        parser.error(f'{args.run} is not a run folder (bag/ and metrics.json)')
    try:
        lines = report(args.run, args.after, args.late)
    except ValueError as err:
        print(f'gait_report: {err}', file=sys.stderr)
        return 1
    print('\n'.join(lines))
    return 0


if __name__ == '__main__':
    sys.exit(main())
