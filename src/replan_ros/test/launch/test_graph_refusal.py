"""launch.graph: a node that refuses its configuration (exit code 2) stops the graph with its
``config error:`` line and is not respawned; a node that dies otherwise is respawned. Stand-in
processes, no ROS."""

from __future__ import annotations

import sys
import time
from pathlib import Path

from replan_ros.launch.graph import EXIT_CONFIG, Graph, ManagedNode

CONFIG = Path(__file__).resolve().parents[4] / 'config'
REASON = 'config error: cannot derive /robot_description and /tf of x'


def _graph(tmp_path: Path, lines: list[str], code: int) -> Graph:
    graph = Graph(tmp_path / 'run', config_dir=CONFIG, profile='ideal', log=lines.append)
    script = ("print('[INFO] [recorder]: starting'); "
              f"print('[FATAL] [1.0] [recorder]: {REASON}'); raise SystemExit({code})")
    graph.nodes = [ManagedNode('recorder', [sys.executable, '-c', script],
                               graph.log_dir / 'recorder.log', respawn=True)]
    graph.nodes[0].start(graph.env)
    graph.nodes[0].process.wait(30)
    return graph


def test_a_node_that_refuses_its_configuration_stops_the_graph_without_respawn(tmp_path):
    lines: list[str] = []
    graph = _graph(tmp_path, lines, EXIT_CONFIG)
    assert graph.nodes[0].refused
    assert graph.poll() == EXIT_CONFIG
    assert lines[-1].endswith(f'recorder refused its configuration, stopping the graph: {REASON}')
    assert graph.nodes[0].respawn_at is None and graph.failed == ['recorder']
    graph.stop()


def test_a_node_that_dies_otherwise_is_respawned(tmp_path):
    lines: list[str] = []
    graph = _graph(tmp_path, lines, 1)
    assert not graph.nodes[0].refused
    assert graph.poll() is None
    assert graph.nodes[0].respawn_at is not None and 'respawning recorder in 1 s' in lines[-1]
    graph.nodes[0].respawn_at = time.monotonic()
    assert graph.poll() is None and graph.nodes[0].starts == 2
    graph.stop()
