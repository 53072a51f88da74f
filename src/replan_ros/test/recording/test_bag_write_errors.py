"""BagWriter on a full disk or an unwritable folder: one error naming the path and the cause,
no write after it, and what was written before is read back by recovering the file."""

import errno
import os

import pytest
from rclpy.serialization import serialize_message
from std_msgs.msg import String

from replan_ros.recording import bag_writer
from replan_ros.recording.bag_open import iter_raw_files, readable_files
from replan_ros.recording.bag_writer import BagWriteError, BagWriter


def test_a_full_disk_at_the_start_is_one_error_with_path_and_cause():
    if not os.path.exists('/dev/full'):
        pytest.skip('no /dev/full')
    with pytest.raises(BagWriteError) as info:
        BagWriter('/dev/full', directory_metadata=False)
    assert str(info.value) == 'cannot write /dev/full: No space left on device'
    assert info.value.cause.errno == errno.ENOSPC


def test_a_folder_that_cannot_hold_the_file_is_one_error(tmp_path):
    blocker = tmp_path / 'not_a_folder'
    blocker.write_text('')
    with pytest.raises(BagWriteError, match=f'cannot write {blocker}/x.mcap: Not a directory'):
        BagWriter(blocker / 'x.mcap')


@pytest.mark.skipif(os.geteuid() == 0, reason='root writes into a read-only folder')
def test_an_unwritable_folder_is_one_error(tmp_path):
    folder = tmp_path / 'ro'
    folder.mkdir()
    folder.chmod(0o500)
    try:
        with pytest.raises(BagWriteError, match='Permission denied'):
            BagWriter(folder / 'x.mcap')
    finally:
        folder.chmod(0o700)


def test_the_disk_filling_mid_run_stops_the_writer_and_keeps_the_finished_chunks(
        tmp_path, monkeypatch):
    path = tmp_path / 'bag.mcap'
    writer = BagWriter(path, chunk_size=2048, chunk_interval=1e9)
    channel = writer.add_channel('/chatter', 'std_msgs/msg/String')
    data = serialize_message(String(data='x' * 200))
    for k in range(40):
        writer.write(channel, data, k, k)
    assert writer.chunk_count >= 2

    def full(fd, view):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    monkeypatch.setattr(bag_writer.os, 'write', full)
    with pytest.raises(BagWriteError, match=f'cannot write {path}: No space left on device'):
        for k in range(40, 200):
            writer.write(channel, data, k, k)
    with pytest.raises(BagWriteError):      # refused at once afterwards: no half records
        writer.write(channel, data, 300, 300)
    writer.close()                          # closes the file, raises nothing
    monkeypatch.undo()
    lines = []
    files = readable_files(path, lines.append)
    assert len(lines) == 1 and 'recovered' in lines[0]
    times = [message.log_time for _, _, message in iter_raw_files(files)]
    assert times == list(range(len(times))) and 0 < len(times) <= 40   # the first, in order
