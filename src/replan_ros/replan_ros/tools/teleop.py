"""Keyboard teleoperation: a geometry_msgs/Twist set-point on cmd_vel, repeated at 10 Hz.

    scripts/teleop.sh [--rate HZ] [--gait NAME|FILE]

Keys (each press moves the set-point by one increment, clamped to the gait node's limits):
    w / s, Up / Down       forward / backward (vx)
    a / d, Left / Right    left / right (vy)
    q / e                  turn left / right (wz)
    + / -                  larger / smaller increment
    space                  stop (zero set-point)
    x, Ctrl-C              send a zero set-point and quit

The limits are max_linear_x, max_linear_y and max_angular_z of the gait (HyQ's units), read from
$REPLAN_CONFIG/gaits/NAME.yaml (--gait, default crawl) or a gait file: beyond them the gait
node clamps anyway. The
set-point is repeated because the gait node stops the robot when cmd_vel falls silent for
cmd_vel_timeout (0.5 s). Needs a terminal (stdin a TTY); for scripted set-points use
scripts/cmd_vel.sh.
"""

from __future__ import annotations

import argparse
import contextlib
import os
import select
import signal
import sys
import termios
import time
import tty
from dataclasses import dataclass, replace
from pathlib import Path

import rclpy
from geometry_msgs.msg import Twist
from rclpy.node import Node
from rclpy.signals import SignalHandlerOptions
from rclpy.utilities import remove_ros_args

from replan_core.gait.gait_file import gait_file_path, load_gait_file
from replan_ros.params.robot import config_dir
from replan_ros.transport import qos

# Increments per key press, as fractions of each axis' limit; + / - move along this list.
STEP_FRACTIONS = (0.05, 0.1, 0.25, 0.5, 1.0)
DEFAULT_STEP = 2
QUIT_KEYS = ('x', 'X', '\x03')       # \x03: Ctrl-C, should the terminal not turn it into SIGINT
_AXIS_KEYS = {
    'w': ('vx', 1), 'up': ('vx', 1), 's': ('vx', -1), 'down': ('vx', -1),
    'a': ('vy', 1), 'left': ('vy', 1), 'd': ('vy', -1), 'right': ('vy', -1),
    'q': ('wz', 1), 'e': ('wz', -1),
}
_ARROWS = {'A': 'up', 'B': 'down', 'C': 'right', 'D': 'left'}


@dataclass(frozen=True)
class Limits:
    """Largest |vx|, |vy| (m/s) and |wz| (rad/s) the gait node accepts unclamped."""

    vx: float
    vy: float
    wz: float

    @classmethod
    def from_gait_file(cls, path: Path) -> Limits:
        """The gait's ``max_linear_x``, ``max_linear_y``, ``max_angular_z``."""
        params = load_gait_file(path).params()
        return cls(params.max_linear_x, params.max_linear_y, params.max_angular_z)


@dataclass(frozen=True)
class SetPoint:
    """The commanded body velocity and the current increment (index in STEP_FRACTIONS)."""

    vx: float = 0.0
    vy: float = 0.0
    wz: float = 0.0
    step: int = DEFAULT_STEP


def apply_key(setpoint: SetPoint, key: str, limits: Limits) -> tuple[SetPoint, bool]:
    """The set-point after one key (a character or an arrow name), and whether to quit.

    Quitting returns the zero set-point, which the caller sends last. Unbound keys change
    nothing.
    """
    if key in QUIT_KEYS:
        return replace(setpoint, vx=0.0, vy=0.0, wz=0.0), True
    if key == ' ':
        return replace(setpoint, vx=0.0, vy=0.0, wz=0.0), False
    if key in ('+', '='):                     # '=' is '+' without shift on most layouts
        return replace(setpoint, step=min(setpoint.step + 1, len(STEP_FRACTIONS) - 1)), False
    if key in ('-', '_'):
        return replace(setpoint, step=max(setpoint.step - 1, 0)), False
    # Upper case too, so that caps lock does not silently disable the keys.
    bound = _AXIS_KEYS.get(key if len(key) > 1 else key.lower())
    if bound is None:
        return setpoint, False
    axis, sign = bound
    limit = getattr(limits, axis)
    value = getattr(setpoint, axis) + sign * STEP_FRACTIONS[setpoint.step] * limit
    # Rounded so that repeated increments land on the limit instead of 0.15000000000000002.
    return replace(setpoint, **{axis: round(min(max(value, -limit), limit), 9)}), False


