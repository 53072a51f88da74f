"""Soak benchmark: 10 minutes of sim time walking with changing set-points and pushes.

    scripts/soak.sh [--duration 600] [--out runs/soak] [--profile realistic]

Builds a scenario (a new set-point every ``--segment`` s of sim time from a fixed cycle of
forward, sideways, turning and standing; a lateral push of ``--push-force`` N for 0.2 s every
``--push-every`` s, alternating sides), runs it with the scenario runner (realistic profile by
default; recorded) and, while it runs, samples the resident memory (VmRSS) of every node
process every ``--sample-period`` wall s. Then it reports and writes ``OUT/soak.json``:

- fall: from the scenario's metrics (the simulator's truth);
- memory growth: the total RSS of the nodes at the end against the total after warm-up
  (``--warmup`` s of sim time; target under 5 %);
- solve time: the MPC's solve time (``/diagnostics`` of the bag) in the first and the last third
  after warm-up (medians);
- tick time: wall time per control tick (``control_period / real_time_factor`` of the sim's
  ``/diagnostics``), same thirds. The machine is shared: a growth of more than 20 % in either
  is reported as growth.

Exit code 0 when every target holds, 1 otherwise, 2 when the run could not be made. A benchmark,
not a test: run it under ``flock /tmp/graph.lock`` on a shared machine.
"""

from __future__ import annotations

import argparse
import json
import math
import re
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import yaml

from replan_ros.recording.bag_io import iter_decoded

CYCLE = ((0.15, 0.0, 0.0), (0.05, 0.0, 0.2), (0.0, 0.08, 0.0), (0.1, 0.0, -0.15),
         (0.0, 0.0, 0.0), (0.12, 0.0, 0.0), (0.0, -0.08, 0.0), (0.05, 0.0, -0.2))
MEMORY_TARGET_PCT = 5.0
TREND_LIMIT = 1.2          # last third / first third above this: growth
CONTROL_PERIOD = 0.004     # s, config/sim.yaml


def scenario(duration: float, segment: float, push_every: float, push_force: float) -> dict:
    """The soak's scenario: set-points cycling every ``segment`` s, pushes in between."""
    events = []
    t, k = 1.0, 0
    while t < duration:
        events.append({'t': round(t, 3), 'cmd_vel': list(CYCLE[k % len(CYCLE)])})
        t, k = t + segment, k + 1
    t, side = push_every, 1.0
    while t < duration - 5.0:
        events.append({'t': round(t, 3), 'push': {'force': [0.0, side * push_force, 0.0],
                                                  'duration': 0.2}})
        t, side = t + push_every, -side
    events.sort(key=lambda e: e['t'])
    return {'name': 'soak', 'duration': duration, 'events': events}


def _rss_mb(pid: int) -> float | None:
    try:
        for line in Path(f'/proc/{pid}/status').read_text().splitlines():
            if line.startswith('VmRSS:'):
                return int(line.split()[1]) / 1024.0
    except OSError:
        return None
    return None


class MemorySampler:
    """VmRSS of the node processes (pids from the launcher's 'started X (pid N)' lines)."""

    def __init__(self, period: float, log: Path) -> None:
        self.period = period
        self.log = log                  # one JSON line per sample: the analysis can be redone
        self.pids: dict[str, int] = {}
        self.samples: list[tuple[float, dict[str, float]]] = []   # (wall s, node -> MB)
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)

    def line(self, text: str) -> None:
        match = re.search(r'(?:started|respawned) (\w+) \(pid (\d+)\)', text)
        if match:
            self.pids[match.group(1)] = int(match.group(2))

    def start(self) -> None:
        self._thread.start()

    def stop(self) -> None:
        self._stop.set()
        self._thread.join()

    def _run(self) -> None:
        t0 = time.monotonic()
        while not self._stop.wait(self.period):
            sample = {name: mb for name, pid in list(self.pids.items())
                      if (mb := _rss_mb(pid)) is not None}
            if sample:
                self.samples.append((time.monotonic() - t0, sample))
                with open(self.log, 'a') as stream:
                    stream.write(json.dumps([self.samples[-1][0], sample]) + '\n')


def _thirds(times: np.ndarray, values: np.ndarray, start: float) -> tuple[float, float]:
    keep = times >= start
    times, values = times[keep], values[keep]
    if len(values) < 6:
        return math_nan(), math_nan()
    span = times[-1] - times[0]
    first = values[times <= times[0] + span / 3]
    last = values[times >= times[-1] - span / 3]
    return float(np.median(first)), float(np.median(last))


def math_nan() -> float:
    return float('nan')


