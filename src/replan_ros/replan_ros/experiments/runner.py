"""The paper's experiments on the realistic robot, many runs per claim, and the results page.

    scripts/experiments.sh [--quick] [--jobs N] [--only NAME ...] [--out DIR] [--page FILE]

Runs the experiments of ``config/experiments.yaml`` (``full``, or ``quick`` with --quick) as
scenario runs (``replan_ros.experiments.scenario``, one process graph each, on its own
ROS_DOMAIN_ID), then writes the results page (``docs/results.md`` for a full run, DIR/results.md
for a quick one, plots beside it) from the runs' ``metrics.json``: per claim the metric's mean,
spread and number of runs, the paper's claim and whether the runs support it.

A run's folder is named after a hash of its scenario document, so a run already made with the
same document (an interrupted call, or two experiments sharing a run) is read, not made again
(``--fresh`` makes every run again). Lock-step makes a run the same however many run at once.
"""

from __future__ import annotations

import argparse
import contextlib
import fcntl
import hashlib
import json
import math
import os
import platform
import shutil
import subprocess
import sys
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import yaml

from replan_ros.experiments.page import write_page

DEFAULT_DOMAIN_BASE = 150      # the node tests reserve 2..101 (test/harness.py)
# The keys each experiment reads: a misspelt one in the plan file is an error, not a default.
PLAN_KEYS = {
    'velocity_changes': {'scenarios', 'seeds', 'prompt_steps', 'duration'},
    'lateral_push': {'scenario', 'phases', 'first_push', 'after_push', 'push_duration',
                     'direction', 'first_impulse', 'max_impulse', 'probes', 'seed', 'settings',
                     'duration'},
    'replan_window': {'scenario', 'windows', 'seeds', 'setpoints', 'duration'},
    'haptic': {'scenario', 'seeds', 'duration', 'durations', 'terrains'},
    'velocity_term': {'scenario', 'seeds', 'setpoints', 'duration'},
    'qp_timing': {'replans', 'formulations'},
    'fastest_crawl': {'scenario', 'setpoints', 'velocity_clamp', 'seed'},
    'ideal_world': {'replan_window', 'haptic', 'velocity_changes'},
}
EXPERIMENTS = tuple(PLAN_KEYS)


class ExperimentError(ValueError):
    """A plan file or option that cannot be run, with the reason."""


# -- runs ------------------------------------------------------------------------------------


def run_key(doc: dict) -> str:
    """Folder name of the run of scenario document ``doc``: its name and a hash of it."""
    text = yaml.safe_dump(doc, sort_keys=True)
    return f'{doc.get("name", "run")}-{hashlib.sha1(text.encode()).hexdigest()[:10]}'


@dataclass
class RunResult:
    key: str
    doc: dict
    metrics: dict
    folder: Path

    @property
    def ok(self) -> bool:
        """The run completed and its metrics can be used (a fall is a valid outcome)."""
        return bool(self.metrics.get('sim_time_s')) and self.metrics.get('fell') is not None

    @property
    def fell(self) -> bool:
        return bool(self.metrics.get('fell'))


class Progress:
    """One line: runs done, running, left (an upper bound where a bisection may stop early)
    and the time to go at the pace so far."""

    def __init__(self, total: int, stream=sys.stdout, quiet: bool = False) -> None:
        self.total, self.stream, self.quiet = total, stream, quiet
        self.done = self.running = self.reused = 0
        self.start = time.monotonic()
        self.lock = threading.Lock()

    def update(self, *, started: int = 0, finished: int = 0, reused: int = 0,
               skipped: int = 0) -> None:
        with self.lock:
            self.running += started - finished
            self.done += finished + reused
            self.reused += reused
            self.total -= skipped
            if self.quiet:
                return
            made = self.done - self.reused
            elapsed = time.monotonic() - self.start
            left = max(self.total - self.done, 0)
            eta = f'{elapsed / made * left / 60:.0f} min' if made else '?'
            self.stream.write(f'\r[experiments] {self.done}/{self.total} runs done '
                              f'({self.reused} reused), {self.running} running, {left} left, '
                              f'about {eta} to go   ')
            self.stream.flush()

    def close(self) -> None:
        if not self.quiet:
            self.stream.write('\n')
            self.stream.flush()


