"""A setting's effect on the response to set-point changes: each robot's response run of the
robots page (``config/robots_page.yaml``: forward from standing, then sideways, then turning)
with parameters overridden, on noise seeds, read as docs/robots.md and ``gait_report`` read it.

    scripts/response_variants.sh [--set NODE.KEY=VALUE ...] [--robot NAME ...] [--seed N ...]
                                 [--phase K ...] [--jobs N] [--out DIR]

Per robot, seed and phase of the changes, per set-point: each whole cycle opened by each leg,
judged as the page judges them (docs/gait.md, "Response to a set-point change"). Without
``--set``: today's settings. Runs go through the experiments' runner with their bags kept: a
run made before with the same scenario and code is read, not made again (default folder
``runs/response_variants``).
"""

from __future__ import annotations

import argparse
import os
import sys
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

from replan_experiments.gait_report import report
from replan_experiments.plan import ExperimentError, parse_settings, variant
from replan_experiments.robot_info import robot_info
from replan_experiments.robots_plan import RobotsPlan, load_robots_plan, response_doc
from replan_experiments.runs import DEFAULT_DOMAIN_BASE, Runner

# gait_report's line that judges a set-point: each leg's cycles, as the page judges them.
_JUDGED = 'as docs/robots.md judges them'


def settings(items: list[str]) -> dict[str, dict]:
    """``plan.parse_settings`` of the ``--set`` items; the sim's noise seed is ``--seed``'s,
    not a setting."""
    params = parse_settings(items)
    if 'noise_seed' in params.get('sim', {}):
        raise ExperimentError('--set sim.noise_seed: give the seeds with --seed')
    return params


def variant_doc(base: dict, info, plan: RobotsPlan, seed: int, params: dict,
                phase: int = 0) -> dict:
    """The page's response document of ``info``'s robot on noise seed ``seed`` with its
    changes at ``phase`` (``robots_plan.response_doc``) and ``params`` (node -> {key: value})
    on top of the scenario's own."""
    return variant(response_doc(base, info, plan, seed, phase), params=params,
                   world=plan.profile)


def judged_lines(lines: list[str]) -> list[str]:
    """The lines of a ``gait_report`` that judge each set-point."""
    return [line for line in lines if _JUDGED in line]


def _arguments(argv) -> argparse.Namespace:
    parser = argparse.ArgumentParser(prog='response_variants.sh', description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('--set', action='append', default=[], metavar='NODE.KEY=VALUE',
                        help='a parameter of the runs (repeatable), e.g. '
                             'gait.correction_threshold=0.3')
    parser.add_argument('--robot', action='append', default=[], metavar='NAME',
                        help='a robot of the plan (repeatable; default all)')
    parser.add_argument('--seed', action='append', type=int, default=[], metavar='N',
                        help="the sim's noise seed (repeatable; default the plan's response "
                             'seeds)')
    parser.add_argument('--phase', action='append', type=int, default=[], metavar='K',
                        help='the phase of the changes, 0 to the plan\'s response phases - 1 '
                             '(repeatable; default every phase of the plan)')
    parser.add_argument('--jobs', type=int, default=1,
                        help='runs at once, each on its own ROS_DOMAIN_ID (default 1)')
    parser.add_argument('--out', type=Path, help='run folder (default runs/response_variants)')
    parser.add_argument('--domain-base', type=int,
                        default=int(os.environ.get('REPLAN_EXPERIMENTS_DOMAIN',
                                                   DEFAULT_DOMAIN_BASE)),
                        help='each run takes the first ROS_DOMAIN_ID from here up that no '
                             f'graph holds (default {DEFAULT_DOMAIN_BASE})')
    args = parser.parse_args(argv)
    if not 1 <= args.jobs <= 8:
        parser.error(f'--jobs must be 1-8, got {args.jobs}')
    if any(seed < 0 for seed in args.seed):
        parser.error('--seed must be >= 0')
    return args


def main(argv=None) -> int:
    from replan_ros.params import ConfigError

    args = _arguments(argv)
    root = Path(os.environ.get('REPLAN_ROOT', '.')).resolve()
    config_dir = Path(os.environ.get('REPLAN_CONFIG', root / 'config'))
    try:
        params = settings(args.set)
        plan = load_robots_plan(config_dir / 'robots_page.yaml', False, args.robot)
        infos = [robot_info(config_dir, name, plan.profile) for name in plan.robots]
    except (ExperimentError, ConfigError, ValueError) as err:
        print(f'response_variants: {err}', file=sys.stderr)
        return 2
    seeds = args.seed or plan.tests['response']['seeds']
    phases = args.phase or list(range(plan.tests['response']['phases']))
    out = args.out or root / 'runs' / 'response_variants'
    out.mkdir(parents=True, exist_ok=True)
    runner = Runner(out, config_dir, jobs=args.jobs, domain_base=args.domain_base)
    base = runner.scenario(plan.tests['response']['scenario'])
    try:
        docs = [(f'{info.name}, seed {seed}, phase {phase}',
                 variant_doc(base, info, plan, seed, params, phase))
                for info in infos for seed in seeds for phase in phases]
    except ExperimentError as err:
        print(f'response_variants: {err}', file=sys.stderr)
        return 2
    print(f'[response_variants] {", ".join(plan.robots)}, seeds {seeds}, phases {phases}, '
          f'settings {params or "as configured"}; {args.jobs} runs at a time, in {out}',
          flush=True)
    with ThreadPoolExecutor(max(len(docs), 1)) as pool:
        results = list(pool.map(lambda d: runner.run(d[1], True), docs))
    failed = 0
    for (label, _), result in zip(docs, results, strict=True):
        print(f'{label} ({result.folder}):')
        if not result.ok:
            failed += 1
            print('  the run failed: see its output.log')
            continue
        try:
            lines = judged_lines(report(result.folder, after=2.0, late=0.04))
        except (OSError, ValueError) as err:
            failed += 1
            print(f'  no report: {err}')
            continue
        print('\n'.join(lines))
    for failure in runner.failures:
        print(f'[response_variants] run failed: {failure}', file=sys.stderr)
    return 1 if failed else 0


if __name__ == '__main__':
    sys.exit(main())
