"""A two-node Ray cluster for a test: head and worker started in network and process
namespaces of their own with only the loopback up (``replan_experiments.benchmarks.loopback``),
so that no cluster traffic leaves the machine and nothing of the cluster outlives the call."""

from __future__ import annotations

import json
import shlex
from pathlib import Path

from replan_experiments.benchmarks.loopback import command as loopback

# A node: 1 graph slot, a small object store (the runs send back a few hundred kB each).
NODE = "--num-cpus=1 --resources='{\"graph_slot\": 1}' --object-store-memory=80000000"
HEAD = ('ray start --head --node-ip-address=127.0.0.1 --port=6379 --include-dashboard=false '
        '--disable-usage-stats ' + NODE)
WORKER = 'ray start --address=127.0.0.1:6379 --node-ip-address=127.0.0.1 ' + NODE


def on_cluster(cmd: list[str], temp: str, worker_env: str = '') -> list[str]:
    """``cmd`` in a namespace of its own, after a head and a worker node were started there
    (``worker_env``: variables for the worker node's ``ray start``)."""
    script = (f'set -e; {HEAD} --temp-dir={temp} >/dev/null; '
              f'{worker_env} {WORKER} >/dev/null; exec {shlex.join(cmd)}')
    return loopback(['bash', '-c', script])


def run_metrics(out: Path) -> dict[str, dict]:
    """metrics.json of each run folder of an experiments call's ``out``, by run key."""
    return {p.parent.name: json.loads(p.read_text()) for p in (out / 'runs').glob('*/metrics.json')}
