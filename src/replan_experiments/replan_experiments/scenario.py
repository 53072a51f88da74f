"""Run a scripted scenario headless and write the bag, metrics.json and plots.

    scripts/scenario.sh FILE.yaml [--out DIR] [--gui] [--quiet] [--repeat N] [--robot NAME|FILE]
                        [--gait NAME]

A scenario file (see config/scenarios/ and docs/usage.md, "Scenarios"):

    name: forward                       # optional, for the summary
    duration: 20.0                      # s of sim time
    profile: realistic                  # optional: realistic (default) | ideal | a YAML file
    robot: hyq                          # optional: a name of config/robots/ (default hyq) or
                                        #   a robot file (docs/robot_files.md)
    gait: crawl                         # optional: a name of config/gaits/ (default crawl)
    terrain: flat                       # flat | step_up | step_down | rough, or a mapping
                                        #   {type: step_up, <sim terrain parameters>};
                                        #   the only place for the terrain (a terrain key
                                        #   under params: is refused)
    params:                             # parameter overrides per node (as in config/<node>.yaml)
      gait: {haptic: true}
    events:                             # timed inputs, sim time
      - {t: 0.5, cmd_vel: [0.15, 0.0, 0.0]}            # vx, vy (m/s), wz (rad/s)
      - {t: 8.0, push: {force: [0.0, 150.0, 0.0], duration: 0.2}}   # N, s
      - {t: 12.0, gait: trot}                          # switch at the next step boundary

Every parameter of the run is checked before anything starts (replan_ros/params/): a bad
one ends the run with one ``config error:`` line and exit code 2. Events are sent before the
simulation starts, stamped with their sim time, on the transient-local
schedule topics (`cmd_vel_stamped`, `external_wrench`), so the same file always gives the same run.
While it runs, a progress line (launch.sh's, plus ``events due/sent``) is printed unless
``--quiet``. The sim stops at the scenario's duration (its ``stop_time``), so a run ends at the
same tick every time; ``--repeat N`` runs it N times and says whether the runs are
bit-identical (docs/ARCHITECTURE.md, "Bit-exact runs").
"""

from __future__ import annotations

import argparse
import json
import math
import os
import shutil
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

import yaml
from geometry_msgs.msg import TwistStamped
from std_msgs.msg import Header

from replan_core.evaluation.metrics import FallLimits
from replan_ros.launch.graph import EXIT_CONFIG, Graph, run_graph
from replan_ros.launch.launch_graph import (
    add_gait_option,
    add_live_option,
    add_robot_option,
    check_live_port,
    live_argv,
)
from replan_ros.launch.param_files import (
    DEFAULT_GAIT,
    DEFAULT_PROFILE,
    DEFAULT_ROBOT,
    check_run_files,
    gait_parameters,
    profile_file,
    robot_parameters,
)
from replan_ros.launch.progress import ProgressLine
from replan_ros.launch.watch import ScheduledInputs
from replan_ros.messages.stamps import sec_to_ns, sec_to_stamp, stamp_to_sec
from replan_ros.messages.wrench import wrench_to_msg
from replan_ros.params import ConfigError, Source, load_param_file
from replan_ros.tools.reproduce import (
    RerunError,
    compare_messages,
    compare_trajectories,
    find_bag,
    load_run,
)

NODE_NAMES = ('sim', 'gait', 'mpc', 'wbc', 'recorder')
TOP_KEYS = {'name', 'description', 'duration', 'profile', 'robot', 'gait', 'terrain', 'params',
            'events', 'fall_limits'}


class ScenarioError(ValueError):
    """A scenario file that cannot be run, with the reason."""


@dataclass
class Scenario:
    name: str
    duration: float
    terrain: dict
    params: dict[str, dict]
    cmd_vel_events: list[tuple[float, tuple[float, float, float]]] = field(default_factory=list)
    push_events: list[tuple[float, tuple[float, float, float], float]] = field(
        default_factory=list)
    gait_events: list[tuple[float, str]] = field(default_factory=list)
    fall_limits: dict = field(default_factory=dict)
    profile: str = DEFAULT_PROFILE
    robot: str = DEFAULT_ROBOT        # a name of config/robots/ or a robot file
    gait: str = DEFAULT_GAIT          # a name of config/gaits/
    source_text: str = ''
    source: str = '<scenario>'
    terrain_given: bool = False       # the file has a top-level terrain (else: flat)


