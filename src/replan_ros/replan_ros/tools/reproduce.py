"""Re-run a recorded run and compare the base trajectory: a bag becomes a reproducible report.

    scripts/rerun.sh BAG [--out DIR] [--tolerance M] [--gui] [--quiet]

BAG: an .mcap file or a bag directory (its files, a respawned recorder's splits, read as one);
a killed recorder's file is recovered on the way, with one line saying so.

1. From BAG: the inputs (``velocity_setpoint``: the set-point each re-plan used; ``applied_wrench``:
   each external wrench change as applied, both stamped in sim time), the configuration (the
   ``replan_config`` metadata: every node's parameter file and the ``--params`` files of the run)
   and the recorded base trajectory (``odom``).
2. A fresh lock-step simulation with that configuration; before it starts, the inputs are sent
   with their recorded stamps as ``cmd_vel_stamped`` and ``external_wrench`` (transient local
   schedule topics), so the new run sees the same inputs at the same sim times.
3. The new ``odom`` positions are compared with the recorded ones at equal stamps; the largest
   deviation (m) is printed. Exit code 0 if it is within ``--tolerance`` (default 0 m) and the
   new run covered the recording, 1 otherwise, 2 for a bag that cannot be re-run.
4. Every message of the run's state and decisions (``EXACT_TOPICS``: sensors, truth, estimate,
   commands, plans, inputs) is compared byte for byte at each stamp, and the last stamp of
   each bag: runs are bit-exact (docs/ARCHITECTURE.md, "Bit-exact runs"), so anything but
   "bit-identical" names the first topic and stamp where they part.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from geometry_msgs.msg import TwistStamped, WrenchStamped
from mcap.exceptions import McapError
from mcap.reader import make_reader
from nav_msgs.msg import Odometry
from rclpy.serialization import deserialize_message
from std_msgs.msg import Header

from replan_ros.launch.graph import NODES
from replan_ros.messages.stamps import stamp_to_ns, stamp_to_sec
from replan_ros.params import ConfigError
from replan_ros.recording.bag_files import bag_files
from replan_ros.recording.bag_io import check_bag
from replan_ros.recording.bag_open import iter_raw_files, readable_files
from replan_ros.transport.stamped_buffer import cdr_header_stamp_ns

INPUT_TOPICS = {'/velocity_setpoint': TwistStamped, '/applied_wrench': WrenchStamped,
                '/gait_in_force': Header}
# What a run computes, tick by tick and re-plan by re-plan; each message starts with a
# std_msgs/Header. Left out: wall-clock figures (/diagnostics, /rosout, solve times) and what
# is derived for viewers at the recorder's pace.
EXACT_TOPICS = ('/joint_states', '/imu', '/joint_torque_cmd', '/odom', '/contacts',
                '/contact_events', '/ground_truth/odom', '/ground_truth/contacts', '/footholds',
                '/com_plan', '/zmp_plan', '/com_path', '/velocity_setpoint', '/applied_wrench')
# The simulator's truth; bags recorded before the state estimator have it on /odom.
ODOM_TOPIC = '/ground_truth/odom'
LEGACY_ODOM_TOPIC = '/odom'


class RerunError(ValueError):
    """A bag that cannot be re-run, with the reason."""


@dataclass
class RecordedRun:
    """What a re-run needs from a bag."""

    setpoints: list[TwistStamped] = field(default_factory=list)
    wrenches: list[WrenchStamped] = field(default_factory=list)
    gaits: list[Header] = field(default_factory=list)            # the gait of each re-plan
    odom: dict[int, np.ndarray] = field(default_factory=dict)   # stamp ns -> position (m)
    config_files: list[str] = field(default_factory=list)        # recorded order
    config_text: dict[str, str] = field(default_factory=dict)    # path -> content
    run_info: dict[str, str] = field(default_factory=dict)
    scenario: dict[str, str] = field(default_factory=dict)

    @property
    def duration(self) -> float:
        """Sim seconds covered by the recorded ``odom``."""
        return max(self.odom) * 1e-9 if self.odom else 0.0


def odom_positions(messages) -> dict[int, np.ndarray]:
    """stamp ns -> base position, first message of each stamp (the sim re-publishes a state
    whose command was lost: duplicates carry the same state)."""
    out: dict[int, np.ndarray] = {}
    for msg in messages:
        stamp = stamp_to_ns(msg.header.stamp)
        if stamp not in out:
            p = msg.pose.pose.position
            out[stamp] = np.array([p.x, p.y, p.z])
    return out


_SAID: set[str] = set()


def _say(line: str) -> None:
    """One line on stderr per bag file (a comparison opens a bag more than once)."""
    path = line.split(':', 1)[0]
    if path not in _SAID:
        _SAID.add(path)
        print(f'[rerun] {line}', file=sys.stderr, flush=True)


def bag_files_checked(bag: str | Path) -> list[Path]:
    """The files of ``bag`` (recovered if its recorder was killed), each read once."""
    files = readable_files(bag, _say)
    if not files:
        raise RerunError(f'cannot read {bag}: no .mcap file')
    for path in files:
        try:
            check_bag(path)     # a truncated or corrupt bag: one line, not a traceback
        except McapError as err:
            raise RerunError(f'cannot read {path}: {err}') from None
    return files


def load_run(bag: str | Path) -> RecordedRun:
    """Inputs, configuration and trajectory of a recorded bag (a file or a bag directory)."""
    files = bag_files_checked(bag)
    run = RecordedRun()
    odom: dict[str, list[Odometry]] = {ODOM_TOPIC: [], LEGACY_ODOM_TOPIC: []}
    for path in files:          # a split bag: every file holds the run's records
        with open(path, 'rb') as stream:
            for record in make_reader(stream).iter_metadata():
                if record.name == 'replan_config' and not run.config_text:
                    run.config_text.update(record.metadata)
                elif record.name == 'replan_run' and not run.run_info:
                    run.run_info = dict(record.metadata)
                elif record.name == 'replan_scenario' and not run.scenario:
                    run.scenario = dict(record.metadata)
    for _schema, channel, message in iter_raw_files(files, [*INPUT_TOPICS, *odom]):
        if channel.topic in odom:
            odom[channel.topic].append(deserialize_message(message.data, Odometry))
        elif channel.topic == '/velocity_setpoint':
            run.setpoints.append(deserialize_message(message.data, TwistStamped))
        elif channel.topic == '/gait_in_force':
            run.gaits.append(deserialize_message(message.data, Header))
        else:
            run.wrenches.append(deserialize_message(message.data, WrenchStamped))
    run.odom = odom_positions(odom[ODOM_TOPIC] or odom[LEGACY_ODOM_TOPIC])
    try:
        run.config_files = list(json.loads(run.run_info.get('config_files', '[]')))
    except ValueError:
        run.config_files = []
    for path in run.config_text:
        if path not in run.config_files:
            run.config_files.append(path)
    return run


def _twist_key(msg: TwistStamped) -> tuple:
    t = msg.twist
    return (t.linear.x, t.linear.y, t.linear.z, t.angular.x, t.angular.y, t.angular.z)


def schedule_inputs(run: RecordedRun) -> tuple[list[TwistStamped], list[WrenchStamped]]:
    """The inputs to send: set-points where the value changes (a set-point holds from its stamp
    on, so the value at every re-plan is the same), every applied wrench; sorted by stamp."""
    setpoints = sorted(run.setpoints, key=lambda m: stamp_to_ns(m.header.stamp))
    changes: list[TwistStamped] = []
    for msg in setpoints:
        if not changes or _twist_key(msg) != _twist_key(changes[-1]):
            changes.append(msg)
    wrenches = sorted(run.wrenches, key=lambda m: stamp_to_ns(m.header.stamp))
    return changes, wrenches


def schedule_gaits(run: RecordedRun) -> list[Header]:
    """The gait requests to send: each re-plan's gait where it changes, stamped with that
    re-plan (so the re-run's re-plan at that stamp switches as the recorded one did)."""
    changes: list[Header] = []
    for msg in sorted(run.gaits, key=lambda m: stamp_to_ns(m.stamp)):
        if not changes or msg.frame_id != changes[-1].frame_id:
            changes.append(msg)
    return changes[1:]          # the first is the run's start gait, in its parameters


def write_config(run: RecordedRun, out_dir: Path, fallback_dir: Path,
                 log=print) -> tuple[Path, list[Path]]:
    """Recreate the run's configuration under ``out_dir``: ``config/<node>.yaml`` for the graph's
    nodes (the recorded file, else the current one, with a warning) and the other recorded
    files, in their recorded order, as extra parameter files."""
    config_dir = out_dir / 'config'
    params_dir = out_dir / 'params'
    config_dir.mkdir(parents=True, exist_ok=True)
    extra: list[Path] = []
    placed: set[str] = set()
    for index, path in enumerate(run.config_files):
        text = run.config_text.get(path)
        if text is None:
            log(f'[rerun] {path} was listed but its content is not in the bag: skipped')
            continue
        name = Path(path).name
        node = name[:-len('.yaml')] if name.endswith('.yaml') else ''
        if node in NODES and node not in placed:
            (config_dir / name).write_text(text)
            placed.add(node)
        else:
            params_dir.mkdir(parents=True, exist_ok=True)
            target = params_dir / f'{index:02d}_{name}'
            target.write_text(text)
            extra.append(target)
    for node in (*NODES, 'recorder'):
        if node in placed:
            continue
        source = fallback_dir / f'{node}.yaml'
        if node != 'recorder':
            log(f'[rerun] no recorded {node}.yaml: using the current {source}')
        if source.is_file():
            shutil.copyfile(source, config_dir / f'{node}.yaml')
    return config_dir, extra


@dataclass
class Comparison:
    max_deviation: float            # m, largest position difference at a common stamp
    at_stamp: float | None          # s, where it occurs
    matched: int                    # stamps in both runs
    missing: int                    # recorded stamps the new run does not have
    rms: float                      # m

    @property
    def coverage(self) -> float:
        total = self.matched + self.missing
        return self.matched / total if total else 0.0


def compare_trajectories(recorded: dict[int, np.ndarray],
                         rerun: dict[int, np.ndarray]) -> Comparison:
    """Position deviation of ``rerun`` from ``recorded`` at their common stamps."""
    common = sorted(set(recorded) & set(rerun))
    missing = len(set(recorded) - set(rerun))
    if not common:
        return Comparison(float('inf'), None, 0, missing, float('inf'))
    ref = np.array([recorded[s] for s in common])
    new = np.array([rerun[s] for s in common])
    dev = np.linalg.norm(new - ref, axis=1)
    worst = int(np.argmax(dev))
    return Comparison(float(dev[worst]), common[worst] * 1e-9, len(common), missing,
                      float(np.sqrt(np.mean(dev ** 2))))


def stamped_messages(bag: str | Path) -> dict[str, dict[int, bytes]]:
    """topic -> stamp ns -> serialized message (the first of each stamp: a republished tick
    is the same message again) of the ``EXACT_TOPICS`` in ``bag``."""
    out: dict[str, dict[int, bytes]] = {}
    for _schema, channel, message in iter_raw_files(readable_files(bag, _say), EXACT_TOPICS):
        stamp = cdr_header_stamp_ns(message.data)
        if stamp is not None:
            out.setdefault(channel.topic, {}).setdefault(stamp, bytes(message.data))
    return out


@dataclass
class MessageComparison:
    """Two runs' ``EXACT_TOPICS`` compared byte for byte at their common stamps."""

    topics: int                     # topics in either bag
    messages: int                   # messages compared (common stamps, all topics)
    differing: dict[str, tuple[int, float]]     # topic -> (stamps that differ, first one s)
    end: tuple[float, float]        # last stamp of each run (s), over all its topics

    @property
    def identical(self) -> bool:
        return not self.differing and self.end[0] == self.end[1]

    def text(self) -> str:
        ends = (f'both end at t = {self.end[0]:.3f} s' if self.end[0] == self.end[1] else
                f'they end at t = {self.end[0]:.3f} s and {self.end[1]:.3f} s')
        if not self.differing:
            return (f'bit-identical ({self.messages} messages of {self.topics} topics at '
                    f'common stamps), {ends}')
        first = min(self.differing.items(), key=lambda item: (item[1][1], item[0]))
        return (f'DIFFERENT: {len(self.differing)} of {self.topics} topics differ, first '
                f'{first[0]} at t = {first[1][1]:.3f} s ({first[1][0]} stamps); {ends}')


def compare_messages(bag_a: str | Path, bag_b: str | Path) -> MessageComparison:
    """Byte-for-byte comparison of two bags' ``EXACT_TOPICS`` (stamp by stamp)."""
    a, b = stamped_messages(bag_a), stamped_messages(bag_b)
    messages = 0
    differing: dict[str, tuple[int, float]] = {}
    for topic in sorted(set(a) | set(b)):
        ta, tb = a.get(topic, {}), b.get(topic, {})
        common = set(ta) & set(tb)
        messages += len(common)
        bad = sorted(stamp for stamp in common if ta[stamp] != tb[stamp])
        if bad:
            differing[topic] = (len(bad), bad[0] * 1e-9)

    def end(run: dict[str, dict[int, bytes]]) -> float:
        return max((max(stamps) for stamps in run.values() if stamps), default=0) * 1e-9

    return MessageComparison(len(set(a) | set(b)), messages, differing, (end(a), end(b)))


def find_bag(folder: Path) -> Path:
    """A run's bag in its bag ``folder``: its one file, or the folder when the recorder was
    respawned (a split bag, read as one)."""
    files = bag_files(folder)
    if not files and not list(folder.glob('*.mcap')):
        raise RerunError(f'no bag (*.mcap) in {folder}')
    return files[0] if len(files) == 1 else folder


def rerun(bag: Path, out_dir: Path, *, tolerance: float = 0.0, gui: bool = False,
          config_dir: Path | None = None, log=print,
          progress=None) -> tuple[Comparison, int, MessageComparison]:
    """Re-run ``bag`` into ``out_dir``; returns the trajectory comparison, the launcher's
    exit code and the message comparison.
    ``progress``: a ``progress.ProgressLine`` to print the progress on while it runs."""
    from replan_ros.launch.graph import Graph, run_graph
    from replan_ros.launch.watch import ScheduledInputs
    from replan_ros.transport import qos

    run = load_run(bag)
    if not run.odom:
        raise RerunError(f'{bag} has no {ODOM_TOPIC}: nothing to compare')
    if not run.config_text:
        log('[rerun] the bag holds no configuration (replan_config): using the current one')
    setpoints, wrenches = schedule_inputs(run)
    if max(len(setpoints), len(wrenches)) > qos.SCHEDULE.depth:
        log(f'[rerun] more inputs than the schedule depth {qos.SCHEDULE.depth}: '
            'the early ones may not reach a late subscriber')
    fallback = config_dir or Path(os.environ.get('REPLAN_CONFIG', 'config'))
    out_dir.mkdir(parents=True, exist_ok=True)
    new_config, param_files = write_config(run, out_dir, fallback, log=log)
    extra_params = {}
    if run.scenario.get('content'):
        (out_dir / 'scenario.yaml').write_text(run.scenario['content'])
        extra_params = {'recorder': {'scenario_file': str(out_dir / 'scenario.yaml')}}
    bag_dir = out_dir / 'bag'
    # The recorded parameter files include the run's profile: none is added again.
    # The recorded parameter files include the run's gait: none is added again either.
    graph = Graph(out_dir, config_dir=new_config, param_files=param_files, profile=None,
                  gait=None, record_dir=bag_dir, gui=gui, respawn=False,
                  extra_params=extra_params, log=log, stop_time=run.duration)
    gaits = schedule_gaits(run)

    def send_inputs(node) -> list:
        deliveries = ScheduledInputs(setpoints, wrenches, gaits).publish(node)
        log(f'[rerun] sent {len(setpoints)} set-points, {len(wrenches)} wrenches and '
            f'{len(gaits)} gait switches')
        return deliveries

    log(f'[rerun] {bag}: {run.duration:.2f} s of sim time, recorded at git '
        f'{run.run_info.get("git_revision", "?")}; output in {out_dir}')
    event_times = [stamp_to_sec(m.header.stamp) for m in [*setpoints, *wrenches]]
    event_times += [stamp_to_sec(m.stamp) for m in gaits]
    code = run_graph(graph, run.duration, wall_timeout=max(300.0, 20.0 * run.duration),
                     on_start=send_inputs, progress=progress, event_times=event_times)
    new_bag = find_bag(bag_dir)
    return (compare_trajectories(run.odom, load_run(new_bag).odom), code,
            compare_messages(bag, new_bag))


def report(comparison: Comparison, tolerance: float) -> tuple[str, bool]:
    ok = comparison.max_deviation <= tolerance and comparison.coverage >= 0.99
    at = f' at t = {comparison.at_stamp:.3f} s' if comparison.at_stamp is not None else ''
    text = (f'[rerun] largest base position deviation: {comparison.max_deviation:.3g} m{at} '
            f'(rms {comparison.rms:.3g} m, {comparison.matched} common stamps, '
            f'{comparison.missing} recorded stamps missing) -> '
            f'{"MATCH" if ok else "DIFFERENT"} (tolerance {tolerance} m)')
    return text, ok


def _print_report(comparison, messages, tolerance: float) -> bool:
    """Print the trajectory comparison and the messages' verdict; True if within tolerance."""
    text, ok = report(comparison, tolerance)
    print(text)
    print(f'[rerun] messages: {messages.text()}')
    return ok


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog='rerun.sh', description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('bag', type=Path)
    parser.add_argument('--out', type=Path, help='output folder (default runs/rerun-<time>)')
    parser.add_argument('--tolerance', type=float, default=0.0,
                        help='m (default 0: runs are bit-exact on the same code and machine; '
                             'loosen it for a bag of another revision or machine)')
    parser.add_argument('--gui', action='store_true')
    parser.add_argument('--against', type=Path, metavar='OTHER_BAG',
                        help='compare BAG with another recorded run instead of re-running '
                             '(e.g. two runs of one scenario)')
    parser.add_argument('--quiet', action='store_true',
                        help='no progress line (sim time, real-time factor, distance, '
                             're-plans, inputs) while the graph runs')
    args = parser.parse_args(argv)
    if args.against is not None:
        try:
            comparison = compare_trajectories(load_run(args.bag).odom,
                                              load_run(args.against).odom)
            messages = compare_messages(args.bag, args.against)
        except (RerunError, OSError) as err:
            print(f'rerun: {err}', file=sys.stderr)
            return 2
        return 0 if _print_report(comparison, messages, args.tolerance) else 1
    root = Path(os.environ.get('REPLAN_ROOT', '.'))
    out = args.out or root / 'runs' / f'rerun-{time.strftime("%Y%m%d-%H%M%S")}'
    try:
        from replan_ros.launch.progress import ProgressLine
        comparison, code, messages = rerun(args.bag, out, tolerance=args.tolerance,
                                           gui=args.gui,
                                           progress=None if args.quiet else ProgressLine())
    except ConfigError as err:      # the recorded configuration no longer passes the check
        print(f'config error: {err}', file=sys.stderr)
        return 2
    except (RerunError, OSError) as err:
        print(f'rerun: {err}', file=sys.stderr)
        return 2
    ok = _print_report(comparison, messages, args.tolerance)
    if code != 0:
        print(f'[rerun] the launcher exited with code {code}', file=sys.stderr)
    return 0 if ok and code == 0 else 1


if __name__ == '__main__':
    sys.exit(main())
