"""Start the node graph (sim, gait, mpc, wbc, optionally the recorder) and supervise it.

There is no `ros2 launch` in the PyPI wheels; this is the project's launcher, behind
``scripts/launch.sh``. Before anything starts, every parameter file of the run (the node files,
the profile, ``--params``) is checked against the nodes' parameter tables
(``replan_ros/params/``): an unknown key (with the closest name), a wrong type, a value out
of range or not among the choices, or two nodes that disagree (``wbc.control_rate`` and
``sim.control_period``; ``sim.command_timeout`` must exceed ``wbc.plan_timeout``) stops the
start with one line, e.g. ``config error: /tmp/x.yaml: gait.replan_window = 0 is out of range
[1, 8]``; so does an unknown ``--robot`` or a robot file whose names do not match its model.
Each node is its own process (own process group) with its log in the run folder. A node that
dies is reported (which, when, exit code) and started again after a back-off of 1 s,
2 s, 4 s ...; a node that dies 3 times within 30 s stops the graph and its last 20 log lines
are printed. With ``--no-respawn`` the first death stops the rest. A node that exits with
code 2 refused its configuration (a bad parameter, a robot it cannot load, a recorder whose bag
could not show the robot): it is not respawned, the graph stops with its ``config error:``
line. Ctrl-C, SIGTERM or the
sim-time ``--duration`` stop everything cleanly (SIGINT, then SIGKILL after a timeout).

While the graph runs, a progress line shows the sim time, the real-time factor (last 5 wall
seconds and overall), the distance from the start (``/ground_truth/odom`` when the run is
recorded, as scenarios and re-runs are; else the estimate ``/odom``, so that nothing but the
recorder reads the truth) and the re-plans: refreshed in place on a terminal, one plain line
every 5 s otherwise; ``--quiet`` turns it off.

Exit codes: 0 done; 1 a node died (``--no-respawn``); 2 bad command line or configuration
(nothing was started, or a node refused its configuration); 3 wall-time limit (scenarios); 4 a
node kept dying (respawn limit).
"""

from __future__ import annotations

import argparse
import datetime
import os
import socket
import sys
from pathlib import Path

from replan_core.gait.gait_file import gait_names
from replan_core.robot.robot_file import robot_names
from replan_ros.launch.graph import EXIT_CONFIG, Graph, run_graph
from replan_ros.launch.param_files import (
    DEFAULT_GAIT,
    DEFAULT_PROFILE,
    DEFAULT_ROBOT,
    PROFILES,
    profile_file,
)
from replan_ros.launch.progress import ProgressLine
from replan_ros.params import ConfigError
from replan_ros.params.robot import config_dir

LIVE_DEFAULT_PORT = 8765       # Foxglove's default WebSocket port
LIVE_HOST = '127.0.0.1'        # config/live_view.yaml's host: this machine only (ssh -L)


def add_robot_option(parser: argparse.ArgumentParser, default: str | None = DEFAULT_ROBOT,
                     ) -> None:
    """``--robot NAME|FILE``, shared by launch.sh and scenario.sh."""
    parser.add_argument('--robot', default=default, metavar='NAME|FILE',
                        help='the robot: a name of config/robots/ ('
                             f'{", ".join(robot_names(config_dir()))}) or a robot file '
                             '(docs/robot_files.md); its parameters are derived '
                             f'from the reference robot\'s (default {DEFAULT_ROBOT})')


def add_gait_option(parser: argparse.ArgumentParser, default: str | None = DEFAULT_GAIT,
                    ) -> None:
    """``--gait NAME``, shared by launch.sh and scenario.sh."""
    parser.add_argument('--gait', default=default, metavar='NAME',
                        help='the gait: a name of config/gaits/ ('
                             f'{", ".join(gait_names(config_dir()))}; docs/gait.md, "Gait '
                             f'files"; default {DEFAULT_GAIT})')


def add_live_option(parser: argparse.ArgumentParser) -> None:
    """``--live [PORT]``, shared by launch.sh and scenario.sh."""
    parser.add_argument('--live', nargs='?', const=LIVE_DEFAULT_PORT, type=int, metavar='PORT',
                        help='serve the run to Foxglove/Lichtblick: a WebSocket on '
                             f'{LIVE_HOST}:PORT (default {LIVE_DEFAULT_PORT}); from another '
                             f'machine: ssh -L {LIVE_DEFAULT_PORT}:localhost:{LIVE_DEFAULT_PORT} '
                             'HOST')


