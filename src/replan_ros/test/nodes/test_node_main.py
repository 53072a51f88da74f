"""nodes.node_main: the logging helper every node's core callbacks go through."""

import pytest
from rclpy.logging import get_logger

from replan_ros.nodes.node_main import log_at


def test_one_helper_logs_at_every_severity_in_turn():
    logger = get_logger('test_log_at')
    # A single getattr(logger, level)(text) call site raised ValueError at its second
    # severity (a gait node died at its first forced touchdown after an info line).
    for level in ('info', 'warning', 'error', 'debug', 'info', 'error'):
        log_at(logger, level, f'a line at {level}')
    with pytest.raises(ValueError, match='unknown log level'):
        log_at(logger, 'warn', 'no such level')