def _finite_numbers(value, count: int, where: str) -> tuple[float, ...]:
    if (not isinstance(value, (list, tuple)) or len(value) != count
            or not all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in value)):
        raise ScenarioError(f'{where}: expected a list of {count} numbers, got {value!r}')
    if not all(math.isfinite(v) for v in value):
        raise ScenarioError(f'{where}: non-finite value in {value!r}')
    return tuple(float(v) for v in value)


def parse_scenario(text: str, source: str = '<scenario>') -> Scenario:
    """Validate a scenario document; ScenarioError says what is wrong and where."""
    try:
        doc = yaml.safe_load(text)
    except yaml.YAMLError as err:
        raise ScenarioError(f'{source}: not valid YAML: {err}') from err
    if not isinstance(doc, dict):
        raise ScenarioError(f'{source}: the top level must be a mapping')
    unknown = set(doc) - TOP_KEYS
    if unknown:
        raise ScenarioError(f'{source}: unknown keys {sorted(unknown)} (known: {sorted(TOP_KEYS)})')
    duration = doc.get('duration')
    if not isinstance(duration, (int, float)) or isinstance(duration, bool) or not (
            0 < duration < 3600):
        raise ScenarioError(f'{source}: duration must be a number of sim seconds in (0, 3600)')
    terrain = doc.get('terrain', 'flat')
    if isinstance(terrain, str):
        terrain = {'type': terrain}
    if not isinstance(terrain, dict) or not isinstance(terrain.get('type'), str):
        raise ScenarioError(f'{source}: terrain must be a name or a mapping with a type')
    params = doc.get('params') or {}
    if not isinstance(params, dict) or not all(
            isinstance(v, dict) for v in params.values()):
        raise ScenarioError(f'{source}: params must map node names to parameter mappings')
    bad_nodes = set(params) - set(NODE_NAMES)
    if bad_nodes:
        raise ScenarioError(f'{source}: params for unknown nodes {sorted(bad_nodes)}')
    profile = doc.get('profile', DEFAULT_PROFILE)
    if not isinstance(profile, str) or not profile:
        raise ScenarioError(f'{source}: profile must be a profile name or a YAML file')
    robot = doc.get('robot', DEFAULT_ROBOT)
    if not isinstance(robot, str) or not robot:
        raise ScenarioError(f'{source}: robot must be a robot name or a robot file')
    gait = doc.get('gait', DEFAULT_GAIT)
    if not isinstance(gait, str) or not gait:
        raise ScenarioError(f'{source}: gait must be a name of config/gaits/')
    scenario = Scenario(name=str(doc.get('name', Path(source).stem)), duration=float(duration),
                        terrain=terrain, params=params, fall_limits=doc.get('fall_limits') or {},
                        profile=profile, robot=robot, gait=gait, source_text=text, source=source,
                        terrain_given='terrain' in doc)
    for i, event in enumerate(doc.get('events') or []):
        where = f'{source}: events[{i}]'
        if not isinstance(event, dict) or 't' not in event:
            raise ScenarioError(f'{where}: each event needs a time t')
        t = event['t']
        if not isinstance(t, (int, float)) or isinstance(t, bool) or not 0 <= t <= duration:
            raise ScenarioError(f'{where}: t must be within [0, duration]')
        kinds = set(event) - {'t'}
        if kinds == {'cmd_vel'}:
            scenario.cmd_vel_events.append((float(t), _finite_numbers(
                event['cmd_vel'], 3, f'{where}.cmd_vel')))
        elif kinds == {'gait'}:
            if not isinstance(event['gait'], str) or not event['gait']:
                raise ScenarioError(f'{where}.gait: a name of config/gaits/')
            scenario.gait_events.append((float(t), event['gait']))
        elif kinds == {'push'}:
            push = event['push']
            if not isinstance(push, dict) or set(push) != {'force', 'duration'}:
                raise ScenarioError(f'{where}.push: needs exactly force and duration')
            force = _finite_numbers(push['force'], 3, f'{where}.push.force')
            length = _finite_numbers([push['duration']], 1, f'{where}.push.duration')[0]
            if length <= 0:
                raise ScenarioError(f'{where}.push.duration must be positive')
            scenario.push_events.append((float(t), force, length))
        else:
            raise ScenarioError(f'{where}: an event is one of cmd_vel, push or gait, got '
                                f'{sorted(kinds)}')
    return scenario


