"""Speed of the lock-step graph against its targets, every figure from one run of one command.

``scripts/bench_speed.sh [--runs N] [--duration S] [--robot NAME|FILE] [--out DIR] [--json]
[--page FILE]``

Every part runs the robot of ``--robot`` (a name of ``config/robots/`` or a robot file; default
hyq, docs/robot_files.md): physics alone with its model, its PD gains and realistic payload
scaled from HyQ's (``sim_bench.bench_robot``), the graph with its derived parameters (the
launcher's, ``Graph(robot=...)``, walking the robot's own forward scenario as
``bench_graph.sh`` does, ``walk_scenario``), the MPC benchmark with its crawl
(``mpc_bench.bench_crawl``: its standing feet, timing and set-points scaled, its CoM height as
the LIP height). A robot that cannot be used stops the bench with one ``config error:`` line
before anything runs.

Each round (default 3, interleaved so that a ratio is measured under one load) runs:

- physics alone (``replan_core.bench.sim_bench``): the bare PyBullet world with the sim node's
  state queries, ideal and with every realism element on;
- the graph walking the robot's forward scenario (``walk_scenario``: HyQ 0.15 m/s, Go1 0.05
  m/s ... from t = 1 s), headless,
  lock-step, ``--duration`` sim s (default 22) in four set-ups: the ideal profile, the
  realistic one, the realistic one with the recorder, and with the recorder and the live view
  watched by a headless viewer subscribed to every channel it advertises
  (``view/live_client.py``).

and once the MPC benchmark (``replan_core.bench.mpc_bench``, 200 re-plans at the paper's size,
back to back), and again with ``MPC_IDLE`` wall s of sleep before each re-plan: in the graph
the mpc idles between touchdowns and each solve starts cold (caches, the core's state), which
alone doubled its CPU time on the 2-core machine (docs/mpc.md).
The real-time factor of a run is the launcher's (sim s per wall s from the first tick); the
tick is the sim's mean command-to-command time (its ``tick budget`` line); the MPC's solve
times in the graph come from the mpc's shutdown line (wall and thread CPU time, so that work
and waiting for a core are told apart); with the recorder, the re-plan path's wall latency
(estimate out to ``com_plan`` out, ``run_analysis.replan_wall_latency``) from the bag.

It prints one table (target, figure, verdict: met / not met) and, with ``--json``, one JSON
line of everything; with ``--page FILE`` it also writes that Markdown page (``docs/speed.md``:
the targets, every round's figures, CPU time per node, the MPC's times, the machine and the
revision), so that the figures quoted in the docs come from a run, not from hand copies.
Targets and why the unmet ones are not met: docs/ARCHITECTURE.md, "Speed targets".
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import re
import shlex
import statistics
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import yaml

from replan_core.bench import bench_robots
from replan_core.bench.mpc_bench import BenchCrawl, bench_crawl
from replan_core.bench.mpc_bench import run as mpc_bench_run
from replan_core.robot.robot_file import load_robot_file, robot_file_path
from replan_experiments.analysis import replan_wall_latency
from replan_experiments.benchmarks.tick_table import read_budgets, table
from replan_experiments.runner import git_revision, machine_description
from replan_experiments.scenario import load_scenario, params_document, scenario_inputs
from replan_ros.launch.graph import EXIT_CONFIG, Graph, run_graph
from replan_ros.launch.launch_graph import add_robot_option
from replan_ros.launch.param_files import DEFAULT_ROBOT, profile_file, robot_parameters
from replan_ros.nodes.mpc_node import SOLVE_TIMES_LOG
from replan_ros.params import ConfigError
from replan_ros.recording.bag_read import read_messages
from replan_ros.view.live_client import WatchEverything, free_port

if TYPE_CHECKING:
    from replan_core.bench.sim_bench import BenchRobot

ROOT = Path(__file__).resolve().parents[4]
CONFIG = ROOT / 'config'


def walk_scenario(robot: str) -> Path:
    """The walk the graph benches (this one and ``bench_graph.sh``) run for ``robot`` (a name
    of ``config/robots/`` or a robot file): ``config/scenarios/<name>_forward.yaml``, its
    robot-appropriate set-point, where the robot has one; else ``forward.yaml`` (0.15 m/s,
    HyQ's). RobotFileError (one line) for a robot that cannot be used, as the launcher's."""
    path = robot_file_path(robot, CONFIG)
    name = path.stem if path.parent == CONFIG / 'robots' else load_robot_file(path, ROOT).name
    own = CONFIG / 'scenarios' / f'{name}_forward.yaml'
    return own if own.is_file() else CONFIG / 'scenarios' / 'forward.yaml'


# name -> (profile, recorder, live view with a viewer)
SETUPS = {
    'ideal': ('ideal', False, False),
    'realistic': ('realistic', False, False),
    'realistic+recorder': ('realistic', True, False),
    'realistic+recorder+live': ('realistic', True, True),
}
# The targets: real-time factor, its share of physics alone, the recorder's cost,
# the MPC alone and inside the graph.
RTF_TARGET = 1.5
PHYSICS_SHARE_TARGET = 0.2
RECORDER_COST_TARGET = 0.10
MPC_MEDIAN_TARGET_MS = 2.0
MPC_P99_TARGET_MS = 5.0
MPC_GRAPH_FACTOR_TARGET = 1.5
MPC_IDLE = 0.3              # wall s between two re-plans of the idle MPC benchmark
MPC_IDLE_REPLANS = 40


@dataclass(frozen=True)
class SpeedRobot:
    """The robot of a run as each part of the bench takes it."""

    name: str               # the robot file's name (go1): the table's, the JSON's, the page's
    given: str              # as --robot gave it (a name or a file): what the graph's launcher reads
    physics: BenchRobot     # physics alone: its model, gains and payload scaled from HyQ's
    crawl: BenchCrawl       # the MPC benchmark's crawl


def speed_robot(robot: str) -> SpeedRobot:
    """``robot`` (a name of config/robots/ or a robot file) for every part of the bench, each
    through the project's own resolution: the launcher's parameters in every profile of
    ``SETUPS`` (``param_files.robot_parameters``, what ``Graph`` does again per run),
    ``sim_bench.bench_robot`` and ``mpc_bench.bench_crawl``. ConfigError with one line for an
    unknown name or a robot file that does not fit its model, before anything runs."""
    try:
        layers = [robot_parameters(CONFIG, robot, profile_file(CONFIG, profile))
                  for profile in dict.fromkeys(profile for profile, _, _ in SETUPS.values())]
        _, reference, rules = bench_robots(robot, ROOT)
        crawl = bench_crawl(robot, ROOT)
    except ValueError as err:           # ConfigError, RobotFileError: one line each
        raise ConfigError(str(err)) from None
    # PyBullet prints its banner on import: only once the robot is known to be usable.
    from replan_core.bench.sim_bench import bench_robot

    spec = layers[0].spec
    return SpeedRobot(spec.name, robot, bench_robot(spec, reference, rules), crawl)


@contextlib.contextmanager
def _native_stdout_to_stderr():
    """PyBullet's C code prints its banner on file descriptor 1: keep stdout for the table."""
    sys.stdout.flush()
    saved = os.dup(1)
    os.dup2(2, 1)
    try:
        yield
    finally:
        os.dup2(saved, 1)
        os.close(saved)


def physics_alone(robot: BenchRobot) -> dict:
    """Physics alone (``sim_bench.physics_rtf``, best of 3): sim s per wall s of ``robot``'s
    bare world, ideal and with every realism element on."""
    from replan_core.bench.sim_bench import physics_rtf

    with _native_stdout_to_stderr():
        return {profile: round(physics_rtf(robot.urdf, realistic=realistic, robot=robot)[0], 2)
                for profile, realistic in (('ideal', False), ('realistic', True))}


def graph_run(setup: str, out: Path, duration: float, log, walk: Path,
              robot: str = DEFAULT_ROBOT) -> dict:
    """One headless run of ``setup`` with ``robot`` (as ``--robot`` gives it) walking
    ``walk`` (a scenario file, ``walk_scenario``): real-time factor, mean tick, MPC solve
    times."""
    profile, record, live = SETUPS[setup]
    scenario = load_scenario(walk)
    out.mkdir(parents=True, exist_ok=True)
    params_file = out / 'params.yaml'
    params_file.write_text(yaml.safe_dump(params_document(scenario), sort_keys=False))
    port = free_port() if live else None
    graph = Graph(out, config_dir=CONFIG, profile=profile, param_files=[params_file],
                  record_dir=out / 'bag' if record else None, respawn=False,
                  log=lambda text: log(text, quiet=True), live_port=port, stop_time=duration,
                  robot=robot)
    inputs = scenario_inputs(scenario)
    viewer = WatchEverything(port) if live else None

    def on_start(node) -> list:
        if viewer is not None:
            viewer.start()
        return inputs.publish(node)

    try:
        code = run_graph(graph, duration, wall_timeout=max(300.0, 20.0 * duration),
                         on_start=on_start)
    finally:
        if viewer is not None:
            viewer.stop()
    result: dict = {'setup': setup, 'exit_code': code, 'real_time_factor': graph.real_time_factor,
                    'cpu_ms_per_sim_s': graph.cpu_ms_per_sim_s}
    budgets = read_budgets(graph.log_dir)
    if {'sim', 'wbc'} <= set(budgets):
        totals = table(budgets['sim'], budgets['wbc'])[1]
        result['tick_ms_mean'] = round(totals['tick_ms_mean'], 3)
    result['mpc'] = mpc_solve_times(graph.log_dir / 'mpc.log')
    if record:          # the planning pipeline's wall latency, from the bag (run_analysis)
        result['replan_wall'] = replan_wall_latency(
            read_messages(out / 'bag', topics=('/odom', '/footholds', '/com_plan')))
    if viewer is not None:
        result['viewer_frames'] = viewer.frames
        result['viewer_mb'] = round(viewer.bytes / 1e6, 1)
        if viewer.error:
            result['viewer_error'] = viewer.error
    return result


def mpc_solve_times(log_path: Path) -> dict:
    """The mpc node's shutdown summary of its solve times ({} if it has none)."""
    if not log_path.exists():
        return {}
    found = re.findall(re.escape(SOLVE_TIMES_LOG) + r' (\{.*\})', log_path.read_text())
    return json.loads(found[-1]) if found else {}


_NODE_ORDER = ('sim', 'wbc', 'gait', 'mpc', 'recorder', 'live_view')


def _median(values: list) -> float | None:
    values = [v for v in values if v is not None]
    return round(statistics.median(values), 3) if values else None


def _span(values: list, digits: int = 2, scale: float = 1.0, unit: str = '') -> str:
    """median (min-max) of the values given, times ``scale``, with ``digits`` decimals."""
    values = [v * scale for v in values if v is not None]
    if not values:
        return 'n/a'
    return (f'{statistics.median(values):.{digits}f}{unit} '
            f'({min(values):.{digits}f}-{max(values):.{digits}f}{unit})')


def _verdict(ok: bool | None) -> str:
    return 'n/a' if ok is None else ('met' if ok else 'NOT met')


def _cost(round_: dict, with_it: str, without: str) -> float | None:
    """1 - RTF(with_it) / RTF(without) in one round (the cost of what ``with_it`` adds)."""
    a = round_['graph'][with_it]['real_time_factor']
    b = round_['graph'][without]['real_time_factor']
    return 1.0 - a / b if a and b else None


def summarise(rounds: list[dict], mpc_bench: dict,
              mpc_idle: dict | None = None) -> tuple[list[tuple[str, str, str]], dict]:
    """Table rows (target, figure, verdict) and the summary, from the rounds' results and
    the MPC benchmark back to back (``mpc_bench``) and after idling (``mpc_idle``)."""
    rtf = {s: [r['graph'][s]['real_time_factor'] for r in rounds] for s in SETUPS}
    rows = []
    summary: dict = {'real_time_factor': {s: _median(v) for s, v in rtf.items()}}
    for setup, values in rtf.items():
        median = _median(values)
        rows.append((f'real-time factor >= {RTF_TARGET}: {setup}', _span(values),
                     _verdict(None if median is None else median >= RTF_TARGET)))
    for setup, physics_key in (('ideal', 'ideal'), ('realistic', 'realistic')):
        shares = [r['graph'][setup]['real_time_factor'] / r['physics'][physics_key]
                  if r['graph'][setup]['real_time_factor'] else None for r in rounds]
        median = _median(shares)
        summary[f'{setup}_over_physics'] = median
        physics = _span([r['physics'][physics_key] for r in rounds])
        rows.append((f'graph >= {PHYSICS_SHARE_TARGET} x physics alone: {setup} '
                     f'(physics {physics})', _span(shares, digits=3),
                     _verdict(None if median is None else median >= PHYSICS_SHARE_TARGET)))
    for label, with_it, without in (('recorder', 'realistic+recorder', 'realistic'),
                                    ('live view + viewer', 'realistic+recorder+live',
                                     'realistic+recorder')):
        costs = [_cost(r, with_it, without) for r in rounds]
        median = _median(costs)
        summary[f'{label} cost'] = median
        target = label == 'recorder'
        rows.append((f'{label} costs <= {RECORDER_COST_TARGET:.0%} of the RTF' if target else
                     f'{label} cost (no target)', _span(costs, 1, 100.0, ' %'),
                     _verdict(None if median is None or not target
                              else median <= RECORDER_COST_TARGET)))
    rows.append((f'MPC alone: median <= {MPC_MEDIAN_TARGET_MS} ms, p99 <= '
                 f'{MPC_P99_TARGET_MS} ms', f'{mpc_bench["median_ms"]:.2f} / '
                 f'{mpc_bench["p99_ms"]:.2f} ms',
                 _verdict(mpc_bench['median_ms'] <= MPC_MEDIAN_TARGET_MS
                          and mpc_bench['p99_ms'] <= MPC_P99_TARGET_MS)))
    if mpc_idle is not None:
        rows.append((f'MPC alone, {mpc_idle["idle_s"]:g} s idle before each re-plan (no '
                     'target)', f'{mpc_idle["median_ms"]:.2f} / {mpc_idle["p99_ms"]:.2f} ms, '
                     f'CPU median {mpc_idle["cpu_median_ms"]:.2f} ms', 'n/a'))
    for setup in SETUPS:
        medians = [r['graph'][setup]['mpc'].get('wall_median_ms') for r in rounds]
        p99s = [r['graph'][setup]['mpc'].get('wall_p99_ms') for r in rounds]
        cpus = [r['graph'][setup]['mpc'].get('cpu_median_ms') for r in rounds]
        median, p99 = _median(medians), _median(p99s)
        summary[f'mpc_in_graph_{setup}'] = {'median_ms': median, 'p99_ms': p99,
                                            'cpu_median_ms': _median(cpus)}
        ok = None
        if median is not None and p99 is not None:
            ok = (median <= MPC_GRAPH_FACTOR_TARGET * mpc_bench['median_ms']
                  and p99 <= MPC_GRAPH_FACTOR_TARGET * mpc_bench['p99_ms'])
        rows.append((f'MPC in the graph <= {MPC_GRAPH_FACTOR_TARGET} x alone: {setup}',
                     f'median {_span(medians)}, p99 {_span(p99s)}, CPU median '
                     f'{_span(cpus)} ms', _verdict(ok)))
    for setup in SETUPS:
        cpu = [r['graph'][setup].get('cpu_ms_per_sim_s') or {} for r in rounds]
        if not any(cpu):
            continue
        nodes = sorted({name for c in cpu for name in c}, key=_NODE_ORDER.index)
        per_node = {name: _median([c.get(name) for c in cpu]) for name in nodes}
        totals = [sum(c.values()) if c else None for c in cpu]
        summary[f'cpu_ms_per_sim_s_{setup}'] = {**per_node, 'all': _median(totals)}
        rows.append((f'CPU time per sim s (no target): {setup}',
                     f'all {_span(totals)} ms: '
                     + ', '.join(f'{name} {ms:.0f}' for name, ms in per_node.items()), 'n/a'))
    for setup in SETUPS:
        latencies = [r['graph'][setup].get('replan_wall') for r in rounds]
        if not any(latencies):
            continue
        medians = [x['median'] if x else None for x in latencies]
        maxima = [x['max'] if x else None for x in latencies]
        summary[f'replan_wall_{setup}'] = {'median_ms': _median(medians),
                                           'max_ms': _median(maxima)}
        rows.append((f're-plan path, estimate out -> com_plan out (no target): {setup}',
                     f'median {_span(medians)}, max {_span(maxima)} ms', 'n/a'))
    return rows, summary


def print_rows(rows, out=sys.stdout) -> None:
    width = max(len(target) for target, _, _ in rows)
    for target, figure, verdict in rows:
        print(f'{target:<{width}}  {figure:<48}  {verdict}', file=out)


def _cell(value, digits: int = 2) -> str:
    return '-' if value is None else f'{value:.{digits}f}'


def render_page(rows, summary: dict, rounds: list[dict], mpc_bench: dict,
                mpc_idle: dict | None, meta: dict) -> str:
    """The speed page (Markdown) of one run: ``rows`` and ``summary`` from ``summarise``, the
    rounds' raw figures, the MPC benchmarks and ``meta`` (command, date, machine, revision,
    duration, robot)."""
    setups = list(SETUPS)
    physics = [r['physics'][k] for r in rounds for k in ('ideal', 'realistic')]
    lines = [
        '# Speed of the lock-step graph',
        '',
        f'Robot **{meta["robot"]}**. Generated by `{meta["command"]}` on {meta["date"]} '
        f'({meta["machine"]}, revision {meta["revision"]}): {len(rounds)} rounds, each physics '
        f'alone and then the graph walking `{meta.get("walk", "forward")}` for '
        f'{meta["duration"]:g} s '
        f'of sim time in {len(setups)} set-ups, interleaved so that every ratio is measured '
        f'under one load; then the MPC benchmark on {meta["robot"]}\'s crawl. Do not edit by '
        'hand: every figure below comes from that run '
        '(`replan_experiments/benchmarks/bench_speed.py`). '
        'Why the unmet targets are not met, and what was tried: '
        '[ARCHITECTURE.md, "Speed targets"](ARCHITECTURE.md#speed-targets).',
        '',
        'Speed differs between machines and, on a shared virtual machine, between minutes: '
        f'physics alone ran at {min(physics):.1f} to {max(physics):.1f} x real time in this '
        'run. Compare the ratios of one run (share of physics alone, the recorder\'s cost), '
        'not real-time factors across runs.',
        '',
        '## Targets',
        '',
        '| target | figure: median (min-max) over the rounds | verdict |',
        '| --- | --- | --- |',
    ]
    lines += [f'| {target} | {figure} | {verdict} |' for target, figure, verdict in rows]
    lines += [
        '',
        '## Rounds',
        '',
        'Real-time factor (sim s per wall s from the first tick) and, in brackets, the mean '
        'tick (ms, command to command); physics alone in sim s per wall s.',
        '',
        '| round | physics alone: ideal / realistic | '
        + ' | '.join(setups) + ' | recorder cost |',
        '| --- | --- | ' + ' | '.join('---' for _ in setups) + ' | --- |',
    ]
    for k, r in enumerate(rounds, 1):
        cells = []
        for setup in setups:
            g = r['graph'][setup]
            tick = g.get('tick_ms_mean')
            cells.append(_cell(g['real_time_factor'])
                         + ('' if tick is None else f' ({tick:.2f})')
                         + ('' if g['exit_code'] == 0 else f' exit {g["exit_code"]}'))
        cost = _cost(r, 'realistic+recorder', 'realistic')
        cost = '-' if cost is None else f'{cost:.0%}'
        lines.append(f'| {k} | {r["physics"]["ideal"]:.1f} / {r["physics"]["realistic"]:.1f} '
                     f'| ' + ' | '.join(cells) + f' | {cost} |')
    cpu = {setup: summary.get(f'cpu_ms_per_sim_s_{setup}') for setup in setups}
    nodes = sorted({n for c in cpu.values() if c for n in c if n != 'all'},
                   key=_NODE_ORDER.index)
    if nodes:
        lines += [
            '',
            '## CPU time per sim s',
            '',
            'User + system CPU time of each node process from the first tick to the stop, per '
            'second of sim time (ms, median over the rounds): the figure to compare changes by, '
            'since it moves far less with the machine\'s load than the real-time factor.',
            '',
            '| set-up | ' + ' | '.join(nodes) + ' | all |',
            '| --- | ' + ' | '.join('---' for _ in nodes) + ' | --- |',
        ]
        for setup in setups:
            c = cpu[setup] or {}
            lines.append(f'| {setup} | ' + ' | '.join(_cell(c.get(n), 0) for n in nodes)
                         + f' | {_cell(c.get("all"), 0)} |')
    lines += [
        '',
        '## MPC solve times',
        '',
        'The whole `LipMpc.solve` of a re-plan at the paper\'s size (8 s horizon, 40 ms '
        'samples): the benchmark back to back and with idle time before each re-plan, and '
        'the mpc node in each set-up (wall time, and the thread\'s CPU time; median over '
        'the rounds of each round\'s median and p99).',
        '',
        '| where | median ms | p99 ms | CPU median ms |',
        '| --- | --- | --- | --- |',
        f'| benchmark, back to back | {_cell(mpc_bench["median_ms"])} | '
        f'{_cell(mpc_bench["p99_ms"])} | {_cell(mpc_bench.get("cpu_median_ms"))} |',
    ]
    if mpc_idle is not None:
        lines.append(f'| benchmark, {mpc_idle["idle_s"]:g} s idle before each re-plan | '
                     f'{_cell(mpc_idle["median_ms"])} | {_cell(mpc_idle["p99_ms"])} | '
                     f'{_cell(mpc_idle["cpu_median_ms"])} |')
    for setup in setups:
        mpc = summary[f'mpc_in_graph_{setup}']
        lines.append(f'| graph: {setup} | '
                     + ' | '.join(_cell(mpc[k]) for k in ('median_ms', 'p99_ms', 'cpu_median_ms'))
                     + ' |')
    return '\n'.join(lines) + '\n'


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    """The command line (usage errors exit 2 through argparse)."""
    parser = argparse.ArgumentParser(
        prog='bench_speed.sh', description=__doc__.split('\n\n')[0],
        formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('--runs', type=int, default=3, help='rounds (default 3)')
    parser.add_argument('--duration', type=float, default=22.0,
                        help='sim s of each graph run (default 22)')
    add_robot_option(parser)
    parser.add_argument('--out', type=Path, help='run folder (default: a temporary one)')
    parser.add_argument('--json', action='store_true', help='also one JSON line of everything')
    parser.add_argument('--page', type=Path, metavar='FILE',
                        help='also write the Markdown page of the run to FILE (docs/speed.md)')
    args = parser.parse_args(argv)
    if args.runs < 1 or args.duration <= 1.0:
        parser.error('--runs must be >= 1 and --duration > 1 s (the walk starts at 1 s)')
    return args


def header(robot: str, runs: int, duration: float, out: Path) -> str:
    """The table's first line: the robot, the rounds, the walk, the machine, the run folder."""
    return (f'bench_speed: robot {robot}, {runs} rounds, walk {walk_scenario(robot).stem} '
            f'{duration:g} sim s, '
            f'{os.cpu_count()} CPUs ({out})')


def json_line(robot: str, summary: dict, rounds: list[dict], mpc_bench: dict,
              mpc_idle: dict) -> str:
    """``--json``: one line of everything, the robot first."""
    return json.dumps({'robot': robot, 'summary': summary, 'rounds': rounds,
                       'mpc_bench': {k: mpc_bench[k] for k in ('median_ms', 'p99_ms',
                                                                'cpu_median_ms')},
                       'mpc_bench_idle': {k: mpc_idle[k] for k in (
                           'idle_s', 'median_ms', 'p99_ms', 'cpu_median_ms')}})


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    try:                # a wrong robot stops here, in one line, before anything runs
        robot = speed_robot(args.robot)
    except ConfigError as err:
        print(f'config error: {err}', file=sys.stderr)
        return EXIT_CONFIG
    walk = walk_scenario(robot.name)
    out = args.out or Path(tempfile.mkdtemp(prefix='bench_speed_'))

    def log(text: str, quiet: bool = False) -> None:
        if not quiet:
            print(text, file=sys.stderr, flush=True)

    log(f'bench_speed: robot {robot.name}, {args.runs} rounds, {len(SETUPS)} graph set-ups of '
        f'{args.duration:g} sim s each, in {out}')
    # The code measured: the revision when the run starts (docs edited meanwhile do not count).
    revision = git_revision(ROOT)
    rounds = []
    for k in range(1, args.runs + 1):
        physics = physics_alone(robot.physics)
        graph = {}
        for setup in SETUPS:
            result = graph_run(setup, out / f'{setup}_{k}', args.duration, log, walk,
                               robot.given)
            graph[setup] = result
            log(f'round {k}: {setup}: real-time factor {result["real_time_factor"]}, '
                f'tick {result.get("tick_ms_mean")} ms, mpc {result["mpc"]}')
        rounds.append({'physics': physics, 'graph': graph})
    settings = robot.crawl.settings()                   # the graph's robot's crawl
    mpc_bench = mpc_bench_run(settings, robot.crawl, 200, 0)
    mpc_idle = mpc_bench_run(settings, robot.crawl, MPC_IDLE_REPLANS, 0, idle=MPC_IDLE)
    rows, summary = summarise(rounds, mpc_bench, mpc_idle)
    print(header(robot.name, args.runs, args.duration, out))
    print_rows(rows)
    if args.json:
        print(json_line(robot.name, summary, rounds, mpc_bench, mpc_idle))
    if args.page:
        meta = {'command': 'scripts/bench_speed.sh ' + shlex.join(argv if argv is not None
                                                                  else sys.argv[1:]),
                'date': time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime()),
                'machine': machine_description(), 'revision': revision,
                'duration': args.duration, 'robot': robot.name,
                'walk': walk.stem}
        args.page.parent.mkdir(parents=True, exist_ok=True)
        args.page.write_text(render_page(rows, summary, rounds, mpc_bench, mpc_idle, meta))
        log(f'bench_speed: page written to {args.page}')
    failed = [r for r in rounds for g in r['graph'].values() if g['exit_code'] != 0]
    return 1 if failed else 0


if __name__ == '__main__':
    sys.exit(main())
