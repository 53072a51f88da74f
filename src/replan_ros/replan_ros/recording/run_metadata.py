"""What a bag says about its run, and when its messages arrived: the bag's path, the mcap
metadata records of the run's configuration (``replan_run``: git revision, recorder parameters,
command line, ...; ``replan_config``: path -> content of each config file; ``replan_scenario``;
``replan_user``), and the log time of a message taken from a DDS queue (``arrival_time``)."""

from __future__ import annotations

import json
import os
import socket
import subprocess
import sys
from datetime import datetime
from pathlib import Path

from replan_ros.recording.bag_files import recovered_name


def git_output(root: Path, *args: str) -> str:
    """stdout of ``git -C root args``, '' without git or a repository."""
    try:
        out = subprocess.run(['git', '-C', str(root), *args], capture_output=True, text=True,
                             timeout=5, check=True)
        return out.stdout.strip()
    except (OSError, subprocess.SubprocessError):
        return ''


def bag_path(output: str) -> Path:
    """The bag file: ``output`` if it names an .mcap file, else a time-stamped file in the
    folder ``output`` (default: $REPLAN_ROOT/runs). A name taken (a respawned recorder within
    the same second, or a given file that exists) gets ``_1``, ``_2``, ...: a killed
    recorder's file is never overwritten, and the new one sorts after it (a split)."""
    stamp = datetime.now().strftime('%Y%m%d_%H%M%S')
    target = Path(output) if output else Path(os.environ.get('REPLAN_ROOT', '.'), 'runs')
    if target.suffix != '.mcap':
        target = target / f'replan_{stamp}.mcap'
    base, number = target, 0
    while target.exists() or recovered_name(target).exists():
        number += 1
        target = base.with_name(f'{base.stem}_{number}.mcap')
    return target.resolve()


def run_records(p: dict, use_sim_time: bool) -> tuple[list[tuple[str, dict]], list[str]]:
    """The metadata records (name, string map) of a run recorded with the recorder's
    parameters ``p``, and what could not be stored (one line each)."""
    root = Path(os.environ.get('REPLAN_ROOT', Path(__file__).resolve().parents[4]))
    # Without git or a .git folder (a Docker image), the revision baked in at build time.
    revision = (git_output(root, 'rev-parse', 'HEAD') or os.environ.get('REPLAN_GIT_REVISION')
                or 'unknown')
    status = git_output(root, 'status', '--porcelain', '--untracked-files=no')
    records = [('replan_run', {
        'git_revision': revision,
        'git_dirty': 'true' if status else 'false',
        'git_status': status,
        'wall_start': datetime.now().astimezone().isoformat(),
        'hostname': socket.gethostname(),
        'ros_distro': os.environ.get('ROS_DISTRO', 'jazzy'),
        'rmw_implementation': os.environ.get('RMW_IMPLEMENTATION', ''),
        'ros_domain_id': os.environ.get('ROS_DOMAIN_ID', '0'),
        'command_line': ' '.join(sys.argv),
        'use_sim_time': str(use_sim_time).lower(),
        'log_time_clock': p['log_time_clock'],
        'recorder_parameters': json.dumps(p, sort_keys=True),
        'config_files': json.dumps([str(Path(f).resolve()) for f in p['config_files']]),
        'scenario_file': str(Path(p['scenario_file']).resolve()) if p['scenario_file'] else '',
    })]
    errors = []
    configs = {}
    for name in p['config_files']:
        path = Path(name).resolve()
        try:
            configs[str(path)] = path.read_text()
        except OSError as err:
            errors.append(f'config file {path} not stored: {err}')
    if configs:
        records.append(('replan_config', configs))
    if p['scenario_file']:
        path = Path(p['scenario_file']).resolve()
        try:
            records.append(('replan_scenario', {'path': str(path), 'content': path.read_text()}))
        except OSError as err:
            errors.append(f'scenario file {path} not stored: {err}')
    if p['metadata_json']:
        try:
            extra = json.loads(p['metadata_json'])
            if not isinstance(extra, dict):
                raise ValueError('not a JSON object')
            records.append(('replan_user', {
                str(k): v if isinstance(v, str) else json.dumps(v) for k, v in extra.items()}))
        except ValueError as err:
            errors.append(f'metadata_json not stored: {err}')
    return records, errors


def arrival_time(received_wall_ns: int, previous: tuple[int, int] | None,
                 take: tuple[int, int]) -> int:
    """The ``log_time_clock``'s time when a message arrived: its DDS reception time (wall,
    CLOCK_REALTIME) placed between the previous take and this one, each a (wall ns, log clock
    ns) pair, linearly. A message that arrived before the previous take
    gets that take's time; without a previous take or a reception time, this take's. So log
    times follow arrival, not the take grid, and never decrease while the clock does not."""
    if previous is None or received_wall_ns <= 0 or take[0] <= previous[0]:
        return take[1]
    fraction = min(max((received_wall_ns - previous[0]) / (take[0] - previous[0]), 0.0), 1.0)
    return previous[1] + round(fraction * (take[1] - previous[1]))
