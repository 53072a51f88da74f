"""The experiment plan (``config/experiments.yaml``): its checked ``full`` or ``quick`` section,
the number of runs it makes, the node settings the experiments derive from, and ``variant``,
the scenario document of one run."""

from __future__ import annotations

import copy
import hashlib
import json
from pathlib import Path

import yaml

from replan_experiments.robot_info import robot_info
from replan_experiments.stats import BINARY_TESTS, TESTS, VARIANT_WHERE
from replan_ros.launch.param_files import check_run_files, gait_parameters

# The keys each experiment reads: a misspelt one in the plan file is an error, not a default.
PLAN_KEYS = {
    'velocity_changes': {'scenarios', 'seeds', 'prompt_steps', 'duration', 'steady_tolerance'},
    'lateral_push': {'scenario', 'phases', 'first_push', 'after_push', 'push_duration',
                     'direction', 'first_impulse', 'max_impulse', 'probes', 'seeds', 'settings',
                     'duration', 'second_push'},
    'replan_window': {'scenario', 'windows', 'seeds', 'setpoints', 'duration'},
    'haptic': {'scenario', 'seeds', 'duration', 'durations', 'terrains'},
    'velocity_term': {'scenario', 'seeds', 'setpoints', 'duration', 'step_scenario',
                      'motion_after', 'params'},
    'sustained_push': {'scenario', 'push_start', 'push_duration', 'forces', 'direction',
                       'horizon', 'duration', 'seeds', 'settings'},
    'large_push': {'scenario', 'phases', 'first_push', 'push_duration', 'impulse', 'direction',
                   'horizon', 'seeds', 'settings'},
    'qp_timing': {'replans', 'formulations'},
    'fastest_crawl': {'scenario', 'setpoints', 'velocity_clamp', 'seed'},
    'ideal_world': {'replan_window', 'haptic', 'velocity_changes', 'lateral_push'},
}
EXPERIMENTS = tuple(PLAN_KEYS)

# The claims that pre-register one primary test (``primary`` in their section) and the measures
# each one's code computes (its rows' keys), of which the primary measure is one.
PRIMARY_MEASURES = {
    'velocity_changes': {'rise_time_s', 'rise_steps', 'settle_time_s', 'settle_steps',
                         'steady_error_mps', 'fell'},
    'lateral_push': {'survived_ns'},
    'replan_window': {'steady_error_mps', 'linear_error_mps', 'cop_margin_p5_m',
                      'cop_zmp_deviation_rms_m', 'fell'},
    'haptic': {'pitch_peak_max_deg', 'pitch_peak_mean_deg', 'touchdown_timing_median_abs_s',
               'touchdown_timing_mean_s', 'fell', 'crossed'},
    'velocity_term': {'rise_time_s', 'swing_travel_share', 'backward_travel_m',
                      'stride_length_m', 'fell'},
    'sustained_push': {'capture_margin_p5_m', 'capture_margin_min_m', 'trunk_shift_max_m',
                       'foot_offset_change_m', 'fell'},
    'large_push': {'capture_margin_p5_m', 'capture_margin_min_m', 'trunk_shift_max_m',
                   'foot_offset_change_m', 'fell'},
}
for _name in PRIMARY_MEASURES:
    PLAN_KEYS[_name] = PLAN_KEYS[_name] | {'primary'}
# A claim again on another robot, gait or set-point scale: a section of its own name with
# ``experiment`` (the claim it repeats), its keys and these. Not the claims whose pushes are
# timed by the crawl's cycle (lateral_push, large_push).
VARIANT_KEYS = {'experiment', *VARIANT_WHERE}
VARIANT_EXPERIMENTS = ('velocity_changes', 'replan_window', 'haptic', 'velocity_term',
                       'sustained_push')
# A primary block: every key below is required, one of ``compare`` (two settings, treatment
# minus control) or ``against`` (one setting against a fixed bound) too; ``where`` and
# ``pair_by`` select and pair the runs; ``baseline`` (with ``compare``) makes each run's
# measure a difference from its setting's run that matches it (a difference in differences).
PRIMARY_REQUIRED = {'measure', 'unit', 'direction', 'smallest_effect', 'reason', 'test', 'n',
                    'pilot_seeds'}
