"""The robots page's response runs through the gait's and the MPC's cores alone: each robot's
walk-off forward and its change to sideways, at every phase of the changes, judged as
docs/robots.md judges them, in seconds instead of minutes.

    scripts/response_loop.sh [--set NODE.KEY=VALUE ...] [--robot NAME ...] [--phase K ...]
                             [--late S] [--steps]

The loop runs the gait node's own re-planner (``gait.replanner.GaitReplanner``: touchdown rule,
speed feedback, step timing, foothold correction, idle stance) and the MPC
(``mpc.lip_mpc.LipMpc``, started as the node starts it) at the sim's control period
(``sim.control_period``). The trunk is exactly on the CoM plan, the base ``mpc.com_offset``
behind the CoM; each foot lands on its target ``--late`` s after its planned touchdown (the
realistic haptic touchdown's 40 ms by default). Left out: the simulator's dynamics, the
controller's tracking, the estimator, contact sensing and noise, DDS. The trunk's yaw is the
yaw reference of the last step down, so a turning cycle reads the planned over the walked step
period: the turning set-point is left out. The cycles are each leg's, from its touchdowns
(``evaluation.metrics``), judged by the page's rule (``robots_page.response_axis``);
docs/gait.md, "Response to a set-point change", says how close they come to the graph's.
Neither the runs nor the pages import this module.
"""

from __future__ import annotations

import argparse
import math
import os
import sys
from pathlib import Path
from typing import NamedTuple

import numpy as np

from replan_core.common.types import LEGS, BaseState, ContactState
from replan_core.evaluation.metrics import command_segments, tracking_errors
from replan_core.gait.crawl import is_stand_plan
from replan_core.gait.replanner import GaitReplanner
from replan_core.mpc.lip_mpc import LipMpc, replan_start_state
from replan_core.mpc.support import implied_velocity
from replan_core.robot.model import RobotModel
from replan_core.robot.robot_file import robot_facts
from replan_experiments.gait_report import judged
from replan_experiments.plan import ExperimentError, parse_settings
from replan_experiments.planner_loop import run_values
from replan_experiments.robot_info import robot_info
from replan_experiments.robots_plan import load_robots_plan, response_doc
from replan_experiments.runs import read_scenario
from replan_ros.params.convert import gait_params, mpc_settings

LATE = 0.04             # s, a realistic touchdown after its planned time (docs/gait.md)


class LoopRun(NamedTuple):
    """A ``loop_run``: the touchdowns ((t s, leg), one per executed step), per tick the times
    (s), base positions (m, world xy) and yaws (rad), and the robot's standing feet (m, base
    frame xy, (4, 2))."""

    touchdowns: list[tuple[float, int]]
    times: np.ndarray
    bases: np.ndarray
    yaws: np.ndarray
    feet_xy: np.ndarray


