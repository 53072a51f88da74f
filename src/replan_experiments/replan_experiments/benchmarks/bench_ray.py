"""Wall time of the quick experiments: the local runner against Ray tasks on a private cluster.

    scripts/bench_ray.sh [--out DIR] [--jobs N] [--domain-base ID]

Runs ``scripts/experiments.sh --quick`` twice into fresh folders, first with ``--jobs N``,
then with ``--ray local --jobs N`` (a private cluster with N graph slots), and prints each
call's wall time (start-up of Ray, the runs, the page) and their ratio. Both run in a network
namespace of their own with only the loopback up (``loopback``), so the cluster's traffic
stays on this machine and both calls see the same network.
"""

from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

from replan_experiments.benchmarks.loopback import command as loopback


def only_loopback() -> bool:
    """True when ``lo`` is this process's only network interface."""
    lines = Path('/proc/net/dev').read_text().splitlines()[2:]
    return [line.split(':')[0].strip() for line in lines] == ['lo']


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog='bench_ray.sh', description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('--out', type=Path, help='folder of both calls (default '
                        'runs/bench-ray; emptied first)')
    parser.add_argument('--jobs', type=int, default=2, help='runs at once (default 2)')
    parser.add_argument('--domain-base', type=int, default=210,
                        help='ROS_DOMAIN_ID of the first run (default 210)')
    args = parser.parse_args(argv)
    if not only_loopback():
        cmd = loopback([sys.executable, '-m', 'replan_experiments.benchmarks.bench_ray',
                        *(sys.argv[1:] if argv is None else argv)])
        os.execvp(cmd[0], cmd)
    root = Path(os.environ.get('REPLAN_ROOT', '.')).resolve()
    out = (args.out or root / 'runs' / 'bench-ray').resolve()
    common = ['--quick', '--quiet', '--jobs', str(args.jobs),
              '--domain-base', str(args.domain_base)]
    walls = {}
    for name, extra in (('local', []), ('ray', ['--ray', 'local'])):
        folder = out / name
        shutil.rmtree(folder, ignore_errors=True)
        cmd = [str(root / 'scripts' / 'experiments.sh'), *common, *extra, '--out', str(folder)]
        print(f'[bench_ray] {" ".join(cmd[1:])}', flush=True)
        start = time.monotonic()
        done = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
        walls[name] = time.monotonic() - start
        if done.returncode != 0:
            print(done.stdout, file=sys.stderr)
            print(f'[bench_ray] {name}: exit {done.returncode}', file=sys.stderr)
            return 1
        print(f'[bench_ray] {name}: {walls[name]:.1f} s', flush=True)
    print(f'[bench_ray] quick plan, {args.jobs} graphs at once: --jobs {walls["local"]:.1f} s, '
          f'--ray local {walls["ray"]:.1f} s, ratio {walls["ray"] / walls["local"]:.3f} '
          '(target <= 1.10)')
    return 0


if __name__ == '__main__':
    sys.exit(main())
