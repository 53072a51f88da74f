"""The plan of the robots page (``config/robots_page.yaml``, docs/robots.md): its checked
``full`` or ``quick`` section and robots, each robot's facts and derived parameters as the
launcher derives them (``robot_info``), and the scenario documents of its runs: forces from its
mass, push times from its crawl cycle, step heights and distances from its leg length; and
per other gait of the plan (``gaits:``) its set-points (the trot's from a Froude number of the
leg length, the walking trot's from the crawl's) and runs timed in that gait's cycle.

Nothing here is robot-specific: every robot number comes from the plan file or the robot's
model and files."""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from pathlib import Path

import yaml

from replan_core.common.types import GRAVITY
from replan_experiments.plan import ExperimentError, variant
from replan_experiments.robot_info import RobotInfo

TOP_KEYS = {'profile', 'seed', 'parameters', 'robots', 'full', 'quick', 'gaits'}
ROBOT_KEYS = ('forward', 'lateral', 'yaw')
# Each test's keys, all required: a misspelt or missing one is an error, not a default.
TEST_KEYS = {
    'stand': {'scenario', 'duration', 'drift_from'},
    'walk': {'scenario', 'duration'},
    'response': {'scenario', 'segment_cycles', 'seeds', 'phases'},
    'push': {'levels', 'phases', 'push_duration', 'direction', 'first_push_cycles',
             'after_push_cycles'},
    'step_down': {'scenario', 'shares', 'step_x_legs', 'cross_legs', 'time_margin'},
}
# The other gaits' runs (``gaits.<name>.full`` and ``.quick``), in the gait's cycles: a walk
# forward then a stop (the standing after it), a walk sideways then turning, and the crawl's
# push and step down tests (step downs as a ladder: up to the first share not crossed).
GAIT_TEST_KEYS = {
    'walk': {'scenario', 'forward_cycles', 'steady_cycles', 'settle_s', 'quiet_s'},
    'turn': {'scenario', 'segment_cycles', 'steady_cycles'},
    'push': TEST_KEYS['push'],
    'step_down': TEST_KEYS['step_down'],
    'fast': {'scenario', 'froude', 'forward_cycles', 'steady_cycles'},
}
# Gait tests a gait may leave out: ``fast``, a walk forward from standing at a higher Froude
# number than the gait's set-point (how close each robot comes to it).
OPTIONAL_GAIT_TESTS = {'fast'}
# A gait's set-points from each robot: forward from the Froude number v^2 / (g l) of its leg
# length l (``froude``) or a multiple of its crawl forward set-point (``crawl_times``), one
# of the two; lateral = ``lateral_share`` x forward; yaw = forward / (``yaw_legs`` x l).
SETPOINT_KEYS = {'lateral_share', 'yaw_legs'}
FORWARD_RULES = ('froude', 'crawl_times')
_TEXT_KEYS = {'scenario'}
_LIST_KEYS = {'levels', 'shares', 'direction'}


@dataclass
class RobotsPlan:
    """One section of the plan file, checked."""

    source: str
    profile: str
    seed: int
    parameters: list[str]
    robots: dict[str, dict[str, float]]      # name -> {forward, lateral, yaw}
    tests: dict[str, dict]                   # TEST_KEYS name -> its settings
    # The other gaits: name -> {'setpoints': rule, 'tests': GAIT_TEST_KEYS name -> settings}.
    gaits: dict[str, dict] = field(default_factory=dict)
    gait: str | None = None      # a gait's plan (``gait_plan``): the gait its documents run


def _fail(source: str, key: str, problem: str) -> ExperimentError:
    return ExperimentError(f'{source}: {key}: {problem}')


def _number(value, source: str, key: str, positive: bool = True) -> float:
    if (not isinstance(value, (int, float)) or isinstance(value, bool)
            or not math.isfinite(value) or (positive and value <= 0)):
        raise _fail(source, key, f'expected a {"positive " if positive else ""}number, '
                                 f'got {value!r}')
    return float(value)


def _whole(value, source: str, key: str, least: int) -> int:
    if not isinstance(value, int) or isinstance(value, bool) or value < least:
        raise _fail(source, key, f'expected a whole number >= {least}, got {value!r}')
    return value