def load_scenario(path: Path) -> Scenario:
    try:
        text = path.read_text()
    except OSError as err:
        raise ScenarioError(f'cannot read {path}: {err}') from err
    return parse_scenario(text, str(path))


def params_document(scenario: Scenario) -> dict:
    """The parameter override file of the run: per-node params plus the terrain for the sim."""
    doc: dict = {}
    for node, values in scenario.params.items():
        doc.setdefault(node, {'ros__parameters': {}})['ros__parameters'].update(values)
    sim = doc.setdefault('sim', {'ros__parameters': {}})['ros__parameters']
    sim['terrain'] = scenario.terrain['type']
    for key, value in scenario.terrain.items():
        if key != 'type':
            sim[f'terrain_{key}'] = value
    return doc


def _terrain_keys(values: dict) -> list[str]:
    return [k for k in values if k == 'terrain' or k.startswith('terrain_')]


def check_scenario(scenario: Scenario, config_dir: Path, extra_param_files=()) -> None:
    """Check the run's parameters before anything starts (ConfigError, one line): the
    scenario's ``params`` and terrain, its profile and the extra files against the nodes'
    tables (``param_files.check_run_files``), and no terrain set in two places: the sim's
    terrain comes from the top-level ``terrain:`` (``flat`` when absent), which a
    ``params: {sim: {terrain...}}`` entry or a terrain key in an extra file would contradict
    (before this check one of them silently won)."""
    top = (f'the top-level terrain ({scenario.terrain["type"]}'
           + (')' if scenario.terrain_given else ', the default when terrain: is absent)'))
    hint = ('set the terrain with the top-level terrain: key (a name or {type: step_up, '
            'step_height: 0.05, ...})')
    keys = _terrain_keys(scenario.params.get('sim', {}))
    if keys:
        raise ConfigError(f'{scenario.source}: params.sim.{keys[0]} = '
                          f'{scenario.params["sim"][keys[0]]!r} conflicts with {top}; {hint}')
    for path in extra_param_files:
        sim = load_param_file(path).get('sim', {})
        keys = _terrain_keys(sim)
        if keys:
            raise ConfigError(f'{path}: sim.{keys[0]} = {sim[keys[0]]!r} conflicts with {top} '
                              f'of {scenario.source}; {hint}')
    doc = params_document(scenario)
    terrain = {k: v for k, v in doc['sim']['ros__parameters'].items() if k.startswith('terrain')}
    profile = profile_file(config_dir, scenario.profile)
    gait = gait_parameters(config_dir, scenario.gait)
    for _, name in scenario.gait_events:
        gait_parameters(config_dir, name)           # an unknown gait: one line, nothing started
    robot = robot_parameters(config_dir, scenario.robot, profile, gait)
    sources = [gait, profile, robot.derived, robot.overrides,
               Source(f'{scenario.source} (params)', scenario.params),
               Source(f'{scenario.source} (terrain)', {'sim': terrain}),
               *extra_param_files]
    check_run_files(config_dir, sources)


