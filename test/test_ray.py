"""scripts/experiments.sh --ray on a real Ray cluster (``ray_cluster.py``): a killed worker's
run made again, a node with other code refused. The graphs run in the cluster's namespace, on
domains from the session's reserved one up (the Ray runner's per-node pool). The quick plan's
runs on a cluster against the local ones: test_experiments.py, which makes the local ones."""

from __future__ import annotations

import contextlib
import json
import os
import re
import shutil
import signal
import subprocess
import time
from pathlib import Path

import pytest
from harness import REPO_ROOT, descends_from, experiments, graph_env
from ray_cluster import on_cluster, run_metrics

pytest.importorskip('ray', reason='Ray is optional: scripts/setup.sh --with-ray')

from replan_experiments.benchmarks.loopback import command as loopback


def scenario_processes(ancestor: int) -> dict[int, int]:
    """pid -> parent pid of the scenario runs that descend from ``ancestor``."""
    found = {}
    for entry in Path('/proc').iterdir():
        if not entry.name.isdigit():
            continue
        try:
            cmdline = (entry / 'cmdline').read_bytes().split(b'\0')
            status = (entry / 'status').read_text()
        except OSError:
            continue
        if b'replan_experiments.scenario' in cmdline and b'-m' in cmdline:
            pid = int(entry.name)
            if descends_from(pid, ancestor):
                found[pid] = next(int(line.split()[1]) for line in status.splitlines()
                                  if line.startswith('PPid:'))
    return found


def test_a_killed_worker_is_retried_by_ray(ros_domain, tmp_path):
    plan = tmp_path / 'plan.yaml'
    plan.write_text('quick:\n  replan_window: {scenario: exp_walk, windows: [1], seeds: [0], '
                    'setpoints: [0.15], duration: 4.0}\n')
    out = tmp_path / 'out'
    cmd = loopback([str(REPO_ROOT / 'scripts' / 'experiments.sh'), '--quick', '--plan',
                    str(plan), '--ray', 'local', '--jobs', '1', '--out', str(out),
                    '--domain-base', str(ros_domain), '--quiet'])
    call = subprocess.Popen(cmd, env=graph_env(ros_domain), stdout=subprocess.PIPE,
                            stderr=subprocess.STDOUT, text=True)
    workers, killed = set(), None
    deadline = time.monotonic() + 300
    try:
        while call.poll() is None and time.monotonic() < deadline:
            for worker in set(scenario_processes(call.pid).values()) - workers:
                with contextlib.suppress(OSError):
                    if not Path(f'/proc/{worker}/cmdline').read_bytes().startswith(b'ray::'):
                        continue        # an orphan of the killed worker, not a worker
                workers.add(worker)
                if killed is None:
                    time.sleep(3.0)        # the graph is up and walking
                    os.kill(worker, signal.SIGKILL)
                    killed = worker
            time.sleep(0.2)
        output = call.communicate(timeout=max(deadline - time.monotonic(), 1))[0]
    finally:
        if call.poll() is None:
            call.kill()
            call.wait()
    assert call.returncode == 0, output
    assert killed is not None and len(workers) >= 2, (workers, output)   # made again
    data = json.loads((out / 'results.json').read_text())
    assert data['meta']['failures'] == [] and data['meta']['runs'] == 1, output
    (metrics,) = run_metrics(out).values()
    assert metrics['completed'] and metrics['sim_time_s'] == pytest.approx(4.0, abs=0.01)


def test_a_node_with_other_code_is_refused(ros_domain, tmp_path, ray_temp):
    # The worker node's checkout: a copy of this one with one parameter file changed.
    other = tmp_path / 'other'
    for part in ('src', 'config', 'urdf'):
        shutil.copytree(REPO_ROOT / part, other / part, symlinks=True,
                        ignore=shutil.ignore_patterns('__pycache__'))
    with open(other / 'config' / 'sim.yaml', 'a') as handle:
        handle.write('# changed\n')
    env = f'REPLAN_ROOT={other} REPLAN_CONFIG={other / "config"}'
    call = experiments(['--quick', '--only', 'velocity_changes', '--ray', '127.0.0.1:6379',
                        '--domain-base', str(ros_domain), '--quiet'], tmp_path / 'out',
                       graph_env(ros_domain), timeout=300,
                       wrap=lambda cmd: on_cluster(cmd, ray_temp, worker_env=env))
    assert call.done.returncode == 2, call.output
    refusal = [line for line in call.done.stderr.splitlines() if line.startswith('experiments:')]
    assert len(refusal) == 1, call.output
    assert re.search(r'node \S+ runs other code \(.*other: revision .*\) than this checkout',
                     refusal[0]), refusal
    assert not (tmp_path / 'out' / 'runs').exists()        # nothing was run
