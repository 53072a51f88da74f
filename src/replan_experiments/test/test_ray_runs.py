"""The parts of the Ray runner that need no cluster (replan_experiments/ray_runs.py): the
refusal of other code, the run folder sent back and the clean-up of a killed worker's folder
(its pool of ROS_DOMAIN_IDs: replan_ros/test/launch/test_domain.py). The runs on a real
cluster: test/test_ray.py."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

from replan_experiments.ray_runs import mismatch, read_back, work_folder


def test_other_code_is_refused_in_one_line():
    node = {'host': 'n1', 'root': '/x', 'code': 'aaa', 'revision': 'r1'}
    assert mismatch(node, 'aaa', 'r2') is None
    line = mismatch(node, 'bbb', 'r2')
    assert line and '\n' not in line and 'n1' in line and 'aaa' in line and 'bbb' in line


def test_the_bag_comes_back_only_when_asked(tmp_path):
    (tmp_path / 'metrics.json').write_text('{}')
    (tmp_path / 'logs').mkdir()
    (tmp_path / 'logs' / 'sim.log').write_text('x')
    (tmp_path / 'bag').mkdir()
    (tmp_path / 'bag' / 'bag_0.mcap').write_bytes(b'\x89MCAP')
    assert set(read_back(tmp_path, bag=False)) == {'metrics.json', 'logs/sim.log'}
    assert read_back(tmp_path, bag=True)['bag/bag_0.mcap'] == b'\x89MCAP'


def test_a_dead_workers_folder_is_removed_a_live_ones_never(tmp_path):
    """Who is alive is a lock, not a pid: a worker in another PID namespace (a second cluster
    on the machine, as CI's and a developer's) has pids this one cannot see."""
    # A killed worker's folder: its owner lock was dropped with the process.
    killed = subprocess.run(
        [sys.executable, '-c', 'import sys; from pathlib import Path; '
         'from replan_experiments.ray_runs import work_folder; '
         'ctx = work_folder(Path(sys.argv[1])); print(ctx.__enter__()); sys.stdout.flush(); '
         'import os; os._exit(0)', str(tmp_path)],
        capture_output=True, text=True, check=True).stdout.strip()
    assert Path(killed).is_dir()
    # A folder whose worker lives, with a pid that means nothing here (another namespace).
    with work_folder(tmp_path) as other:
        alive = other.rename(tmp_path / '999999999-other')
        with work_folder(tmp_path) as mine:
            assert mine.is_dir() and not Path(killed).exists()
            assert alive.is_dir()                               # its lock is held: it stays
            with work_folder(tmp_path) as second:
                assert second != mine and mine.is_dir()
            assert not second.exists()                          # removed on leaving
            assert '.owner' not in read_back(mine, bag=True)
