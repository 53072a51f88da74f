"""Is a bag complete? What was published counted against what was written.

- The sim's per-tick topics (``TICK_TOPICS``: one message per 4 ms tick, stamped with it):
  the distinct header stamps written against the ticks the sim ran, from the first tick any
  of them holds to the last tick the sim ran (the newest per-tick stamp, or the ``tick`` count
  of the sim's last ``/diagnostics`` times the period, whichever is later; its ``sim_time``
  has 6 significant digits only). A republished tick counts once.
- Every other topic with a single publisher, the controller's per-tick ``/odom``,
  ``/contacts``, ``/joint_torque_cmd`` too (a dead controller answers no tick, and that is no
  loss of the recording): the publisher's own count, its DDS publication
  sequence number (1, 2, 3, ... per writer), which the recorder stores as the mcap message's
  ``sequence`` (what the mcap format means that field for). A gap between two written
  sequence numbers is a lost message; a number that drops starts a new writer (a respawned
  node, a second publisher). Messages before the recorder subscribed, or after its last take,
  are not seen.
- The controller's estimate (``ESTIMATE_TOPICS``), which the sequence count cannot see before
  the recorder subscribed: when the bag holds the controller's commands from its first
  (``/joint_torque_cmd`` numbered from 1), each estimate topic must hold the tick of that first
  command too (the controller publishes a tick's estimate before or with its command); the
  ticks from the first command to the estimate's first are missing.
- Topics with several publishers (``/diagnostics``, ``/rosout``) are not counted.

The recorder counts while it writes (``Counter``) and stores the result in the bag as the
metadata record ``replan_completeness`` (``Completeness.record``); ``bag_dir`` copies it into
``metadata.yaml``'s ``custom_data``. ``bag_completeness`` reads it back, or counts the bag's
messages when no file has it (a killed recorder, a split bag); a file without summary (or its
recovered copy) is incomplete whatever it holds, since its end is in no file. ``is_complete`` is
the verdict.
"""

from __future__ import annotations

import contextlib
import json
import sys
from dataclasses import dataclass, field
from pathlib import Path

from mcap.reader import make_reader

from replan_ros.recording.bag_files import RECOVERED_SUFFIX, bag_files
from replan_ros.recording.bag_io import iter_raw, summarize

RECORD = 'replan_completeness'
TICK_TOPICS = frozenset({'/imu', '/joint_states', '/ground_truth/odom', '/ground_truth/contacts'})
# Topics every node publishes on: one sequence per writer, interleaved, so not counted.
DIAGNOSTICS = '/diagnostics'
SHARED_TOPICS = frozenset({DIAGNOSTICS, '/rosout', '/parameter_events'})
SIM_STATUS = 'sim'            # the sim's status name on /diagnostics
COMMANDS = '/joint_torque_cmd'
ESTIMATE_TOPICS = ('/odom', '/contacts')
MAX_GAPS = 20                 # gaps listed per topic (all are counted)
MAX_TICKS = 50_000_000        # more ticks than this between two stamps: not a tick stream
MAX_WRITERS = 64              # runs of sequence numbers followed per topic


def _stamp_ns(data: bytes) -> int | None:
    """``header.stamp`` (ns) of a CDR payload whose first field is a std_msgs/Header."""
    if len(data) < 12:
        return None
    order = 'little' if data[1] & 1 else 'big'      # CDR encapsulation: 0x0001 little endian
    return (int.from_bytes(data[4:8], order, signed=True) * 1_000_000_000
            + int.from_bytes(data[8:12], order))