class Runner:
    """Makes scenario runs, at most ``jobs`` at a time, each on its own ROS_DOMAIN_ID."""

    def __init__(self, out_dir: Path, config_dir: Path, *, jobs: int = 1,
                 domain_base: int = DEFAULT_DOMAIN_BASE, fresh: bool = False,
                 progress: Progress | None = None,
                 lock_file: Path | None = None) -> None:
        self.out_dir, self.config_dir = out_dir, config_dir
        self.lock_file = lock_file
        self.fresh, self.progress = fresh, progress
        self.slots = [domain_base + i for i in range(jobs)]
        self.free = threading.Condition()
        self.results: dict[str, RunResult | threading.Event] = {}
        self.lock = threading.Lock()
        self.failures: list[str] = []

    def scenario(self, name: str) -> dict:
        path = self.config_dir / 'scenarios' / f'{name}.yaml'
        try:
            return yaml.safe_load(path.read_text())
        except (OSError, yaml.YAMLError) as err:
            raise ExperimentError(f'cannot read scenario {path}: {err}') from err

    def run(self, doc: dict) -> RunResult:
        """The run of scenario ``doc``: made now, or read if made before or under way."""
        key = run_key(doc)
        with self.lock:
            entry = self.results.get(key)
            if entry is None:
                self.results[key] = threading.Event()
        if isinstance(entry, RunResult):
            if self.progress:
                self.progress.update(reused=1)
            return entry
        if isinstance(entry, threading.Event):
            entry.wait()
            if self.progress:
                self.progress.update(reused=1)
            return self.results[key]
        event = self.results[key]
        try:
            result = self._make(key, doc)
        except (OSError, subprocess.SubprocessError, ValueError) as err:
            self.failures.append(f'{key}: {err}')
            result = RunResult(key, doc, {}, self.out_dir / 'runs' / key)
        with self.lock:
            self.results[key] = result
        event.set()
        return result

    @contextlib.contextmanager
    def machine_lock(self):
        """Hold ``lock_file`` (flock) for the run, if one was given: graphs of other tools
        that take the same lock then never run at the same time as this one."""
        if self.lock_file is None:
            yield
            return
        with open(self.lock_file, 'a') as handle:
            fcntl.flock(handle, fcntl.LOCK_EX)
            try:
                yield
            finally:
                fcntl.flock(handle, fcntl.LOCK_UN)

    def _make(self, key: str, doc: dict) -> RunResult:
        folder = self.out_dir / 'runs' / key
        text = yaml.safe_dump(doc, sort_keys=False)
        metrics_file = folder / 'metrics.json'
        if (not self.fresh and metrics_file.exists()
                and (folder / 'input.yaml').exists()
                and (folder / 'input.yaml').read_text() == text):
            result = RunResult(key, doc, json.loads(metrics_file.read_text()), folder)
            if result.ok:
                if self.progress:
                    self.progress.update(reused=1)
                return result
        if folder.exists():
            shutil.rmtree(folder)
        folder.mkdir(parents=True)
        (folder / 'input.yaml').write_text(text)
        with self.free:
            while not self.slots:
                self.free.wait()
            domain = self.slots.pop()
        if self.progress:
            self.progress.update(started=1)
        try:
            env = dict(os.environ, ROS_DOMAIN_ID=str(domain))
            env.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
            with open(folder / 'output.log', 'w') as output, self.machine_lock():
                code = subprocess.run(
                    [sys.executable, '-m', 'replan_ros.experiments.scenario',
                     str(folder / 'input.yaml'),
                     '--out', str(folder), '--quiet', '--no-plots', '--no-bag'],
                    env=env, stdout=output, stderr=subprocess.STDOUT, timeout=3600).returncode
        finally:
            with self.free:
                self.slots.append(domain)
                self.free.notify()
            if self.progress:
                self.progress.update(finished=1)
        metrics = json.loads(metrics_file.read_text()) if metrics_file.exists() else {}
        result = RunResult(key, doc, metrics, folder)
        if not result.ok:
            tail = (folder / 'output.log').read_text()[-400:].strip().splitlines()
            self.failures.append(f'{key}: exit {code}: {tail[-1] if tail else "no output"}')
        return result