def diagnostics_series(bag: Path) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """(sim t, value) of the mpc's solve_time_ms and the sim's real_time_factor."""
    if bag.is_dir():                    # the scenario runner's bag folder
        bag = sorted(bag.glob('*.mcap'))[-1]
    series = {'solve_time_ms': ([], []), 'real_time_factor': ([], [])}
    for _, _, _, msg in iter_decoded(bag, ['/diagnostics']):
        t = msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9
        for status in msg.status:
            values = {kv.key: kv.value for kv in status.values}
            if status.name == 'mpc' and 'solve_time_ms' in values:
                series['solve_time_ms'][0].append(t)
                series['solve_time_ms'][1].append(float(values['solve_time_ms']))
            if status.name == 'sim' and values.get('mode') == 'lock_step':
                rtf = float(values.get('real_time_factor', 0.0))
                if rtf > 0.0:
                    series['real_time_factor'][0].append(float(values['sim_time']))
                    series['real_time_factor'][1].append(rtf)
    return {k: (np.array(t), np.array(v)) for k, (t, v) in series.items()}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog='soak', description=__doc__.split('\n')[0])
    parser.add_argument('--duration', type=float, default=600.0, help='sim s (default 600)')
    parser.add_argument('--segment', type=float, default=20.0, help='sim s per set-point')
    parser.add_argument('--push-every', type=float, default=45.0, help='sim s between pushes')
    parser.add_argument('--push-force', type=float, default=80.0, help='N, lateral')
    parser.add_argument('--warmup', type=float, default=60.0, help='sim s left out of trends')
    parser.add_argument('--sample-period', type=float, default=2.0, help='wall s')
    parser.add_argument('--profile', default='realistic')
    parser.add_argument('--out', type=Path, default=Path('runs') / 'soak')
    parser.add_argument('--analyse', action='store_true',
                        help='do not run: analyse the finished run in OUT again')
    args = parser.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    scenario_file = args.out / 'soak_scenario.yaml'
    plan = scenario(args.duration, args.segment, args.push_every, args.push_force)
    run_dir = args.out / 'run'
    memory_log = args.out / 'memory.jsonl'
    sampler = MemorySampler(args.sample_period, memory_log)
    wall = math_nan()
    if args.analyse:
        plan = yaml.safe_load(scenario_file.read_text())
        if memory_log.exists():
            sampler.samples = [tuple(json.loads(line)) for line in
                               memory_log.read_text().splitlines() if line.strip()]
    else:
        scenario_file.write_text(yaml.safe_dump(plan, sort_keys=False))
        memory_log.unlink(missing_ok=True)
        cmd = [sys.executable, '-m', 'replan_experiments.scenario', str(scenario_file),
               '--out', str(run_dir), '--no-plots', '--quiet', '--profile', args.profile]
        sampler.start()
        wall0 = time.monotonic()
        with subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                              text=True) as proc:
            for line in proc.stdout:
                sampler.line(line)
                print(line.rstrip(), flush=True)
        sampler.stop()
        wall = time.monotonic() - wall0
    metrics_file = run_dir / 'metrics.json'
    if not metrics_file.exists():
        print(f'soak: no {metrics_file}: the scenario did not finish', file=sys.stderr)
        return 2
    if math.isnan(wall):
        wall = metrics.get('wall_time_s', math_nan()) if (metrics := json.loads(
            metrics_file.read_text())) else math_nan()
    metrics = json.loads(metrics_file.read_text())

    # Memory: the sampled wall times map to sim time through the run's real-time factor.
    rtf = metrics.get('real_time_factor') or 1.0
    totals = [(t * rtf, sum(s.values())) for t, s in sampler.samples if len(s) >= 4]
    after = [mb for t, mb in totals if t >= args.warmup]
    growth = (100.0 * (np.median(after[-5:]) - np.median(after[:5])) / np.median(after[:5])
              if len(after) >= 10 else math_nan())
    series = diagnostics_series(run_dir / 'bag')
    solve = _thirds(*series['solve_time_ms'], args.warmup)
    tick = tuple(CONTROL_PERIOD * 1e3 / v for v in _thirds(*series['real_time_factor'],
                                                               args.warmup))
    checks = {
        'no fall': metrics.get('completed') and not metrics.get('fell'),
        f'memory growth under {MEMORY_TARGET_PCT} %': (None if math.isnan(growth)
                                                        else bool(growth < MEMORY_TARGET_PCT)),
        'no growth of the solve time': bool(solve[1] <= TREND_LIMIT * solve[0]),
        'no growth of the tick time': bool(tick[1] <= TREND_LIMIT * tick[0]),
    }
    ok = all(v is not False for v in checks.values())
    summary = {
        'command': 'scripts/soak.sh ' + ' '.join(   # the run's command (not --analyse)
            a for a in (argv if argv is not None else sys.argv[1:]) if a != '--analyse'),
        'duration_s': metrics.get('sim_time_s', 0.0), 'wall_s': round(wall, 1),
        'profile': args.profile,
        'setpoints': sum('cmd_vel' in e for e in plan['events']),
        'pushes': sum('push' in e for e in plan['events']),
        'fell': bool(metrics.get('fell')), 'fall_reason': metrics.get('fall_reason'),
        'distance_m': metrics.get('distance_m'),
        'memory_total_mb_after_warmup': round(float(np.median(after[:5])), 1) if after else None,
        'memory_total_mb_end': round(float(np.median(after[-5:])), 1) if after else None,
        'memory_growth_pct': (round(float(growth), 2) if not math.isnan(growth)
                              else 'not measured (no memory samples)'),
        'peak_memory_mb': metrics.get('peak_memory_mb'),
        'solve_time_trend': f'{solve[0]:.2f} -> {solve[1]:.2f}',
        'tick_time_trend': f'{tick[0]:.3f} -> {tick[1]:.3f}',
        'checks': checks,
        'verdict': ('FAIL' if not ok else 'pass' if all(checks.values())
                    else 'pass on what was measured'),
    }
    (args.out / 'soak.json').write_text(json.dumps(summary, indent=1) + '\n')
    print(f'[soak] {summary["duration_s"]:.0f} s sim in {wall:.0f} s wall, '
          f'{summary["setpoints"]} set-points, {summary["pushes"]} pushes')
    for name, passed in checks.items():
        print(f'  {"n/a " if passed is None else "ok  " if passed else "FAIL"} {name}')
    print(f'  memory {summary["memory_total_mb_after_warmup"]} -> '
          f'{summary["memory_total_mb_end"]} MB ({summary["memory_growth_pct"]} %), '
          f'solve median {summary["solve_time_trend"]} ms, tick {summary["tick_time_trend"]} '
          f'ms -> {args.out / "soak.json"}')
    return 0 if ok else 1


if __name__ == '__main__':
    sys.exit(main())