@dataclass
class _Sequence:
    """One topic's publication sequence numbers, in the order they were written. Each writer
    counts 1, 2, 3, ...; the writer of a number is not known, so a number continues the run
    that ended just before it, else the highest run below it (a gap), else it starts a run (a
    new writer: a respawned node, a second publisher such as a user's tool)."""
    last: int = 0                   # the newest number (0: none counted)
    ends: set[int] = field(default_factory=set)
    missing: int = 0
    gaps: list[tuple[int, int]] = field(default_factory=list)

    def add(self, number: int) -> None:
        if number <= 0:
            return                      # no sequence number: not counted
        self.last = number
        ends = self.ends
        if number - 1 in ends:          # the common case: the next of a run
            ends.discard(number - 1)
            ends.add(number)
            return
        below = [end for end in ends if end < number]
        if below:
            end = max(below)
            self.missing += number - end - 1
            if len(self.gaps) < MAX_GAPS:
                self.gaps.append((end + 1, number - 1))
            ends.discard(end)
        ends.add(number)
        if len(ends) > MAX_WRITERS:     # a bound on memory: the oldest runs are closed
            ends.discard(min(ends))


@dataclass
class TopicCount:
    """A topic's verdict: ``counted_by`` 'ticks', 'sequence' or '' (not counted)."""
    written: int = 0
    counted_by: str = ''
    missing: int = 0
    gaps: list[list[int]] = field(default_factory=list)   # [first, last] tick ns or sequence


@dataclass
class Completeness:
    complete: bool = True
    tick_period_ns: int = 0
    first_tick_ns: int = 0
    last_tick_ns: int = 0
    topics: dict[str, TopicCount] = field(default_factory=dict)
    # Files whose recording ended without a summary (a killed recorder, a full disk) or
    # their recovered copies: what came after their last chunk is in no file, and no count
    # of the messages that are there can show it.
    cut: list[str] = field(default_factory=list)

    @property
    def ticks(self) -> int:
        if not self.tick_period_ns:
            return 0
        return round((self.last_tick_ns - self.first_tick_ns) / self.tick_period_ns) + 1

    def gaps_text(self) -> str:
        """'complete' or each incomplete topic with its count, in one line."""
        if self.complete:
            return 'complete'
        parts = [f'{topic} misses {count.missing} '
                 f'{"tick" if count.counted_by == "ticks" else "message"}'
                 f'{"s" if count.missing > 1 else ""}'
                 for topic, count in sorted(self.topics.items()) if count.missing]
        parts += [f'{name} ends early (its recorder was killed or its disk was full)'
                  for name in self.cut]
        return 'incomplete: ' + ', '.join(parts)

    def record(self) -> dict[str, str]:
        """The ``replan_completeness`` metadata record (a string map, as mcap requires)."""
        return {
            'complete': 'true' if self.complete else 'false',
            'summary': self.gaps_text(),
            'ticks': str(self.ticks),
            'tick_period_ns': str(self.tick_period_ns),
            'first_tick_ns': str(self.first_tick_ns),
            'last_tick_ns': str(self.last_tick_ns),
            'topics': json.dumps({t: vars(c) for t, c in sorted(self.topics.items())},
                                 sort_keys=True),
        }

    @classmethod
    def from_record(cls, record: dict[str, str]) -> Completeness:
        topics = {t: TopicCount(**c) for t, c in json.loads(record.get('topics', '{}')).items()}
        return cls(record.get('complete') == 'true', int(record.get('tick_period_ns', 0)),
                   int(record.get('first_tick_ns', 0)), int(record.get('last_tick_ns', 0)),
                   topics)