PRIMARY_KEYS = PRIMARY_REQUIRED | {'compare', 'against', 'where', 'pair_by', 'baseline'}
# Keys without a default, and what each says: a plan without one is refused.
REQUIRED_KEYS = {
    'velocity_changes': {'steady_tolerance': 'the share of the set-point speed the steady '
                                             'state must be in'},
    'velocity_term': {'motion_after': 's into a straight walk where its trunk travel is '
                                      'measured from'},
}


class ExperimentError(ValueError):
    """A plan file or option that cannot be run, with the reason."""


def experiment_of(name: str, cfg) -> str:
    """The experiment section ``name`` runs: its own name, or a variant's ``experiment``."""
    if isinstance(cfg, dict) and 'experiment' in cfg:
        return str(cfg['experiment'])
    return name


def variant_of(cfg: dict) -> dict:
    """A variant section's ``robot``, ``gait`` and ``setpoint_scale`` (those it sets)."""
    return {k: cfg[k] for k in VARIANT_WHERE if k in cfg}


def phase_impulses(impulse, phases: int) -> list[float]:
    """The large push's impulse at each of ``phases`` phases (N s): ``impulse`` is one figure
    for all, or a list of one per phase; ExperimentError if it is neither or not positive."""
    values = impulse if isinstance(impulse, list) else [impulse] * phases
    try:
        values = [float(v) for v in values]
    except (TypeError, ValueError):
        values = []
    if len(values) != phases or not all(v > 0 for v in values):
        raise ExperimentError(f'large_push.impulse: one positive figure (N s) or a list of '
                              f'{phases} (one per phase), got {impulse!r}')
    return values



def parse_settings(items: list[str]) -> dict[str, dict]:
    """``--set NODE.KEY=VALUE`` items (VALUE read as YAML) as scenario ``params``: node ->
    {key: value}. ExperimentError for an item that is not of that form or a key given twice;
    whether the node has the key is the launcher's check, at the run's start."""
    params: dict[str, dict] = {}
    for item in items:
        name, sep, text = item.partition('=')
        node, dot, key = name.partition('.')
        if not (sep and dot and node and key and text.strip()):
            raise ExperimentError(f'--set {item!r}: expected NODE.KEY=VALUE')
        try:
            value = yaml.safe_load(text)
        except yaml.YAMLError as err:
            raise ExperimentError(f'--set {item!r}: {err}') from err
        if key in params.get(node, {}):
            raise ExperimentError(f'--set {name}: given twice')
        params.setdefault(node, {})[key] = value
    return params

def variant(base: dict, *, params: dict | None = None,
            world: str = 'realistic', seed: int | None = None, terrain: dict | None = None,
            setpoint: tuple[float, float, float] | None = None, duration: float | None = None,
            push: tuple[float, tuple[float, float, float], float] | None = None,
            pushes: tuple = ()) -> dict:
    """A copy of scenario ``base`` with the experiment's changes: parameter overrides (per
    node), the world profile, the seed (sim ``noise_seed``; the terrain seed too), the terrain,
    the first set-point, the duration and pushes (t, force, duration): ``push`` and each of
    ``pushes``."""
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
    for t, force, length in ([push] if push is not None else []) + list(pushes):
        events.append({'t': round(float(t), 4), 'push': {
            'force': [round(float(f), 4) for f in force], 'duration': float(length)}})
    doc['events'] = events
    return doc