def _check_test(name: str, cfg, source: str, where: str, known: dict | None = None) -> dict:
    if not isinstance(cfg, dict):
        raise _fail(source, where, 'must be a mapping')
    keys = (known or TEST_KEYS)[name]
    if set(cfg) - keys:
        raise _fail(source, f'{where}.{sorted(set(cfg) - keys)[0]}',
                    f'unknown key (known: {", ".join(sorted(keys))})')
    if keys - set(cfg):
        raise _fail(source, f'{where}.{sorted(keys - set(cfg))[0]}', 'missing')
    out = {}
    for key, value in cfg.items():
        at = f'{where}.{key}'
        if key in _TEXT_KEYS:
            if not isinstance(value, str) or not value:
                raise _fail(source, at, f'expected a scenario name, got {value!r}')
            out[key] = value
        elif key in _LIST_KEYS:
            if not isinstance(value, list) or not value:
                raise _fail(source, at, f'expected a non-empty list of numbers, got {value!r}')
            out[key] = [_number(v, source, f'{at}[{i}]', positive=key != 'direction')
                        for i, v in enumerate(value)]
        elif key in ('phases', 'segment_cycles', 'forward_cycles', 'steady_cycles'):
            # A response needs a first cycle and later ones to tell rise from steady state.
            out[key] = _whole(value, source, at,
                              2 if key in ('segment_cycles', 'forward_cycles') else 1)
        elif key == 'seeds':
            # The sim's noise seeds of the response runs: one run each.
            if not isinstance(value, list) or not value:
                raise _fail(source, at, f'expected a non-empty list of seeds, got {value!r}')
            out[key] = [_whole(v, source, f'{at}[{i}]', 0) for i, v in enumerate(value)]
            if len(set(out[key])) != len(out[key]):
                raise _fail(source, at, 'each seed once')
        elif key == 'drift_from':
            out[key] = _number(value, source, at, positive=False)
            if out[key] < 0:
                raise _fail(source, at, f'expected a number >= 0, got {value!r}')
        else:
            out[key] = _number(value, source, at)
    for key in ('levels', 'shares'):
        if key in out and out[key] != sorted(set(out[key])):
            raise _fail(source, f'{where}.{key}', 'must rise, each value once')
    if 'direction' in out and (len(out['direction']) != 2 or not any(out['direction'])):
        raise _fail(source, f'{where}.direction', 'expected [x, y], not both zero')
    if name == 'stand' and out['drift_from'] >= out['duration']:
        raise _fail(source, f'{where}.drift_from', 'must come before the duration')
    cycles = out.get('forward_cycles', out.get('segment_cycles'))
    if 'steady_cycles' in out and out['steady_cycles'] >= cycles:
        raise _fail(source, f'{where}.steady_cycles', 'must be fewer than the segment\'s '
                                                      f'cycles ({cycles})')
    return out


def _check_gait_tests(tests, source: str, where: str) -> dict[str, dict]:
    if not isinstance(tests, dict):
        raise _fail(source, where, 'must be a mapping')
    unknown = set(tests) - set(GAIT_TEST_KEYS)
    missing = set(GAIT_TEST_KEYS) - OPTIONAL_GAIT_TESTS - set(tests)
    if unknown or missing:
        wrong = sorted(unknown | missing)[0]
        raise _fail(source, f'{where}.{wrong}', 'unknown test' if wrong in tests else 'missing')
    return {n: _check_test(n, c, source, f'{where}.{n}', GAIT_TEST_KEYS)
            for n, c in tests.items()}