def loop_run(robot: str, profile: str, events: list[tuple[float, np.ndarray]],
             duration: float, overrides: dict[str, dict] | None = None, late: float = LATE,
             root: Path | None = None) -> LoopRun:
    """One run of the gait's and the MPC's cores (module docstring) from the robot's standing
    feet: ``events`` (t s, (vx, vy, wz)) are the set-points from t on."""
    values, spec = run_values(robot, profile, overrides, root)
    model = RobotModel(str(spec.urdf), spec.joints, spec.feet)
    params = gait_params(values['gait'])
    params.hip_offsets = tuple((float(x), float(y)) for x, y in model.hip_offsets[:, :2])
    gait = values['gait']
    replanner = GaitReplanner(params, float(gait['min_swing_fraction']),
                              float(gait['max_extension']), float(gait['start_delay']),
                              plan_latency=float(gait['plan_latency']))
    mpc = LipMpc(mpc_settings(values['mpc']))
    com_offset = np.asarray(values['mpc']['com_offset'], dtype=float)     # m, body
    height = float(values['mpc']['com_height'])
    hips = np.asarray(model.hip_offsets, dtype=float)                     # (4, 3) m, body
    standing = np.asarray(robot_facts(spec).feet_xy, dtype=float)         # (4, 2) m, base
    feet = np.column_stack([standing, np.zeros(4)])
    events = sorted(events, key=lambda e: e[0])
    tick = float(values['sim']['control_period'])                         # s

    def setpoint(t: float) -> np.ndarray:
        now = [v for start, v in events if start <= t + 1e-9]
        return np.asarray(now[-1] if now else np.zeros(3), dtype=float)

    com, vel = np.array([com_offset[0], com_offset[1], height]), np.zeros(3)
    yaw, contact = 0.0, np.ones(4, dtype=bool)
    steps, com_plan, stood = None, None, False
    touchdowns, times, bases, yaws = [], [], [], []
    for n in range(round(duration / tick) + 1):
        t = round(n * tick, 9)
        if com_plan is not None and com_plan.start_time <= t:
            com, vel, _ = com_plan.sample(t)
        rotation = np.array([[math.cos(yaw), -math.sin(yaw)], [math.sin(yaw), math.cos(yaw)]])
        base_xy = com[:2] - rotation @ com_offset
        times.append(t)
        bases.append(base_xy)
        yaws.append(yaw)
        # Each leg of the plan in force is in the air from its lift-off to `late` after its
        # planned touchdown, and lands on its target.
        down = np.ones(4, dtype=bool)
        for step in steps or []:
            if step.liftoff_time <= t < step.touchdown_time + late:
                down[step.leg] = False
        landed = down & ~contact
        for step in steps or []:
            if landed[step.leg] and step.liftoff_time <= t:
                feet[step.leg] = step.target
                yaw = float(step.yaw)
                touchdowns.append((t, step.leg))
                landed[step.leg] = False
        state = ContactState(t, feet.copy(), np.zeros((4, 3)), down, down & ~contact,
                             contact & ~down)
        contact = down
        replanner.tick(state)
        if replanner.pending is None:
            continue
        quaternion = np.array([0.0, 0.0, math.sin(yaw / 2), math.cos(yaw / 2)])
        base = BaseState(t, np.array([base_xy[0], base_xy[1], height]), quaternion,
                         vel.copy(), np.zeros(3))
        turn = np.eye(3)
        turn[:2, :2] = rotation
        plan = replanner.plan_pending(base, base.position + hips @ turn.T, setpoint(t), 'loop')
        if plan is None:
            continue
        replanner.adopt(plan)
        steps = plan.steps
        start = replan_start_state(t, com, vel, plan, com_plan, stood)
        result = mpc.solve(t, *start, plan, v_ref=implied_velocity(plan))
        if result.plan is not None:
            com_plan = result.plan
        stood = is_stand_plan(plan)
    return LoopRun(touchdowns, np.array(times), np.array(bases), np.array(yaws), standing)


def _first_after(touchdowns: list[tuple[float, int]], start: float) -> int:
    """The index of the first touchdown after ``start`` (s)."""
    return next(i for i, (t, _) in enumerate(touchdowns) if t > start)


def _step_travels(touchdowns: list[tuple[float, int]], times: np.ndarray, bases: np.ndarray,
                  direction) -> np.ndarray:
    """The trunk's travel (m) along ``direction`` over each step, from one touchdown to the
    next (one fewer than the touchdowns)."""
    unit = np.asarray(direction, dtype=float)[:2]
    unit = unit / np.linalg.norm(unit)
    ticks = np.searchsorted(times, [t for t, _ in touchdowns])
    return np.diff(bases[ticks] @ unit)


def step_excess(touchdowns: list[tuple[float, int]], times: np.ndarray, bases: np.ndarray,
                start: float, direction, steps: int = 4, legs: int = 4,
                later: int = 3) -> list[tuple[float, float]]:
    """Per step of the first ``steps`` after ``start`` (s; a step from one touchdown to the
    next): its start (s after ``start``) and the trunk's travel along ``direction`` over it
    less that over the step ``later`` crawl cycles (``legs`` steps each) on, at the same
    phase of the steady walk (m). Their sum is the lag (-) or lead (+) built after a change."""
    travel = _step_travels(touchdowns, times, bases, direction)
    first = _first_after(touchdowns, start)
    return [(touchdowns[i][0] - start, float(travel[i] - travel[i + later * legs]))
            for i in range(first, first + steps) if i + later * legs < len(travel)]