def live_argv(argv: list[str] | None) -> list[str]:
    """``argv`` with a bare ``--live`` that is followed by something other than a port given
    its default port, so that ``scenario.sh --live FILE`` does not take FILE for the port
    (argparse's optional value would)."""
    args = list(sys.argv[1:] if argv is None else argv)
    out = []
    for i, arg in enumerate(args):
        following = args[i + 1] if i + 1 < len(args) else None
        if arg == '--live' and following is not None and not following.isdigit():
            arg = f'--live={LIVE_DEFAULT_PORT}'
        out.append(arg)
    return out


def check_live_port(parser: argparse.ArgumentParser, port: int | None) -> None:
    """Refuse (usage error, nothing started) a port out of range or already taken: the live
    view would die at start and stop the graph."""
    if port is None:
        return
    if not 1 <= port <= 65535:
        parser.error(f'--live {port}: a port is 1..65535')
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as probe:
        probe.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            probe.bind((LIVE_HOST, port))
        except OSError as err:
            parser.error(f'--live {port}: port not free on {LIVE_HOST} ({err.strerror})')


def default_run_dir(root: Path) -> Path:
    return root / 'runs' / datetime.datetime.now().strftime('%Y%m%d-%H%M%S')


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog='launch.sh', description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('--gui', action='store_true', help='PyBullet GUI window')
    parser.add_argument('--record', metavar='DIR', type=Path,
                        help='record an mcap bag into DIR')
    parser.add_argument('--params', metavar='FILE', type=Path, nargs='+', default=[],
                        help='extra parameter YAML files (sections per node name)')
    parser.add_argument('--profile', default=DEFAULT_PROFILE, metavar='NAME',
                        help=f'world profile: {" | ".join(PROFILES)} (config/profiles/NAME.yaml) '
                             f'or a YAML file; default {DEFAULT_PROFILE}')
    parser.add_argument('--duration', metavar='SIM_SECONDS', type=float,
                        help='stop after this much sim time (the sim steps no further than '
                             'the first tick at or after it: sim.stop_time)')
    parser.add_argument('--no-respawn', action='store_true',
                        help='if a node dies, stop the others and exit non-zero')
    parser.add_argument('--run-dir', type=Path, help='folder for logs (default runs/<time>)')
    parser.add_argument('--config-dir', type=Path,
                        default=Path(os.environ.get('REPLAN_CONFIG', 'config')))
    parser.add_argument('--quiet', action='store_true',
                        help='no progress line (sim time, real-time factor, distance, '
                             're-plans) while the graph runs')
    add_robot_option(parser)
    add_gait_option(parser)
    add_live_option(parser)
    args = parser.parse_args(live_argv(argv))
    for path in args.params:
        if not path.is_file():
            parser.error(f'parameter file {path} does not exist')
    check_live_port(parser, args.live)
    root = Path(os.environ.get('REPLAN_ROOT', '.'))
    run_dir = args.run_dir or default_run_dir(root)
    try:
        profile_file(args.config_dir, args.profile)
    except ValueError as err:
        parser.error(str(err))
    try:
        graph = Graph(run_dir, config_dir=args.config_dir, param_files=args.params,
                      profile=args.profile, record_dir=args.record, gui=args.gui,
                      respawn=not args.no_respawn, live_port=args.live,
                      stop_time=args.duration, robot=args.robot, gait=args.gait)
    except ConfigError as err:
        print(f'config error: {err}', file=sys.stderr)
        return EXIT_CONFIG
    print(f'[launch] run folder {run_dir} (domain {os.environ.get("ROS_DOMAIN_ID", "0")}), '
          f'profile {args.profile}, robot {graph.robot}, gait {graph.gait}')
    if args.live is not None:
        print(f'[launch] live view: open ws://localhost:{args.live} in Foxglove or Lichtblick '
              '(layout config/foxglove/replan.json)')
    return run_graph(graph, args.duration,
                     progress=None if args.quiet else ProgressLine())


if __name__ == '__main__':
    sys.exit(main())