# -- scenario documents ----------------------------------------------------------------------


def variant(base: dict, *, params: dict | None = None,
            world: str = 'realistic', seed: int | None = None, terrain: dict | None = None,
            setpoint: tuple[float, float, float] | None = None, duration: float | None = None,
            push: tuple[float, tuple[float, float, float], float] | None = None) -> dict:
    """A copy of scenario ``base`` with the experiment's changes: parameter overrides (per
    node), the world profile, the seed (sim ``noise_seed``; the terrain seed too), the terrain,
    the first set-point, the duration and one push (t, force, duration)."""
    doc = json.loads(json.dumps(base))
    doc['profile'] = world
    merged: dict = doc.get('params') or {}
    for node, values in (params or {}).items():
        merged.setdefault(node, {}).update(values)
    if seed is not None:
        merged.setdefault('sim', {})['noise_seed'] = int(seed)
    if terrain is not None:
        doc['terrain'] = dict(terrain)
        if terrain.get('type') == 'rough' and seed is not None:
            merged.setdefault('sim', {})['seed'] = int(seed)       # the heightfield's seed
    if merged:
        doc['params'] = merged
    events = list(doc.get('events') or [])
    if setpoint is not None:
        first = next(i for i, e in enumerate(events) if 'cmd_vel' in e)
        events[first] = {'t': events[first]['t'], 'cmd_vel': [float(v) for v in setpoint]}
    if duration is not None:
        doc['duration'] = float(duration)
        events = [e for e in events if e['t'] <= duration]
    if push is not None:
        t, force, length = push
        events.append({'t': round(float(t), 4), 'push': {
            'force': [round(float(f), 4) for f in force], 'duration': float(length)}})
    doc['events'] = events
    return doc


# -- experiments -----------------------------------------------------------------------------


@dataclass
class Context:
    runner: Runner
    settings: dict          # node_settings(): the node parameters the experiments derive from


def _parallel(jobs: list[Callable[[], object]]) -> list:
    """Run ``jobs`` (callables that make runs) in threads; their results in order."""
    out: list = [None] * len(jobs)
    errors: list[BaseException] = []

    def call(i: int) -> None:
        try:
            out[i] = jobs[i]()
        except BaseException as err:     # re-raised below, in the caller's thread
            errors.append(err)

    threads = [threading.Thread(target=call, args=(i,), daemon=True) for i in range(len(jobs))]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    if errors:
        raise errors[0]
    return out


def _summary(result: RunResult, **extra) -> dict:
    m = result.metrics
    row = {'run': result.key, 'fell': result.fell, 'ok': result.ok,
           'cop_margin_min_m': m.get('cop_margin_min_m'),
           'cop_margin_p5_m': m.get('cop_margin_p5_m'),
           'mpc_solve_ms_median': m.get('mpc_solve_ms_median'),
           'mpc_solve_ms_p99': m.get('mpc_solve_ms_p99'),
           'final_x_m': (m.get('final_position_m') or [None])[0],
           'cop_zmp_deviation_rms_m': (m.get('cop_zmp_deviation_m') or {}).get('rms'),
           'estimator_xy_error_end_m': (m.get('estimator') or {}).get('xy_error_end_m'),
           'real_time_factor': m.get('real_time_factor')}
    tracking = [s for s in m.get('velocity_tracking') or [] if any(s.get('commanded', []))]
    if tracking:
        last = tracking[-1]
        row.update(linear_error_mps=last.get('linear_error_mps'),
                   achieved=last.get('achieved'), commanded=last.get('commanded'),
                   settle_time_s=last.get('settle_time_s'), settle_steps=last.get('settle_steps'),
                   rise_time_s=last.get('rise_time_s'), rise_steps=last.get('rise_steps'),
                   yaw_rate_error_radps=last.get('yaw_rate_error_radps'))
    pitch = m.get('touchdown_pitch_peak_deg') or {}
    timing = m.get('touchdown_timing_error_s') or {}
    row.update(pitch_peak_mean_deg=pitch.get('mean'), pitch_peak_max_deg=pitch.get('max'),
               touchdown_timing_median_abs_s=timing.get('median_abs'),
               max_pitch_deg=(math.degrees(m['max_pitch_rad'])
                              if m.get('max_pitch_rad') is not None else None))
    row.update(extra)
    return row