def steady_cycle_travel(touchdowns: list[tuple[float, int]], times: np.ndarray,
                        bases: np.ndarray, start: float, direction, legs: int = 4,
                        later: int = 3) -> float | None:
    """The trunk's travel (m) along ``direction`` over the whole cycle (``legs`` steps) that
    begins ``later`` cycles after the first touchdown after ``start`` (s): the steady cycle
    ``step_excess`` compares with. None if the run ends before it."""
    travel = _step_travels(touchdowns, times, bases, direction)
    first = _first_after(touchdowns, start) + later * legs
    return float(np.sum(travel[first:first + legs])) if first + legs <= len(travel) else None


def first_swing(touchdowns: list[tuple[float, int]], start: float, feet_xy,
                direction) -> tuple[str, str]:
    """The leg that swings in the first step of ``step_excess`` after ``start`` (s; from the
    first touchdown after it to the second: the leg of the second), and its side of the trunk
    along the set-point ``direction`` (body frame): 'leading' if its standing foot
    (``feet_xy``, (4, 2) m, base frame) lies ahead of the base along it, else 'trailing'."""
    leg = touchdowns[_first_after(touchdowns, start) + 1][1]
    ahead = float(np.dot(np.asarray(feet_xy, dtype=float)[leg], np.asarray(direction)[:2]))
    return LEGS[leg], 'leading' if ahead > 0.0 else 'trailing'


def speed_along(times: np.ndarray, bases: np.ndarray, t: float, direction) -> float:
    """The trunk's velocity (m/s) along ``direction`` at ``t`` (s), from the positions of the
    ticks either side."""
    unit = np.asarray(direction, dtype=float)[:2]
    unit = unit / np.linalg.norm(unit)
    i = int(np.clip(np.searchsorted(times, t), 1, len(times) - 2))
    return float((bases[i + 1] - bases[i - 1]) @ unit / (times[i + 1] - times[i - 1]))


def response_lines(robot: str, profile: str, doc: dict, overrides: dict[str, dict] | None,
                   late: float = LATE, root: Path | None = None,
                   steps: bool = False) -> tuple[list[str], list[tuple[str, list[str]]]]:
    """The judged line (``gait_report.judged``) of each translational set-point of the
    robots page's response document ``doc`` run through ``loop_run``; with ``steps``, also
    the ``step_excess`` of the first steps after each change of set-point (mm, and in % of
    the ``steady_cycle_travel``) and the ``first_swing`` after it. Also each set-point's axis
    and what it misses (``robots_render.response_misses``), for ``tally``."""
    events = [(float(e['t']), np.asarray(e['cmd_vel'], dtype=float)) for e in doc['events']]
    touchdowns, times, bases, yaws, feet_xy = loop_run(robot, profile, events,
                                                       float(doc['duration']), overrides, late,
                                                       root)
    segments = command_segments([(t, tuple(v)) for t, v in events], end_time=times[-1])
    rows = tracking_errors(times, bases, yaws, segments, settle=2.0, touchdowns=touchdowns)
    lines, verdicts = [], []
    for row in rows:
        if not any(row['commanded'][:2]):
            continue
        line, axis, misses = judged(row)
        lines.append(line)
        verdicts.append((axis, misses))
        if steps:
            excess = step_excess(touchdowns, times, bases, row['start_s'],
                                 row['commanded'][:2])
            lines.append('    travel of each step after the change less the steady step\'s '
                         'at its phase (mm): ' + ', '.join(f'{1000 * dx:+.0f} from {t:.2f} s'
                                                           for t, dx in excess))
            cycle = steady_cycle_travel(touchdowns, times, bases, row['start_s'],
                                        row['commanded'][:2])
            if excess and cycle:
                leg, side = first_swing(touchdowns, row['start_s'], feet_xy,
                                        row['commanded'][:2])
                lines.append(f'    the same in % of a steady cycle\'s travel ({1000 * cycle:.0f} '
                             'mm): ' + ' '.join(f'{100 * dx / cycle:+.0f}' for _, dx in excess)
                             + f'; the first step\'s swing: {leg}, on the {side} side')
            if excess:
                at = row['start_s'] + excess[0][0]
                speed = speed_along(times, bases, at, row['commanded'][:2])
                lines.append(f'    the trunk at the first touchdown after the change '
                             f'({at:.2f} s): {speed:+.3f} m/s along the set-point of '
                             f'{float(np.linalg.norm(row["commanded"][:2])):.3f} m/s')
    return lines, verdicts


