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
import json
import os
import platform
import subprocess
import sys
import time
from pathlib import Path

from replan_ros.experiments.claims import run_all
from replan_ros.experiments.page import write_page
from replan_ros.experiments.plan import EXPERIMENTS, ExperimentError, load_plan, planned_runs
from replan_ros.experiments.runs import DEFAULT_DOMAIN_BASE, Progress, Runner, RunResult


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
            'revision': git_revision(root), 'code': runner.code,
            'date': time.strftime('%Y-%m-%d %H:%M UTC', time.gmtime()),
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
