"""The recorder's bookkeeping of its topics: what it received and wrote per topic, and the
values of its ``/diagnostics`` status (``recorder: bag``)."""

from __future__ import annotations

from pathlib import Path


class RecordedTopic:
    """One recorded topic: its channel and counters."""

    def __init__(self, name: str, type_name: str, channel_id: int, stamp_in_header: bool):
        self.name = name
        self.type_name = type_name
        self.channel_id = channel_id
        self.stamp_in_header = stamp_in_header
        self.received = 0
        self.written = 0


def totals(topics: dict[str, RecordedTopic]) -> tuple[int, int]:
    """(received, written) over all ``topics``."""
    return (sum(t.received for t in topics.values()), sum(t.written for t in topics.values()))


def status_values(path: Path, topics: dict[str, RecordedTopic], write_errors: int,
                  chunks: int, size: int) -> dict:
    """The recorder's diagnostics values: totals, then received and written per topic."""
    received, written = totals(topics)
    values = {'file': str(path), 'topics': len(topics), 'received': received,
              'written': written, 'queued': received - written, 'write_errors': write_errors,
              'chunks': chunks, 'bytes': size}
    for name in sorted(topics):
        values[f'{name} received'] = topics[name].received
        values[f'{name} written'] = topics[name].written
    return values
