"""Per-tick budget of the lock-step loop: run the graph headless, print where a tick goes.

Runs ``scripts/launch.sh`` (the four nodes, the recorder too with ``--record``) or a scenario
(``--scenario FILE``, e.g. config/scenarios/forward.yaml: it walks and records) for
``--duration`` sim seconds, reads the per-phase figures that the sim and wbc nodes log at
shutdown (tick_budget.py, "tick budget: {...}" lines, the last ``capacity`` ticks of the run)
and prints one table: phase, median and mean ms per tick, share of the tick (from the means,
which add up), and the run's real-time factor. docs/ARCHITECTURE.md, "Per-tick budget".

The tick is the sim's: from one command's callback to the next. Its own phases run in
sequence; its wait for the command (the round trip) is broken down into the controller's
phases and the DDS transport and executor wake-up of both processes (from the DDS message
info: writer's source timestamp, reader's reception timestamp, the callback's start on
CLOCK_REALTIME). "not accounted" is the wait left over; it is negative when the controller
starts work while the sim is still inside its ``joint_states`` publish (two processes, two
cores).
"""

from __future__ import annotations

import argparse
import json
import re
import subprocess
import sys
import tempfile
from pathlib import Path

from replan_ros.telemetry.tick_budget import parse_log_line

ROOT = Path(__file__).resolve().parents[4]

SIM_OWN = (
    ('sim_decode', 'sim: command decode'),
    ('sim_physics', 'sim: physics steps after the lead ones'),
    ('sim_sensing', 'sim: sensing (IMU, encoders)'),
    ('sim_conversion', 'sim: imu, joint_states messages'),
    ('sim_publish_imu', 'sim: publish imu'),
    ('sim_publish_joint_states', 'sim: publish joint_states'),
    ('sim_truth_first', 'sim: truth sensed, built, published first'),
)
# Work off the chain (not added to the tick): the sim's after joint_states are out, while the
# controller computes; the controller's after its command is out, while the sim steps.
OVERLAPPED_HEADING = 'meanwhile, off the chain (not added):'
OVERLAPPED_PREFIX = '  + '
OVERLAPPED = (
    ('sim_truth_sensing', 'sim: truth (base state, contact forces)'),
    ('sim_truth_conversion', 'sim: truth -> 2 messages'),
    ('sim_publish_truth_odom', 'sim: publish ground_truth/odom'),
    ('sim_publish_truth_contacts', 'sim: publish ground_truth/contacts'),
    ('sim_publish_clock', 'sim: publish /clock (1 tick in 5)'),
    ('sim_lead_physics', 'sim: wrenches + lead physics steps (actuator delay)'),
    ('wbc_publish_state', 'wbc: publish odom, contacts, events (after the command)'),
    ('wbc_estimator_next', "wbc: estimator's next covariance step (after the command)"),
)
ROUND_TRIP = (
    ('wbc_transport_in', 'joint_states DDS transport sim -> wbc'),
    ('wbc_wake', 'wbc: executor wake-up, take, deserialize'),
    ('wbc_decode', 'wbc: joint_states decode'),
    ('wbc_take', 'wbc: take queued imu / ground truth'),
    ('wbc_estimator', 'wbc: state estimator'),
    ('wbc_state_msgs', 'wbc: estimate -> odom/contacts messages'),
    ('wbc_logic', 'wbc: plan following logic'),
    ('wbc_plan_wait', 'wbc: held for plans (re-plan ticks)'),
    ('wbc_controller', 'wbc: controller maths (pinocchio+QP)'),
    ('wbc_command', 'wbc: torque msg + publish'),
    ('sim_transport_cmd', 'joint_torque_cmd DDS transport wbc -> sim'),
    ('sim_wake', 'sim: executor wake-up, take, deserialize'),
)


def read_budgets(log_dir: Path) -> dict[str, dict]:
    """node -> its logged tick budget, from the node logs in ``log_dir``."""
    budgets = {}
    for log in sorted(log_dir.glob('*.log')):
        for line in log.read_text(errors='replace').splitlines():
            found = parse_log_line(line)
            if found is not None:
                budgets[found['node']] = found
    return budgets


def table(sim: dict, wbc: dict) -> tuple[list[tuple[str, float, float, float]], dict]:
    """Rows (label, median ms, mean ms, share of the tick) and the totals."""
    phases = {**sim['phases'], **wbc['phases']}
    tick = phases['sim_tick']['mean_ms']
    rows = []

    def row(label: str, key: str | None = None, median: float = float('nan'),
            mean: float = 0.0) -> float:
        if key is not None:
            median, mean = phases[key]['median_ms'], phases[key]['mean_ms']
        rows.append((label, median, mean, mean / tick if tick > 0 else float('nan')))
        return mean

    own = sum(row(label, key) for key, label in SIM_OWN if key in phases)
    wait = phases['sim_wait']['mean_ms']
    row('sim: rest of its callback and timers', mean=tick - own - wait)
    rows.append(('sim: wait for the command (round trip) =', phases['sim_wait']['median_ms'],
                 wait, wait / tick))
    explained = sum(row('  ' + label, key) for key, label in ROUND_TRIP)
    row('  not accounted (< 0: overlap with the publish)', mean=wait - explained)
    rows.append((OVERLAPPED_HEADING, float('nan'), float('nan'), float('nan')))
    overlapped = sum(row(OVERLAPPED_PREFIX + label, key) for key, label in OVERLAPPED
                     if key in phases)
    totals = {'tick_ms_mean': tick, 'tick_ms_median': phases['sim_tick']['median_ms'],
              'sim_own_ms': own, 'round_trip_ms': wait, 'overlapped_ms': overlapped,
              'wbc_work_ms': sum(phases[k]['mean_ms'] for k, _ in ROUND_TRIP
                                 if k.startswith('wbc_') and k not in ('wbc_transport_in',
                                                                      'wbc_wake')),
              'ticks': sim['ticks']}
    return rows, totals


