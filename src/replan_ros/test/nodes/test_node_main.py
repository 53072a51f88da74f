"""nodes.node_main: the logging helpers every node's core callbacks go through."""

import pytest
from rclpy.logging import get_logger

from replan_ros.nodes.node_main import ThrottledLog, log_at


def test_one_helper_logs_at_every_severity_in_turn():
    logger = get_logger('test_log_at')
    # A single getattr(logger, level)(text) call site raised ValueError at its second
    # severity (a gait node died at its first forced touchdown after an info line).
    for level in ('info', 'warning', 'error', 'debug', 'info', 'error'):
        log_at(logger, level, f'a line at {level}')
    with pytest.raises(ValueError, match='unknown log level'):
        log_at(logger, 'warn', 'no such level')


class _Lines:
    """A logger that keeps its lines: (severity, text)."""

    def __init__(self) -> None:
        self.lines: list[tuple[str, str]] = []

    def __getattr__(self, level):
        return lambda text: self.lines.append((level, text))


def test_throttled_lines_are_throttled_per_key_and_the_period_can_change():
    logger, now = _Lines(), [100.0]
    log = ThrottledLog(logger, 2.0, clock=lambda: now[0])
    log('odom', 'first')
    log('odom', 'again at once')                  # same key within the period: dropped
    log('contacts', 'another key', level='error')
    now[0] += 2.0
    log('odom', 'a period later')
    log.period = 10.0
    now[0] += 5.0
    log('odom', 'within the new period')
    assert logger.lines == [('warning', 'first'), ('error', 'another key'),
                            ('warning', 'a period later')]


_SIGNALLED_NODE = '''
import os
import signal
import time

from rclpy.node import Node
from std_msgs.msg import Header

from replan_ros.nodes.node_main import run_node


class Signalled(Node):
    """Gets SIGINT in the middle of a callback, then publishes, as the wbc publishes a tick's
    estimate right after the command the launcher stops on."""

    def __init__(self):
        super().__init__('test_signalled_node')
        self.pub = self.create_publisher(Header, 'test_signalled_node_out', 1)
        self.create_timer(0.05, self.tick)

    def tick(self):
        os.kill(os.getpid(), signal.SIGINT)
        time.sleep(0.3)
        self.pub.publish(Header())
        print('published after the signal', flush=True)


run_node(Signalled)
'''


def test_a_signal_stops_the_node_after_the_callback_it_came_in():
    import subprocess
    import sys
    done = subprocess.run([sys.executable, '-c', _SIGNALLED_NODE], capture_output=True,
                          text=True, timeout=60)
    assert done.returncode == 0, done.stdout + done.stderr
    assert done.stdout.count('published after the signal') == 1, done.stdout + done.stderr
