"""The one ``main()`` of a node process: rclpy up, the node made and spun until Ctrl-C or an
external shutdown, then destroyed and rclpy down, whatever happened in between."""

from __future__ import annotations

import math
import os
import signal
import sys
import time
from collections.abc import Callable
from typing import NoReturn

import rclpy
from rclpy.duration import Duration
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.node import Node
from rclpy.signals import SignalHandlerOptions

from replan_ros.params import ConfigError
from replan_ros.params.robot import NodeRobot, node_robot


def log_at(logger, level: str, text: str) -> None:
    """``text`` at ``level`` ('debug', 'info', 'warning' or 'error'), one call site per
    severity: rclpy refuses a call site whose severity changes between calls (ValueError:
    "Logger severity cannot be changed between calls"), so a shared ``getattr(logger,
    level)(text)`` crashes a node at its second severity."""
    if level == 'debug':
        logger.debug(text)
    elif level == 'info':
        logger.info(text)
    elif level == 'warning':
        logger.warning(text)
    elif level == 'error':
        logger.error(text)
    else:
        raise ValueError(f'unknown log level {level!r}')


class ThrottledLog:
    """Log lines throttled per key: at most one every ``period`` wall seconds for each key.
    rclpy's own throttle is per call site, and a node's warnings about different inputs
    (``key``) would share one; a repeated fault must not flood the log at the tick rate."""

    def __init__(self, logger, period: float, clock=time.monotonic) -> None:
        self.logger = logger
        self.period = float(period)       # wall s; a node's run-time parameter may change it
        self._clock = clock
        self._last: dict[str, float] = {}

    def __call__(self, key: str, text: str, level: str = 'warning') -> None:
        now = self._clock()
        if now - self._last.get(key, -math.inf) >= self.period:
            self._last[key] = now
            log_at(self.logger, level, text)


# The exit code of a node that refuses its configuration (as params.declare's): the launcher
# stops the graph instead of respawning a node that would refuse again.
EXIT_CONFIG = 2


def refuse_configuration(node: Node, reason: object) -> NoReturn:
    """One ``config error:`` line and exit code ``EXIT_CONFIG``."""
    node.get_logger().fatal(f'config error: {reason}')
    raise SystemExit(EXIT_CONFIG)


def load_node_robot(node: Node, p: dict, default_urdf: str = '') -> NodeRobot:
    """The model and names of the node's ``robot_file`` / ``urdf_path`` parameters
    (params.robot.node_robot); a robot file that cannot be used is one ``config error:`` line
    and exit code 2, as a bad parameter."""
    try:
        return node_robot(str(p['robot_file']), str(p['urdf_path']), default_urdf)
    except ConfigError as err:
        refuse_configuration(node, err)


# The exit code of a node that found another graph on its ROS domain.
EXIT_SHARED_DOMAIN = 3


def stop_if_domain_shared(node: Node, own_topic: str) -> None:
    """Two graphs on one ROS domain mix their topics (each controller answers both sims, each
    sim takes both controllers' torques): neither run is what it claims. A second publisher
    of ``own_topic``, which only one node of a graph publishes (the sim's ``/clock``), is
    another graph: stop with one line rather than run on mixed inputs."""
    others = node.count_publishers(own_topic) - 1
    if others > 0:
        domain = os.environ.get('ROS_DOMAIN_ID', '0')
        node.get_logger().fatal(
            f'another graph publishes {own_topic} on ROS_DOMAIN_ID {domain} ({others} other '
            'publisher(s)): two graphs on one domain mix their topics; stopping. Give each '
            'graph its own domain: ROS_DOMAIN_ID=N before the script (experiments.sh --jobs '
            'does this itself)')
        raise SystemExit(EXIT_SHARED_DOMAIN)


DRAIN_QUIET = 0.3     # s without anything drained: done
DRAIN_LIMIT = 10.0    # s, longest drain before the node is destroyed anyway
ACK_LIMIT = 1.0       # s, longest wait for the readers' acknowledgements at the stop


def wait_for_acks(node: Node, limit: float = ACK_LIMIT) -> bool:
    """Wait until the reliable readers of every writer of ``node`` have acknowledged all its
    samples, at most ``limit`` s in all; False if they did not. A writer destroyed at once
    never sends again a sample lost in transport in its last heartbeat period (100 ms), and its
    reader holds every later one until then: the bag lost the topic's tail (docs/recording.md,
    "The end of a run")."""
    end = time.monotonic() + limit
    for publisher in list(node.publishers):
        remaining = end - time.monotonic()
        if remaining <= 0.0 or not publisher.wait_for_all_acked(Duration(seconds=remaining)):
            return False
    return True


def run_node(make_node: Callable[[], Node], args=None, *,
             one_line_errors: tuple[type[BaseException], ...] = (), label: str = '',
             drain: Callable[[Node], int] | None = None) -> None:
    """Run one node in this process. An exception of ``one_line_errors`` (e.g. the live view's
    port taken) is printed as one line ``[label] error`` and ends the process with code 1; a
    node that refuses its configuration exits by itself (SystemExit 2, replan_ros.params).
    SIGINT and SIGTERM stop the node between two callbacks, never inside one: rclpy's own
    handlers shut the context down at once, so a publish still to come in the callback that
    was running failed (the wbc publishes a tick's estimate right after its command, and the
    launcher stops the graph as soon as it sees the command of the stop tick: the bag held the
    last estimate or not by that race). With ``drain`` (the recorder, which runs a little behind
    the graph under load), ``drain(node)`` is then called until it returns 0 for
    ``DRAIN_QUIET`` s (at most ``DRAIN_LIMIT`` s) before the node is destroyed."""
    stop: list[int] = []
    rclpy.init(args=args, signal_handler_options=SignalHandlerOptions.NO)
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, lambda signum, _frame: stop.append(signum))
    node = None
    profiler = _profiler(label or getattr(make_node, '__name__', 'node'))
    try:
        node = make_node()
        if profiler is not None:
            profiler.enable()
        executor = SingleThreadedExecutor()
        executor.add_node(node)
        while not stop and rclpy.ok():
            executor.spin_once(timeout_sec=0.1)
        if drain is not None:
            quiet_since = time.monotonic()
            end = quiet_since + DRAIN_LIMIT
            while time.monotonic() < end and time.monotonic() - quiet_since < DRAIN_QUIET:
                if drain(node):
                    quiet_since = time.monotonic()
                time.sleep(0.05)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except one_line_errors as err:
        print(f'[{label}] {err}', file=sys.stderr, flush=True)
        raise SystemExit(1) from None
    finally:
        if profiler is not None:
            profiler.disable()
            profiler.dump_stats(os.path.join(os.environ['REPLAN_CPROFILE_DIR'],
                                             f'{profiler.replan_name}.{os.getpid()}.prof'))
        if node is not None:
            if rclpy.ok():
                wait_for_acks(node)
            node.destroy_node()
        rclpy.try_shutdown()


def _profiler(name: str):
    """A cProfile profiler of the spin when ``REPLAN_CPROFILE_DIR`` names a directory (the
    per-stage figures of docs/performance.md); None otherwise, at no cost."""
    if not os.environ.get('REPLAN_CPROFILE_DIR'):
        return None
    import cProfile
    # CPU time of the spinning thread: wall time would charge whatever runs when the OS
    # switches to another node to the function that was on the stack.
    profiler = cProfile.Profile(time.thread_time)
    profiler.replan_name = name
    return profiler