def print_table(rows, totals, rtf: float | None, out=sys.stdout) -> None:
    print(f'{"phase":<52} {"median ms":>9} {"mean ms":>8} {"share":>7}', file=out)
    for label, median, mean, share in rows:
        med = '' if median != median else f'{median:9.3f}'
        if mean != mean:                        # a heading
            print(label, file=out)
            continue
        print(f'{label:<52} {med:>9} {mean:8.3f} {share * 100:6.1f}%', file=out)
    print(f'{"tick (sim: command to command)":<52} {totals["tick_ms_median"]:9.3f} '
          f'{totals["tick_ms_mean"]:8.3f} {100.0:6.1f}%', file=out)
    rtf_text = f'{rtf:.2f}' if rtf is not None else '?'
    from_tick = 4.0 / totals['tick_ms_mean']
    print(f'real-time factor {rtf_text} (4 ms of sim time per tick: {from_tick:.2f} from the '
          f'mean tick); {totals["ticks"]} ticks', file=out)


def _rtf_from_launch_log(text: str) -> float | None:
    found = re.findall(r'real-time factor ([0-9.]+) \(from the first tick\)', text)
    return float(found[-1]) if found else None


def _cpu_line_from_launch_log(text: str) -> str | None:
    found = re.findall(r'(CPU time per sim s since the first tick: .*)', text)
    return found[-1] if found else None


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog='tick_budget.sh', description=__doc__.split('\n\n')[0],
        formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('--profile', default='realistic', help='realistic (default) | ideal')
    parser.add_argument('--record', action='store_true', help='recorder on (launch.sh --record)')
    parser.add_argument('--duration', type=float, default=20.0, help='sim s (default 20)')
    parser.add_argument('--scenario', type=Path,
                        help='run this scenario instead (scenario.sh; it records)')
    parser.add_argument('--out', type=Path, help='run folder (default: a temporary one)')
    parser.add_argument('--params', type=Path, nargs='+', default=[],
                        help='extra parameter files (launch.sh / scenario.sh --params)')
    parser.add_argument('--json', action='store_true', help='also one JSON line of the totals')
    args = parser.parse_args(argv)
    out = args.out or Path(tempfile.mkdtemp(prefix='tick_budget_'))
    out.mkdir(parents=True, exist_ok=True)
    extra = ['--params', *map(str, args.params)] if args.params else []
    if args.scenario is not None:
        cmd = [str(ROOT / 'scripts' / 'scenario.sh'), str(args.scenario), '--profile',
               args.profile, '--out', str(out / 'scenario')]
        log_dir = out / 'scenario' / 'logs'
    else:
        cmd = [str(ROOT / 'scripts' / 'launch.sh'), '--profile', args.profile, '--duration',
               str(args.duration), '--run-dir', str(out / 'run'), '--quiet']
        if args.record:
            cmd += ['--record', str(out / 'bag')]
        log_dir = out / 'run' / 'logs'
    cmd += extra
    with open(out / 'launch.log', 'w') as log:
        status = subprocess.run(cmd, stdout=log, stderr=subprocess.STDOUT).returncode
    if status != 0:
        print(f'tick_budget: {cmd[0]} exited with {status} (see {out})', file=sys.stderr)
        return 1
    launch_log = (out / 'launch.log').read_text()
    if args.scenario is not None:
        metrics = json.loads((out / 'scenario' / 'metrics.json').read_text())
        rtf = metrics.get('real_time_factor')
    else:
        rtf = _rtf_from_launch_log(launch_log)
    budgets = read_budgets(log_dir)
    if not {'sim', 'wbc'} <= set(budgets):
        print(f'tick_budget: no tick budget line from sim and wbc in {log_dir}', file=sys.stderr)
        return 1
    rows, totals = table(budgets['sim'], budgets['wbc'])
    what = args.scenario.name if args.scenario else f'launch {args.duration:g} s'
    print(f'tick budget: {what}, profile {args.profile}, recorder '
          f'{"on" if args.record or args.scenario else "off"} ({out})')
    print_table(rows, totals, rtf)
    cpu = _cpu_line_from_launch_log(launch_log)
    if cpu is not None:
        print(cpu)
    if args.json:
        print(json.dumps({'real_time_factor': rtf, **{k: round(v, 4) for k, v in totals.items()},
                          'phases_mean_ms': {label: round(mean, 4)
                                             for label, _, mean, _ in rows}}))
    return 0


if __name__ == '__main__':
    sys.exit(main())