def scenario_inputs(scenario: Scenario) -> ScheduledInputs:
    """The scenario's events as stamped messages: each push is its wrench from ``t`` and a zero
    wrench from ``t + duration``."""
    setpoints, wrenches = [], []
    for t, (vx, vy, wz) in sorted(scenario.cmd_vel_events):
        msg = TwistStamped()
        msg.header.stamp = sec_to_stamp(t)
        msg.header.frame_id = 'base_link'
        msg.twist.linear.x, msg.twist.linear.y, msg.twist.angular.z = vx, vy, wz
        setpoints.append(msg)
    for t, force, length in sorted(scenario.push_events):
        for stamp, f in ((t, force), (t + length, (0.0, 0.0, 0.0))):
            wrenches.append(wrench_to_msg(sec_to_ns(stamp), f))
    gaits = []
    for t, name in sorted(scenario.gait_events):
        msg = Header(frame_id=name)
        msg.stamp = sec_to_stamp(t)
        gaits.append(msg)
    return ScheduledInputs(setpoints, wrenches, gaits)


def run_scenario(scenario: Scenario, out_dir: Path, *, gui: bool = False,
                 config_dir: Path | None = None, extra_param_files: list[Path] = (),
                 log=print, progress: ProgressLine | None = None, plots: bool = True,
                 keep_bag: bool = True, live_port: int | None = None) -> dict:
    """Run, then analyse; returns the metrics (also written to out_dir/metrics.json). With
    ``progress``, a progress line is printed while the graph runs (``run_graph``). Without
    ``plots`` no figure is drawn; without ``keep_bag`` the bag is deleted once analysed (the
    run folder keeps scenario.yaml and params.yaml, from which the run is made again)."""
    from replan_experiments.analysis import analyse_run  # matplotlib only when needed

    config_dir = config_dir or Path(os.environ.get('REPLAN_CONFIG', 'config'))
    check_scenario(scenario, config_dir, extra_param_files)     # ConfigError: nothing started
    out_dir.mkdir(parents=True, exist_ok=True)
    (out_dir / 'scenario.yaml').write_text(scenario.source_text)
    params_file = out_dir / 'params.yaml'
    params_file.write_text(yaml.safe_dump(params_document(scenario), sort_keys=False))
    bag_dir = out_dir / 'bag'
    graph = Graph(out_dir, config_dir=config_dir, profile=scenario.profile,
                  param_files=[params_file, *extra_param_files], record_dir=bag_dir,
                  gui=gui, respawn=False,
                  extra_params={'recorder': {'scenario_file': str(out_dir / 'scenario.yaml')}},
                  log=log, live_port=live_port, stop_time=scenario.duration,
                  robot=scenario.robot, gait=scenario.gait)
    inputs = scenario_inputs(scenario)

    def publish_events(node) -> list:
        deliveries = inputs.publish(node)
        log(f'[scenario] sent {inputs.count} timed inputs')
        return deliveries

    wall_start = time.monotonic()
    event_times = [stamp_to_sec(m.header.stamp) for m in [*inputs.setpoints, *inputs.wrenches]]
    event_times += [stamp_to_sec(m.stamp) for m in inputs.gaits]
    code = run_graph(graph, scenario.duration,
                     wall_timeout=max(300.0, 20.0 * scenario.duration), on_start=publish_events,
                     progress=progress, event_times=event_times)
    wall = time.monotonic() - wall_start
    if graph.robot_layer is not None and 'min_height' not in scenario.fall_limits:
        # The fall height is the reference robot's scaled by standing height: HyQ's 0.30 m
        # would count a standing Go1 (0.27 m) as fallen.
        scenario.fall_limits = {**scenario.fall_limits, 'min_height':
                                FallLimits().min_height * graph.robot_layer.height_ratio}
    metrics = analyse_run(bag_dir, scenario, out_dir, launch_exit_code=code,
                          dead_nodes=graph.failed, wall_time_total=wall, plots=plots)
    metrics['robot'] = graph.robot
    metrics['launcher_real_time_factor'] = graph.real_time_factor
    metrics['peak_memory_mb'] = {k: round(v, 1) for k, v in graph.peak_memory_mb.items()}
    metrics['peak_memory_total_mb'] = round(sum(graph.peak_memory_mb.values()), 1)
    if not keep_bag:
        shutil.rmtree(bag_dir, ignore_errors=True)
        metrics['bag'] = None
    (out_dir / 'metrics.json').write_text(json.dumps(metrics, indent=2))
    return metrics


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog='scenario.sh', description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('scenario', type=Path)
    parser.add_argument('--out', type=Path, help='output folder (default runs/<name>-<time>)')
    parser.add_argument('--gui', action='store_true')
    parser.add_argument('--params', type=Path, nargs='+', default=[],
                        help='extra parameter files, applied after the scenario\'s')
    parser.add_argument('--profile', metavar='NAME',
                        help='world profile (realistic | ideal | a YAML file), instead of the '
                             'scenario\'s profile: key (default realistic)')
    parser.add_argument('--no-plots', action='store_true',
                        help='metrics.json only, no figures (faster; experiments.sh uses it)')
    parser.add_argument('--no-bag', action='store_true',
                        help='delete the bag once analysed (scenario.yaml and params.yaml '
                             'stay, and make the run again)')
    parser.add_argument('--quiet', action='store_true',
                        help='no progress line (sim time, real-time factor, distance, '
                             're-plans, events) while the graph runs')
    parser.add_argument('--repeat', type=int, metavar='N', default=1,
                        help='run it N times (OUT/run-1 ... run-N) and compare every run with '
                             'the first: base trajectory and every message of the run\'s state '
                             'and decisions, byte for byte (reproduce.EXACT_TOPICS); exit 0 only '
                             'if all are bit-identical')
    add_robot_option(parser, default=None)
    add_gait_option(parser, default=None)
    add_live_option(parser)
    args = parser.parse_args(live_argv(argv))
    check_live_port(parser, args.live)
    if args.repeat < 1:
        parser.error('--repeat takes a number of runs >= 1')
    if args.repeat > 1 and args.no_bag:
        parser.error('--repeat compares the runs\' bags: it cannot go with --no-bag')
    config_dir = Path(os.environ.get('REPLAN_CONFIG', 'config'))
    for path in args.params:
        if not path.is_file():
            parser.error(f'parameter file {path} does not exist')
    try:
        scenario = load_scenario(args.scenario)
        if args.profile:
            scenario.profile = args.profile
        if args.robot:
            scenario.robot = args.robot
        if args.gait:
            scenario.gait = args.gait
        profile_file(config_dir, scenario.profile)
        check_scenario(scenario, config_dir, args.params)
    except ConfigError as err:
        print(f'config error: {err}', file=sys.stderr)
        return EXIT_CONFIG
    except (ScenarioError, ValueError) as err:
        print(f'scenario: {err}', file=sys.stderr)
        return EXIT_CONFIG
    root = Path(os.environ.get('REPLAN_ROOT', '.'))
    out = args.out or root / 'runs' / f'{scenario.name}-{time.strftime("%Y%m%d-%H%M%S")}'
    print(f'[scenario] {scenario.name}: {scenario.duration} s of sim time, profile '
          f'{scenario.profile}, robot {scenario.robot}, gait {scenario.gait}, output in {out}')
    outs = [out] if args.repeat == 1 else [out / f'run-{k}' for k in range(1, args.repeat + 1)]
    completed = True
    for run_out in outs:
        metrics = run_scenario(scenario, run_out, gui=args.gui, config_dir=config_dir,
                               extra_param_files=args.params,
                               progress=None if args.quiet else ProgressLine(),
                               plots=not args.no_plots, keep_bag=not args.no_bag,
                               live_port=args.live)
        print(summary(metrics, run_out))
        completed &= bool(metrics.get('completed'))
    if args.repeat > 1:
        identical = compare_repeats(scenario.name, outs)
        return 0 if completed and identical else 1
    return 0 if completed else 1


