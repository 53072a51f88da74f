"""The plan of the robots page (``config/robots_page.yaml``, docs/robots.md): its checked
``full`` or ``quick`` section and robots, each robot's facts and derived parameters as the
launcher derives them (``robot_info``), and the scenario documents of its runs: forces from its
mass, push times from its crawl cycle, step heights and distances from its leg length.

Nothing here is robot-specific: every robot number comes from the plan file or the robot's
model and files."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import yaml

from replan_ros.experiments.plan import ExperimentError, variant

TOP_KEYS = {'profile', 'seed', 'parameters', 'robots', 'full', 'quick'}
ROBOT_KEYS = ('forward', 'lateral', 'yaw')
# Each test's keys, all required: a misspelt or missing one is an error, not a default.
TEST_KEYS = {
    'stand': {'scenario', 'duration', 'drift_from'},
    'walk': {'scenario', 'duration'},
    'response': {'scenario', 'segment_cycles'},
    'push': {'levels', 'phases', 'push_duration', 'direction', 'first_push_cycles',
             'after_push_cycles'},
    'step_down': {'scenario', 'shares', 'step_x_legs', 'cross_legs', 'time_margin'},
}
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


@dataclass
class RobotInfo:
    """A robot as a run on the plan's profile gets it."""

    name: str
    mass_kg: float               # the model's (robot_facts), without the profile's payload
    leg_length_m: float
    standing_height_m: float
    com_height_m: float
    min_joint_inertia: float     # kg m^2
    values: dict = field(default_factory=dict)   # node -> {key: value}, as the nodes get them

    def value(self, name: str):
        """A node parameter ``node.key`` as the nodes get it; KeyError if there is none."""
        node, _, key = name.partition('.')
        return self.values[node][key]

    @property
    def cycle_s(self) -> float:
        """The crawl cycle: four swings, each with its four-feet phase."""
        return 4.0 * (float(self.value('gait.swing_duration'))
                      + float(self.value('gait.four_feet_duration')))


def _fail(source: str, key: str, problem: str) -> ExperimentError:
    return ExperimentError(f'{source}: {key}: {problem}')


def _number(value, source: str, key: str, positive: bool = True) -> float:
    if (not isinstance(value, (int, float)) or isinstance(value, bool)
            or not math.isfinite(value) or (positive and value <= 0)):
        raise _fail(source, key, f'expected a {"positive " if positive else ""}number, '
                                 f'got {value!r}')
    return float(value)


def _check_test(name: str, cfg, source: str, where: str) -> dict:
    if not isinstance(cfg, dict):
        raise _fail(source, where, 'must be a mapping')
    keys = TEST_KEYS[name]
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
        elif key in ('phases', 'segment_cycles'):
            # A response needs a first cycle and later ones to tell rise from steady state.
            least = 2 if key == 'segment_cycles' else 1
            if not isinstance(value, int) or isinstance(value, bool) or value < least:
                raise _fail(source, at, f'expected a whole number >= {least}, got {value!r}')
            out[key] = value
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
    seed = doc.get('seed', 0)
    if not isinstance(seed, int) or isinstance(seed, bool) or seed < 0:
        raise _fail(source, 'seed', f'expected a whole number >= 0, got {seed!r}')
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
                      {n: _check_test(n, c, source, f'{section}.{n}') for n, c in tests.items()})


def robot_info(config_dir: Path, robot: str, profile: str) -> RobotInfo:
    """The robot's facts (``robot_facts`` on its model) and every node parameter as a run on
    ``profile`` gives it (the launcher's derivation: node files, profile, the scaling rules,
    the robot file's own parameters). ConfigError for an unknown robot or a bad file."""
    from replan_core.robot.robot_file import robot_facts  # pinocchio: only here
    from replan_ros.launch.param_files import check_run_files, profile_file, robot_parameters

    profile_path = profile_file(config_dir, profile)
    layer = robot_parameters(config_dir, robot, profile_path)
    values = check_run_files(config_dir, [profile_path, layer.derived, layer.overrides]).values
    facts = robot_facts(layer.spec)
    return RobotInfo(robot, facts.mass, facts.leg_length, facts.standing_height,
                     facts.com_height, facts.min_joint_inertia, values)


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


def _robot_doc(doc: dict, info: RobotInfo, kind: str) -> dict:
    doc['robot'] = info.name
    doc['name'] = f'{info.name}_{kind}'
    return doc


def walk_start(base: dict) -> float:
    """Sim time of the base scenario's first set-point (the walk's start)."""
    return float(next(e['t'] for e in base.get('events') or [] if 'cmd_vel' in e))


def stand_doc(base: dict, info: RobotInfo, plan: RobotsPlan) -> dict:
    cfg = plan.tests['stand']
    return _robot_doc(variant(base, world=plan.profile, seed=plan.seed,
                              duration=cfg['duration']), info, 'stand')


def walk_doc(base: dict, info: RobotInfo, plan: RobotsPlan, axis: str) -> dict:
    """A walk from standing at the robot's ``axis`` set-point (forward, lateral or yaw)."""
    setpoint = [0.0, 0.0, 0.0]
    setpoint[ROBOT_KEYS.index(axis)] = plan.robots[info.name][axis]
    return _robot_doc(variant(base, world=plan.profile, seed=plan.seed,
                              duration=plan.tests['walk']['duration'],
                              setpoint=tuple(setpoint)), info, axis)


def response_doc(base: dict, info: RobotInfo, plan: RobotsPlan) -> dict:
    """From standing, the robot's forward set-point, then its lateral one, then its yaw one,
    each for ``segment_cycles`` of its crawl cycles from the base scenario's first
    set-point."""
    span = plan.tests['response']['segment_cycles'] * info.cycle_s
    start = walk_start(base)
    events = []
    for k, axis in enumerate(ROBOT_KEYS):
        setpoint = [0.0, 0.0, 0.0]
        setpoint[k] = float(plan.robots[info.name][axis])
        events.append({'t': round(start + k * span, 4), 'cmd_vel': setpoint})
    doc = variant(base, world=plan.profile, seed=plan.seed,
                  duration=round(start + len(ROBOT_KEYS) * span, 4))
    doc['events'] = events
    return _robot_doc(doc, info, 'response')


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
    return _robot_doc(doc, info, f'push_{dv:g}')


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
    return _robot_doc(doc, info, f'step_down_{share:g}')
