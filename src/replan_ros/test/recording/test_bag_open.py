"""bag_open: a killed recorder's file recovered on the way (one line), split bags read as one,
by the tools too (replay --info, rerun's reading)."""

from pathlib import Path

from nav_msgs.msg import Odometry
from rclpy.serialization import serialize_message
from rosbags.highlevel import AnyReader

from replan_ros.recording.bag_dir import write_directory_metadata
from replan_ros.recording.bag_files import bag_files, recovered_name
from replan_ros.recording.bag_open import (
    has_summary,
    iter_raw_files,
    readable_files,
    recover_killed,
    summarize_files,
)
from replan_ros.recording.bag_writer import BagWriter
from replan_ros.recording.run_metadata import bag_path
from replan_ros.tools import replay, reproduce

TICK = 4_000_000


def _odom(k: int) -> bytes:
    msg = Odometry(child_frame_id='base_link')
    msg.header.frame_id = 'odom'
    msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(k * TICK, 1_000_000_000)
    msg.pose.pose.position.x = 0.001 * k
    return serialize_message(msg)


def _write(path: Path, ticks, close: bool = True) -> BagWriter:
    """/ground_truth/odom at ``ticks``, in chunks of about 20 messages."""
    writer = BagWriter(path, chunk_size=20 * 800, directory_metadata=close)
    channel = writer.add_channel('/ground_truth/odom', 'nav_msgs/msg/Odometry')
    for k in ticks:
        writer.write(channel, _odom(k), k * TICK, k * TICK)
    if close:
        writer.close()
    return writer


def _killed(path: Path, ticks) -> int:
    """A recorder killed mid-write: its finished chunks, then half a record; no summary.
    Returns how many messages the finished chunks hold."""
    writer = _write(path, ticks, close=False)
    writer.flush()
    kept = writer.message_count
    channel = writer.add_channel('/ground_truth/odom', 'nav_msgs/msg/Odometry')
    for k in range(ticks[-1] + 1, ticks[-1] + 5):     # the open chunk, lost
        writer.write(channel, _odom(k), k * TICK, k * TICK)
    with open(path, 'ab') as stream:
        stream.write(b'\x06\xff\xff\x00\x00')     # a chunk record cut short
    return kept


def test_a_killed_file_is_recovered_once_and_said_so_in_one_line(tmp_path):
    bag = tmp_path / 'walk.mcap'
    kept = _killed(bag, range(100))
    assert not has_summary(bag)
    lines = []
    files = readable_files(bag, lines.append)
    assert files == [recovered_name(bag)] and has_summary(files[0])
    assert len(lines) == 1 and str(bag) in lines[0] and 'recovered' in lines[0]
    assert f'recovered {kept} messages' in lines[0]
    assert sum(1 for _ in iter_raw_files(files)) == kept
    assert readable_files(bag, lines.append) == files            # not recovered again
    assert len(lines) == 2 and 'reading its recovered copy' in lines[1]
    assert recover_killed(tmp_path, lines.append) == []


def test_a_respawned_recorder_s_split_is_read_as_one_bag(tmp_path):
    first = tmp_path / 'replan_20000101_000000.mcap'
    _killed(first, range(0, 100))
    lines = []
    recover_killed(tmp_path, lines.append)      # what the respawned recorder does first
    second = bag_path(str(tmp_path))            # never the killed file's name
    assert second.parent == tmp_path and not second.exists()
    _write(second, range(120, 200))
    files = bag_files(tmp_path)
    assert files == [recovered_name(first), second]
    stamps = [m.log_time for _, _, m in iter_raw_files(files)]
    assert stamps == sorted(stamps) and stamps[-1] == 199 * TICK
    summary = summarize_files(files)
    assert summary.topics['/ground_truth/odom'].message_count == len(stamps)
    report = write_directory_metadata(tmp_path)
    assert report.files == [f.name for f in files]
    with AnyReader([tmp_path]) as reader:          # rosbag2's reading of the directory
        assert reader.message_count == len(stamps)
    # The tools read the directory as one bag.
    info = replay.format_info(readable_files(tmp_path))
    assert f'{len(stamps)}' in info and 'misses' in info      # the dead recorder's ticks
    run = reproduce.load_run(tmp_path)
    assert len(run.odom) == len(stamps)
    assert reproduce.find_bag(tmp_path) == tmp_path


def test_a_given_file_name_that_exists_is_never_overwritten(tmp_path):
    taken = tmp_path / 'walk.mcap'
    taken.write_bytes(b'')
    assert bag_path(str(taken)) == tmp_path / 'walk_1.mcap'


def test_a_file_that_is_not_mcap_at_all_is_said_and_left(tmp_path):
    """A recorder whose disk was full at once leaves a few bytes: no copy, one line."""
    (tmp_path / 'empty.mcap').write_bytes(b'\x89MC')
    lines = []
    assert recover_killed(tmp_path, lines.append) == []
    assert len(lines) == 1 and 'no recovered copy' in lines[0]
    assert not recovered_name(tmp_path / 'empty.mcap').exists()