def velocity_changes(ctx: Context, cfg: dict, world: str = 'realistic') -> list[dict]:
    runner = ctx.runner
    specs = [(name, seed) for name in cfg['scenarios'] for seed in cfg['seeds']]

    def one(name: str, seed: int):
        def make():
            doc = variant(runner.scenario(name), world=world, seed=seed,
                          duration=cfg.get('duration'))
            return _summary(runner.run(doc), scenario=name, seed=seed, world=world,
                            prompt_steps=int(cfg.get('prompt_steps', 4)))
        return make
    return _parallel([one(n, s) for n, s in specs])


def bisect_impulse(runner: Runner, base: dict, cfg: dict, setting: dict, push_time: float
                   ) -> dict:
    """Largest lateral impulse survived at one push time: the first probe at
    ``first_impulse``, then bisection between the largest survived and the smallest fallen
    (``max_impulse`` standing in for the latter until one falls)."""
    direction = np.asarray(cfg['direction'], dtype=float)
    direction /= np.linalg.norm(direction)
    survived, fallen = 0.0, float(cfg['max_impulse'])
    fell_seen = False
    probes, first = [], None
    impulse = float(cfg['first_impulse'])
    for i in range(int(cfg['probes'])):
        force = direction * impulse / cfg['push_duration']
        duration = cfg.get('duration') or push_time + float(cfg['after_push'])
        doc = variant(base, params=setting, seed=cfg['seed'], duration=duration,
                      push=(push_time, (force[0], force[1], 0.0), cfg['push_duration']))
        result = runner.run(doc)
        if not result.ok:
            break
        push = (result.metrics.get('pushes') or [{}])[0]
        probes.append({'impulse_ns': impulse, 'fell': result.fell, 'run': result.key,
                       'velocity_change_mps': push.get('velocity_change_mps'),
                       'support_inradius_min_m': push.get('support_inradius_min_m'),
                       'support_inradius_before_m': push.get('support_inradius_before_m')})
        if i == 0:
            first = probes[-1]
        if result.fell:
            fallen, fell_seen = impulse, True
        else:
            survived = impulse
        impulse = 0.5 * (survived + fallen)
    return {'survived_ns': survived, 'fallen_ns': fallen if fell_seen else None,
            'probes': probes, 'first': first, 'complete': len(probes) == int(cfg['probes'])}


def lateral_push(ctx: Context, cfg: dict) -> dict:
    base = ctx.runner.scenario(cfg['scenario'])
    phases = int(cfg['phases'])
    cycle = ctx.settings['crawl_cycle_s']
    times = [cfg['first_push'] + cycle * k / phases for k in range(phases)]
    jobs, keys = [], []
    for name, setting in cfg['settings'].items():
        for k, t in enumerate(times):
            keys.append((name, k, t))
            jobs.append(lambda s=setting, t=t: bisect_impulse(ctx.runner, base, cfg, s, t))
    outcomes = _parallel(jobs)
    table: dict = {name: [] for name in cfg['settings']}
    for (name, k, t), outcome in zip(keys, outcomes, strict=True):
        table[name].append({'phase': k, 'phase_fraction': k / phases, 'push_time_s': t,
                            **outcome})
    return {'settings': table, 'config': {**cfg, 'cycle': cycle},
            'robot_mass_kg': _robot_mass(ctx.runner)}


def _robot_mass(runner: Runner) -> float | None:
    """Mass of the simulated realistic robot (kg): the model's URDF plus the profile's
    payload; None if either cannot be read."""
    try:
        from replan_core.robot_model import RobotModel
        urdf = os.environ.get('REPLAN_URDF', str(runner.config_dir.parent / 'urdf' / 'hyq.urdf'))
        profile = yaml.safe_load((runner.config_dir / 'profiles' / 'realistic.yaml').read_text())
        payload = float(profile['sim']['ros__parameters'].get('payload_mass', 0.0))
        return RobotModel(urdf).total_mass + payload
    except (OSError, KeyError, TypeError, ValueError, yaml.YAMLError):
        return None


