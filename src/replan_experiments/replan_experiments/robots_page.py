"""The robots page (docs/robots.md): per robot its facts, its derived parameters and
what it does on the realistic profile, from scenario runs.

    scripts/robots_page.sh [--quick] [--jobs N] [--robot NAME ...] [--out DIR] [--page FILE]

For each robot of ``config/robots_page.yaml`` (or those of ``--robot``): a stand at zero
set-point from launch (travel of the trunk on the truth, touchdowns), a walk from standing at
each of its forward, lateral and yaw set-points (achieved against commanded), a run through
the three set-points in turn, the changes at several phases of its crawl cycle and on each of
its noise seeds (each whole crawl cycle of each leg after a change against the set-point),
lateral pushes while walking forward, given as the velocity they give the free body (force =
mass x dv / duration), at phases over its crawl cycle, level after level up to the first level
that fells it at some phase, and blind step downs of shares of its leg length. Real-time
factor and MPC solve time come from all its runs. A robot that falls walking on flat ground is
reported so, and is not pushed or sent down a step.

Then each other gait of the plan (``gaits:``, e.g. the trot and the walking trot) at set-points
from the robot's leg length (the trot's forward at a Froude number) or its crawl set-point: a
walk forward then a stop (achieved over the last whole cycles of the gait before the stop, and
the standing still after it), a walk sideways then turning, lateral pushes at phases of the
gait's cycle and blind step downs one after the other up to the first not crossed.

Runs go through the experiments' runner (``runs.Runner``): a run's folder is named after a hash
of its scenario and the code, so a run made before is read, not made again; at most ``--jobs``
at once, each on its own ROS_DOMAIN_ID from ``--domain-base``. The page names the revision and
code fingerprint it was made from.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np

from replan_core.common.types import LEGS
from replan_core.evaluation.metrics import steady_velocity as last_cycles_velocity
from replan_experiments.plan import ExperimentError
from replan_experiments.push_effects import read_truth
from replan_experiments.robot_info import RobotInfo, robot_info
from replan_experiments.robots_plan import (
    ROBOT_KEYS,
    RobotsPlan,
    froude_number,
    gait_fast_doc,
    gait_plan,
    gait_turn_doc,
    gait_walk_doc,
    listed_parameters,
    load_robots_plan,
    push_doc,
    push_force,
    push_times,
    quiet_window,
    response_doc,
    stand_doc,
    step_doc,
    step_geometry,
    walk_doc,
    walk_start,
)
from replan_experiments.runs import (
    DEFAULT_DOMAIN_BASE,
    Progress,
    Runner,
    RunResult,
    git_revision,
)
from replan_experiments.stats import steady_velocity

# -- what a run measured ---------------------------------------------------------------------


def walk_row(result: RunResult, axis: str, commanded: float) -> dict:
    """Achieved against commanded on ``axis`` (mean body-frame velocity of the truth over the
    last whole crawl cycles, ``stats.steady_velocity``, of the last segment with a set-point;
    after the settling if it has none: ``cycles`` 0), or the fall."""
    row = {'run': result.key, 'ok': result.ok, 'fell': result.fell, 'commanded': commanded,
           'fall_time_s': result.metrics.get('fall_time_s'), 'achieved': None, 'cycles': 0}
    segments = [s for s in result.metrics.get('velocity_tracking') or []
                if any(s.get('commanded') or [])]
    if segments and segments[-1].get('achieved') is not None:
        last = segments[-1]
        row['achieved'] = float(steady_velocity(last)[ROBOT_KEYS.index(axis)])
        row['cycles'] = (int(last['steady_cycles']) if last.get('achieved_steady') else
                         int(last.get('cycles') or 0) if last.get('achieved_cycles') else 0)
    return row


def stand_measures(bag: Path, drift_from: float) -> dict | None:
    """From the truth of a stand's bag: the trunk's horizontal travel and the touchdowns (a
    foot's true contact flag rising) from ``drift_from`` (s) to the end; None without the
    truth."""
    base, contacts = read_truth(bag)
    return drift_and_touchdowns([(t, b.position) for t, b in base.items()],
                                [(t, contacts[t].contact) for t in sorted(contacts)],
                                drift_from)


def drift_and_touchdowns(positions: list, contacts: list, drift_from: float) -> dict | None:
    """``stand_measures`` from (stamp, xyz) and (stamp, four contact flags), by stamp:
    ``travel_m`` the largest horizontal distance from the trunk at ``drift_from``, ``drift_m``
    its distance at the end, ``touchdowns`` the rising contact flags after ``drift_from``."""
    window = [(t, np.asarray(p, float)) for t, p in positions if t >= drift_from]
    if len(window) < 2:
        return None
    start = window[0][1]
    distances = [float(np.linalg.norm(p[:2] - start[:2])) for _, p in window]
    touchdowns, last = 0, None
    after = [(t, np.asarray(c, bool)) for t, c in contacts if t >= drift_from]
    if len(after) > 1:
        flags = np.array([c for _, c in after])
        stamps = np.array([t for t, _ in after])[1:]
        rises = flags[1:] & ~flags[:-1]
        touchdowns = int(rises.sum())
        if rises.any():
            last = round(float(stamps[np.flatnonzero(rises.any(axis=1))[-1]]), 3)
    return {'drift_m': round(distances[-1], 5), 'travel_m': round(max(distances), 5),
            'drift_window_s': [round(float(window[0][0]), 3), round(float(window[-1][0]), 3)],
            'touchdowns': touchdowns, 'last_touchdown_s': last}


def response_row(result: RunResult) -> dict:
    """Per set-point of a response run (forward, lateral, yaw, in ``ROBOT_KEYS`` order): the
    commanded component's mean over each whole crawl cycle after the change opened by each
    leg, as a share of the set-point (``leg_cycle_velocities`` of the truth), the worst first
    cycle's and the worst later cycle's distance from 1, and the largest share (overshoot
    above 1); or the fall."""
    row = {'run': result.key, 'ok': result.ok, 'fell': result.fell,
           'fall_time_s': result.metrics.get('fall_time_s'), 'axes': {}}
    segments = [s for s in result.metrics.get('velocity_tracking') or []
                if any(s.get('commanded') or [])]
    for segment in segments:
        axis, cell = response_axis(segment)
        row['axes'][axis] = cell
    return row


def response_axis(segment: dict) -> tuple[str, dict]:
    """The commanded component of one set-point of ``metrics.json``'s ``velocity_tracking``
    (its largest, one of ``ROBOT_KEYS``) and its response cell: per leg, in the order the legs
    open their cycles, its first touchdown after the change (s) and the mean of the component
    over each whole crawl cycle it opens, as a share of the set-point (``legs``); the worst
    first cycle's and the worst later cycle's distance from 1 over the legs, and the largest
    share less 1 (``robots_render.response_misses`` judges it). Every leg is judged alike: the
    first cycles of the four legs start a step apart on the way to the new speed."""
    commanded = segment['commanded']
    k = int(np.argmax(np.abs(commanded)))
    legs = [{'leg': LEGS[row['leg']], 'start_s': row['cycles'][0]['start_s'],
             'shares': [round(c['velocity'][k] / commanded[k], 4) for c in row['cycles']]}
            for row in segment.get('leg_cycle_velocities') or []]
    firsts = [leg['shares'][0] for leg in legs]
    laters = [x for leg in legs for x in leg['shares'][1:]]
    return ROBOT_KEYS[k], {
        'commanded': commanded[k], 'start_s': segment.get('start_s'), 'legs': legs,
        'first_error': round(max(abs(x - 1.0) for x in firsts), 4) if firsts else None,
        'later_error': round(max(abs(x - 1.0) for x in laters), 4) if laters else None,
        'overshoot': round(max(firsts + laters) - 1.0, 4) if firsts else None}


def cached_stand_measures(folder: Path, drift_from: float) -> dict | None:
    """``stand_measures`` of the run in ``folder``, kept in ``folder/stand.json``."""
    key = {'drift_from': drift_from, 'measures': 'travel'}
    cache = folder / 'stand.json'
    if cache.exists():
        try:
            stored = json.loads(cache.read_text())
            if stored.get('key') == key:
                return stored.get('measures')
        except (OSError, ValueError):
            pass
    if not (folder / 'bag').exists():
        return None
    measures = stand_measures(folder / 'bag', drift_from)
    cache.write_text(json.dumps({'key': key, 'measures': measures}))
    return measures


# -- the runs of one robot -------------------------------------------------------------------


def push_ladder(runner: Runner, base: dict, info: RobotInfo, plan: RobotsPlan) -> dict:
    """Level after level (all phases of a level at once) up to the first level at which the
    robot falls at some phase, or a run fails: the largest level survived at every phase."""
    cfg, times = plan.tests['push'], push_times(base, info, plan)
    levels, survived, fell_at, failed = [], None, None, False
    with ThreadPoolExecutor(max(len(times), 1)) as pool:
        for dv in cfg['levels']:
            results = list(pool.map(lambda t, dv=dv: runner.run(push_doc(base, info, plan, dv,
                                                                          t)), times))
            force = float(np.linalg.norm(push_force(info, plan, dv)))
            levels.append({'dv_mps': dv, 'force_n': round(force, 2),
                           'impulse_ns': round(force * cfg['push_duration'], 3),
                           'phases': [{'t': t, 'phase': k, 'ok': r.ok, 'fell': r.fell,
                                       'run': r.key}
                                      for k, (t, r) in enumerate(zip(times, results,
                                                                     strict=True))]})
            if not all(r.ok for r in results):
                failed = True
                break
            if any(r.fell for r in results):
                fell_at = dv
                break
            survived = dv
    return {'levels': levels, 'survived_dv': survived, 'fell_dv': fell_at, 'failed': failed,
            'phases': len(times), 'times_s': times, 'cycle_s': round(info.cycle_s, 4)}


def step_row(result: RunResult, geometry: dict) -> dict:
    x = (result.metrics.get('final_position_m') or [None])[0]
    crossed = (bool(not result.fell and x is not None and x > geometry['cross_x_m'])
               if result.ok else None)
    return {**geometry, 'run': result.key, 'ok': result.ok, 'fell': result.fell,
            'fall_time_s': result.metrics.get('fall_time_s'), 'final_x_m': x,
            'crossed': crossed}


def timing(results: list[RunResult]) -> dict:
    """Real-time factor and MPC solve time over the robot's runs that completed."""
    ok = [r.metrics for r in results if r.ok]

    def pick(key: str) -> list[float]:
        return [float(m[key]) for m in ok if m.get(key) is not None]
    rtf, median, p99 = pick('real_time_factor'), pick('mpc_solve_ms_median'), pick(
        'mpc_solve_ms_p99')
    return {'runs': len(ok),
            'rtf_median': round(float(np.median(rtf)), 3) if rtf else None,
            'rtf_min': round(min(rtf), 3) if rtf else None,
            'mpc_median_ms': round(float(np.median(median)), 3) if median else None,
            'mpc_p99_max_ms': round(max(p99), 3) if p99 else None}


def measure_robot(runner: Runner, plan: RobotsPlan, info: RobotInfo) -> dict:
    """Every run of one robot and what they measured (the page's column)."""
    walk_base = runner.scenario(plan.tests['walk']['scenario'])
    stand_base = runner.scenario(plan.tests['stand']['scenario'])
    response_base = runner.scenario(plan.tests['response']['scenario'])
    step_base = runner.scenario(plan.tests['step_down']['scenario'])
    made: list[RunResult] = []
    row: dict = {'robot': info.name, 'setpoints': plan.robots[info.name],
                 'cycle_s': round(info.cycle_s, 4)}
    with ThreadPoolExecutor(8) as pool:
        walks = {axis: pool.submit(runner.run, walk_doc(walk_base, info, plan, axis))
                 for axis in ROBOT_KEYS}
        stand = pool.submit(runner.run, stand_doc(stand_base, info, plan), True)
        responses = [(seed, phase, pool.submit(runner.run, response_doc(
            response_base, info, plan, seed, phase)))
            for seed in plan.tests['response']['seeds']
            for phase in range(plan.tests['response']['phases'])]
        forward = walks['forward'].result()
        steps, row['push'] = [], None
        walks_on_flat = forward.ok and not forward.fell
        if walks_on_flat:
            steps = [(share, pool.submit(runner.run, step_doc(step_base, info, plan, share)))
                     for share in plan.tests['step_down']['shares']]
            row['push'] = push_ladder(runner, walk_base, info, plan)
        row['walks'] = {}
        for axis, future in walks.items():
            made.append(future.result())
            row['walks'][axis] = walk_row(made[-1], axis, plan.robots[info.name][axis])
        stand_run = stand.result()
        made.append(stand_run)
        row['stand'] = {'run': stand_run.key, 'ok': stand_run.ok, 'fell': stand_run.fell,
                        'fall_time_s': stand_run.metrics.get('fall_time_s'),
                        **((cached_stand_measures(stand_run.folder,
                                                  plan.tests['stand']['drift_from']) or {})
                           if stand_run.ok else {})}
        row['response'] = []
        for seed, phase, future in responses:
            made.append(future.result())
            row['response'].append({'seed': seed, 'phase': phase, **response_row(made[-1])})
        row['step_down'] = []
        for share, future in steps:
            made.append(future.result())
            row['step_down'].append(step_row(made[-1], step_geometry(info, plan, share)))
    if row['push']:
        made += [runner.results[p['run']] for level in row['push']['levels']
                 for p in level['phases'] if isinstance(runner.results.get(p['run']),
                                                        RunResult)]
    row['skipped'] = (None if walks_on_flat else
                      'falls walking forward on flat ground' if forward.ok
                      else 'the forward walk did not complete')
    row['timing'] = timing(made)
    return row


def planned_runs(plan: RobotsPlan) -> int:
    """Upper bound of the runs: per robot three walks, the stand, the response on each seed at
    each phase, every step down and every push level at every phase (the pushes stop at the
    first level that fells it); per other gait the walk and stop, the turn, every step down
    and every push."""
    def ladders(tests: dict) -> int:
        push = tests['push']
        return len(tests['step_down']['shares']) + len(push['levels']) * push['phases']
    per_robot = (len(ROBOT_KEYS) + 1 + len(plan.tests['response']['seeds'])
                 * plan.tests['response']['phases'] + ladders(plan.tests))
    per_robot += sum(2 + ('fast' in g['tests']) + ladders(g['tests'])
                     for g in plan.gaits.values())
    return per_robot * len(plan.robots)


# -- the other gaits -------------------------------------------------------------------------


def gait_axes(result: RunResult, steady_cycles: int) -> dict:
    """Per segment with a set-point of a gait's run (its axis: the set-point's largest
    component): the mean of that component over the last ``steady_cycles`` whole cycles of
    the gait (a true touchdown of a leg to its next) before the next set-point, as a share of
    the set-point (``share`` None with fewer cycles), the cycles it had and each whole cycle's
    mean as a share (``cycle_shares``: how much one cycle scatters about the mean)."""
    axes = {}
    for segment in result.metrics.get('velocity_tracking') or []:
        commanded = segment.get('commanded') or []
        if not any(commanded):
            continue
        k = int(np.argmax(np.abs(commanded)))
        cycles = segment.get('cycle_velocities') or []
        steady = last_cycles_velocity(cycles, steady_cycles)
        axes[ROBOT_KEYS[k]] = {'commanded': commanded[k], 'cycles': len(cycles),
                               'achieved': None if steady is None else round(steady[k], 5),
                               'share': (None if steady is None
                                         else round(steady[k] / commanded[k], 4)),
                               'cycle_shares': [round(c['velocity'][k] / commanded[k], 4)
                                                for c in cycles]}
    return axes


def _run_row(result: RunResult) -> dict:
    return {'run': result.key, 'ok': result.ok, 'fell': result.fell,
            'fall_time_s': result.metrics.get('fall_time_s')}


def step_ladder(runner: Runner, base: dict, info: RobotInfo, plan: RobotsPlan) -> list[dict]:
    """The step downs one after the other, up to the first share not crossed."""
    rows = []
    for share in plan.tests['step_down']['shares']:
        rows.append(step_row(runner.run(step_doc(base, info, plan, share)),
                             step_geometry(info, plan, share)))
        if not rows[-1]['crossed']:
            break
    return rows


def measure_gait(runner: Runner, plan: RobotsPlan, info: RobotInfo) -> dict:
    """Every run of one robot in the gait of ``plan`` (``gait_plan``; ``info`` the robot in
    that gait): the walk and stop (achieved forward, the standing after it), the turn
    (achieved lateral and yaw), the pushes and the step downs; the last two only if the walk
    did not fall."""
    tests = plan.tests
    walk_base = runner.scenario(tests['walk']['scenario'])
    turn_base = runner.scenario(tests['turn']['scenario'])
    step_base = runner.scenario(tests['step_down']['scenario'])
    setpoints = plan.robots[info.name]
    row: dict = {'gait': plan.gait, 'setpoints': setpoints, 'cycle_s': round(info.cycle_s, 4),
                 'froude': round(froude_number(setpoints['forward'], info.leg_length_m), 4),
                 'push': None, 'step_down': []}
    with ThreadPoolExecutor(2) as pool:
        turn_future = pool.submit(runner.run, gait_turn_doc(turn_base, info, plan))
        fast_future = (pool.submit(runner.run, gait_fast_doc(
            runner.scenario(tests['fast']['scenario']), info, plan)) if 'fast' in tests
            else None)
        walk = runner.run(gait_walk_doc(walk_base, info, plan), True)
        walks_on_flat = walk.ok and not walk.fell
        if walks_on_flat:
            steps = pool.submit(step_ladder, runner, step_base, info, plan)
            row['push'] = push_ladder(runner, walk_base, info, plan)
            row['step_down'] = steps.result()
        turn = turn_future.result()
    row['walk'] = {**_run_row(walk), 'axes': gait_axes(walk, tests['walk']['steady_cycles'])}
    row['turn'] = {**_run_row(turn), 'axes': gait_axes(turn, tests['turn']['steady_cycles'])}
    fast = fast_future.result() if fast_future else None
    if fast is not None:
        row['fast'] = {**_run_row(fast), 'froude': tests['fast']['froude'],
                       'axes': gait_axes(fast, tests['fast']['steady_cycles'])}
    begin, end = quiet_window(info, plan, walk_start(walk_base))
    standing = None
    if walks_on_flat and (walk.folder / 'bag').exists():
        standing = cached_stand_measures(walk.folder, begin)
    row['standing'] = {'window_s': [begin, end], **(standing or {})}
    made = [walk, turn] + ([fast] if fast else []) + [runner.results[s['run']]
                                                      for s in row['step_down']]
    if row['push']:
        made += [runner.results[p['run']] for level in row['push']['levels']
                 for p in level['phases']]
    made = [r for r in made if isinstance(r, RunResult)]
    row['falls'] = [r.key for r in made if r.ok and r.fell]
    row['runs'] = len(made)
    row['skipped'] = (None if walks_on_flat else
                      'falls walking forward on flat ground' if walk.ok
                      else 'the forward walk did not complete')
    row['timing'] = timing(made)
    return row


def measure_gaits(runner: Runner, plan: RobotsPlan, gait_infos: dict[str, dict[str, RobotInfo]],
                  name: str) -> dict:
    """``measure_gait`` of robot ``name`` in each of the plan's gaits (``gait_infos``: gait ->
    robot -> the robot in that gait)."""
    return {gait: measure_gait(runner, gait_plan(plan, gait, infos), infos[name])
            for gait, infos in gait_infos.items()}


def robot_facts_row(info: RobotInfo, plan: RobotsPlan) -> dict:
    """The page's facts and derived parameters of one robot."""
    return {'mass_kg': info.mass_kg, 'leg_length_m': info.leg_length_m,
            'standing_height_m': info.standing_height_m, 'com_height_m': info.com_height_m,
            'min_joint_inertia': info.min_joint_inertia, 'cycle_s': info.cycle_s,
            'parameters': listed_parameters(info, plan)}


# -- the command line ------------------------------------------------------------------------


def _arguments(argv) -> argparse.Namespace:
    parser = argparse.ArgumentParser(prog='robots_page.sh', description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('--quick', action='store_true',
                        help='the plan\'s quick section: one short run of each kind; the page '
                             'goes to DIR/robots.md')
    parser.add_argument('--jobs', type=int, default=1,
                        help='runs at once, each on its own ROS_DOMAIN_ID (default 1)')
    parser.add_argument('--robot', action='append', default=[], metavar='NAME',
                        help='only this robot of the plan (repeatable; default all)')
    parser.add_argument('--out', type=Path,
                        help='run folder (default runs/robots_page[-quick]); runs already in '
                             'it with the same scenario and code are read, not made again')
    parser.add_argument('--page', type=Path,
                        help='the page (default docs/robots.md, with --quick DIR/robots.md)')
    parser.add_argument('--plan', type=Path,
                        help='the plan (default config/robots_page.yaml)')
    parser.add_argument('--domain-base', type=int,
                        default=int(os.environ.get('REPLAN_EXPERIMENTS_DOMAIN',
                                                   DEFAULT_DOMAIN_BASE)),
                        help='each run takes the first ROS_DOMAIN_ID from here up that no '
                             f'graph holds (default {DEFAULT_DOMAIN_BASE})')
    parser.add_argument('--fresh', action='store_true', help='make every run again')
    parser.add_argument('--render', action='store_true',
                        help='no run: the page and the README\'s table again from '
                             'the robots.json of --out')
    parser.add_argument('--lock', type=Path, metavar='FILE',
                        help='hold this file lock (flock) during each run')
    parser.add_argument('--quiet', action='store_true', help='no progress line')
    args = parser.parse_args(argv)
    if not 1 <= args.jobs <= 8:
        parser.error('--jobs must be within 1..8')
    if not 0 <= args.domain_base <= 232 - args.jobs:
        parser.error('--domain-base must keep every job within ROS_DOMAIN_ID 0..232')
    return args


def _shown(path: Path, root: Path) -> str:
    """``path`` as the page names it: relative to the repository when inside it (a page made
    in one checkout names no folder of that machine)."""
    resolved = Path(path).resolve()
    return (str(resolved.relative_to(root)) if resolved.is_relative_to(root)
            else str(path))


README_BEGIN, README_END = '<!-- robots:begin -->', '<!-- robots:end -->'


def _fill_readme(root: Path, page: Path, data: dict) -> None:
    """The README's short table of the page (``robots_render.readme_block``), for the full
    page of the repository only (a quick or elsewhere-written page is not the project's)."""
    from replan_experiments.findings import replace_block
    from replan_experiments.robots_render import readme_block
    if data['meta'].get('quick') or page.resolve() != (root / 'docs' / 'robots.md').resolve():
        return
    if replace_block(root / 'README.md', README_BEGIN, README_END, readme_block(data)):
        print(f'[robots_page] README.md: its table between {README_BEGIN} and {README_END}')


def render_saved(root: Path, out: Path, page: Path) -> int:
    """``--render``: the page and the README's table again from ``out``/robots.json, no run."""
    from replan_experiments.robots_render import render_page
    saved = out / 'robots.json'
    if not saved.is_file():
        print(f'robots_page: --render: no {saved} (run the page first)', file=sys.stderr)
        return 2
    data = json.loads(saved.read_text())
    page.write_text(render_page(data))
    _fill_readme(root, page, data)
    print(f'[robots_page] page {page} rendered again from {saved}')
    return 0


def main(argv=None) -> int:
    from replan_experiments.robots_render import render_page
    from replan_experiments.runner import machine_description
    from replan_ros.params import ConfigError

    args = _arguments(argv)
    root = Path(os.environ.get('REPLAN_ROOT', '.')).resolve()
    config_dir = Path(os.environ.get('REPLAN_CONFIG', root / 'config'))
    plan_file = args.plan or config_dir / 'robots_page.yaml'
    try:
        plan = load_robots_plan(plan_file, args.quick, args.robot)
        infos = {name: robot_info(config_dir, name, plan.profile) for name in plan.robots}
        gait_infos = {gait: {name: robot_info(config_dir, name, plan.profile, gait=gait)
                             for name in plan.robots} for gait in plan.gaits}
        gait_plans = {gait: gait_plan(plan, gait, gait_infos[gait]) for gait in plan.gaits}
        facts = {name: robot_facts_row(info, plan) for name, info in infos.items()}
    except (ExperimentError, ConfigError, ValueError) as err:
        print(f'robots_page: {err}', file=sys.stderr)
        return 2
    out = args.out or root / 'runs' / ('robots_page-quick' if args.quick else 'robots_page')
    page = args.page or (out / 'robots.md' if args.quick else root / 'docs' / 'robots.md')
    if args.render:
        return render_saved(root, out, page)
    out.mkdir(parents=True, exist_ok=True)
    progress = Progress(planned_runs(plan), quiet=args.quiet)
    runner = Runner(out, config_dir, jobs=args.jobs, domain_base=args.domain_base,
                    fresh=args.fresh, progress=progress, lock_file=args.lock)
    print(f'[robots_page] {", ".join(plan.robots)}: {"quick" if args.quick else "full"} plan '
          f'of {plan_file}, {args.jobs} runs at a time, in {out}; page {page}')
    started = time.monotonic()
    try:
        with ThreadPoolExecutor(len(infos)) as pool:
            rows = dict(zip(infos, pool.map(
                lambda i: {**measure_robot(runner, plan, i),
                           'gaits': measure_gaits(runner, plan, gait_infos, i.name)},
                infos.values()), strict=True))
    except ExperimentError as err:
        progress.close()
        print(f'robots_page: {err}', file=sys.stderr)
        return 2
    progress.close()
    made = [r for r in runner.results.values() if isinstance(r, RunResult)]
    command = 'scripts/robots_page.sh ' + ' '.join(argv if argv is not None else sys.argv[1:])
    meta = {'command': command.strip(), 'machine': machine_description(),
            'revision': git_revision(root), 'code': runner.code,
            'date': time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime()),
            'wall_time_min': round((time.monotonic() - started) / 60.0, 1),
            'runs': sum(r.ok for r in made), 'reused': progress.reused, 'quick': args.quick,
            'jobs': args.jobs, 'failures': runner.failures, 'plan_file': _shown(plan_file, root),
            'profile': plan.profile, 'seed': plan.seed, 'tests': plan.tests,
            'gaits': {gait: {'setpoints': plan.gaits[gait]['setpoints'],
                             'tests': gait_plans[gait].tests} for gait in plan.gaits}}
    data = {'meta': meta, 'facts': facts, 'robots': rows}
    (out / 'robots.json').write_text(json.dumps(data, indent=1, default=str))
    page.parent.mkdir(parents=True, exist_ok=True)
    page.write_text(render_page(data))
    _fill_readme(root, page, data)
    print(f'[robots_page] {meta["runs"]} runs ({progress.reused} reused) in '
          f'{meta["wall_time_min"]} min; page {page}, data {out / "robots.json"}')
    for failure in runner.failures:
        print(f'[robots_page] run failed: {failure}', file=sys.stderr)
    return 1 if runner.failures else 0


if __name__ == '__main__':
    sys.exit(main())
