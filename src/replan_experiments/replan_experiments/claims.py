"""The experiments, one function each: the runs it makes (in parallel where they do not
depend on each other) and the rows it gives the results page; ``run_all`` runs a plan's."""

from __future__ import annotations

import copy
import json
import math
import os
import subprocess
import sys
import threading
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import yaml

from replan_core.robot.robot_file import default_urdf
from replan_experiments.motion_effects import cached_motion_effects
from replan_experiments.plan import (
    EXPERIMENTS,
    VARIANT_EXPERIMENTS,
    ExperimentError,
    claim_hashes,
    node_settings,
    phase_impulses,
    variant,
    variant_of,
)
from replan_experiments.push_effects import cached_push_effects
from replan_experiments.robot_info import robot_info
from replan_experiments.runs import Runner, RunResult
from replan_experiments.stats import steady_error


@dataclass
class Context:
    runner: Runner
    settings: dict          # node_settings(): the node parameters the experiments derive from


class PlanRunner:
    """A runner whose every run is a confirmatory run of the claim pre-registered with hash
    ``plan`` (``plan.claim_hash``): its key holds the hash (``runs.run_key``), so its rows say
    which pre-registration they were made for. The rest is the wrapped runner's."""

    def __init__(self, runner: Runner, plan: str) -> None:
        self.runner, self.plan = runner, plan

    def run(self, doc: dict, bag: bool = False) -> RunResult:
        return self.runner.run(doc, bag=bag, plan=self.plan)

    def __getattr__(self, name: str):
        return getattr(self.runner, name)


class VariantRunner:
    """A runner for a variant section (``plan.VARIANT_KEYS``): each scenario it reads runs
    the section's ``robot`` and ``gait`` (the document's top-level keys) with every set-point
    of its events times ``setpoint_scale``; set-points the section gives itself (``setpoints``)
    are the section's. The rest is the wrapped runner's."""

    def __init__(self, runner, robot: str | None = None, gait: str | None = None,
                 setpoint_scale: float | None = None) -> None:
        self.runner, self.gait, self.setpoint_scale = runner, gait, setpoint_scale
        self.variant_robot = robot
        self.robot = robot or getattr(runner, 'robot', None)    # _robot_mass reads it

    def scenario(self, name: str) -> dict:
        doc = self.runner.scenario(name)
        suffix = [v for v in (self.gait, self.variant_robot) if v]
        if self.variant_robot:
            doc['robot'] = self.variant_robot
        if self.gait:
            doc['gait'] = self.gait
        if self.setpoint_scale is not None:
            scale = float(self.setpoint_scale)
            doc['events'] = [{**e, 'cmd_vel': [round(float(v) * scale, 6) for v in e['cmd_vel']]}
                             if 'cmd_vel' in e else e for e in doc.get('events') or []]
            suffix.append(f'x{scale:g}')
        doc['name'] = '_'.join([str(doc.get('name', name)), *suffix])
        return doc

    def __getattr__(self, name: str):
        return getattr(self.runner, name)


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
           'plan': getattr(result, 'plan', None),
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
                   achieved_cycles=last.get('achieved_cycles'), cycles=last.get('cycles'),
                   achieved_steady=last.get('achieved_steady'),
                   steady_cycles=last.get('steady_cycles'),
                   cycle_velocities=last.get('cycle_velocities'),
                   settle_time_s=last.get('settle_time_s'), settle_steps=last.get('settle_steps'),
                   rise_time_s=last.get('rise_time_s'), rise_steps=last.get('rise_steps'),
                   yaw_rate_error_radps=last.get('yaw_rate_error_radps'),
                   steady_error_mps=steady_error(last))
    pitch = m.get('touchdown_pitch_peak_deg') or {}
    timing = m.get('touchdown_timing_error_s') or {}
    row.update(pitch_peak_mean_deg=pitch.get('mean'), pitch_peak_max_deg=pitch.get('max'),
               touchdown_timing_median_abs_s=timing.get('median_abs'),
               touchdown_timing_mean_s=timing.get('mean'),
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
                            prompt_steps=int(cfg.get('prompt_steps', 4)),
                            steady_tolerance=float(cfg['steady_tolerance']))
        return make
    return _parallel([one(n, s) for n, s in specs])