def planned_runs(plan: dict, selected: list[str]) -> int:
    """Upper bound of the runs of the ``selected`` experiments of ``plan`` (a run shared by two
    experiments counted twice)."""
    n = 0
    for section in selected:
        cfg = plan[section]
        name = experiment_of(section, cfg)
        if name == 'velocity_changes':
            n += len(cfg['scenarios']) * len(cfg['seeds'])
        elif name == 'lateral_push':
            n += (len(cfg['settings']) * int(cfg['phases']) * len(cfg['seeds'])
                  * (int(cfg['probes']) + bool(cfg.get('second_push'))))
        elif name == 'replan_window':
            n += len(cfg['windows']) * len(cfg['seeds']) * len(cfg['setpoints'])
        elif name == 'haptic':
            n += 2 * len(cfg['terrains']) * len(cfg['seeds'])
        elif name == 'velocity_term':
            n += 2 * len(cfg['seeds']) * (len(cfg['setpoints']) + bool(cfg.get('step_scenario')))
        elif name == 'sustained_push':
            n += len(cfg['settings']) * len(cfg['seeds']) * len(cfg['forces'])
        elif name == 'large_push':
            n += len(cfg['settings']) * int(cfg['phases']) * len(cfg['seeds'])
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
    for name, cfg in plan.items():
        error = _section_error(name, cfg)
        if error:
            raise ExperimentError(f'{path}: {section}.{error}')
    entries = [(name, cfg) for name, cfg in plan.items()]
    entries += [(f'ideal_world.{k}', v) for k, v in (plan.get('ideal_world') or {}).items()]
    for where, entry in entries:
        name = where.split('.')[-1]             # ideal_world: the realistic keys
        if not isinstance(entry, dict):
            raise ExperimentError(f'{path}: {section}.{where} must be a mapping')
        keys = PLAN_KEYS.get(experiment_of(name, entry), set())
        if '.' not in where and name not in EXPERIMENTS:
            keys = keys | VARIANT_KEYS
        unknown = set(entry) - keys
        if unknown:
            raise ExperimentError(f'{path}: {section}.{where}: unknown keys {sorted(unknown)} '
                                  f'(known: {", ".join(sorted(keys))})')
    for name, cfg in plan.items():
        for key, meaning in REQUIRED_KEYS.get(experiment_of(name, cfg), {}).items():
            if key not in cfg:
                raise ExperimentError(f'{path}: {section}.{name}: {key} missing ({meaning})')
        experiment = experiment_of(name, cfg)
        if experiment in PRIMARY_MEASURES and 'primary' in cfg:
            error = primary_error(experiment, cfg)
            if error:
                raise ExperimentError(f'{path}: {section}.{name}.primary: {error}')
        if experiment == 'velocity_term' and cfg.get('params') is not None:
            shared = cfg['params']
            if not isinstance(shared, dict) or not all(isinstance(v, dict)
                                                       for v in shared.values()):
                raise ExperimentError(f'{path}: {section}.{name}.params: a mapping of node '
                                      'to parameters, e.g. {gait: {velocity_feedback_gain: 0.0}}')
            if 'velocity_weight' in (shared.get('mpc') or {}):
                raise ExperimentError(f'{path}: {section}.{name}.params: '
                                      'mpc.velocity_weight is what the two settings differ in')
    large = plan.get('large_push')
    if isinstance(large, dict):
        try:
            phase_impulses(large.get('impulse'), int(large.get('phases', 0)))
        except ExperimentError as err:
            raise ExperimentError(f'{path}: {section}.{err}') from err
        except (TypeError, ValueError) as err:
            raise ExperimentError(f'{path}: {section}.large_push.phases: a whole number, got '
                                  f'{large.get("phases")!r}') from err
    bad = set(only) - set(plan)
    if bad:
        raise ExperimentError(f'--only: {sorted(bad)} not in the {section} plan '
                              f'(there: {", ".join(plan)})')
    return plan, [name for name in plan if not only or name in only]


