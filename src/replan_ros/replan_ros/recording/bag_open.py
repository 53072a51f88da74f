"""A bag opened for reading as one, whatever its recorder went through.

- A file without summary (its recorder was killed, or its disk filled) is recovered on the way
  (``bag_writer.recover`` into ``X.recovered.mcap`` beside it, ``metadata.yaml`` rewritten),
  and the tool says so in one line; ``bag_files`` then reads the copy in its place. Where the
  copy cannot go beside it (the disk that stopped the recorder is still full, a read-only
  folder), it goes to the temporary folder instead (``elsewhere``), kept for the next read.
- A bag directory's files (a respawned recorder's splits) are read as one bag: one summary,
  messages merged in log-time order.
"""

from __future__ import annotations

import contextlib
import hashlib
import heapq
import tempfile
from collections.abc import Callable, Iterable, Iterator
from pathlib import Path

from mcap.reader import make_reader
from mcap.records import Channel, Message, Schema

from replan_ros.recording.bag_files import bag_files, recovered_name
from replan_ros.recording.bag_io import BagSummary, TopicInfo, iter_raw, summarize
from replan_ros.recording.bag_writer import BagWriteError, recover


def has_summary(path: Path) -> bool:
    """True if ``path`` is an mcap file with its summary (a recorder that closed it)."""
    try:
        with open(path, 'rb') as stream:
            return make_reader(stream).get_summary() is not None
    except Exception:   # truncated or not mcap at all: no summary to use
        return False


def elsewhere(path: Path) -> Path:
    """Where the recovered copy of ``path`` goes when it cannot go beside it: the temporary
    folder, named after the file's path, size and time, so a later read of the same file
    reuses it and a file written on gets a new one."""
    info = path.stat()
    key = hashlib.sha1(f'{path.resolve()}:{info.st_size}:{info.st_mtime_ns}'.encode())
    return (Path(tempfile.gettempdir()) / f'replan_recovered_{key.hexdigest()[:16]}'
            / recovered_name(path).name)


def _recover(path: Path, out: Path) -> str:
    """Recover ``path`` into ``out``: the line that says so. A half-written copy is removed,
    since it would replace the file."""
    try:
        report = recover(path, out)
    except Exception:
        with contextlib.suppress(OSError):
            out.unlink(missing_ok=True)
        raise
    return (f'{path}: no summary (its recorder was killed or its disk was full): recovered '
            f'{report.messages} messages of {report.chunks} chunks into '
            f'{out.name if out.parent == path.parent else out}, '
            f'{report.truncated_bytes} bytes at the end dropped')


def recover_killed(bag: str | Path, log: Callable[[str], None] = print) -> list[Path]:
    """Recover every file of ``bag`` (a file or a bag directory) that has no summary and no
    recovered copy yet, beside it or else ``elsewhere``; one line each through ``log``.
    Returns the copies made or found elsewhere."""
    bag = Path(bag)
    candidates = [bag] if bag.is_file() else sorted(bag.glob('*.mcap'))
    made = []
    for path in candidates:
        if path.name.endswith('.recovered.mcap') or recovered_name(path).exists() \
                or has_summary(path):
            continue
        other = elsewhere(path)
        if other.is_file():
            log(f'{path}: no summary (its recorder was killed or its disk was full): reading '
                f'its recovered copy {other}')
            made.append(other)
            continue
        try:
            try:
                log(_recover(path, recovered_name(path)))
                made.append(recovered_name(path))
            except BagWriteError as err:   # no room or no right beside it
                other.parent.mkdir(parents=True, exist_ok=True)
                log(f'{_recover(path, other)} (not beside it: {err})')
                made.append(other)
        except Exception as err:   # not mcap at all, no room anywhere: read what is there
            what = str(err).splitlines()[0] if str(err) else type(err).__name__
            log(f'{path}: no summary, and no recovered copy: {what}')
    return made


def readable_files(bag: str | Path, log: Callable[[str], None] = print) -> list[Path]:
    """The files to read for ``bag`` (a file or a bag directory), recovering killed ones."""
    bag = Path(bag)
    made = recover_killed(bag, log)
    copies = {p.name: p for p in made}
    if bag.is_file() and not has_summary(bag):
        if recovered_name(bag).is_file():
            if recovered_name(bag) not in made:
                log(f'{bag}: no summary (its recorder was killed or its disk was full): '
                    f'reading its recovered copy {recovered_name(bag).name}')
            return [recovered_name(bag)]
        if recovered_name(bag).name in copies:
            return [copies[recovered_name(bag).name]]
    if bag.is_file():
        return [bag]
    # A copy made elsewhere stands in for its file, in the file's place.
    return [copies.get(recovered_name(f).name, f) for f in bag_files(bag)]


def summarize_files(files: list[Path]) -> BagSummary:
    """One summary of the files of a bag: counts added, the time span of all, metadata
    records of the first file that has each."""
    out = BagSummary()
    for index, path in enumerate(files):
        part = summarize(path)
        if index == 0:
            out.profile, out.library = part.profile, part.library
        for topic, info in part.topics.items():
            mine = out.topics.setdefault(topic, TopicInfo(
                info.topic, info.type_name, info.offered_qos_profiles, 0, info.type_hash))
            mine.message_count += info.message_count
        if part.message_count:
            out.start_ns = (part.start_ns if not out.message_count
                            else min(out.start_ns, part.start_ns))
            out.end_ns = max(out.end_ns, part.end_ns)
        out.message_count += part.message_count
        for name, record in part.metadata.items():
            out.metadata.setdefault(name, record)
    return out


def iter_raw_files(files: list[Path], topics: Iterable[str] | None = None
                   ) -> Iterator[tuple[Schema | None, Channel, Message]]:
    """(schema, channel, message) of all ``files`` merged in log-time order."""
    topics = list(topics) if topics else None
    streams = [iter_raw(path, topics) for path in files]
    if len(streams) == 1:
        yield from streams[0]
        return
    yield from heapq.merge(*streams, key=lambda item: item[2].log_time)
