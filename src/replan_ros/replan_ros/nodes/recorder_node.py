"""Recorder: every topic of the graph (or a list / a regex) into an mcap bag that rosbag2,
Foxglove and any mcap reader open (conventions in ``bag_io``).

- Topics are discovered as they appear (graph polled every ``discovery_period`` s) and
  subscribed with ``raw=True``: payloads are stored as received, serialized CDR.
- The subscriptions are read on demand (``on_demand.py``): their samples wait in the DDS queues
  (KEEP_ALL with ``queue_depth`` 0: none is overwritten before it is taken; the publishers'
  histories resend what a busy recorder missed, docs/recording.md "No loss") and are taken
  every ``take_period`` wall s, all topics at once, and written in the order they were
  received. One wake-up per period instead of one per message keeps the recorder from slowing
  the lock-step graph (docs/performance.md).
- Counted while written (``completeness``): the sim's per-tick topics against its ticks, the
  others against their publisher's sequence numbers (stored as the mcap ``sequence``); the
  verdict goes into the bag (``replan_completeness``) and ``metadata.yaml``.
- A file that cannot be written (full disk, unwritable folder): one error line with the path
  and the cause, and the recorder records no more; the graph runs on unaffected.
- A respawned recorder continues the bag as a split: a new file beside the killed one, which
  it recovers first (``bag_open``); ``metadata.yaml`` lists both.
- The subscription QoS follows the publishers, as rosbag2 does (``qos.recorder_qos``).
- Times (docs/recording.md): ``log_time`` = the ``log_time_clock`` (``sim``: the newest
  ``/clock`` taken, read on demand, not through rclpy's time source, whose callback woke the
  executor at every ``/clock``) when the message arrived (``arrival_time``); ``publish_time``
  per the ``publish_time`` parameter (``source``: the DDS source timestamp, as rosbag2).
- Chunks close at ``chunk_size`` bytes or ``chunk_interval`` s (checked at every take).
  Everything runs in the executor's thread.
- ``/robot_description``, ``/tf`` and the viewers' figures are derived (``state_view``) and
  written, never subscribed; a robot without them stops the start (``config error:``, exit 2).
- The run's configuration goes in metadata records (``run_metadata``).
- SIGINT/SIGTERM: the last chunk, indexes and summary are written. SIGKILL: the finished chunks
  are on disk; the readers recover them on the way (``bag_open``).
"""

from __future__ import annotations

import sys
import time

from diagnostic_msgs.msg import DiagnosticArray
from rclpy.clock import Clock, ClockType
from rclpy.node import Node
from rosgraph_msgs.msg import Clock as ClockMsg

from replan_ros.messages.introspection import message_class
from replan_ros.messages.stamps import ns_to_stamp
from replan_ros.nodes.node_main import log_at, refuse_configuration, run_node
from replan_ros.params import ConfigError, declare_node_parameters
from replan_ros.params.robot import node_robot
from replan_ros.recording.bag_files import recovered_name
from replan_ros.recording.bag_io import (
    has_header,
    message_definition,
    normalize_type_name,
    qos_profiles_yaml,
)
from replan_ros.recording.bag_open import recover_killed
from replan_ros.recording.bag_writer import BagWriteError, BagWriter
from replan_ros.recording.completeness import RECORD, Counter
from replan_ros.recording.recorder_state import (
    RecordedTopic,
    TopicSelection,
    status_values,
    totals,
)
from replan_ros.recording.run_metadata import arrival_time, bag_path, run_records
from replan_ros.telemetry import diagnostics
from replan_ros.transport.on_demand import OnDemandSubscriptions
from replan_ros.transport.qos import COMMAND, INTERNAL_PUB_EVENTS, LATCHED, recorder_qos
from replan_ros.transport.stamped_buffer import cdr_header_stamp_ns
from replan_ros.view.state_view import (
    DERIVED_TOPICS,
    DESCRIPTION_TOPIC,
    INPUT_TOPICS,
    Derived,
    StateView,
    definition,
    robot_state_view,
)

CLOCK_TOPIC = '/clock'
CLOCK_TYPE = 'rosgraph_msgs/msg/Clock'