def _section_error(name: str, cfg) -> str | None:
    """What is wrong with plan section ``name`` as a section (an experiment, or a variant of
    one: ``VARIANT_KEYS``), in one line starting with its name, or None."""
    if not isinstance(cfg, dict):
        return f'{name} must be a mapping'
    if name in EXPERIMENTS:
        if set(cfg) & (VARIANT_KEYS - {'experiment'}) or 'experiment' in cfg:
            return (f'{name}: {", ".join(sorted(set(cfg) & VARIANT_KEYS))}: only a variant '
                    'section (a name of its own with experiment:) runs a claim elsewhere')
        return None
    experiment = cfg.get('experiment')
    if experiment is None:
        return (f'{name}: unknown experiment (known: {", ".join(EXPERIMENTS)}; a variant '
                'names the one it repeats with experiment:)')
    if experiment not in VARIANT_EXPERIMENTS:
        return (f'{name}.experiment: {experiment!r} cannot be repeated as a variant (one of '
                f'{", ".join(VARIANT_EXPERIMENTS)})')
    if not set(cfg) & set(VARIANT_WHERE):
        return f'{name}: a variant sets robot, gait or setpoint_scale'
    for key in ('robot', 'gait'):
        value = cfg.get(key)
        if key in cfg and not (isinstance(value, str) and value.replace('_', '').isalnum()):
            return f'{name}.{key}: a name of config/{key}s/, got {value!r}'
    if 'setpoint_scale' in cfg:
        scale = cfg['setpoint_scale']
        if isinstance(scale, bool) or not isinstance(scale, (int, float)) or not scale > 0:
            return f'{name}.setpoint_scale: a positive figure, got {scale!r}'
    return None


def primary_error(name: str, cfg: dict) -> str | None:
    """What is wrong with experiment ``name``'s primary block (``cfg['primary']``), in one
    line, or None."""
    block = cfg['primary']
    if not isinstance(block, dict):
        return 'must be a mapping'
    missing, unknown = PRIMARY_REQUIRED - set(block), set(block) - PRIMARY_KEYS
    if missing:
        return f'missing keys {sorted(missing)}'
    if unknown:
        return f'unknown keys {sorted(unknown)} (known: {", ".join(sorted(PRIMARY_KEYS))})'
    if ('compare' in block) == ('against' in block):
        return 'needs one of compare (two settings) or against (a fixed bound)'
    compare = block.get('compare')
    if compare is not None and (not isinstance(compare, dict)
                                or set(compare) != {'by', 'treatment', 'control'}):
        return 'compare: a mapping of by, treatment and control'
    baseline = block.get('baseline')
    if baseline is not None:
        if compare is None or block['test'] in BINARY_TESTS or not isinstance(baseline, dict) \
                or not baseline:
            return ('baseline: a mapping of run keys (e.g. force_n: 0.0), with compare and a '
                    'paired test of a measured figure')
        if compare['by'] in baseline:
            return f'baseline: {compare["by"]!r} is what the settings differ in (compare.by)'
    if block['measure'] not in PRIMARY_MEASURES[name]:
        return (f'measure: {block["measure"]!r} is not one the claim computes (known: '
                f'{", ".join(sorted(PRIMARY_MEASURES[name]))})')
    if block['direction'] not in ('higher', 'lower'):
        return f'direction: higher or lower, got {block["direction"]!r}'
    if block['test'] not in TESTS:
        return f'test: one of {", ".join(TESTS)}, got {block["test"]!r}'
    if (block['test'] in BINARY_TESTS) != (block['measure'] in ('fell', 'crossed')):
        return f'test: {block["test"]} does not fit measure {block["measure"]}'
    try:
        smallest = float(block['smallest_effect'])
    except (TypeError, ValueError):
        smallest = 0.0
    if not smallest > 0.0:
        return f'smallest_effect: a positive figure, got {block["smallest_effect"]!r}'
    seeds, pilot = list(cfg.get('seeds') or []), list(block['pilot_seeds'] or [])
    if block['n'] != len(seeds):
        return f'n: {block["n"]!r}, but the confirmatory seeds are {len(seeds)}'
    if set(seeds) & set(pilot):
        return f'pilot_seeds: {sorted(set(seeds) & set(pilot))} are confirmatory seeds too'
    return None


def primary_blocks(plan: dict) -> dict:
    """Per pre-registered claim of ``plan``, its primary block with its confirmatory
    ``seeds`` and, where the claim has them, the node ``params`` both its settings get and a
    variant's ``experiment``, ``robot``, ``gait`` and ``setpoint_scale`` (they define the
    comparison: changing them is a new pre-registration). The paper's claims first, then the
    variants in the plan's order."""
    names = [n for n in PRIMARY_MEASURES if isinstance(plan.get(n), dict)]
    names += [n for n, cfg in plan.items() if n not in EXPERIMENTS
              and experiment_of(n, cfg) in PRIMARY_MEASURES]
    return {name: {**plan[name]['primary'], 'seeds': list(plan[name].get('seeds') or []),
                   **({'params': plan[name]['params']} if plan[name].get('params') else {}),
                   **({'experiment': plan[name]['experiment'], **variant_of(plan[name])}
                      if name not in EXPERIMENTS else {})}
            for name in names if 'primary' in plan[name]}