def split_keys(data: str) -> list[str]:
    """Keys in a chunk read from the terminal; arrow escape sequences become 'up' etc.

    Other escape sequences (function keys, Home, ...) are dropped whole, so that their bytes
    are not taken for letters.
    """
    keys, i = [], 0
    while i < len(data):
        if data[i] != '\x1b':
            keys.append(data[i])
            i += 1
            continue
        j = i + 1
        if j < len(data) and data[j] in '[O':          # CSI or SS3: up to the final byte
            j += 1
            while j < len(data) and not '@' <= data[j] <= '~':
                j += 1
            if j < len(data) and data[j] in _ARROWS:
                keys.append(_ARROWS[data[j]])
        i = j + 1
    return keys


def status_line(setpoint: SetPoint) -> str:
    return (f'vx {setpoint.vx:+.3f} m/s   vy {setpoint.vy:+.3f} m/s   '
            f'wz {setpoint.wz:+.3f} rad/s   increment {STEP_FRACTIONS[setpoint.step]:.0%} '
            f'of the limits')


def keys_help() -> str:
    """The key table of this module's docstring."""
    return next(p for p in __doc__.split('\n\n') if p.startswith('Keys'))


def _gait_file(gait: str) -> Path:
    """A gait file, or the file of a gait name of the configuration folder."""
    if gait.endswith(('.yaml', '.yml')):
        return Path(gait)
    return gait_file_path(gait, config_dir())


def _raise_interrupt(signum, frame) -> None:
    raise KeyboardInterrupt


def run(limits: Limits, rate: float, ros_args: list[str]) -> int:
    """The interactive loop; the terminal is restored and zero sent however it ends."""
    # No rclpy signal handlers: Ctrl-C must leave the context up to send the final zero.
    rclpy.init(args=ros_args, signal_handler_options=SignalHandlerOptions.NO)
    node = Node('teleop')
    pub = node.create_publisher(Twist, 'cmd_vel', qos.COMMAND)

    def send(setpoint: SetPoint) -> None:
        twist = Twist()
        twist.linear.x, twist.linear.y, twist.angular.z = setpoint.vx, setpoint.vy, setpoint.wz
        pub.publish(twist)

    fd = sys.stdin.fileno()
    saved = termios.tcgetattr(fd)
    # A closed terminal or a kill must restore it too.
    for sig in (signal.SIGTERM, signal.SIGHUP):
        signal.signal(sig, _raise_interrupt)
    setpoint = SetPoint()
    period = 1.0 / rate
    try:
        tty.setcbreak(fd)     # one key at a time, no echo; Ctrl-C still interrupts
        print(keys_help() + '\n', flush=True)
        next_send = time.monotonic()
        quit_now = False
        while not quit_now:
            ready, _, _ = select.select([fd], [], [], max(next_send - time.monotonic(), 0.0))
            if ready:
                data = os.read(fd, 64).decode(errors='ignore')
                if not data:                       # end of input
                    break
                for key in split_keys(data):
                    setpoint, quit_now = apply_key(setpoint, key, limits)
                    if quit_now:
                        break
                next_send = time.monotonic()       # a key takes effect at once
            if time.monotonic() >= next_send:
                send(setpoint)
                next_send = max(next_send + period, time.monotonic())
            sys.stdout.write('\r' + status_line(setpoint) + '\x1b[K')
            sys.stdout.flush()
    except KeyboardInterrupt:
        pass
    finally:
        termios.tcsetattr(fd, termios.TCSADRAIN, saved)
        send(SetPoint())
        # Give the reliable writer a moment to deliver the zero before the node goes away.
        with contextlib.suppress(KeyboardInterrupt):
            time.sleep(0.3)
        print('\nteleop: sent a zero set-point', flush=True)
        node.destroy_node()
        rclpy.try_shutdown()
    return 0


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog='teleop.sh', description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('--rate', type=float, default=10.0, help='publish rate, Hz (default 10)')
    parser.add_argument('--gait', default='crawl', metavar='NAME|FILE',
                        help='the gait whose limits apply: a name of config/gaits/ or a gait '
                             'file (default crawl)')
    argv = list(sys.argv[1:] if argv is None else argv)
    # Only what follows --ros-args is rclpy's: any other unknown option is an error.
    args = parser.parse_args(remove_ros_args(['', *argv])[1:])
    if not args.rate > 0:
        parser.error('--rate must be positive')
    if not sys.stdin.isatty():
        print('teleop: stdin is not a terminal; run it in an interactive terminal '
              '(for scripted set-points: scripts/cmd_vel.sh VX VY WZ)', file=sys.stderr)
        return 2
    try:
        limits = Limits.from_gait_file(_gait_file(args.gait))
    except ValueError as err:
        print(f'teleop: cannot read the limits: {err}', file=sys.stderr)
        return 2
    return run(limits, args.rate, ['teleop.sh', *argv])


if __name__ == '__main__':
    sys.exit(main())
