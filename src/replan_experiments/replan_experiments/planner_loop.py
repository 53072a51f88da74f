"""The planner alone in a closed loop: the gait's footholds (``crawl.compute_footholds``) and the
LIP MPC, re-planned at every planned touchdown from the state of the MPC's own plan there (the
trunk exactly on the plan: no dynamics, no controller, no sensing, no DDS). A 26 s walk takes
seconds, so a planner setting can be tried before the graph runs it.

    scripts/planner_loop.sh [--robot NAME|FILE] [--profile realistic|ideal]
                            [--at T VX VY WZ ...] [--duration S] [--late S]
                            [--base-offset DX DY] [--set node.key=VALUE ...] [--json]

Prints the mean velocity of each whole crawl cycle (four touchdowns) from the last set-point
change on, body frame of the cycle's mean heading (vx, vy m/s; wz rad/s), and where the trunk
stood over its feet: the centre of the four feet minus the CoM at the cycle's touchdowns (body
frame, m, their mean). The MPC has no position target, so nothing but the foothold correction
brings a trunk that fell beside its feet back over them. What it leaves out, on purpose:
the velocity feedback and step timing of the gait node (they act on measured velocity and
touchdowns), the trunk's lag behind its plan and the controller (the graph's ``scenario.sh``
has them). ``--late S`` makes every touchdown S seconds later than planned, as the haptic
touchdown does on the realistic robot; the strides are stretched for it as the gait node's
step timing would. ``--base-offset DX DY`` lays the footholds out about a base DX, DY m (body)
behind the CoM, as on a robot whose CoM is not over the centre of its feet, and measures that
base (velocities and the feet centre minus it). Used in docs/gait.md ("The way to a new speed
takes cycles", "Why the CoM offset").
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from dataclasses import replace
from itertools import pairwise
from pathlib import Path

import numpy as np

from replan_experiments.plan import parse_settings
from replan_ros.params.robot import project_root


def walk(robot: str, profile: str, schedule: list[tuple[float, np.ndarray]], duration: float,
         overrides: dict[str, dict] | None = None, late: float = 0.0,
         root: Path | None = None, base_offset=(0.0, 0.0),
         ) -> list[tuple[float, np.ndarray, float, np.ndarray]]:
    """(t, base xy (m, world), yaw (rad), centre of the four feet xy (m, world)) at the start
    and at every touchdown of a walk from the robot's standing feet. ``schedule``: (t, (vx, vy,
    wz)) set-points in force from t on; ``overrides``: node -> {key: value} on top of the
    run's parameters (gait, mpc). The base is where the footholds are laid out about: the CoM
    itself by default, or ``base_offset`` (m, body x, y) behind it, as a robot whose CoM is
    that far ahead of its base (the CoM still starts over the centre of the feet); the
    position term's ``mpc.com_offset`` is ``base_offset`` unless ``overrides`` set it."""
    from replan_core.gait.crawl import compute_footholds
    from replan_core.mpc.lip_mpc import LipMpc
    from replan_core.mpc.support import implied_velocity
    from replan_core.robot.model import RobotModel
    from replan_core.robot.robot_file import robot_facts
    from replan_ros.params.convert import gait_params, mpc_settings

    # The loop's CoM sits base_offset ahead of its base, so that is the offset the position
    # term knows of (mpc.com_offset), unless the caller sets another.
    loop = {'mpc': {'com_offset': [float(v) for v in base_offset]}}
    overrides = overrides or {}
    values, spec = run_values(robot, profile, {
        node: {**loop.get(node, {}), **overrides.get(node, {})} for node in ('gait', 'mpc')},
        root, known=overrides)
    model = RobotModel(str(spec.urdf), spec.joints, spec.feet)
    gait = replace(gait_params(values['gait']),
                   hip_offsets=tuple((float(x), float(y)) for x, y in model.hip_offsets[:, :2]))
    mpc = LipMpc(mpc_settings(values['mpc']))
    facts = robot_facts(spec)
    feet = np.column_stack([np.asarray(facts.feet_xy, dtype=float), np.zeros(4)])

    def setpoint(t: float) -> np.ndarray:
        now = [v for start, v in schedule if start <= t + 1e-9]
        return np.asarray(now[-1] if now else np.zeros(3), dtype=float)

    offset = np.asarray(base_offset, dtype=float).reshape(2)

    def base(com: np.ndarray, yaw: float) -> np.ndarray:
        c, s = np.cos(yaw), np.sin(yaw)
        return np.array([com[0] - c * offset[0] + s * offset[1],
                         com[1] - s * offset[0] - c * offset[1], com[2]])

    t, yaw = 0.0, 0.0
    com = np.array([0.0, 0.0, float(values['mpc']['com_height'])])
    vel, acc = np.zeros(3), np.zeros(3)
    scale = (gait.step_period + late) / gait.step_period
    plan = compute_footholds(setpoint(t), feet, base(com, yaw), yaw, None, gait.sequence[0], t,
                             gait, delay=float(values['gait']['start_delay']))
    log = [(t, base(com, yaw)[:2], yaw, feet[:, :2].mean(axis=0))]
    while t < duration:
        result = mpc.solve(t, com, vel, acc, plan, v_ref=implied_velocity(plan))
        first = plan.steps[0]
        t = first.touchdown_time + late
        com, vel, acc = result.plan.sample(t)
        feet = feet.copy()
        feet[first.leg] = first.target
        yaw = float(first.yaw)
        log.append((t, base(com, yaw)[:2], yaw, feet[:, :2].mean(axis=0)))
        following = gait.sequence[(gait.sequence.index(first.leg) + 1) % len(gait.sequence)]
        plan = compute_footholds(setpoint(t), feet, base(com, yaw), yaw, None, following, t,
                                 gait, stride_time_scale=scale)
    return log


