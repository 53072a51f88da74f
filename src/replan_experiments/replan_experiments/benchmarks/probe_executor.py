"""What an rclpy executor does with what our nodes need, each case in its own process.

Whether rclpy's ``EventsExecutor`` (``rclpy.experimental``) stalls the lock-step graph
instead of running it slower. This probe answers it for the installed rclpy by running,
for each executor and each way of spinning it, one small node in a child process:

- ``timer``: a 20 ms timer (the sim's republish, the gait's contact poll);
- ``subscription``: a subscription with a one-argument callback, fed at 50 Hz by a publisher in
  another process;
- ``with_info``: the same with a two-argument callback (message, ``MessageInfo``), as the sim
  and the controller use for the DDS timestamps of the per-tick messages.

Spin modes: ``spin`` is ``rclpy.spin(node, executor)`` as every node's ``main()`` runs it
(``spin_once()`` without a timeout, in a loop); ``spin_once_timeout`` calls
``spin_once(timeout_sec=0.05)`` in a loop. After ``duration`` s the child counts the callbacks,
sends itself SIGINT and waits a second for the spin to end (as the launcher's stop does).

Prints one table (or ``--json``, one JSON line).
    python -m replan_experiments.benchmarks.probe_executor [--executors single,events]
                                                          [--duration S]
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import signal
import subprocess
import sys
import threading
import time

EXECUTORS = ('single', 'events')
MODES = ('spin', 'spin_once_timeout')
CASES = ('timer', 'subscription', 'with_info')
PUBLISH_RATE = 50.0      # Hz
TIMER_PERIOD = 0.02      # s
STOP_GRACE = 1.0         # s a spin gets to end after SIGINT
# s from the spin's start to the count's: an executor that stalls may still run a timer that
# was already due when the spin began, once (the EventsExecutor under rclpy.spin does, when
# the spin starts more than one timer period after the timer: measured with a session script,
# 1 call after a 0.1 or 0.5 s delay, none without; CI once counted that call, "1 of 50")
SETTLE = 0.5
DISCOVERY_TIMEOUT = 15.0  # s for the publisher to be matched
_MARK = 'PROBE_EXECUTOR '


def _make_executor(name: str):
    if name == 'single':
        from rclpy.executors import SingleThreadedExecutor
        return SingleThreadedExecutor()
    from rclpy.experimental import EventsExecutor
    return EventsExecutor()


def _child(executor_name: str, mode: str, case: str, topic: str, duration: float) -> int:
    """One case: prints one marked JSON line, always (a stalled spin is reported by the
    watchdog thread, which then ends the process)."""
    import rclpy
    from rclpy.executors import ExternalShutdownException
    from std_msgs.msg import String

    rclpy.init()
    node = rclpy.create_node(f'probe_executor_{os.getpid()}')
    calls = [0]
    result = {'executor': executor_name, 'mode': mode, 'case': case, 'calls': 0,
              'expected': 0, 'stopped_by_sigint': False, 'error': ''}

    def count(*_args) -> None:
        calls[0] += 1

    subscription = None
    if case == 'timer':
        node.create_timer(TIMER_PERIOD, count)
        result['expected'] = int(duration / TIMER_PERIOD)
    elif case == 'subscription':
        subscription = node.create_subscription(String, topic, lambda msg: count(msg), 100)
        result['expected'] = int(duration * PUBLISH_RATE)
    else:
        subscription = node.create_subscription(String, topic,
                                                lambda msg, info: count(msg, info), 100)
        result['expected'] = int(duration * PUBLISH_RATE)
    lock = threading.Lock()
    reported = [False]
    spinning = threading.Event()

    def report(**fields) -> None:
        with lock:
            if reported[0]:
                return
            reported[0] = True
            result.update(fields)
            print(_MARK + json.dumps(result), flush=True)

    def watchdog() -> None:
        # Discovery between processes takes up to a few seconds and needs no spinning (the
        # graph is DDS's): the count starts once the publisher is matched.
        deadline = time.monotonic() + DISCOVERY_TIMEOUT
        while (subscription is not None and subscription.get_publisher_count() == 0
               and time.monotonic() < deadline):
            time.sleep(0.01)
        spinning.wait(DISCOVERY_TIMEOUT)
        time.sleep(SETTLE)
        start = calls[0]
        time.sleep(duration)
        result['calls'] = calls[0] - start
        os.kill(os.getpid(), signal.SIGINT)
        time.sleep(STOP_GRACE)
        report(stopped_by_sigint=False)
        os._exit(0)

    try:
        executor = _make_executor(executor_name)
        executor.add_node(node)
        threading.Thread(target=watchdog, daemon=True).start()
        spinning.set()
        if mode == 'spin':
            rclpy.spin(node, executor)
        else:
            while rclpy.ok():
                executor.spin_once(timeout_sec=0.05)
        report(stopped_by_sigint=True)
    except (KeyboardInterrupt, ExternalShutdownException):
        report(stopped_by_sigint=True)
    except Exception as error:
        if not rclpy.ok():
            # SIGINT's shutdown came while spin_once set up its wait: rclpy then raises
            # RCLError ("failed to create timer: the given context is not valid"), not
            # ExternalShutdownException (a suite run, spin_once_timeout, after all 50 calls).
            # The spin ended because of SIGINT all the same.
            report(stopped_by_sigint=True)
        else:                            # the finding itself: what the executor raised
            report(error=f'{type(error).__name__}: {error}')
    rclpy.try_shutdown()
    return 0


def _publisher(topic: str) -> int:
    import rclpy
    from rclpy.executors import ExternalShutdownException
    from std_msgs.msg import String

    rclpy.init()
    node = rclpy.create_node(f'probe_executor_publisher_{os.getpid()}')
    publisher = node.create_publisher(String, topic, 100)
    node.create_timer(1.0 / PUBLISH_RATE, lambda: publisher.publish(String(data='probe')))
    with contextlib.suppress(KeyboardInterrupt, ExternalShutdownException):
        rclpy.spin(node)
    rclpy.try_shutdown()
    return 0


def run_case(executor_name: str, mode: str, case: str, topic: str, duration: float) -> dict:
    """One case in a child process; its result dict (``error`` says when it printed none)."""
    command = [sys.executable, '-m', 'replan_experiments.benchmarks.probe_executor', '--child',
               executor_name, mode, case, topic, str(duration)]
    try:
        done = subprocess.run(command, capture_output=True, text=True,
                              timeout=duration + STOP_GRACE + DISCOVERY_TIMEOUT + 30.0)
        output = done.stdout
    except subprocess.TimeoutExpired as timeout:
        output = timeout.stdout.decode() if isinstance(timeout.stdout, bytes) else ''
    for line in reversed(output.splitlines()):
        if line.startswith(_MARK):
            return json.loads(line[len(_MARK):])
    return {'executor': executor_name, 'mode': mode, 'case': case, 'calls': 0, 'expected': 0,
            'stopped_by_sigint': False, 'error': 'the child printed no result'}


def verdict(result: dict) -> str:
    """``ok`` (callbacks ran, at least half as many as due, and SIGINT ended the spin),
    else what failed."""
    if result['error']:
        return 'raised ' + result['error']
    problems = []
    if result['calls'] < 0.5 * result['expected']:
        problems.append(f"{result['calls']} of {result['expected']} callbacks")
    if not result['stopped_by_sigint']:
        problems.append('SIGINT did not end the spin')
    return '; '.join(problems) or 'ok'


def probe(executors: tuple[str, ...], duration: float) -> list[dict]:
    """Every case of every executor and spin mode, with its verdict."""
    topic = f'probe_executor_{os.getpid()}'
    publisher = subprocess.Popen(
        [sys.executable, '-m', 'replan_experiments.benchmarks.probe_executor',
         '--publisher', topic],
        stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    results = []
    try:
        for executor_name in executors:
            for mode in MODES:
                for case in CASES:
                    result = run_case(executor_name, mode, case, topic, duration)
                    result['verdict'] = verdict(result)
                    results.append(result)
    finally:
        publisher.send_signal(signal.SIGINT)
        try:
            publisher.wait(timeout=5)
        except subprocess.TimeoutExpired:
            publisher.kill()
            publisher.wait()
    return results


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(
        prog='probe_executor', description=__doc__.split('\n\n')[0],
        formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('--executors', default=','.join(EXECUTORS),
                        help=f'comma-separated, of {", ".join(EXECUTORS)} (default: both)')
    parser.add_argument('--duration', type=float, default=1.5,
                        help='s each case runs before SIGINT (default 1.5)')
    parser.add_argument('--json', action='store_true', help='one JSON line instead of a table')
    parser.add_argument('--child', nargs=5, metavar=('EXECUTOR', 'MODE', 'CASE', 'TOPIC', 'S'),
                        help=argparse.SUPPRESS)
    parser.add_argument('--publisher', metavar='TOPIC', help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.child:
        executor_name, mode, case, topic, duration = args.child
        return _child(executor_name, mode, case, topic, float(duration))
    if args.publisher:
        return _publisher(args.publisher)
    executors = tuple(name.strip() for name in args.executors.split(',') if name.strip())
    unknown = [name for name in executors if name not in EXECUTORS]
    if unknown or not executors:
        parser.error(f'--executors: unknown {unknown}; choose from {", ".join(EXECUTORS)}')
    if not args.duration > 0.0:
        parser.error('--duration must be positive')
    results = probe(executors, args.duration)
    if args.json:
        print(json.dumps(results))
        return 0
    version = _rclpy_version()
    print(f'probe_executor: rclpy {version}, each case {args.duration:g} s, then SIGINT')
    print(f'{"executor":10} {"spin mode":18} {"case":13} {"callbacks":>11}  verdict')
    for r in results:
        print(f"{r['executor']:10} {r['mode']:18} {r['case']:13} "
              f"{r['calls']:>5} / {r['expected']:<4}  {r['verdict']}")
    return 0


def _rclpy_version() -> str:
    from importlib import metadata
    try:
        return metadata.version('ros-jazzy-rclpy')
    except metadata.PackageNotFoundError:
        return 'unknown'


if __name__ == '__main__':
    sys.exit(main())