def tally(verdicts: list[tuple[str, list[str]]]) -> str:
    """One line: per axis, how many cells (an axis of one run) meet the page's rule (no miss
    of ``robots_render.response_misses``), and how many meet it with the first cycle's
    shortfall allowed (no 'later' and no 'overshoot' miss: every cycle from the second
    within 5 %, none more than 5 % above the set-point)."""
    axes = list(dict.fromkeys(axis for axis, _ in verdicts))

    def count(axis: str, allowed: set[str]) -> str:
        cells = [misses for a, misses in verdicts if a == axis]
        return f'{axis} {sum(not set(m) - allowed for m in cells)} of {len(cells)}'
    return ('cells met by the page\'s rule: ' + ', '.join(count(a, set()) for a in axes)
            + '; with the first cycle\'s shortfall allowed (from the second cycle within 5 %, '
            'none over 105 %): ' + ', '.join(count(a, {'first'}) for a in axes))


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog='response_loop.sh', description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('--set', action='append', default=[], metavar='NODE.KEY=VALUE',
                        help='a gait or mpc parameter (repeatable)')
    parser.add_argument('--robot', action='append', default=[], metavar='NAME',
                        help='a robot of the plan (repeatable; default all)')
    parser.add_argument('--phase', action='append', type=int, default=[], metavar='K',
                        help="the phase of the changes (repeatable; default every phase of "
                             "the plan's response)")
    parser.add_argument('--steps', action='store_true',
                        help='also each of the first steps after a change against the steady '
                             "step at its phase: the lag or lead it builds (mm, and in %% of a "
                             "steady cycle's travel), and which leg swings first after it")
    parser.add_argument('--late', type=float, default=LATE,
                        help=f's each foot lands after its planned touchdown (default {LATE})')
    args = parser.parse_args(argv)
    if not 0.0 <= args.late < 1.0:
        parser.error(f'--late must be 0 to 1 s, got {args.late}')
    root = Path(os.environ.get('REPLAN_ROOT', '.')).resolve()
    config_dir = Path(os.environ.get('REPLAN_CONFIG', root / 'config'))
    try:
        overrides = parse_settings(args.set)
        plan = load_robots_plan(config_dir / 'robots_page.yaml', False, args.robot)
        phases = args.phase or list(range(plan.tests['response']['phases']))
        base = read_scenario(config_dir, plan.tests['response']['scenario'])
        verdicts = []
        for name in plan.robots:
            info = robot_info(config_dir, name, plan.profile)
            for phase in phases:
                doc = response_doc(base, info, plan, plan.seed, phase)
                print(f'{name}, phase {phase}:', flush=True)
                lines, judged = response_lines(name, plan.profile, doc, overrides, args.late,
                                               root, args.steps)
                verdicts += judged
                print('\n'.join(lines), flush=True)
        print(tally(verdicts))
    except (ExperimentError, ValueError, KeyError, OSError) as err:
        print(f'response_loop: {err}', file=sys.stderr)
        return 2
    return 0


if __name__ == '__main__':
    sys.exit(main())