def replan_window(ctx: Context, cfg: dict, world: str = 'realistic') -> list[dict]:
    runner = ctx.runner
    base = runner.scenario(cfg.get('scenario', 'exp_walk'))
    jobs = []
    for window in cfg['windows']:
        for seed in cfg['seeds']:
            for v in cfg['setpoints']:
                def make(window=window, seed=seed, v=v):
                    doc = variant(base, world=world, seed=seed, setpoint=(v, 0.0, 0.0),
                                  duration=cfg.get('duration'),
                                  params={'gait': {'replan_window': int(window)}}
                                  if window != 1 else None)
                    return _summary(runner.run(doc), window=window, seed=seed, setpoint=v,
                                    world=world)
                jobs.append(make)
    return _parallel(jobs)


def haptic(ctx: Context, cfg: dict, world: str = 'realistic',
           terrains: list[str] | None = None) -> list[dict]:
    runner = ctx.runner
    base = runner.scenario(cfg.get('scenario', 'exp_blind_terrain'))
    jobs = []
    for terrain_name, terrain in cfg['terrains'].items():
        if terrains is not None and terrain_name not in terrains:
            continue
        for mode in (True, False):
            for seed in cfg['seeds']:
                def make(terrain_name=terrain_name, terrain=terrain, mode=mode, seed=seed):
                    doc = variant(base, world=world, seed=seed, terrain=terrain,
                                  duration=(cfg.get('durations') or {}).get(
                                      terrain_name, cfg.get('duration')),
                                  params=None if mode else {'gait': {'haptic': False}})
                    result = runner.run(doc)
                    crossed = None
                    end = _terrain_end(terrain)
                    if end is not None and result.ok:
                        x = (result.metrics.get('final_position_m') or [0.0])[0]
                        crossed = bool(not result.fell and x > end)
                    return _summary(result, terrain=terrain_name, haptic=mode, seed=seed,
                                    world=world, crossed=crossed, terrain_end_x=end)
                jobs.append(make)
    return _parallel(jobs)


def _terrain_end(terrain: dict) -> float | None:
    """x the base must pass for the hind feet to be over the terrain feature (0.5 m behind the
    base: HyQ's hips are 0.37 m behind it, the feet a little further)."""
    margin = 0.5
    if terrain.get('type') == 'step_down':
        return float(terrain.get('step_x', 0.6)) + margin
    if terrain.get('type') == 'rough':
        return (float(terrain.get('rough_start_x', 0.6)) + float(terrain.get('rough_length', 4.0))
                + margin)
    return None


def velocity_term(ctx: Context, cfg: dict) -> list[dict]:
    runner = ctx.runner
    base = runner.scenario(cfg['scenario'])
    jobs = []
    for on in (True, False):
        for seed in cfg['seeds']:
            for v in cfg['setpoints']:
                def make(on=on, seed=seed, v=v):
                    doc = variant(base, seed=seed, setpoint=(v, 0.0, 0.0),
                                  duration=cfg.get('duration'),
                                  params=None if on else {'mpc': {'velocity_weight': 0.0}})
                    return _summary(runner.run(doc), velocity_term=on, seed=seed, setpoint=v)
                jobs.append(make)
    return _parallel(jobs)


def qp_timing(ctx: Context, cfg: dict) -> dict:
    """The re-planner alone at the paper's size (replan_core.bench.mpc_bench), one
    single-threaded process per formulation, while no graph runs."""
    out = {}
    for formulation in cfg['formulations']:
        env = dict(os.environ, OMP_NUM_THREADS='1')
        with ctx.runner.machine_lock():
            proc = subprocess.run(
                [sys.executable, '-m', 'replan_core.bench.mpc_bench', '--formulation',
                 formulation,
                 '--replans', str(cfg['replans'])], env=env, capture_output=True, text=True,
                timeout=1800)
        lines = proc.stdout.strip().splitlines()
        try:
            out[formulation] = json.loads(lines[-1])
        except (IndexError, json.JSONDecodeError):
            out[formulation] = {'error': (proc.stderr.strip().splitlines() or ['no output'])[-1]}
    return out


