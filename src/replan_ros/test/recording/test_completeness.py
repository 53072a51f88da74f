"""completeness: per-tick topics against the sim's ticks, others against their publisher's
sequence numbers; the verdict stored in the bag, in metadata.yaml, and read back."""

import struct

import pytest
import yaml
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from nav_msgs.msg import Odometry
from rclpy.serialization import serialize_message
from std_msgs.msg import String

from replan_ros.recording.bag_dir import METADATA_FILE, write_directory_metadata
from replan_ros.recording.bag_writer import BagWriter
from replan_ros.recording.completeness import (
    RECORD,
    Completeness,
    Counter,
    bag_completeness,
    count_files,
    is_complete,
)
from replan_ros.recording.completeness import main as completeness_main

TICK = 4_000_000


def _odom(ns: int) -> bytes:
    msg = Odometry()
    msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(ns, 1_000_000_000)
    return serialize_message(msg)


def _sim_status(ticks: int) -> bytes:
    """The sim's status as it publishes it: sim_time with 6 digits, the ticks done exactly."""
    status = DiagnosticStatus(name='sim', values=[
        KeyValue(key='sim_time', value=f'{ticks * TICK * 1e-9:.6g}'),
        KeyValue(key='tick', value=str(ticks))])
    return serialize_message(DiagnosticArray(status=[status]))


def _ticks(counter: Counter, topic: str, ticks) -> None:
    for k in ticks:
        counter.add(topic, _odom(k * TICK), 0)


def test_every_tick_and_every_sequence_number_is_complete():
    counter = Counter()
    _ticks(counter, '/joint_states', range(100))
    _ticks(counter, '/ground_truth/odom', [*range(100), 99])     # a republished tick
    for n in range(1, 6):
        counter.add('/footholds', b'', n)
    result = counter.result()
    assert result.complete, result.gaps_text()
    assert (result.tick_period_ns, result.ticks) == (TICK, 100)
    assert result.topics['/ground_truth/odom'].written == 101
    assert result.topics['/footholds'].counted_by == 'sequence'


def test_a_lost_tick_and_a_lost_message_are_named_with_their_place():
    counter = Counter()
    _ticks(counter, '/joint_states', [k for k in range(100) if k not in (40, 41, 42)])
    _ticks(counter, '/ground_truth/odom', range(100))
    for n in (1, 2, 5, 6):
        counter.add('/footholds', b'', n)
    result = counter.result()
    assert not result.complete
    joints = result.topics['/joint_states']
    assert (joints.counted_by, joints.missing) == ('ticks', 3)
    assert joints.gaps == [[40 * TICK, 42 * TICK]]
    assert result.topics['/footholds'].missing == 2
    assert result.topics['/footholds'].gaps == [[3, 4]]
    assert result.gaps_text() == ('incomplete: /footholds misses 2 messages, '
                                  '/joint_states misses 3 ticks')


def test_ticks_the_sim_ran_after_the_last_written_one_are_missing():
    counter = Counter()
    _ticks(counter, '/joint_states', range(50))
    counter.add('/diagnostics', _sim_status(59), 0)
    result = counter.result()
    assert result.ticks == 60
    assert result.topics['/joint_states'].missing == 10
    # 20 min in, 6 digits of sim_time are 10 ms: the tick count places the last tick.
    counter = Counter()
    _ticks(counter, '/joint_states', range(308640, 308643))
    counter.add('/diagnostics', _sim_status(308642), 0)
    assert counter.result().complete


def test_the_controller_s_per_tick_topics_count_against_its_own_sequence():
    """A dead controller answers no tick: no loss of the recording, so /odom is counted
    against what the controller published, not against the sim's ticks."""
    counter = Counter()
    _ticks(counter, '/joint_states', range(100))
    for n, k in enumerate([*range(40), *range(70, 100)], start=1):   # ticks 40-69: dead
        counter.add('/odom', _odom(k * TICK), n)
    result = counter.result()
    assert result.complete and result.topics['/odom'].counted_by == 'sequence'


def test_an_estimate_without_the_tick_of_the_controller_s_first_command_is_incomplete():
    """The estimate of t = 0 published before the recorder subscribed shows no sequence gap
    (the count starts wherever the bag's first number is): the controller's first command
    (number 1) says which tick the estimate must start at."""
    counter = Counter()
    _ticks(counter, '/joint_states', range(100))
    for k in range(100):
        counter.add('/joint_torque_cmd', _odom(k * TICK), k + 1)
        if k:                                # odom of t = 0 before the recorder: number 1
            counter.add('/odom', _odom(k * TICK), k + 1)
        counter.add('/contacts', _odom(k * TICK), k + 3)   # republished twice: 3 is t = 0
    result = counter.result()
    assert not result.complete
    assert result.topics['/odom'].missing == 1 and result.topics['/odom'].gaps == [[0, 0]]
    assert result.topics['/contacts'].missing == 0
    assert result.gaps_text() == 'incomplete: /odom misses 1 message'