def compare_repeats(name: str, outs: list[Path], log=print) -> bool:
    """Compare every run of ``outs`` with the first (base trajectory, every message of
    ``reproduce.EXACT_TOPICS``, the last stamp); True if all are bit-identical."""
    try:
        bags = [find_bag(run_out / 'bag') for run_out in outs]
        first = load_run(bags[0]).odom
        largest, identical = 0.0, True
        for k, bag in enumerate(bags[1:], start=2):
            trajectory = compare_trajectories(first, load_run(bag).odom)
            messages = compare_messages(bags[0], bag)
            largest = max(largest, trajectory.max_deviation)
            identical &= messages.identical and trajectory.max_deviation == 0.0 \
                and trajectory.missing == 0
            log(f'[repeat] run {k} against run 1: base position {trajectory.max_deviation:.3g} '
                f'm at most ({trajectory.matched} stamps, {trajectory.missing} missing); '
                f'messages {messages.text()}')
    except (RerunError, OSError) as err:
        log(f'[repeat] cannot compare the runs: {err}')
        return False
    log(f'[repeat] {name}: {len(outs)} runs, largest base position difference {largest:.3g} m; '
        + ('every run bit-identical to run 1' if identical else 'the runs DIFFER'))
    return identical


def _shown(value, spec: str) -> str:
    """``value`` in format ``spec``; '-' for a figure the run did not give (None or missing:
    a node died, the bag lacks the topic)."""
    return '-' if value is None else format(value, spec)


