"""The recorder's bookkeeping of its topics: what it received and wrote per topic, and the
values of its ``/diagnostics`` status (``recorder: bag``), and which topics it records."""

from __future__ import annotations

import re
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


def is_hidden(topic: str) -> bool:
    """A ROS hidden topic: a name part starting with ``_``."""
    return any(part.startswith('_') for part in topic.split('/'))


class TopicSelection:
    """What the recorder records: ``topics`` (names), ``topics_regex`` (or both: either
    selects), never ``exclude_regex``; with neither, every topic, hidden ones only with
    ``include_hidden``. The regexes are checked by the parameters (``config error:``)."""

    def __init__(self, topics, topics_regex: str, exclude_regex: str, include_hidden: bool):
        self.wanted = {t for t in (topics or []) if t}
        self.include = re.compile(topics_regex) if topics_regex else None
        self.exclude = re.compile(exclude_regex) if exclude_regex else None
        self.include_hidden = bool(include_hidden)

    def __call__(self, topic: str) -> bool:
        if self.exclude is not None and self.exclude.search(topic):
            return False
        if not self.wanted and self.include is None:
            return self.include_hidden or not is_hidden(topic)
        return topic in self.wanted or (
            self.include is not None and self.include.search(topic) is not None)