def bisect_impulse(runner: Runner, base: dict, cfg: dict, setting: dict, push_time: float,
                   seed: int, world: str = 'realistic') -> dict:
    """Largest lateral impulse survived at one push time and seed: the first probe at
    ``first_impulse``, then bisection between the largest survived and the smallest fallen
    (``max_impulse`` standing in for the latter until one falls)."""
    direction = np.asarray(cfg['direction'], dtype=float)
    direction /= np.linalg.norm(direction)
    survived, fallen = 0.0, float(cfg['max_impulse'])
    fell_seen = False
    probes, first, plan = [], None, None
    impulse = float(cfg['first_impulse'])
    for i in range(int(cfg['probes'])):
        force = direction * impulse / cfg['push_duration']
        duration = cfg.get('duration') or push_time + float(cfg['after_push'])
        doc = variant(base, params=setting, seed=seed, duration=duration, world=world,
                      push=(push_time, (force[0], force[1], 0.0), cfg['push_duration']))
        result = runner.run(doc)
        if not result.ok:
            break
        plan = getattr(result, 'plan', None)
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
            'probes': probes, 'first': first, 'complete': len(probes) == int(cfg['probes']),
            'plan': plan}


def second_push(runner: Runner, base: dict, cfg: dict, setting: dict, push_time: float,
                seed: int, step_period: float, world: str = 'realistic') -> dict | None:
    """Two pushes of ``second_push.impulse`` N s each, the second ``second_push.after_steps``
    steps (of ``step_period`` s) after the first: whether the robot falls (the
    support the first push left must still hold the second). None if the run failed."""
    direction = np.asarray(cfg['direction'], dtype=float)
    direction /= np.linalg.norm(direction)
    spec = cfg['second_push']
    impulse, length = float(spec['impulse']), float(cfg['push_duration'])
    later = push_time + float(spec['after_steps']) * step_period
    force = direction * impulse / length
    doc = variant(base, params=setting, seed=seed, world=world,
                  duration=later + float(cfg['after_push']),
                  pushes=[(t, (force[0], force[1], 0.0), length) for t in (push_time, later)])
    result = runner.run(doc)
    if not result.ok:
        return None
    return {'impulse_ns': impulse, 'second_time_s': later, 'fell': bool(result.fell),
            'fall_time_s': result.metrics.get('fall_time_s'), 'run': result.key}


def lateral_push(ctx: Context, cfg: dict, world: str = 'realistic') -> dict:
    """Per setting, phase of the crawl cycle and seed (paired across the settings): the
    largest impulse survived (``bisect_impulse``) and, with ``second_push``, whether two
    pushes a few steps apart are survived. Entries in phase-major, seed-minor order in every
    setting, so that index k pairs them."""
    base = ctx.runner.scenario(cfg['scenario'])
    phases = int(cfg['phases'])
    cycle = ctx.settings['crawl_cycle_s']
    step_period = cycle / 4.0
    times = [cfg['first_push'] + cycle * k / phases for k in range(phases)]
    jobs, keys = [], []
    for name, setting in cfg['settings'].items():
        for k, t in enumerate(times):
            for seed in cfg['seeds']:
                keys.append((name, k, t, seed))
                jobs.append(lambda s=setting, t=t, seed=seed: {
                    **bisect_impulse(ctx.runner, base, cfg, s, t, seed, world),
                    'second': (second_push(ctx.runner, base, cfg, s, t, seed, step_period,
                                           world) if cfg.get('second_push') else None)})
    outcomes = _parallel(jobs)
    table: dict = {name: [] for name in cfg['settings']}
    for (name, k, t, seed), outcome in zip(keys, outcomes, strict=True):
        table[name].append({'phase': k, 'seed': seed, 'phase_fraction': k / phases,
                            'push_time_s': t, **outcome})
    return {'settings': table, 'config': {**cfg, 'cycle': cycle}, 'world': world,
            'robot_mass_kg': _robot_mass(ctx.runner)}


def _push_support(runner: Runner, base: dict, params: dict, seed: int, start: float,
                  force: np.ndarray, length: float, horizon: float, duration: float | None,
                  **labels) -> dict:
    """One run with a lateral ``force`` (N, xy) from ``start`` for ``length`` s, its bag kept:
    its row, with what the push did to the support over ``horizon`` s after it
    (``push_effects``) unless it fell or failed. ``params``: the setting's node parameters."""
    push = (start, (float(force[0]), float(force[1]), 0.0), length)
    doc = variant(base, params=params, seed=seed, push=push, duration=duration)
    result = runner.run(doc, bag=True)
    effects = (cached_push_effects(result.folder, start, length, horizon)
               if result.ok and not result.fell else None)
    return _summary(result, seed=seed, **labels, **(effects or {}))


def _unit(direction) -> np.ndarray:
    vector = np.asarray(direction, dtype=float)
    return vector / np.linalg.norm(vector)