def _check_gaits(gaits, source: str, section: str) -> dict[str, dict]:
    """The plan's ``gaits``: per gait its set-point rule and its ``section``'s tests."""
    if gaits is None:
        return {}
    if not isinstance(gaits, dict):
        raise _fail(source, 'gaits', 'expected a mapping of gait names to their runs')
    out = {}
    for name, cfg in gaits.items():
        where = f'gaits.{name}'
        if name == 'crawl':
            raise _fail(source, where, 'the crawl is the plan\'s own (robots:, full:, quick:)')
        if not isinstance(cfg, dict):
            raise _fail(source, where, 'expected {setpoints, full, quick}')
        if set(cfg) != {'setpoints', 'full', 'quick'}:
            wrong = sorted(set(cfg) ^ {'setpoints', 'full', 'quick'})[0]
            raise _fail(source, f'{where}.{wrong}', 'unknown key' if wrong in cfg else 'missing')
        rule = cfg['setpoints']
        at = f'{where}.setpoints'
        if not isinstance(rule, dict):
            raise _fail(source, at, 'must be a mapping')
        forward = [k for k in FORWARD_RULES if k in rule]
        if len(forward) != 1:
            raise _fail(source, at, f'expected one of {", ".join(FORWARD_RULES)}, '
                                    f'got {forward or "none"}')
        keys = SETPOINT_KEYS | set(forward)
        if set(rule) != keys:
            wrong = sorted(set(rule) ^ keys)[0]
            raise _fail(source, f'{at}.{wrong}', 'unknown key' if wrong in rule else 'missing')
        checked = {k: _number(v, source, f'{at}.{k}') for k, v in rule.items()}
        # Both sections checked: a mistake in the other is found before the page it makes.
        both = {sec: _check_gait_tests(cfg[sec], source, f'{where}.{sec}')
                for sec in ('full', 'quick')}
        out[str(name)] = {'setpoints': checked, 'tests': both[section]}
    return out


def load_robots_plan(path: Path, quick: bool = False, only: list[str] | None = None
                     ) -> RobotsPlan:
    """The ``full`` or ``quick`` section of the plan file ``path``, for the robots ``only``
    (all when empty). ExperimentError (one line naming the file and the key) if anything is
    missing, misspelt or of the wrong kind."""
    source = str(path)
    try:
        doc = yaml.safe_load(Path(path).read_text())
    except (OSError, yaml.YAMLError) as err:
        raise ExperimentError(f'cannot read {source}: {err}') from err
    if not isinstance(doc, dict):
        raise ExperimentError(f'{source}: the top level must be a mapping')
    if set(doc) - TOP_KEYS:
        raise _fail(source, sorted(set(doc) - TOP_KEYS)[0],
                    f'unknown key (known: {", ".join(sorted(TOP_KEYS))})')
    profile = doc.get('profile', 'realistic')
    if not isinstance(profile, str) or not profile:
        raise _fail(source, 'profile', f'expected a profile name, got {profile!r}')
    seed = _whole(doc.get('seed', 0), source, 'seed', 0)
    parameters = doc.get('parameters') or []
    if not isinstance(parameters, list):
        raise _fail(source, 'parameters', 'expected a list of node.key names')
    for i, name in enumerate(parameters):
        if not isinstance(name, str) or '.' not in name:
            raise _fail(source, f'parameters[{i}]', f'expected node.key, got {name!r}')
    robots = doc.get('robots')
    if not isinstance(robots, dict) or not robots:
        raise _fail(source, 'robots', 'expected a mapping of robot names to set-points')
    checked: dict[str, dict[str, float]] = {}
    for name, setpoints in robots.items():
        where = f'robots.{name}'
        if not isinstance(setpoints, dict):
            raise _fail(source, where, 'expected {forward, lateral, yaw}')
        if set(setpoints) != set(ROBOT_KEYS):
            wrong = sorted(set(setpoints) ^ set(ROBOT_KEYS))[0]
            raise _fail(source, f'{where}.{wrong}',
                        'unknown key' if wrong in setpoints else 'missing')
        checked[str(name)] = {k: _number(setpoints[k], source, f'{where}.{k}')
                              for k in ROBOT_KEYS}
    unknown = [name for name in only or [] if name not in checked]
    if unknown:
        raise ExperimentError(f'--robot {unknown[0]}: not in {source} '
                              f'(there: {", ".join(checked)})')
    section = 'quick' if quick else 'full'
    tests = doc.get(section)
    if not isinstance(tests, dict):
        raise _fail(source, section, 'missing, or not a mapping')
    if set(tests) != set(TEST_KEYS):
        wrong = sorted(set(tests) ^ set(TEST_KEYS))[0]
        raise _fail(source, f'{section}.{wrong}', 'unknown test' if wrong in tests
                    else 'missing')
    return RobotsPlan(source, profile, seed, list(parameters),
                      {n: s for n, s in checked.items() if not only or n in only},
                      {n: _check_test(n, c, source, f'{section}.{n}') for n, c in tests.items()},
                      _check_gaits(doc.get('gaits'), source, section))