def run_values(robot: str, profile: str, overrides: dict[str, dict] | None = None,
               root: Path | None = None, known: dict[str, dict] | None = None):
    """The gait and mpc parameters (node -> {key: value}) the launcher gives a run of
    ``robot`` on ``profile``, ``overrides`` on top, the sim's (never overridden: its
    ``control_period`` is the loops' tick), and the robot's spec. A key of ``known`` (default
    ``overrides``: the caller's settings) that the run does not have is refused."""
    from replan_ros.launch.param_files import check_run_files, profile_file, robot_parameters

    config = (root or project_root()) / 'config'
    profile_path = profile_file(config, profile)
    layer = robot_parameters(config, robot, profile_path)
    run = check_run_files(config, [profile_path, layer.derived, layer.overrides]).values
    checked = (overrides if known is None else known) or {}
    unknown = {f'{node}.{key}' for node, keys in checked.items()
               for key in keys if node not in ('gait', 'mpc') or key not in run[node]}
    if unknown:
        raise ValueError(f'unknown parameters {sorted(unknown)} (gait.* and mpc.* only)')
    values = {node: {**run[node], **(overrides or {}).get(node, {})} for node in ('gait', 'mpc')}
    values['sim'] = dict(run['sim'])
    return values, layer.spec


def _to_body(vector: np.ndarray, yaw: float) -> tuple[float, float]:
    """A world xy ``vector`` in the body frame of heading ``yaw`` (rad)."""
    c, s = np.cos(yaw), np.sin(yaw)
    return float(c * vector[0] + s * vector[1]), float(-s * vector[0] + c * vector[1])


def _whole_cycles(log: list[tuple[float, np.ndarray, float, np.ndarray]], start: float,
                  legs: int):
    """The entries of each whole cycle (``legs`` touchdowns) from the first touchdown at or
    after ``start``: ``legs + 1`` entries each, the first the last of the cycle before."""
    times = np.array([entry[0] for entry in log])
    i = int(np.searchsorted(times, start - 1e-9))
    while i + legs < len(log):
        yield log[i:i + legs + 1]
        i += legs


def cycle_velocities(log: list[tuple[float, np.ndarray, float, np.ndarray]], start: float,
                     legs: int = 4) -> list[list[float]]:
    """The mean (vx, vy, wz) of each whole cycle (``legs`` touchdowns) from the first touchdown
    at or after ``start``: the body-frame velocity integrated over the cycle, each step between
    two touchdowns taken as an arc of constant twist (exact for one; a single chord over a
    0.55 rad cycle read the speed 1.3 % low)."""
    out = []
    for cycle in _whole_cycles(log, start, legs):
        travel = np.zeros(2)
        for (_, p0, y0, _), (_, p1, y1, _) in pairwise(cycle):
            # A constant-twist arc's chord lies along its mid heading and is its length
            # times sin(h) / h, h half the turn.
            half = 0.5 * math.remainder(y1 - y0, math.tau)    # yaws wrap at +-pi
            arc = half / np.sin(half) if abs(half) > 1e-9 else 1.0
            travel += arc * np.array(_to_body(p1 - p0, y0 + half))
        (t0, _, y0, _), (t1, _, y1, _) = cycle[0], cycle[-1]
        vx, vy = travel / (t1 - t0)
        out.append([float(vx), float(vy), float((y1 - y0) / (t1 - t0))])
    return out