def fastest_crawl(ctx: Context, cfg: dict) -> dict:
    """Set-points tried in turn up to the first fall, and the speed bound of the gait's step
    length clamp: max_step_length_x per crawl cycle (each leg steps once per cycle)."""
    runner = ctx.runner
    base = runner.scenario(cfg['scenario'])
    clamp = float(cfg['velocity_clamp'])
    rows = []
    for v in cfg['setpoints']:       # one after the other: stop at the first fall
        doc = variant(base, seed=cfg['seed'], setpoint=(v, 0.0, 0.0),
                      params={'gait': {'max_linear_x': clamp}})
        rows.append(_summary(runner.run(doc), setpoint=v))
        if rows[-1]['fell'] or not rows[-1]['ok']:
            break
    step, cycle = ctx.settings['max_step_length_x_m'], ctx.settings['crawl_cycle_s']
    return {'runs': rows, 'step_length_bound': {'max_step_length_x_m': step, 'cycle_s': cycle,
                                                'speed_mps': step / cycle}}


def ideal_world(ctx: Context, cfg: dict, plan: dict) -> dict:
    """Some experiments again in the ideal world, with the realistic ones' settings except
    those ``cfg`` overrides (fewer seeds, set-points, terrains)."""
    makers = {}
    if 'replan_window' in cfg and 'replan_window' in plan:
        makers['replan_window'] = lambda: replan_window(
            ctx, {**plan['replan_window'], **cfg['replan_window']}, world='ideal')
    if 'haptic' in cfg and 'haptic' in plan:
        makers['haptic'] = lambda: haptic(
            ctx, {**plan['haptic'], 'seeds': cfg['haptic']['seeds']}, world='ideal',
            terrains=cfg['haptic']['terrains'])
    if 'velocity_changes' in cfg and 'velocity_changes' in plan:
        makers['velocity_changes'] = lambda: velocity_changes(
            ctx, {**plan['velocity_changes'], **cfg['velocity_changes']}, world='ideal')
    return dict(zip(makers, _parallel(list(makers.values())), strict=True))


def planned_runs(plan: dict, selected: list[str]) -> int:
    """Upper bound of the runs of the ``selected`` experiments of ``plan`` (a run shared by two
    experiments counted twice)."""
    n = 0
    for name in selected:
        cfg = plan[name]
        if name == 'velocity_changes':
            n += len(cfg['scenarios']) * len(cfg['seeds'])
        elif name == 'lateral_push':
            n += len(cfg['settings']) * int(cfg['phases']) * int(cfg['probes'])
        elif name == 'replan_window':
            n += len(cfg['windows']) * len(cfg['seeds']) * len(cfg['setpoints'])
        elif name == 'haptic':
            n += 2 * len(cfg['terrains']) * len(cfg['seeds'])
        elif name == 'velocity_term':
            n += 2 * len(cfg['seeds']) * len(cfg['setpoints'])
        elif name == 'fastest_crawl':
            n += len(cfg['setpoints'])
        elif name == 'ideal_world':
            sub = {k: {**plan.get(k, {}), **v} for k, v in cfg.items() if k in plan}
            n += planned_runs(sub, list(sub))
    return n


def load_plan(path: Path, quick: bool, only: list[str]) -> tuple[dict, list[str]]:
    """The ``full`` or ``quick`` section of the plan file and the experiments to run."""
    try:
        doc = yaml.safe_load(path.read_text())
    except (OSError, yaml.YAMLError) as err:
        raise ExperimentError(f'cannot read {path}: {err}') from err
    section = 'quick' if quick else 'full'
    plan = (doc or {}).get(section)
    if not isinstance(plan, dict):
        raise ExperimentError(f'{path}: no {section}: section')
    unknown = set(plan) - set(EXPERIMENTS)
    if unknown:
        raise ExperimentError(f'{path}: {section}: unknown experiments {sorted(unknown)} '
                              f'(known: {", ".join(EXPERIMENTS)})')
    entries = [(name, cfg) for name, cfg in plan.items()]
    entries += [(f'ideal_world.{k}', v) for k, v in (plan.get('ideal_world') or {}).items()]
    for where, entry in entries:
        keys = PLAN_KEYS.get(where.split('.')[-1], set())   # ideal_world: the realistic keys
        if not isinstance(entry, dict):
            raise ExperimentError(f'{path}: {section}.{where} must be a mapping')
        unknown = set(entry) - keys
        if unknown:
            raise ExperimentError(f'{path}: {section}.{where}: unknown keys {sorted(unknown)} '
                                  f'(known: {", ".join(sorted(keys))})')
    bad = set(only) - set(plan)
    if bad:
        raise ExperimentError(f'--only: {sorted(bad)} not in the {section} plan '
                              f'(there: {", ".join(plan)})')
    return plan, [name for name in plan if not only or name in only]