def listed_parameters(info: RobotInfo, plan: RobotsPlan) -> dict[str, object]:
    """The plan's ``parameters`` of ``info``; ExperimentError naming the one that no node has."""
    out = {}
    for i, name in enumerate(plan.parameters):
        try:
            out[name] = info.value(name)
        except KeyError:
            raise _fail(plan.source, f'parameters[{i}]', f'no node parameter {name}') from None
    return out


# -- the scenario documents of one robot ----------------------------------------------------


def _robot_doc(doc: dict, info: RobotInfo, kind: str, gait: str | None = None) -> dict:
    """The robot's document named ``<robot>_<kind>``; in a gait's plan it runs the gait
    (top-level ``gait:``) and is named ``<robot>_<gait>_<kind>`` (the crawl's documents, and
    so their run keys, are as before gaits had plans)."""
    doc['robot'] = info.name
    doc['name'] = f'{info.name}_{kind}' if gait is None else f'{info.name}_{gait}_{kind}'
    if gait is not None:
        doc['gait'] = gait
    return doc


def walk_start(base: dict) -> float:
    """Sim time of the base scenario's first set-point (the walk's start)."""
    return float(next(e['t'] for e in base.get('events') or [] if 'cmd_vel' in e))


def stand_doc(base: dict, info: RobotInfo, plan: RobotsPlan) -> dict:
    cfg = plan.tests['stand']
    return _robot_doc(variant(base, world=plan.profile, seed=plan.seed,
                              duration=cfg['duration']), info, 'stand', plan.gait)


def walk_doc(base: dict, info: RobotInfo, plan: RobotsPlan, axis: str) -> dict:
    """A walk from standing at the robot's ``axis`` set-point (forward, lateral or yaw)."""
    setpoint = [0.0, 0.0, 0.0]
    setpoint[ROBOT_KEYS.index(axis)] = plan.robots[info.name][axis]
    return _robot_doc(variant(base, world=plan.profile, seed=plan.seed,
                              duration=plan.tests['walk']['duration'],
                              setpoint=tuple(setpoint)), info, axis, plan.gait)


def response_doc(base: dict, info: RobotInfo, plan: RobotsPlan, seed: int,
                 phase: int = 0) -> dict:
    """From standing, the robot's forward set-point, then its lateral one, then its yaw one,
    each for ``segment_cycles`` of its crawl cycles from the base scenario's first
    set-point, with the sim's noise seed ``seed`` (one of ``response.seeds``). ``phase`` (0 to
    ``response.phases`` - 1) delays the two changes by that many ``phases``-th of a crawl
    cycle: each phase, another leg is the first to land after a change and to re-plan for it.
    The page's seed at phase 0 keeps the run's name of a single response run."""
    cfg = plan.tests['response']
    if not 0 <= phase < cfg['phases']:
        raise ExperimentError(f'response phase {phase} is not one of 0-{cfg["phases"] - 1}')
    span = cfg['segment_cycles'] * info.cycle_s
    start = walk_start(base)
    delay = phase * info.cycle_s / cfg['phases']
    events = []
    for k, axis in enumerate(ROBOT_KEYS):
        setpoint = [0.0, 0.0, 0.0]
        setpoint[k] = float(plan.robots[info.name][axis])
        events.append({'t': round(start + k * span + (delay if k else 0.0), 4),
                       'cmd_vel': setpoint})
    doc = variant(base, world=plan.profile, seed=seed,
                  duration=round(start + len(ROBOT_KEYS) * span + delay, 4))
    doc['events'] = events
    name = ('response' + ('' if seed == plan.seed else f'_seed{seed}')
            + (f'_phase{phase}' if phase else ''))
    return _robot_doc(doc, info, name, plan.gait)


def push_times(base: dict, info: RobotInfo, plan: RobotsPlan) -> list[float]:
    """The push times: ``phases`` spread over one crawl cycle of the robot, the first
    ``first_push_cycles`` cycles after the walk starts."""
    cfg, cycle = plan.tests['push'], info.cycle_s
    first = walk_start(base) + cfg['first_push_cycles'] * cycle
    return [round(first + cycle * k / cfg['phases'], 4) for k in range(cfg['phases'])]