class RecorderNode(Node):
    """Records the graph into one mcap file."""

    def __init__(self) -> None:
        super().__init__('recorder')
        # Every parameter from params.RECORDER (default, range, syntax): a wrong value stops
        # the start with one line naming the file and key, as in every node.
        p = declare_node_parameters(self)
        for name in ('topics', 'config_files'):
            p[name] = [v for v in (p[name] or []) if v]
        self._selected = TopicSelection(p['topics'], p['topics_regex'], p['exclude_regex'],
                                        p['include_hidden'])
        self._queue_depth = int(p['queue_depth'])
        self._publish_time = p['publish_time']
        self._log_time_clock = p['log_time_clock']
        self._robot_file = str(p['robot_file'])
        self._sim_ns = 0                # the newest /clock taken (ns of sim time), 0 before it
        self._recorded: dict[str, RecordedTopic] = {}
        self._skipped: set[str] = set()
        self._warned: set[str] = set()
        self._write_errors = 0
        self._closed = False
        self._view_channels: dict[str, int] = {}
        self._counter = Counter()
        self._failed: BagWriteError | None = None
        self._writer: BagWriter | None = None
        # Before the bag is opened: a robot the bag cannot show stops the start (exit code 2)
        # and leaves no bag behind.
        self._view = self._make_view()
        self._input = OnDemandSubscriptions(self)
        self.path = bag_path(p['output'] or p['output_dir'])
        try:
            self._open(p)
        except BagWriteError as err:
            self._stop(err)
        self._batch: list[tuple[int, int, RecordedTopic, bytes, int, int]] = []
        self._last_take: tuple[int, int] | None = None     # (wall ns, node clock ns)
        self._diag_pub = self.create_publisher(DiagnosticArray, '/diagnostics', COMMAND,
                                               event_callbacks=INTERNAL_PUB_EVENTS)
        # Discovery and diagnostics run on the steady clock: a ROS timer under sim time would
        # stop whenever /clock does (before the sim starts, or when it is paused).
        steady = Clock(clock_type=ClockType.STEADY_TIME)
        self._discovery_timer = self.create_timer(float(p['discovery_period']), self._discover,
                                                  clock=steady)
        self._diag_timer = self.create_timer(float(p['diagnostics_period']), self._report,
                                             clock=steady)
        self._take_timer = self.create_timer(float(p['take_period']), self.take, clock=steady)
        if self._failed is None:
            self.get_logger().info(f'recording to {self.path}')
        self._discover()

    def _open(self, p: dict) -> None:
        """Open the bag file and write the run's configuration into it. A killed recorder's
        files in the bag's folder (``output_dir``) are recovered first: this one is a split."""
        try:
            self.path.parent.mkdir(parents=True, exist_ok=True)
        except OSError as err:
            raise BagWriteError(self.path.parent, err) from None
        if p['output_dir'] and not p['output']:
            recover_killed(self.path.parent, self.get_logger().warning)
        self._writer = BagWriter(self.path, chunk_size=int(p['chunk_size']),
                                 chunk_interval=float(p['chunk_interval']),
                                 compression=p['compression'],
                                 library='replan_ros recorder_node (mcap-python)')
        records, errors = run_records(p, self.get_parameter('use_sim_time').value)
        for name, record in records:
            self._writer.add_metadata(name, record)
        for error in errors:
            self.get_logger().error(error)
        if self._view is not None:
            self._write_derived([self._view.description()], 0)

    def _stop(self, err: BagWriteError) -> None:
        """The bag cannot be written: record no more, say so once. The graph never waits for
        the recorder, so the robot walks on; the finished chunks stay readable."""
        if self._failed is not None:
            return
        self._failed = err
        self._say(f'recording stopped: {err}; the robot runs on, the bag holds what was '
                  'written before (recovered when read)', error=True)
        if not self._closed:            # close() has destroyed them already
            self._input.destroy()

    # ------------------------------------------------------------------ discovery

    def _warn_once(self, key: str, text: str) -> None:
        if key not in self._warned:
            self._warned.add(key)
            self.get_logger().warning(text)

    def _discover(self) -> None:
        if self._closed or self._failed is not None:
            return
        for topic, types in self.get_topic_names_and_types():
            if topic in self._recorded or topic in self._skipped:
                continue
            record = self._selected(topic)
            # Sim time is read from /clock even when /clock is not recorded.
            clock_only = (not record and topic == CLOCK_TOPIC
                          and self._log_time_clock == 'sim' and CLOCK_TYPE in types)
            if not record and not clock_only:
                self._skipped.add(topic)
                continue
            publishers = self.get_publishers_info_by_topic(topic)
            if not publishers:
                continue   # only subscribers so far: the QoS to request is not known yet
            if clock_only:
                self._subscribe_clock_only(publishers)
                continue
            if len(types) > 1:
                self._warn_once(f'types:{topic}',
                                f'{topic} has several types {types}; recording {types[0]}')
            self._subscribe(topic, types[0], publishers)

    def _subscribe_clock_only(self, publishers) -> None:
        qos, _, _ = recorder_qos([info.qos_profile for info in publishers], depth=1)
        self._skipped.add(CLOCK_TOPIC)
        self._input.subscribe(ClockMsg, CLOCK_TOPIC, qos, self._on_clock_only, raw=True)

    def _on_clock_only(self, data: bytes) -> None:
        self._sim_ns = cdr_header_stamp_ns(data) or self._sim_ns

    def _now_ns(self) -> int:
        """Now on the ``log_time_clock`` (ns): the newest /clock taken, or the system clock."""
        return self._sim_ns if self._log_time_clock == 'sim' else time.time_ns()

    def _subscribe(self, topic: str, type_name: str, publishers) -> None:
        try:
            msg_type = message_class(type_name)
            definition = message_definition(type_name)
            stamp_in_header = has_header(type_name)
        except (ValueError, OSError, RecursionError) as err:
            self._warn_once(f'type:{topic}', f'not recording {topic}: {err}')
            self._skipped.add(topic)
            return
        profiles = [info.qos_profile for info in publishers]
        qos, reliable, latched = recorder_qos(profiles, self._queue_depth)
        type_hash = str(publishers[0].topic_type_hash)
        channel_id = self._writer.add_channel(
            topic, normalize_type_name(type_name), qos_profiles_yaml(profiles), type_hash,
            definition=definition)
        entry = RecordedTopic(topic, type_name, channel_id, stamp_in_header)
        self._recorded[topic] = entry
        # The channel exists before the first message can be taken.
        self._input.subscribe(msg_type, topic, qos, self._make_callback(entry), raw=True,
                              with_info=True)
        self.get_logger().info(
            f'recording {topic} [{type_name}] '
            f'({"reliable" if reliable else "best effort"}'
            f'{", transient local" if latched else ""})')

    def _make_callback(self, entry: RecordedTopic):
        batch = self._batch

        def on_message(data: bytes, info: dict) -> None:
            entry.received += 1
            batch.append((info.get('received_timestamp', 0), len(batch), entry, data,
                          info.get('source_timestamp', 0),
                          info.get('publication_sequence_number') or 0))

        return on_message

    def take(self) -> int:
        """Take every queued message of every topic and write them in the order they were
        received. Returns how many."""
        if self._closed or self._failed is not None:
            return 0
        self._input.drain()
        self._batch.sort(key=lambda item: (item[0], item[1]))
        if self._log_time_clock == 'sim':
            for _, _, entry, data, _, _ in self._batch:
                if entry.name == CLOCK_TOPIC:
                    self._sim_ns = cdr_header_stamp_ns(data) or self._sim_ns
        take = (time.time_ns(), self._now_ns())
        previous, self._last_take = self._last_take, take
        for received, _, entry, data, source_time, sequence in self._batch:
            log_time = arrival_time(received, previous, take)
            publish_time = None
            if self._publish_time == 'source':
                publish_time = source_time or None
            elif self._publish_time == 'header' and entry.stamp_in_header:
                publish_time = cdr_header_stamp_ns(data)
            self._write_one(entry, data, log_time,
                            log_time if publish_time is None else publish_time, sequence)
            if self._failed is not None:
                break
            if self._view is not None and entry.name in INPUT_TOPICS:
                self._write_derived(self._view.feed(entry.name, data), log_time)
        count = len(self._batch)
        self._batch.clear()
        try:
            if self._failed is None:
                self._writer.poll()          # close a chunk older than chunk_interval
        except BagWriteError as err:
            self._stop(err)
        return count

    # ------------------------------------------------------------------ writing

    def _write_one(self, entry: RecordedTopic, data: bytes, log_time: int, publish_time: int,
                   sequence: int) -> None:
        # The publisher's sequence number is the mcap "sequence": counts what it published.
        try:
            self._writer.write(entry.channel_id, data, log_time, publish_time,
                               sequence=sequence or None)
            entry.written += 1
            self._counter.add(entry.name, data, sequence)
        except BagWriteError as err:
            self._stop(err)
        except Exception as err:  # one bad write must not stop the recording
            self._write_errors += 1
            self._warn_once('write', f'write failed: {err}')

    def _make_view(self) -> StateView | None:
        """What a viewer needs to draw the robot (state_view.py): the URDF at once, then the
        transforms, forces and figures derived from the recorded topics. Written, never
        subscribed: a DDS publisher of the same names (the live view's) is not recorded.

        A robot whose model gives no ``/robot_description`` and ``/tf`` is one ``config
        error:`` line and exit code 2, so the launcher stops the run: a bag recorded on
        without them (every ANYmal C bag once) cannot show the robot, and nothing said so."""
        self._skipped.update(DERIVED_TOPICS)
        if not any(self._selected(t) for t in DERIVED_TOPICS):
            return None
        try:
            # The robot file's model and names (none: the project's HyQ).
            return robot_state_view(node_robot(self._robot_file, '', ''))
        except ConfigError as err:
            refuse_configuration(self, f'{err}; a bag without them cannot show the robot')

    def _write_derived(self, items: list[Derived], log_time: int) -> None:
        for item in items:
            if not self._selected(item.topic):
                continue
            try:
                if item.topic not in self._view_channels:
                    profile = LATCHED if item.topic == DESCRIPTION_TOPIC else COMMAND
                    self._view_channels[item.topic] = self._writer.add_channel(
                        item.topic, item.type_name, qos_profiles_yaml([profile]),
                        definition=definition(item.type_name))
                self._writer.write(self._view_channels[item.topic], item.data, log_time,
                                   item.stamp_ns or log_time)
            except BagWriteError as err:
                self._stop(err)
                return
            except Exception as err:  # a viewer's topic must not stop the recording
                self._write_errors += 1
                self._warn_once('derived', f'{item.topic} not written: {err}')

    def _report(self) -> None:
        writer = self._writer
        values = status_values(self.path, self._recorded, self._write_errors,
                               writer.chunk_count if writer else 0,
                               writer.bytes_written if writer else 0)
        level = diagnostics.OK if not self._write_errors else diagnostics.ERROR
        message = 'recording' if not self._write_errors else 'write errors'
        if self._failed is not None:
            level, message = diagnostics.ERROR, f'recording stopped: {self._failed}'
        self._diag_pub.publish(diagnostics.array(
            ns_to_stamp(self._now_ns()),
            diagnostics.status(f'{self.get_name()}: bag', level, message, values)))

    def close(self) -> None:
        """Stop subscriptions, write what is queued, finish the file (summary and indexes)."""
        if self._closed:
            return
        self.take()
        self._closed = True
        if self._failed is None:
            self._input.destroy()
        completeness = self._counter.result()
        try:
            if self._failed is None:
                self._writer.add_metadata(RECORD, completeness.record())
                # A reader's copy of this file made while it was written: this one is whole.
                recovered_name(self.path).unlink(missing_ok=True)
            if self._writer is not None:
                self._writer.close()
        except (BagWriteError, OSError) as err:
            self._stop(err if isinstance(err, BagWriteError) else BagWriteError(self.path, err))
        if self._writer is None:
            return
        received, written = totals(self._recorded)
        # After a failed write the count covers what was written, and finds it complete;
        # what came after the failure is in no file.
        verdict = (completeness.gaps_text() if self._failed is None
                   else 'incomplete: nothing written after the write that failed')
        text = (f'closed {self.path}: {written} of {received} received messages written, '
                f'{len(self._recorded)} topics, {self._writer.chunk_count} chunks; {verdict}')
        if self._writer.directory_metadata_error:
            text += f'; no metadata.yaml: {self._writer.directory_metadata_error}'
        self._say(text)

    def _say(self, text: str, error: bool = False) -> None:
        if self.context.ok():
            # One call site per severity (log_at): after the error line of a full disk, the
            # closing info line through the same call site raised in rclpy.
            log_at(self.get_logger(), 'error' if error else 'info', text)
        else:   # after SIGINT/SIGTERM the context is shut down: /rosout is gone
            print(f'[recorder] {text}', file=sys.stderr, flush=True)

    def destroy_node(self) -> None:
        self.close()
        super().destroy_node()


def main(args=None):
    # Before it is destroyed, the recorder takes what is still queued in its subscriptions.
    run_node(RecorderNode, args, drain=RecorderNode.take)


if __name__ == '__main__':
    main()