def run_all(plan: dict, selected: list[str], runner: Runner) -> dict:
    """The ``selected`` experiments of ``plan``; returns their data for the page."""
    settings = node_settings(runner.config_dir)        # ExperimentError: nothing run
    ctx = Context(runner, settings)
    results: dict = {}
    if 'qp_timing' in selected:       # before any graph loads the cores
        results['qp_timing'] = qp_timing(ctx, plan['qp_timing'])
    makers = {
        'velocity_changes': lambda: velocity_changes(ctx, plan['velocity_changes']),
        'lateral_push': lambda: lateral_push(ctx, plan['lateral_push']),
        'replan_window': lambda: replan_window(ctx, plan['replan_window']),
        'haptic': lambda: haptic(ctx, plan['haptic']),
        'velocity_term': lambda: velocity_term(ctx, plan['velocity_term']),
        'fastest_crawl': lambda: fastest_crawl(ctx, plan['fastest_crawl']),
        'ideal_world': lambda: ideal_world(ctx, plan['ideal_world'], plan),
    }
    names = [n for n in makers if n in selected]
    for name, value in zip(names, _parallel([makers[n] for n in names]), strict=True):
        results[name] = value
    results['settings'] = settings
    return results


def node_settings(config_dir: Path) -> dict:
    """The node parameters the experiments derive from (the push phases from the crawl cycle)
    and the page's explanations quote, from the node files (the realistic profile does not
    change them); ExperimentError if a file or key is missing."""
    try:
        gait = yaml.safe_load((config_dir / 'gait.yaml').read_text())['gait']['ros__parameters']
        wbc = yaml.safe_load((config_dir / 'wbc.yaml').read_text())['wbc']['ros__parameters']
        out = {'crawl_cycle_s': 4.0 * (float(gait['swing_duration'])
                                       + float(gait['four_feet_duration'])),
               'max_step_length_x_m': float(gait['max_step_length_x']),
               'max_extension_s': float(gait['max_extension']),
               'correction_threshold_m': float(gait['correction_threshold']),
               'touchdown_depth_m': float(wbc['touchdown_depth']),
               'haptic_velocity_mps': float(wbc['haptic_velocity'])}
    except (OSError, KeyError, TypeError, ValueError, yaml.YAMLError) as err:
        raise ExperimentError(f'cannot read the gait and wbc settings in {config_dir}: '
                              f'{err!r}') from err
    out['haptic_search_m'] = (out['touchdown_depth_m']
                              + out['haptic_velocity_mps'] * out['max_extension_s'])
    return out


def machine_description() -> str:
    cpu = platform.processor() or platform.machine()
    try:
        for line in Path('/proc/cpuinfo').read_text().splitlines():
            if line.startswith('model name'):
                cpu = line.split(':', 1)[1].strip()
                break
    except OSError:
        pass
    return f'{os.cpu_count()} cores, {cpu}, {platform.system()} {platform.release()}'