def sustained_push(ctx: Context, cfg: dict) -> list[dict]:
    """A lateral force held for ``push_duration`` s while walking, per setting (foothold
    correction off, literal, sway-free), force and seed: whether the robot falls, and what
    the push does to its support over the steps that follow (``push_effects``, from the run's
    bag, which these runs keep). Paired by seed and force across the settings."""
    base = ctx.runner.scenario(cfg['scenario'])
    direction = _unit(cfg.get('direction', [0.0, 1.0]))
    start, length = float(cfg['push_start']), float(cfg['push_duration'])
    horizon = float(cfg.get('horizon', 6.0))
    jobs = [lambda name=name, setting=setting, force=float(force), seed=seed: _push_support(
                ctx.runner, base, setting, seed, start, force * direction, length, horizon,
                cfg.get('duration'), setting=name, force_n=force)
            for name, setting in cfg['settings'].items()
            for force in cfg['forces'] for seed in cfg['seeds']]
    return _parallel(jobs)


def large_push(ctx: Context, cfg: dict) -> list[dict]:
    """One short lateral push of ``impulse`` N s (one figure, or one per phase: the crawl
    resists a push less at some phases than at others), chosen to move the trunk 10-20 cm
    over its feet, per setting, phase of the crawl cycle and seed: whether the
    robot falls, and what the push does to its support over the ``horizon`` s after it
    (``push_effects``). Paired by phase and seed across the settings. Each run ends
    ``horizon`` s after its push."""
    base = ctx.runner.scenario(cfg['scenario'])
    direction = _unit(cfg['direction'])
    length, phases = float(cfg['push_duration']), int(cfg['phases'])
    impulses = phase_impulses(cfg['impulse'], phases)
    horizon = float(cfg['horizon'])
    cycle = ctx.settings['crawl_cycle_s']
    jobs = []
    for name, setting in cfg['settings'].items():
        for k, impulse in enumerate(impulses):
            start = float(cfg['first_push']) + cycle * k / phases
            force = direction * impulse / length
            for seed in cfg['seeds']:
                jobs.append(lambda name=name, setting=setting, k=k, start=start, seed=seed,
                            force=force, impulse=impulse:
                            _push_support(ctx.runner, base, setting, seed, start, force, length,
                                          horizon, start + length + horizon, setting=name,
                                          phase=k, push_time_s=start, impulse_ns=impulse))
    return _parallel(jobs)


def _robot_mass(runner: Runner) -> float | None:
    """Mass of the simulated realistic robot (kg): the model's URDF plus the profile's
    payload (with the runner's ``robot``: its model and its derived payload); None if either
    cannot be read."""
    try:
        if getattr(runner, 'robot', None):
            info = robot_info(runner.config_dir, runner.robot, 'realistic')
            return info.mass_kg + float(info.value('sim.payload_mass'))
        from replan_core.robot.model import RobotModel
        urdf = default_urdf(runner.config_dir.parent)
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
    """Straight walks at each set-point with the MPC's velocity term on and off (the steady
    speed), and with ``step_scenario`` the same set-point step in both settings (how fast a
    new set-point is reached: the paper's "faster motion"), paired by seed. ``params``: node
    parameters both settings get (e.g. the footholds' speed feedback off, so that only the
    cost term differs); without it the runs are those of before. Every run keeps its bag: how
    the trunk travels between the footholds (``motion_effects``) is read from it, in a straight
    walk from ``motion_after`` s, in a step from the change, to the run's end."""
    runner = ctx.runner
    base = runner.scenario(cfg['scenario'])
    step = runner.scenario(cfg['step_scenario']) if cfg.get('step_scenario') else None
    motion_after = float(cfg['motion_after'])
    shared = copy.deepcopy(cfg.get('params') or {})
    jobs = []
    for on in (True, False):
        params = copy.deepcopy(shared)
        if not on:
            params.setdefault('mpc', {})['velocity_weight'] = 0.0
        params = params or None
        for seed in cfg['seeds']:
            for v in cfg['setpoints']:
                def make(on=on, seed=seed, v=v, params=params):
                    doc = variant(base, seed=seed, setpoint=(v, 0.0, 0.0),
                                  duration=cfg.get('duration'), params=params)
                    result = runner.run(doc, bag=True)
                    return _summary(result, velocity_term=on, seed=seed, setpoint=v,
                                    **_motion(result, doc, motion_after))
                jobs.append(make)
            if step is not None:
                def make_step(on=on, seed=seed, params=params):
                    doc = variant(step, seed=seed, params=params)
                    result = runner.run(doc, bag=True)
                    change = max(e['t'] for e in doc['events'] if 'cmd_vel' in e)
                    return _summary(result, velocity_term=on, seed=seed, setpoint='step',
                                    step_period_s=(result.metrics.get('step_period_s')
                                                   or {}).get('median'),
                                    **_motion(result, doc, change))
                jobs.append(make_step)
    return _parallel(jobs)