@dataclass
class _Ticks:
    """One per-tick topic's stamps, kept as steps (a long run holds millions of ticks): the
    first and last stamp, how often each step between two new stamps occurred, and where the
    first large steps were. A stamp not newer than the last (a republished tick) is skipped."""
    first: int | None = None
    last: int = 0
    smallest: int = 0
    steps: dict[int, int] = field(default_factory=dict)
    jumps: list[tuple[int, int]] = field(default_factory=list)

    def add(self, stamp: int) -> None:
        # Called for every message the recorder writes: a few dict operations, no search.
        if stamp <= self.last and self.first is not None:
            return
        if self.first is None:
            self.first = self.last = stamp
            return
        step = stamp - self.last
        steps = self.steps
        if step in steps:
            steps[step] += 1
        else:
            steps[step] = 1
            # Kept for the list of gaps: the first step (the smallest is not known yet).
            if not self.smallest and len(self.jumps) < MAX_GAPS:
                self.jumps.append((self.last, stamp))
            self.smallest = min(self.smallest or step, step)
        # ... and steps half again the smallest so far.
        if step * 2 > self.smallest * 3 and len(self.jumps) < MAX_GAPS:
            self.jumps.append((self.last, stamp))
        self.last = stamp

    def missing(self, first: int, last: int, period: int) -> tuple[int, list[list[int]]]:
        """Ticks of [first, last] (every ``period`` ns) without a stamp: (count, ranges)."""
        head = round((self.first - first) / period)
        tail = round((last - self.last) / period)
        inner = sum(count * (round(step / period) - 1) for step, count in self.steps.items()
                    if round(step / period) > 1)
        gaps = [[first, self.first - period]] if head > 0 else []
        gaps += [[a + period, b - period] for a, b in self.jumps if round((b - a) / period) > 1]
        if tail > 0:
            gaps.append([self.last + period, last])
        return max(head, 0) + inner + max(tail, 0), gaps[:MAX_GAPS]


class Counter:
    """What a recording wrote, fed message by message (``add``)."""

    def __init__(self) -> None:
        self.written: dict[str, int] = {}
        self.ticks: dict[str, _Ticks] = {}
        self.sequences: dict[str, _Sequence] = {}
        self.shared: set[str] = set(SHARED_TOPICS)
        self.sim_time_ns = 0      # the sim's own report: its sim_time (6 digits) ...
        self.sim_ticks = 0        # ... and its count of ticks done (exact)
        # The first message of the controller's commands and estimate: (stamp ns, sequence).
        self.firsts: dict[str, tuple[int | None, int]] = {}

    def add(self, topic: str, data: bytes, sequence: int) -> None:
        written = self.written
        written[topic] = written.get(topic, 0) + 1
        if topic in TICK_TOPICS:
            stamp = _stamp_ns(data)
            if stamp is not None:
                ticks = self.ticks.get(topic)
                if ticks is None:
                    ticks = self.ticks[topic] = _Ticks()
                ticks.add(stamp)
        elif topic not in self.shared:
            if topic not in self.firsts and (topic == COMMANDS or topic in ESTIMATE_TOPICS):
                self.firsts[topic] = (_stamp_ns(data), sequence)
            numbers = self.sequences.get(topic)
            if numbers is None:
                numbers = self.sequences[topic] = _Sequence()
            numbers.add(sequence)
        elif topic == DIAGNOSTICS:
            self.add_diagnostics(data)

    def add_diagnostics(self, data: bytes) -> None:
        """A ``/diagnostics`` message (CDR): the sim's status, if it holds it."""
        from diagnostic_msgs.msg import DiagnosticArray
        from rclpy.serialization import deserialize_message
        try:
            array = deserialize_message(data, DiagnosticArray)
        except Exception:        # another layout: not the sim's status
            return
        for status in array.status:
            if status.name == SIM_STATUS:
                self.add_sim_status({v.key: v.value for v in status.values})

    def add_sim_status(self, values: dict[str, str]) -> None:
        """The sim's ``/diagnostics`` values: its ``sim_time`` is the tick it has run to."""
        with contextlib.suppress(KeyError, ValueError):
            self.sim_time_ns = max(self.sim_time_ns, round(float(values['sim_time']) * 1e9))
        with contextlib.suppress(KeyError, ValueError):
            self.sim_ticks = max(self.sim_ticks, int(values['tick']))

    def result(self) -> Completeness:
        out = Completeness()
        for topic, written in self.written.items():
            out.topics[topic] = TopicCount(written=written)
        steps = [t.smallest for t in self.ticks.values() if t.smallest]
        # Stamps are float seconds rounded to ns: a period of whole microseconds.
        period = round(min(steps) / 1000) * 1000 if steps else 0
        if period:
            first = min(t.first for t in self.ticks.values())
            last = max(t.last for t in self.ticks.values())
            # The sim's own report: it ran that far (stamps are ticks x period, from 0).
            reported = (self.sim_ticks * period if self.sim_ticks
                        else first + round((self.sim_time_ns - first) / period) * period)
            last = max(last, reported)
        if period and (last - first) / period < MAX_TICKS:     # else no tick stream
            out.tick_period_ns, out.first_tick_ns, out.last_tick_ns = period, first, last
            for topic, ticks in self.ticks.items():
                missing, gaps = ticks.missing(first, last, period)
                out.topics[topic] = TopicCount(self.written[topic], 'ticks', missing, gaps)
        for topic, sequence in self.sequences.items():
            if sequence.last:
                out.topics[topic] = TopicCount(self.written[topic], 'sequence',
                                               sequence.missing,
                                               [list(g) for g in sequence.gaps])
        self._add_estimate_head(out, period)
        out.complete = not any(count.missing for count in out.topics.values())
        return out

    def _add_estimate_head(self, out: Completeness, period: int) -> None:
        """The estimate's ticks from the controller's first command on that the bag lacks at
        its start (published before the recorder subscribed: no sequence gap shows them)."""
        command = self.firsts.get(COMMANDS)
        if command is None or command[0] is None or command[1] != 1:
            return          # not the controller's first command: its start is not in the bag
        first_command = command[0]
        for topic in ESTIMATE_TOPICS:
            first = self.firsts.get(topic)
            count = out.topics.get(topic)
            if first is None or first[0] is None or count is None or first[0] <= first_command:
                continue
            step = period or first[0] - first_command
            count.missing += max(round((first[0] - first_command) / step), 1)
            if len(count.gaps) < MAX_GAPS:
                count.gaps.insert(0, [first_command, first[0] - step])