def git_revision(root: Path) -> str:
    try:
        rev = subprocess.run(['git', 'rev-parse', '--short', 'HEAD'], cwd=root,
                             capture_output=True, text=True, timeout=10).stdout.strip()
        dirty = subprocess.run(['git', 'status', '--porcelain', '--untracked-files=no'],
                               cwd=root, capture_output=True, text=True,
                               timeout=10).stdout.strip()
        return (rev + (' (with uncommitted changes)' if dirty else '')) if rev else 'unknown'
    except (OSError, subprocess.SubprocessError):
        return 'unknown'


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog='experiments.sh', description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('--quick', action='store_true',
                        help='one short run of each kind (a few minutes): checks the page is '
                             'produced; the page goes to DIR/results.md')
    parser.add_argument('--jobs', type=int, default=1,
                        help='runs at once, each on its own ROS_DOMAIN_ID (default 1)')
    parser.add_argument('--only', nargs='+', default=[], metavar='NAME',
                        help=f'only these experiments ({", ".join(EXPERIMENTS)})')
    parser.add_argument('--out', type=Path,
                        help='run folder (default runs/experiments[-quick]); runs already in '
                             'it with the same scenario are read, not made again')
    parser.add_argument('--page', type=Path,
                        help='results page (default docs/results.md, with --quick '
                             'DIR/results.md)')
    parser.add_argument('--plan', type=Path, help='experiment plan (default '
                        'config/experiments.yaml)')
    parser.add_argument('--domain-base', type=int,
                        default=int(os.environ.get('REPLAN_EXPERIMENTS_DOMAIN',
                                                   DEFAULT_DOMAIN_BASE)),
                        help='ROS_DOMAIN_ID of the first job (the others follow; default '
                             f'{DEFAULT_DOMAIN_BASE})')
    parser.add_argument('--fresh', action='store_true', help='make every run again')
    parser.add_argument('--lock', type=Path, metavar='FILE',
                        help='hold this file lock (flock) during each run, to share the '
                             'machine with other graph runs that take it')
    parser.add_argument('--quiet', action='store_true', help='no progress line')
    args = parser.parse_args(argv)
    if args.jobs < 1 or args.jobs > 8:
        parser.error('--jobs must be within 1..8')
    if not 0 <= args.domain_base <= 232 - args.jobs:
        parser.error('--domain-base must keep every job within ROS_DOMAIN_ID 0..232')
    root = Path(os.environ.get('REPLAN_ROOT', '.')).resolve()
    config_dir = Path(os.environ.get('REPLAN_CONFIG', root / 'config'))
    plan_file = args.plan or config_dir / 'experiments.yaml'
    try:
        plan, selected = load_plan(plan_file, args.quick, args.only)
    except ExperimentError as err:
        print(f'experiments: {err}', file=sys.stderr)
        return 2
    out = args.out or root / 'runs' / ('experiments-quick' if args.quick else 'experiments')
    page = args.page or (out / 'results.md' if args.quick else root / 'docs' / 'results.md')
    out.mkdir(parents=True, exist_ok=True)
    total = planned_runs(plan, selected)
    print(f'[experiments] {", ".join(selected)}: up to {total} runs, {args.jobs} at a time, '
          f'in {out}; page {page}')
    progress = Progress(total, quiet=args.quiet)
    runner = Runner(out, config_dir, jobs=args.jobs, domain_base=args.domain_base,
                    fresh=args.fresh, progress=progress, lock_file=args.lock)
    started = time.monotonic()
    try:
        results = run_all(plan, selected, runner)
    except ExperimentError as err:
        progress.close()
        print(f'experiments: {err}', file=sys.stderr)
        return 2
    progress.close()
    wall = time.monotonic() - started
    command = 'scripts/experiments.sh ' + ' '.join(argv if argv is not None else sys.argv[1:])
    made = sum(1 for r in runner.results.values()
               if isinstance(r, RunResult) and r.ok)
    meta = {'command': command.strip(), 'machine': machine_description(),
            'revision': git_revision(root), 'date': time.strftime('%Y-%m-%d %H:%M UTC',
                                                                  time.gmtime()),
            'wall_time_min': round(wall / 60.0, 1), 'runs': made,
            'reused': progress.reused,
            'run_time_min': round(sum(
                r.metrics.get('wall_time_total_s') or 0.0 for r in runner.results.values()
                if isinstance(r, RunResult)) / 60.0, 1),
            'quick': args.quick, 'failures': runner.failures, 'plan_file': str(plan_file)}
    (out / 'results.json').write_text(json.dumps({'meta': meta, 'results': results},
                                                 indent=1, default=str))
    write_page(page, results, meta)
    print(f'[experiments] {made} runs in {wall / 60:.1f} min; page {page}, data '
          f'{out / "results.json"}')
    for failure in runner.failures:
        print(f'[experiments] run failed: {failure}', file=sys.stderr)
    return 1 if runner.failures else 0


if __name__ == '__main__':
    sys.exit(main())