def summary(metrics: dict, out: Path) -> str:
    if metrics.get('fell') is None and metrics.get('error'):
        # Nothing ran to measure (a node refused its configuration, ...): say so, not "no fall".
        dead = metrics.get('dead_nodes')
        return (f'[scenario] {metrics.get("scenario")}: FAILED: {metrics["error"]} (launcher '
                f'exit code {metrics.get("launch_exit_code")}'
                + (f'; nodes that died: {dead}' if dead else '') + f'); logs: {out / "logs"}')
    fall = f'FELL ({metrics.get("fall_reason", "")})' if metrics.get('fell') else 'no fall'
    lines = [f'[scenario] {metrics.get("scenario")}: {fall}'
             f', {_shown(metrics.get("sim_time_s"), ".1f")} s sim in '
             f'{_shown(metrics.get("wall_time_s"), ".1f")} s wall (real-time factor '
             f'{_shown(metrics.get("real_time_factor"), ".2f")})',
             f'  distance {_shown(metrics.get("distance_m"), ".2f")} m, re-plans '
             f'{metrics.get("replans")}, '
             f'MPC solve median {metrics.get("mpc_solve_ms_median")} ms, '
             f'p99 {metrics.get("mpc_solve_ms_p99")} ms, re-plan path (estimate out to '
             f'plan out, wall) median {(metrics.get("replan_wall_ms") or {}).get("median")} ms, '
             f'planned ZMP margin min {metrics.get("min_zmp_margin_m")} m, '
             f'peak memory {metrics.get("peak_memory_total_mb")} MB',
             f'  profile {metrics.get("profile")}: measured CoP margin min '
             f'{metrics.get("cop_margin_min_m")} m, 5th percentile '
             f'{metrics.get("cop_margin_p5_m")} m'
             + (f'; estimator: xy error at the end '
                f'{_shown(estimate.get("xy_error_end_m"), ".3f")} m, velocity RMSE '
                f'{_shown(estimate.get("velocity_rmse_mps"), ".3f")} m/s'
                if (estimate := metrics.get('estimator')) else '')]
    for seg in metrics.get('velocity_tracking', []):
        if seg.get('achieved') is None:
            continue
        cmd = ', '.join(f'{c:+.2f}' for c in seg['commanded'])
        ach = ', '.join(f'{c:+.3f}' for c in seg['achieved'])
        lines.append(f'  {seg["start_s"]:5.1f}-{seg["end_s"]:5.1f} s  commanded ({cmd})  '
                     f'achieved ({ach})')
    if metrics.get('dead_nodes'):
        lines.append(f'  nodes that died: {metrics["dead_nodes"]}')
    if metrics.get('bag_complete') is False:
        lines.append(f'  bag {metrics.get("bag_gaps")}')
    lines.append(f'  bag: {out / "bag"}   metrics: {out / "metrics.json"}   plots: {out}/*.png')
    return '\n'.join(lines)


if __name__ == '__main__':
    sys.exit(main())
