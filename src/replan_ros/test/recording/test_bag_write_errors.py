"""BagWriter on a full disk or an unwritable folder: one error naming the path and the cause,
no write after it, and what was written before is read back by recovering the file."""

import errno
import os

import pytest
from rclpy.serialization import serialize_message
from std_msgs.msg import String

from replan_ros.recording import bag_open, bag_writer
from replan_ros.recording.bag_open import iter_raw_files, readable_files
from replan_ros.recording.bag_writer import BagWriteError, BagWriter
from replan_ros.recording.completeness import count_files


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


def _half_written_bag(path, monkeypatch) -> None:
    """A bag whose disk filled after some chunks: no summary, finished chunks intact."""
    writer = BagWriter(path, chunk_size=2048, chunk_interval=1e9)
    channel = writer.add_channel('/chatter', 'std_msgs/msg/String')
    data = serialize_message(String(data='x' * 200))
    for k in range(40):
        writer.write(channel, data, k, k)
    with monkeypatch.context() as patch:
        patch.setattr(bag_writer.os, 'write', lambda fd, view: (_ for _ in ()).throw(
            OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))))
        with pytest.raises(BagWriteError):
            writer.write(channel, data, 40, 40)
            writer.flush()
    writer.close()


def test_a_bag_on_a_disk_still_full_is_read_through_a_copy_in_the_temporary_folder(
        tmp_path, monkeypatch):
    # The copy beside the file fails as on the full disk that stopped the recorder; the one in
    # the temporary folder is written, and read in the file's place.
    bag_dir = tmp_path / 'bag'
    bag_dir.mkdir()
    path = bag_dir / 'replan_1.mcap'
    _half_written_bag(path, monkeypatch)
    monkeypatch.setattr(bag_open.tempfile, 'gettempdir', lambda: str(tmp_path / 'temp'))
    real_recover = bag_open.recover

    def full_beside(src, dst, **kwargs):
        if dst.parent == bag_dir:
            raise BagWriteError(dst, OSError(errno.ENOSPC, os.strerror(errno.ENOSPC)))
        return real_recover(src, dst, **kwargs)

    monkeypatch.setattr(bag_open, 'recover', full_beside)
    for bag in (bag_dir, path):
        lines = []
        files = readable_files(bag, lines.append)
        assert files == [bag_open.elsewhere(path)] and files[0].is_file(), (files, lines)
        assert len(lines) == 1 and str(path) in lines[0], lines
        times = [message.log_time for _, _, message in iter_raw_files(files)]
        assert times == list(range(len(times))) and 0 < len(times) <= 40
    # Read again: the copy is reused, and nothing was written beside the file.
    assert 'reading its recovered copy' in lines[0]
    assert sorted(p.name for p in bag_dir.iterdir()) == ['replan_1.mcap']


def test_a_bag_whose_disk_filled_is_counted_incomplete_even_when_no_message_is_missing(
        tmp_path, monkeypatch):
    # Every message that reached the file is in order; what the full disk took is in no file,
    # so only the missing summary can tell.
    path = tmp_path / 'replan_1.mcap'
    _half_written_bag(path, monkeypatch)
    for files in ([path], readable_files(path, lambda line: None)):
        result = count_files(files)
        assert not result.complete and result.cut == [files[0].name]
        assert result.gaps_text() == (f'incomplete: {files[0].name} ends early (its recorder '
                                      'was killed or its disk was full)')