def trunk_offsets(log: list[tuple[float, np.ndarray, float, np.ndarray]], start: float,
                  legs: int = 4) -> list[list[float]]:
    """Where the trunk stood over its feet in each whole cycle, as ``cycle_velocities`` cuts
    them: the mean over the cycle's ``legs`` touchdowns of the centre of the four feet minus
    the CoM (the base, with a ``walk`` base offset), in the body frame of each touchdown
    (x, y m)."""
    return [[float(v) for v in np.mean([_to_body(centre - com, yaw)
                                        for _, com, yaw, centre in cycle[1:]], axis=0)]
            for cycle in _whole_cycles(log, start, legs)]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog='scripts/planner_loop.sh',
        description='The planner alone in a closed loop (footholds and MPC, the trunk on the '
                    'plan): the mean velocity of each crawl cycle after the last set-point '
                    'change.')
    parser.add_argument('--robot', default='hyq', help='robot name or file (default hyq)')
    parser.add_argument('--profile', default='realistic', help='parameter profile')
    parser.add_argument('--at', nargs=4, type=float, action='append', default=[],
                        metavar=('T', 'VX', 'VY', 'WZ'),
                        help='set-point (m/s, m/s, rad/s) from T s on; repeatable '
                             '(default: 0.15 0 0 from 0.5 s)')
    parser.add_argument('--duration', type=float, default=26.0, help='s of walk (default 26)')
    parser.add_argument('--late', type=float, default=0.0,
                        help='s each touchdown comes after its plan (default 0)')
    parser.add_argument('--base-offset', nargs=2, type=float, default=[0.0, 0.0],
                        metavar=('DX', 'DY'),
                        help='m, body frame: lay the footholds out about a base this far behind '
                             'the CoM and measure the base (default 0 0: the CoM itself)')
    parser.add_argument('--set', action='append', default=[], metavar='NODE.KEY=VALUE',
                        help='a gait or mpc parameter for this walk; repeatable')
    parser.add_argument('--json', action='store_true', help='one JSON line instead of text')
    args = parser.parse_args(argv)
    if not args.duration > 0 or not args.late >= 0:
        parser.error(f'--duration must be > 0 and --late >= 0 (s), got {args.duration} and '
                     f'{args.late}')
    schedule = sorted((a[0], np.array(a[1:])) for a in args.at) or [
        (0.5, np.array([0.15, 0.0, 0.0]))]
    try:
        log = walk(args.robot, args.profile, schedule, args.duration, parse_settings(args.set),
                   args.late, base_offset=args.base_offset)
    except (ValueError, KeyError, OSError) as err:
        print(f'config error: planner_loop: {err}', file=sys.stderr)
        return 2
    cycles = cycle_velocities(log, schedule[-1][0])
    offsets = trunk_offsets(log, schedule[-1][0])
    if args.json:
        print(json.dumps({'setpoint': schedule[-1][1].tolist(), 'from_s': schedule[-1][0],
                          'cycle_velocities': cycles, 'feet_centre_minus_com_m': offsets}))
        return 0
    target = ', '.join(f'{v:g}' for v in schedule[-1][1])
    print(f'set-point ({target}) from {schedule[-1][0]:g} s; per crawl cycle the mean velocity '
          '(vx m/s, vy m/s, wz rad/s) and the centre of the feet minus the CoM (x, y m, body):')
    for k, (v, d) in enumerate(zip(cycles, offsets, strict=True), 1):
        print(f'  cycle {k}: ({v[0]:+.4f}, {v[1]:+.4f}, {v[2]:+.4f})  '
              f'feet centre - CoM ({d[0]:+.3f}, {d[1]:+.3f})')
    return 0


if __name__ == '__main__':
    sys.exit(main())
