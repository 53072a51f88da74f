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