def count_files(files: list[Path]) -> Completeness:
    """Count the messages of ``files`` (one bag, split or recovered) as the recorder does."""
    counter = Counter()
    cut = [path.name for path in files
           if path.name.endswith(RECOVERED_SUFFIX) or not _has_summary(path)]
    for path in files:
        try:
            for _schema, channel, message in iter_raw(path):
                counter.add(channel.topic, message.data, message.sequence)
        except Exception:   # a killed recorder's file: counted as far as it reads
            continue
    result = counter.result()
    result.cut = cut
    result.complete = result.complete and not cut
    return result


def _has_summary(path: Path) -> bool:
    try:
        with open(path, 'rb') as stream:
            return make_reader(stream).get_summary() is not None
    except Exception:   # truncated or not mcap at all: no summary
        return False


def bag_completeness(bag: str | Path) -> Completeness:
    """The verdict on ``bag`` (a file or a bag directory): the recorder's record when the bag
    is one file that holds it, else counted from the messages of all its files. A path that
    holds no .mcap file has no verdict: FileNotFoundError (not "complete")."""
    files = bag_files(bag)
    if not files:
        raise FileNotFoundError(f'{bag}: no .mcap file')
    return files_completeness(files)


def files_completeness(files: list[Path]) -> Completeness:
    """``bag_completeness`` of a bag's files (``bag_files``, ``bag_open.readable_files``)."""
    if len(files) == 1:
        try:
            record = summarize(files[0]).metadata.get(RECORD)
        except Exception:         # no summary: counted from what the file holds
            record = None
        if record:
            return Completeness.from_record(record)
    return count_files(files)


def is_complete(bag: str | Path) -> bool:
    """True if every counted topic of ``bag`` has all its ticks or messages."""
    return bag_completeness(bag).complete


def main(args: list[str] | None = None) -> int:
    """``python -m replan_ros.recording.completeness BAG...``: one line per bag; exit code 1
    if one is incomplete."""
    bags = sys.argv[1:] if args is None else args
    bad = 0
    for bag in bags:
        try:
            result = bag_completeness(bag)
        except OSError as err:
            print(f'{bag}: not counted: {err}')
            bad += 1
            continue
        bad += not result.complete
        print(f'{bag}: {result.gaps_text()} ({result.ticks} ticks)')
    return 1 if bad else 0


if __name__ == '__main__':
    sys.exit(main())
