"""A node's first publish held until named nodes subscribe to its topics, within a wall-clock
limit: the wbc's first command lets the sim move, so a recorder that must hold the estimate from
t = 0 subscribes first (docs/ARCHITECTURE.md, "Re-plan protocol", 5)."""

from __future__ import annotations

import time


class ListenersGate:
    """``ready()`` is True once every node of ``nodes`` subscribes to its topics among
    ``publishers`` (topic -> the node's publisher on it) and each of those publishers has matched
    every subscription the graph lists on its topic, or ``timeout`` wall s after the first call:
    then it warns which node does not listen to which topic (a recorder told to leave one out, or
    one that died): a graph never waits forever.

    An entry of ``nodes`` is ``name`` (every topic of ``publishers``: the recorder) or
    ``name=topic+topic`` (those topics only: a planner that reads one of them).

    Both, because the graph lists a reader as soon as it is discovered, and the writer matches
    it a moment later (Fast DDS calls the participant's listener before it pairs the endpoints):
    a sample published in between does not reach that reader, and a volatile writer never sends
    it again."""

    def __init__(self, node, publishers: dict, nodes, timeout: float,
                 timeout_name: str = 'first_command_wait_timeout') -> None:
        self._node = node
        self._publishers = dict(publishers)
        self._listeners = [parse_listener(entry, self._publishers) for entry in nodes]
        self._timeout = float(timeout)                  # wall s
        self._timeout_name = timeout_name               # the parameter, for the warning
        self._open = not self._listeners
        self._deadline: float | None = None             # time.monotonic(), set at 1st call

    def missing(self) -> list[str]:
        """'<node> on <topic>' for each subscription still missing."""
        found = []
        for topic in self._publishers:
            readers = {info.node_name for info in self._node.get_subscriptions_info_by_topic(
                self._node.resolve_topic_name(topic))}
            found += [f'{name} on {topic}' for name, topics in self._listeners
                      if topic in topics and name not in readers]
        return found

    def unmatched(self) -> list[str]:
        """The topics whose publisher has not yet matched every reader the graph lists."""
        return [topic for topic, publisher in self._publishers.items()
                if publisher.get_subscription_count()
                < self._node.count_subscribers(self._node.resolve_topic_name(topic))]

    def ready(self) -> bool:
        if self._open:
            return True
        missing = self.missing()
        unmatched = [] if missing else self.unmatched()
        logger = self._node.get_logger()
        if missing or unmatched:
            now = time.monotonic()
            if self._deadline is None:
                self._deadline = now + self._timeout
            if now < self._deadline:
                return False
            if missing:
                logger.warning(
                    f'no subscription of {", ".join(missing)} after {self._timeout_name} '
                    f'({self._timeout:g} s): starting anyway; a bag misses these topics or '
                    'their first samples')
            else:
                logger.warning(
                    f'a reader of {", ".join(unmatched)} not matched after '
                    f'{self._timeout_name} ({self._timeout:g} s): starting anyway; it may miss '
                    'the first samples')
        else:
            logger.info(f'{sorted(name for name, _ in self._listeners)} listen: starting')
        self._open = True
        return True


def parse_listener(entry: str, publishers: dict) -> tuple[str, tuple[str, ...]]:
    """``name`` or ``name=topic+topic`` -> (name, its topics among ``publishers``); a topic
    that is not one of them is a ValueError."""
    name, _, listed = entry.partition('=')
    topics = tuple(listed.split('+')) if listed else tuple(publishers)
    unknown = [topic for topic in topics if topic not in publishers]
    if not name or unknown:
        raise ValueError(f'{entry!r}: expected a node name, or name=topic+topic with topics '
                         f'among {sorted(publishers)}')
    return name, topics
