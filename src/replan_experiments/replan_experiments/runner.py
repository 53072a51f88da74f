"""The paper's experiments on the realistic robot, many runs per claim, and the results page.

    scripts/experiments.sh [--quick | --pilot] [--jobs N | --ray ADDRESS] [--only NAME ...]
                           [--out DIR] [--page FILE] [--robot NAME|FILE]

Runs the experiments of ``config/experiments.yaml`` (``full``, or ``quick`` with --quick) as
scenario runs (``replan_experiments.scenario``, one process graph each, on its own
ROS_DOMAIN_ID), then writes the results page (``docs/results.md`` for a full run, DIR/results.md
for a quick one, plots beside it) from the runs' ``metrics.json``: per claim the metric's mean,
spread and number of runs, the paper's claim and whether the runs support it.

Each claim pre-registers one primary test (the plan file's ``primary`` blocks); the page gives
verdicts to those alone, on the confirmatory runs, whose keys hold the plan's hash. ``--pilot``
makes the pilot runs instead (each pre-registered claim on its ``pilot_seeds``; page
DIR/results-pilot.md, no verdicts). A full call that writes docs/results.md also fills the
verdict table between the ``<!-- results:begin -->`` and ``<!-- results:end -->`` markers of
README.md.

A run's folder is named after a hash of its scenario document, so a run already made with the
same document (an interrupted call, or two experiments sharing a run) is read, not made again
(``--fresh`` makes every run again). Lock-step makes a run the same however many run at once.

With ``--ray ADDRESS`` every run to be made is a Ray task on a cluster (``auto``,
``HOST:PORT`` or ``ray://HOST:10001``, as ray.init takes it; ``local`` starts a private one
here with --jobs graph slots, default one per core). Start the cluster first, on each node
from a checkout at this revision, set up with ``scripts/setup.sh --with-ray`` and after
``source scripts/env.sh``:

    ray start --head --port=6379 --resources='{"graph_slot": 2}'      # the first node
    ray start --address=HEAD:6379 --resources='{"graph_slot": 2}'     # every other node

``graph_slot`` is how many process graphs a node runs at once (about one per core); each
takes its own ROS_DOMAIN_ID of that node from --domain-base up. The runs' folders come back
here; the cache, the progress line and the page are the same as with --jobs. A node that runs
other code than this checkout is refused. More: docs/cluster.md.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import time
from pathlib import Path

from replan_experiments.claims import run_all
from replan_experiments.findings import fill_readme
from replan_experiments.page import write_page
from replan_experiments.plan import (
    EXPERIMENTS,
    ExperimentError,
    load_plan,
    pilot_plan,
    planned_runs,
    preregistration,
)
from replan_experiments.runs import (
    DEFAULT_DOMAIN_BASE,
    Progress,
    Runner,
    RunResult,
    bag_gaps,
    git_revision,
)
from replan_ros.launch.launch_graph import add_robot_option
from replan_ros.launch.param_files import profile_file, robot_parameters
from replan_ros.params import ConfigError


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


def make_runner(args: argparse.Namespace, out: Path, config_dir: Path, jobs: int,
                progress: Progress) -> Runner:
    """The local runner (``--jobs``), or the Ray one (``--ray``), imported only then: Ray is
    an optional dependency."""
    common = dict(domain_base=args.domain_base, fresh=args.fresh, progress=progress,
                  lock_file=args.lock, robot=args.robot)
    if not args.ray:
        return Runner(out, config_dir, jobs=jobs, **common)
    from replan_experiments.ray_runs import RayRunner
    return RayRunner(out, config_dir, address=args.ray, slots=jobs, **common)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog='experiments.sh', description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('--quick', action='store_true',
                        help='one short run of each kind (a few minutes): checks the page is '
                             'produced; the page goes to DIR/results.md')
    parser.add_argument('--pilot', action='store_true',
                        help='the pilot runs: each pre-registered claim on its pilot_seeds; '
                             'the page (DIR/results-pilot.md) gives no verdicts')
    parser.add_argument('--jobs', type=int,
                        help='runs at once, each on its own ROS_DOMAIN_ID (default 1; with '
                             '--ray local: the private cluster\'s graph slots, default one '
                             'per core)')
    parser.add_argument('--ray', metavar='ADDRESS',
                        help='make the runs as tasks on the Ray cluster at ADDRESS (auto, '
                             'HOST:PORT, ray://HOST:10001) or on a private one (local); needs '
                             'scripts/setup.sh --with-ray')
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
                        help='each run takes the first ROS_DOMAIN_ID from here up that no '
                             f'graph holds (default {DEFAULT_DOMAIN_BASE})')
    parser.add_argument('--fresh', action='store_true', help='make every run again')
    parser.add_argument('--lock', type=Path, metavar='FILE',
                        help='hold this file lock (flock) during each run, to share the '
                             'machine with other graph runs that take it')
    parser.add_argument('--quiet', action='store_true', help='no progress line')
    add_robot_option(parser, default=None)
    args = parser.parse_args(argv)
    if args.quick and args.pilot:
        parser.error('--pilot goes with the full plan, not with --quick')
    if args.ray and args.ray != 'local' and args.jobs is not None:
        parser.error('--jobs goes with --ray local only: a cluster\'s nodes say their '
                     'graph slots (ray start --resources)')
    jobs = args.jobs or ((os.cpu_count() or 1) if args.ray == 'local' else 1)
    if jobs < 1 or jobs > 8:
        parser.error('--jobs must be within 1..8')
    if not 0 <= args.domain_base <= 232 - jobs:
        parser.error('--domain-base must keep every job within ROS_DOMAIN_ID 0..232')
    root = Path(os.environ.get('REPLAN_ROOT', '.')).resolve()
    config_dir = Path(os.environ.get('REPLAN_CONFIG', root / 'config'))
    plan_file = args.plan or config_dir / 'experiments.yaml'
    try:
        plan, selected = load_plan(plan_file, args.quick, args.only)
        shown = (plan_file.resolve().relative_to(root)
                 if plan_file.resolve().is_relative_to(root) else plan_file)
        prereg = preregistration(plan, shown, 'quick' if args.quick else
                                 'pilot' if args.pilot else 'confirmatory')
        if args.pilot:
            plan = pilot_plan(plan)
        if args.robot:       # a wrong robot stops here, in one line, before any run
            robot_parameters(config_dir, args.robot, profile_file(config_dir, 'realistic'))
    except (ExperimentError, ConfigError) as err:
        print(f'experiments: {err}', file=sys.stderr)
        return 2
    out = args.out or root / 'runs' / ('experiments-quick' if args.quick else 'experiments')
    default_page = root / 'docs' / 'results.md'
    page = args.page or (out / 'results.md' if args.quick else
                         out / 'results-pilot.md' if args.pilot else default_page)
    out.mkdir(parents=True, exist_ok=True)
    total = planned_runs(plan, selected)
    progress = Progress(total, quiet=args.quiet)
    started = time.monotonic()
    try:
        runner = make_runner(args, out, config_dir, jobs, progress)
    except ExperimentError as err:
        print(f'experiments: {err}', file=sys.stderr)
        return 2
    where = (f'on the Ray cluster {args.ray}, {runner.graph_slots} graph slots'
             if args.ray else f'{jobs} at a time')
    print(f'[experiments] {", ".join(selected)}: up to {total} runs, {where}, '
          f'in {out}; page {page}')
    try:
        results = run_all(plan, selected, runner)
    except ExperimentError as err:
        progress.close()
        print(f'experiments: {err}', file=sys.stderr)
        return 2
    finally:
        if args.ray:
            runner.close()
    progress.close()
    if getattr(runner, 'refused', None):
        print(f'experiments: {runner.refused}', file=sys.stderr)
        return 2
    wall = time.monotonic() - started
    command = 'scripts/experiments.sh ' + ' '.join(argv if argv is not None else sys.argv[1:])
    made = sum(1 for r in runner.results.values()
               if isinstance(r, RunResult) and r.ok)
    meta = {'command': command.strip(), 'machine': machine_description(),
            'revision': git_revision(root),
            'code': runner.code_for({'robot': runner.robot} if runner.robot else {}),
            'date': time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime()),
            'wall_time_min': round(wall / 60.0, 1), 'runs': made,
            'reused': progress.reused,
            'run_time_min': round(sum(
                r.metrics.get('wall_time_total_s') or 0.0 for r in runner.results.values()
                if isinstance(r, RunResult)) / 60.0, 1),
            'quick': args.quick, 'pilot': args.pilot, 'preregistration': prereg,
            'failures': runner.failures, 'plan_file': str(plan_file),
            'robot': args.robot,
            'bag_gaps': bag_gaps(runner.results.values(),
                                 results['settings']['control_period_s'])}
    (out / 'results.json').write_text(json.dumps({'meta': meta, 'results': results},
                                                 indent=1, default=str))
    write_page(page, results, meta)
    if page.resolve() == default_page.resolve() and fill_readme(root / 'README.md', results,
                                                                 meta):
        print('[experiments] README.md: the verdict table between its results markers')
    print(f'[experiments] {made} runs in {wall / 60:.1f} min; page {page}, data '
          f'{out / "results.json"}')
    for failure in runner.failures:
        print(f'[experiments] run failed: {failure}', file=sys.stderr)
    return 1 if runner.failures else 0


if __name__ == '__main__':
    sys.exit(main())
