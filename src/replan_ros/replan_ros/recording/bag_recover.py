"""Recover a bag whose recorder was killed (SIGKILL, power cut, full disk).

    python -m replan_ros.recording.bag_recover BAG [OUT]

Writes OUT (default: BAG with ``.recovered.mcap``) holding every intact record of BAG: schemas,
channels, metadata, and the messages of each finished chunk, with their original times. What
was still in the recorder's open chunk (at most ``chunk_size`` bytes or ``chunk_interval``
seconds of data) is lost. A complete bag is copied whole, so recovering is always safe.
OUT's directory gets a fresh ``metadata.yaml`` (``bag_dir``) listing OUT in place of BAG.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from replan_ros.recording.bag_dir import METADATA_FILE, write_directory_metadata
from replan_ros.recording.bag_writer import recover


def default_output(bag: Path) -> Path:
    return bag.with_name(bag.stem + '.recovered.mcap')


def main(args=None) -> int:
    parser = argparse.ArgumentParser(prog='bag_recover', description=__doc__.split('\n')[0])
    parser.add_argument('bag', type=Path, help='mcap file to recover')
    parser.add_argument('out', type=Path, nargs='?', help='output (default BAG.recovered.mcap)')
    parser.add_argument('--compression', default='zstd', choices=('zstd', 'lz4', 'none'))
    opts = parser.parse_args(args)
    out = opts.out or default_output(opts.bag)
    if out.resolve() == opts.bag.resolve():
        parser.error('OUT must differ from BAG')
    report = recover(opts.bag, out, compression=opts.compression)
    print(f'{opts.bag}: {report.reason}; recovered {report.messages} messages on '
          f'{report.channels} channels from {report.chunks} chunks, {report.metadata} metadata '
          f'records; {report.truncated_bytes} bytes at the end dropped -> {out}')
    # The writer wrote it on close already; again here to say what it lists.
    listed = write_directory_metadata(out.parent)
    if listed.path is not None:
        print(f'{listed.path}: {", ".join(listed.files)}')
    else:
        print(f'{out.parent / METADATA_FILE} not written')
    return 0


if __name__ == '__main__':
    sys.exit(main())