def test_the_estimate_is_not_held_to_commands_whose_start_the_bag_lacks():
    """A recorder started next to a running graph: its first command is not number 1, so
    where the estimate starts says nothing."""
    counter = Counter()
    for k in range(50, 100):
        counter.add('/joint_torque_cmd', _odom(k * TICK), k + 1)
        if k > 52:
            counter.add('/odom', _odom(k * TICK), k + 1)
    assert counter.result().complete


def test_a_new_writer_and_shared_topics_are_not_gaps():
    counter = Counter()
    for n in (1, 2, 3, 1, 2):               # the publisher respawned: its count starts again
        counter.add('/com_plan', b'', n)
    for n in (1, 2, 3, 1, 4, 5, 2):         # a second publisher (a user's tool), interleaved
        counter.add('/cmd_vel', b'', n)
    for n in (7, 1, 9, 2):                  # several nodes' diagnostics, interleaved
        counter.add('/diagnostics', b'', n)
    result = counter.result()
    assert result.complete, result.gaps_text()
    assert result.topics['/diagnostics'].counted_by == ''
    counter.add('/cmd_vel', b'', 8)         # the first publisher's 6 and 7 lost
    assert counter.result().topics['/cmd_vel'].gaps == [[6, 7]]


def test_the_record_round_trips_and_is_read_back_from_the_bag(tmp_path):
    counter = Counter()
    _ticks(counter, '/joint_states', [0, 1, 3])
    result = counter.result()
    again = Completeness.from_record(result.record())
    assert again == result
    bag = tmp_path / 'bag'
    bag.mkdir()
    writer = BagWriter(bag / 'a.mcap')
    channel = writer.add_channel('/joint_states', 'nav_msgs/msg/Odometry')
    for k in (0, 1, 3):
        writer.write(channel, _odom(k * TICK), k * TICK, k * TICK)
    writer.add_metadata(RECORD, result.record())
    writer.close()
    assert bag_completeness(bag) == result
    assert not is_complete(bag / 'a.mcap')
    # Counted again from the messages: the same verdict.
    assert count_files([bag / 'a.mcap']).topics['/joint_states'].gaps == [[2 * TICK, 2 * TICK]]
    custom = yaml.safe_load((bag / METADATA_FILE).read_text())[
        'rosbag2_bagfile_information']['custom_data']
    assert custom['replan_complete'] == 'false'
    assert custom['replan_completeness'] == 'incomplete: /joint_states misses 1 tick'


def test_a_split_bag_is_counted_across_its_files(tmp_path):
    """A respawned recorder's file knows only its own messages: the directory's verdict counts
    both files, so the ticks while no recorder ran are missing."""
    for name, ticks, numbers in (('a.mcap', range(0, 20), (1, 2)),
                                 ('b.mcap', range(30, 50), (5, 6))):
        writer = BagWriter(tmp_path / name, directory_metadata=False)
        odom = writer.add_channel('/joint_states', 'nav_msgs/msg/Odometry')
        plan = writer.add_channel('/footholds', 'std_msgs/msg/String')
        for k in ticks:
            writer.write(odom, _odom(k * TICK), k * TICK, k * TICK)
        for n in numbers:
            writer.write(plan, serialize_message(String(data='x')), n, n, sequence=n)
        own = Counter()
        _ticks(own, '/joint_states', ticks)
        writer.add_metadata(RECORD, own.result().record())     # each file alone: complete
        writer.close()
    write_directory_metadata(tmp_path)
    result = bag_completeness(tmp_path)
    assert result.topics['/joint_states'].missing == 10
    assert result.topics['/footholds'].missing == 2
    custom = yaml.safe_load((tmp_path / METADATA_FILE).read_text())[
        'rosbag2_bagfile_information']['custom_data']
    assert custom['replan_complete'] == 'false'


def _stamped(ns: int) -> bytes:
    """A little-endian CDR payload that starts with a header stamp."""
    sec, nanosec = divmod(ns, 1_000_000_000)
    return b'\x00\x01\x00\x00' + struct.pack('<iI', sec, nanosec)


def test_a_long_run_of_float_stamps_is_counted_exactly_and_a_head_gap_too():
    """Stamps are the sim's float seconds rounded to ns (steps of 3999999..4000001 ns) over
    hours of ticks; the count keeps steps, not stamps."""
    counter = Counter()
    ticks = 50_000
    for k in range(ticks):
        data = _stamped(round(k * (TICK * 1e-9) * 1e9))
        counter.add('/joint_states', data, 0)
        if k >= 5:                              # subscribed 5 ticks late
            counter.add('/ground_truth/odom', data, 0)
    result = counter.result()
    assert (result.tick_period_ns, result.ticks) == (TICK, ticks)
    assert result.topics['/joint_states'].missing == 0
    truth = result.topics['/ground_truth/odom']
    assert (truth.missing, truth.gaps) == (5, [[0, 4 * TICK]])
    assert len(counter.ticks['/joint_states'].steps) <= 3


def test_a_path_without_a_bag_has_no_verdict(tmp_path, capsys):
    with pytest.raises(FileNotFoundError, match=r'no \.mcap file'):
        bag_completeness(tmp_path / 'missing')
    assert completeness_main([str(tmp_path)]) == 1
    assert 'not counted' in capsys.readouterr().out