def push_force(info: RobotInfo, plan: RobotsPlan, dv: float) -> tuple[float, float, float]:
    """The force (N) of a push of ``push_duration`` that gives the robot's free body (its
    model's mass) the velocity change ``dv`` (m/s) along ``direction``."""
    cfg = plan.tests['push']
    x, y = cfg['direction']
    norm = math.hypot(x, y)
    magnitude = info.mass_kg * dv / cfg['push_duration']
    return (magnitude * x / norm, magnitude * y / norm, 0.0)


def push_doc(base: dict, info: RobotInfo, plan: RobotsPlan, dv: float, t: float) -> dict:
    """Walking forward at the set-point, one lateral push of ``dv`` at ``t``."""
    cfg = plan.tests['push']
    duration = t + cfg['push_duration'] + cfg['after_push_cycles'] * info.cycle_s
    doc = variant(base, world=plan.profile, seed=plan.seed, duration=round(duration, 4),
                  setpoint=(plan.robots[info.name]['forward'], 0.0, 0.0),
                  push=(t, push_force(info, plan, dv), cfg['push_duration']))
    return _robot_doc(doc, info, f'push_{dv:g}', plan.gait)


def step_geometry(info: RobotInfo, plan: RobotsPlan, share: float) -> dict:
    """The step down of ``share`` of the leg length: its height, its edge's x and the x the
    base must pass to have crossed it (in leg lengths of the plan)."""
    cfg, leg = plan.tests['step_down'], info.leg_length_m
    edge = cfg['step_x_legs'] * leg
    return {'share': share, 'height_m': round(share * leg, 4), 'edge_x_m': round(edge, 4),
            'cross_x_m': round(edge + cfg['cross_legs'] * leg, 4)}


def step_doc(base: dict, info: RobotInfo, plan: RobotsPlan, share: float) -> dict:
    """Walking forward at the set-point onto a step down the planner does not know, long
    enough to cross it at ``time_margin`` times the time the set-point takes."""
    cfg = plan.tests['step_down']
    geometry = step_geometry(info, plan, share)
    speed = plan.robots[info.name]['forward']
    duration = walk_start(base) + cfg['time_margin'] * geometry['cross_x_m'] / speed
    terrain = {'type': 'step_down', 'step_height': geometry['height_m'],
               'step_x': geometry['edge_x_m']}
    doc = variant(base, world=plan.profile, seed=plan.seed, terrain=terrain,
                  duration=round(duration, 2), setpoint=(speed, 0.0, 0.0))
    return _robot_doc(doc, info, f'step_down_{share:g}', plan.gait)


# -- the other gaits ---------------------------------------------------------------------------


def froude_number(speed: float, leg_length: float) -> float:
    """v^2 / (g l): the speed relative to the leg length, the same for geometrically similar
    robots walking alike."""
    return speed * speed / (GRAVITY * leg_length)


def froude_speed(froude: float, leg_length: float) -> float:
    """m/s, the speed of Froude number ``froude`` for a leg of ``leg_length`` m:
    sqrt(froude g l), ``froude_number``'s inverse."""
    return math.sqrt(froude * GRAVITY * leg_length)


def gait_setpoints(rule: dict, info: RobotInfo, crawl_forward: float) -> dict[str, float]:
    """A robot's set-points in a gait from the plan's rule (``SETPOINT_KEYS``,
    ``FORWARD_RULES``): forward at the Froude number ``froude`` of its leg length, or
    ``crawl_times`` its crawl forward set-point; lateral a share of it; yaw forward over
    ``yaw_legs`` leg lengths. m/s and rad/s to the millimetre (milliradian)."""
    leg = info.leg_length_m
    forward = (froude_speed(rule['froude'], leg) if 'froude' in rule
               else rule['crawl_times'] * crawl_forward)
    return {'forward': round(forward, 3), 'lateral': round(rule['lateral_share'] * forward, 3),
            'yaw': round(forward / (rule['yaw_legs'] * leg), 3)}