def claim_hash(block: dict) -> str:
    """The hash of one claim's pre-registration: its primary block (measure, selection,
    direction, smallest effect, test, n, pilot seeds, baseline) with its confirmatory seeds,
    the ``reason`` text left out. A confirmatory run's key holds its claim's hash, so a claim
    pre-registered again gets runs of its own and the others keep theirs."""
    kept = {k: v for k, v in block.items() if k != 'reason'}
    return hashlib.sha1(json.dumps(kept, sort_keys=True, default=str).encode()).hexdigest()[:12]


def claim_hashes(plan: dict) -> dict[str, str]:
    """Per pre-registered claim of ``plan``, its ``claim_hash``."""
    return {name: claim_hash(block) for name, block in primary_blocks(plan).items()}


def plan_hash(plan: dict) -> str | None:
    """The hash of ``plan``'s whole pre-registration: of its claims' hashes; None without
    primary blocks. The one place both are computed: the confirmatory runs' keys and the page
    take them from here."""
    hashes = claim_hashes(plan)
    if not hashes:
        return None
    return hashlib.sha1(json.dumps(hashes, sort_keys=True).encode()).hexdigest()[:12]


def pilot_plan(plan: dict) -> dict:
    """``plan`` with each pre-registered claim on its pilot seeds and without its primary
    block: the pilot runs, which carry no plan hash and never enter a verdict."""
    out = copy.deepcopy(plan)
    for name in primary_blocks(plan):
        out[name]['seeds'] = list(out[name]['primary']['pilot_seeds'])
        del out[name]['primary']
    return out


def preregistration(plan: dict, plan_file: Path | str, role: str) -> dict:
    """What the page needs of the plan's pre-registration: its hash, the file, the call's
    ``role`` ('confirmatory', 'pilot' or 'quick'), the primary blocks and each claim's
    hash."""
    return {'hash': plan_hash(plan), 'file': str(plan_file), 'role': role,
            'claims': primary_blocks(plan), 'claim_hashes': claim_hashes(plan)}


def node_settings(config_dir: Path, robot: str | None = None) -> dict:
    """The node parameters the experiments derive from (the push phases from the crawl cycle)
    and the page's explanations quote, from the node files (the realistic profile does not
    change them), or with ``robot`` as the launcher derives them for it; ExperimentError if a
    file or key is missing."""
    try:
        if robot:
            values = robot_info(config_dir, robot, 'realistic').values
            gait, wbc = values['gait'], values['wbc']
        else:
            values = check_run_files(config_dir, [gait_parameters(config_dir, 'crawl')]).values
            gait, wbc = values['gait'], values['wbc']
        out = {'crawl_cycle_s': 4.0 * (float(gait['swing_duration'])
                                       + float(gait['four_feet_duration'])),
               'max_step_length_x_m': float(gait['max_step_length_x']),
               'max_extension_s': float(gait['max_extension']),
               'correction_threshold_m': float(gait['correction_threshold']),
               'touchdown_depth_m': float(wbc['touchdown_depth']),
               'haptic_velocity_mps': float(wbc['haptic_velocity']),
               # s, the sim's tick: how many ticks a run's bag holds (runs.bag_gaps)
               'control_period_s': float(yaml.safe_load((config_dir / 'sim.yaml').read_text())[
                   'sim']['ros__parameters']['control_period'])}
    except (OSError, KeyError, TypeError, ValueError, yaml.YAMLError) as err:
        raise ExperimentError(f'cannot read the gait, wbc and sim settings in {config_dir}: '
                              f'{err!r}') from err
    out['haptic_search_m'] = (out['touchdown_depth_m']
                              + out['haptic_velocity_mps'] * out['max_extension_s'])
    return out
