"""A bag directory as rosbag2 writes it: the .mcap file(s) and ``metadata.yaml`` beside them.

``ros2 bag info|play DIR`` and the ``rosbags`` readers open a directory only through its
``metadata.yaml`` (``rosbag2_bagfile_information``, here version 9 as Jazzy writes it). It is
built from the summaries of the directory's .mcap files, so counts, times, types and QoS are
those of the files. Every complete .mcap file of the directory is one file of the bag (split
bags); one recording per directory, as ``launch.sh --record DIR`` makes it.

    python -m replan_ros.recording.bag_dir DIR     # (re)write DIR/metadata.yaml
"""

from __future__ import annotations

import argparse
import os
import sys
from dataclasses import dataclass, field
from pathlib import Path

import yaml
from mcap.exceptions import McapError

from replan_ros.recording.bag_files import replaced
from replan_ros.recording.bag_io import (
    BAG_METADATA_VERSION,
    MESSAGE_ENCODING,
    ROS_DISTRO,
    BagSummary,
    summarize,
)
from replan_ros.recording.completeness import RECORD, Completeness, count_files

METADATA_FILE = 'metadata.yaml'
STORAGE_IDENTIFIER = 'mcap'


@dataclass
class DirectoryReport:
    """What ``write_directory_metadata`` listed and what it left out (path, reason)."""
    path: Path | None = None
    files: list[str] = field(default_factory=list)
    skipped: list[tuple[str, str]] = field(default_factory=list)


def _qos_list(text: str) -> list[dict]:
    """The channel's ``offered_qos_profiles`` string as the YAML list version 9 writes in
    metadata.yaml (the mcap channel keeps it as a string: its metadata is a string map)."""
    try:
        profiles = yaml.safe_load(text) if text else []
    except yaml.YAMLError:
        return []
    return profiles if isinstance(profiles, list) else []


def _span(summary: BagSummary) -> tuple[int, int]:
    """(starting time, duration) in ns; rosbag2's duration is last minus first log time."""
    if not summary.message_count:
        return 0, 0
    return summary.start_ns, max(summary.end_ns - summary.start_ns, 0)


def completeness_data(completeness: Completeness | None) -> dict[str, str]:
    """``custom_data`` of ``metadata.yaml``: the bag's completeness (``completeness``), for
    a reader of the directory that does not open the files."""
    if completeness is None:
        return {}
    record = completeness.record()
    return {'replan_complete': record['complete'], 'replan_completeness': record['summary'],
            'replan_completeness_topics': record['topics']}


def rosbag2_directory_metadata(files: list[tuple[str, BagSummary]],
                               completeness: Completeness | None = None) -> dict:
    """``metadata.yaml`` content (a dict) for a bag of ``files``: (file name relative to the
    directory, its summary), in playback order. Topics seen in several files are counted once
    with the sum of their messages; ``completeness`` goes into ``custom_data``."""
    topics: dict[str, dict] = {}
    file_entries = []
    starts, ends = [], []
    total = 0
    for name, summary in files:
        for info in summary.topics.values():
            entry = topics.get(info.topic)
            if entry is None:
                entry = topics[info.topic] = {
                    'topic_metadata': {
                        'name': info.topic,
                        'type': info.type_name,
                        'serialization_format': MESSAGE_ENCODING,
                        'offered_qos_profiles': _qos_list(info.offered_qos_profiles),
                        'type_description_hash': info.type_hash,
                    },
                    'message_count': 0,
                }
            entry['message_count'] += info.message_count
        start, duration = _span(summary)
        if summary.message_count:
            starts.append(start)
            ends.append(start + duration)
        total += summary.message_count
        file_entries.append({
            'path': name,
            'starting_time': {'nanoseconds_since_epoch': start},
            'duration': {'nanoseconds': duration},
            'message_count': summary.message_count,
        })
    start = min(starts) if starts else 0
    return {'rosbag2_bagfile_information': {
        'version': BAG_METADATA_VERSION,
        'storage_identifier': STORAGE_IDENTIFIER,
        'duration': {'nanoseconds': (max(ends) - start) if ends else 0},
        'starting_time': {'nanoseconds_since_epoch': start},
        'message_count': total,
        'topics_with_message_count': list(topics.values()),
        'compression_format': '',   # mcap compresses per chunk, not rosbag2's per file/message
        'compression_mode': '',
        'relative_file_paths': [name for name, _ in files],
        'files': file_entries,
        'custom_data': completeness_data(completeness),
        'ros_distro': ROS_DISTRO,
    }}


def _completeness(directory: Path, files: list[tuple[str, BagSummary]]) -> Completeness | None:
    """The recorder's verdict stored in a bag of one file; a split bag's counted across its
    files (a respawned recorder's file knows only its own messages)."""
    if len(files) == 1:
        record = files[0][1].metadata.get(RECORD)
        return Completeness.from_record(record) if record else None
    try:
        return count_files([directory / name for name, _ in files])
    except Exception:   # a file unreadable past its summary: no verdict
        return None


def write_directory_metadata(directory: str | Path) -> DirectoryReport:
    """(Re)write ``DIRECTORY/metadata.yaml`` from the summaries of its .mcap files, in name
    order (a recorder's split files sort by their time stamp). Left out: a file without summary
    (recorder killed: recover it first), and ``X.mcap`` when ``X.recovered.mcap`` is there (the
    copy replaces it; listing both would play every message twice). Without any complete
    file, no metadata.yaml is written and a stale one is removed."""
    directory = Path(directory)
    report = DirectoryReport()
    names = sorted(p.name for p in directory.glob('*.mcap') if p.is_file())
    files = []
    for name in names:
        if replaced(name, names):
            report.skipped.append((name, 'replaced by its recovered copy'))
            continue
        try:
            files.append((name, summarize(directory / name)))
        except (McapError, OSError, ValueError) as err:
            what = str(err).splitlines()[0] if str(err) else type(err).__name__
            report.skipped.append((name, what))
    target = directory / METADATA_FILE
    if not files:
        target.unlink(missing_ok=True)
        return report
    text = yaml.safe_dump(rosbag2_directory_metadata(files, _completeness(directory, files)),
                          sort_keys=False, default_flow_style=False)
    # Written aside and renamed: a reader never sees half a file.
    partial = target.with_name(f'.{METADATA_FILE}.{os.getpid()}.tmp')
    partial.write_text(text)
    os.replace(partial, target)
    report.path = target
    report.files = [name for name, _ in files]
    return report


def main(args: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog='bag_dir', description=__doc__.split('\n')[0])
    parser.add_argument('directory', type=Path, help='folder holding the .mcap file(s)')
    opts = parser.parse_args(args)
    if not opts.directory.is_dir():
        parser.error(f'not a directory: {opts.directory}')
    report = write_directory_metadata(opts.directory)
    for name, reason in report.skipped:
        print(f'{opts.directory / name}: left out ({reason})')
    if report.path is None:
        print(f'{opts.directory}: no complete .mcap file, no {METADATA_FILE}')
        return 1
    print(f'{report.path}: {len(report.files)} file(s)')
    return 0


if __name__ == '__main__':
    sys.exit(main())