def _motion(result: RunResult, doc: dict, start: float) -> dict:
    """How the trunk travelled along the last set-point from ``start`` s to the end of a run
    that neither fell nor failed (``motion_effects``); empty otherwise."""
    if not result.ok or result.fell:
        return {}
    command = [e['cmd_vel'] for e in doc['events'] if 'cmd_vel' in e][-1]
    return cached_motion_effects(result.folder, start, float(doc['duration']),
                                 (float(command[0]), float(command[1]))) or {}


def qp_timing(ctx: Context, cfg: dict) -> dict:
    """The re-planner alone at the paper's size (replan_core.bench.mpc_bench), one
    single-threaded process per formulation, while no graph runs."""
    out = {}
    for formulation in cfg['formulations']:
        env = dict(os.environ, OMP_NUM_THREADS='1')
        with ctx.runner.machine_lock():
            proc = subprocess.run(
                [sys.executable, '-m', 'replan_core.bench.mpc_bench', '--formulation',
                 formulation, '--replans', str(cfg['replans']),
                 '--root', str(Path(ctx.runner.config_dir).parent)],
                env=env, capture_output=True, text=True, timeout=1800)
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
    if 'lateral_push' in cfg and 'lateral_push' in plan:
        makers['lateral_push'] = lambda: lateral_push(
            ctx, {**plan['lateral_push'], **cfg['lateral_push']}, world='ideal')
    return dict(zip(makers, _parallel(list(makers.values())), strict=True))


def run_all(plan: dict, selected: list[str], runner: Runner) -> dict:
    """The ``selected`` experiments of ``plan``; returns their data for the page."""
    settings = node_settings(runner.config_dir, getattr(runner, 'robot', None))
    ctx = Context(runner, settings)
    # The pre-registered claims' runs are confirmatory: their keys hold their claim's hash.
    hashes = claim_hashes(plan)

    def context(name: str) -> Context:
        return Context(PlanRunner(runner, hashes[name]), settings) if name in hashes else ctx

    results: dict = {}
    if 'qp_timing' in selected:       # before any graph loads the cores
        results['qp_timing'] = qp_timing(ctx, plan['qp_timing'])
    makers = {
        'velocity_changes': lambda: velocity_changes(context('velocity_changes'),
                                                     plan['velocity_changes']),
        'lateral_push': lambda: lateral_push(context('lateral_push'), plan['lateral_push']),
        'replan_window': lambda: replan_window(context('replan_window'),
                                               plan['replan_window']),
        'haptic': lambda: haptic(context('haptic'), plan['haptic']),
        'velocity_term': lambda: velocity_term(context('velocity_term'),
                                               plan['velocity_term']),
        'sustained_push': lambda: sustained_push(context('sustained_push'),
                                                 plan['sustained_push']),
        'large_push': lambda: large_push(context('large_push'), plan['large_push']),
        'fastest_crawl': lambda: fastest_crawl(ctx, plan['fastest_crawl']),
        'ideal_world': lambda: ideal_world(ctx, plan['ideal_world'], plan),
    }
    # Each experiment a variant can repeat is this module's function of its name.
    functions = {name: globals()[name] for name in VARIANT_EXPERIMENTS}
    for name in selected:
        if name in EXPERIMENTS:
            continue
        cfg = plan[name]
        if cfg.get('robot') and getattr(runner, 'robot', None):
            raise ExperimentError(f'{name}: the plan names its robot ({cfg["robot"]}) and '
                                  f'--robot another ({runner.robot}): leave out one')
        for key in ('robot', 'gait'):
            if cfg.get(key) and not (runner.config_dir / f'{key}s'
                                     / f'{cfg[key]}.yaml').is_file():
                raise ExperimentError(f'{name}.{key}: no config/{key}s/{cfg[key]}.yaml')
        variant_ctx = Context(
            VariantRunner(context(name).runner, cfg.get('robot'), cfg.get('gait'),
                          cfg.get('setpoint_scale')),
            node_settings(runner.config_dir, cfg['robot']) if cfg.get('robot') else settings)
        makers[name] = (lambda function=functions[cfg['experiment']], c=variant_ctx, cfg=cfg:
                        function(c, cfg))
    names = [n for n in makers if n in selected]
    for name, value in zip(names, _parallel([makers[n] for n in names]), strict=True):
        results[name] = value
    results['settings'] = settings
    variants = {n: {'experiment': plan[n]['experiment'], **variant_of(plan[n])}
                for n in names if n not in EXPERIMENTS}
    if variants:
        results['variants'] = variants
    return results