def gait_plan(plan: RobotsPlan, gait: str, infos: dict[str, RobotInfo]) -> RobotsPlan:
    """The plan of ``gait``'s runs: its set-points per robot of ``infos`` (from the robot's
    leg length and crawl set-point) and its tests, so the crawl's document builders
    (``push_doc``, ``step_doc``) make the gait's documents."""
    cfg = plan.gaits[gait]
    robots = {name: gait_setpoints(cfg['setpoints'], infos[name], plan.robots[name]['forward'])
              for name in plan.robots}
    return replace(plan, robots=robots, tests=cfg['tests'], gaits={}, gait=gait)


def gait_walk_doc(base: dict, info: RobotInfo, plan: RobotsPlan) -> dict:
    """A gait's plan: from standing the robot's forward set-point for ``forward_cycles`` of
    the gait's cycles from the base scenario's first set-point, then zero; the run ends
    ``settle_s`` + ``quiet_s`` after the gait's ``idle_after`` from the stop."""
    start = walk_start(base)
    stop = gait_stop(info, plan, start)
    window = quiet_window(info, plan, start)
    doc = variant(base, world=plan.profile, seed=plan.seed, duration=window[1])
    doc['events'] = [{'t': start, 'cmd_vel': [float(plan.robots[info.name]['forward']), 0.0,
                                              0.0]},
                     {'t': stop, 'cmd_vel': [0.0, 0.0, 0.0]}]
    return _robot_doc(doc, info, 'walk', plan.gait)


def fast_setpoint(info: RobotInfo, plan: RobotsPlan) -> float:
    """m/s, the forward set-point of the gait's ``fast`` test: the speed of its Froude number
    for the robot's leg length, to the millimetre."""
    return round(froude_speed(plan.tests['fast']['froude'], info.leg_length_m), 3)


def gait_fast_doc(base: dict, info: RobotInfo, plan: RobotsPlan) -> dict:
    """A gait's plan at the ``fast`` test's Froude number: from standing forward at
    ``fast_setpoint`` for ``forward_cycles`` of the gait's cycles (the run's end)."""
    start = walk_start(base)
    duration = round(start + plan.tests['fast']['forward_cycles'] * info.cycle_s, 4)
    doc = variant(base, world=plan.profile, seed=plan.seed, duration=duration)
    doc['events'] = [{'t': start, 'cmd_vel': [fast_setpoint(info, plan), 0.0, 0.0]}]
    return _robot_doc(doc, info, 'fast', plan.gait)


def gait_stop(info: RobotInfo, plan: RobotsPlan, start: float) -> float:
    """The stop of ``gait_walk_doc`` whose walk starts at ``start``."""
    return round(start + plan.tests['walk']['forward_cycles'] * info.cycle_s, 4)


def quiet_window(info: RobotInfo, plan: RobotsPlan, start: float | None = None
                 ) -> tuple[float, float]:
    """The span after ``gait_walk_doc``'s stop in which the robot must stand still: from the
    gait's ``idle_after`` plus ``settle_s`` after the stop, ``quiet_s`` long (its end is the
    run's). ``start``: the walk's start (default 0.5 s, the walk scenarios')."""
    cfg = plan.tests['walk']
    stop = gait_stop(info, plan, 0.5 if start is None else start)
    begin = stop + float(info.value('gait.idle_after')) + cfg['settle_s']
    return round(begin, 4), round(begin + cfg['quiet_s'], 4)


def gait_turn_doc(base: dict, info: RobotInfo, plan: RobotsPlan) -> dict:
    """A gait's plan: from standing the robot's lateral set-point, then its yaw one, each for
    ``segment_cycles`` of the gait's cycles."""
    span = plan.tests['turn']['segment_cycles'] * info.cycle_s
    start = walk_start(base)
    setpoints = plan.robots[info.name]
    doc = variant(base, world=plan.profile, seed=plan.seed, duration=round(start + 2 * span, 4))
    doc['events'] = [{'t': start, 'cmd_vel': [0.0, float(setpoints['lateral']), 0.0]},
                     {'t': round(start + span, 4), 'cmd_vel': [0.0, 0.0,
                                                               float(setpoints['yaw'])]}]
    return _robot_doc(doc, info, 'turn', plan.gait)
