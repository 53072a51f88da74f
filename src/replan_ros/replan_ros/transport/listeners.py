"""A node's first publish held until named nodes subscribe to its topics, within a wall-clock
limit: the wbc's first command lets the sim move, so a recorder that must hold the estimate from
t = 0 subscribes first (docs/ARCHITECTURE.md, "Re-plan protocol", 5)."""

from __future__ import annotations

import time


class ListenersGate:
    """``ready()`` is True once every node of ``nodes`` subscribes to each of ``topics`` of
    ``node``, or ``timeout`` wall s after the first call: then it warns which node does not
    listen to which topic (a recorder told to leave one out, or one that died): a graph never
    waits forever."""

    def __init__(self, node, topics: tuple[str, ...], nodes, timeout: float,
                 timeout_name: str = 'first_command_wait_timeout') -> None:
        self._node = node
        self._topics = topics
        self._nodes = set(nodes)
        self._timeout = float(timeout)                  # wall s
        self._timeout_name = timeout_name               # the parameter, for the warning
        self._open = not self._nodes
        self._deadline: float | None = None             # time.monotonic(), set at 1st call

    def missing(self) -> list[str]:
        """'<node> on <topic>' for each subscription still missing."""
        found = []
        for topic in self._topics:
            readers = {info.node_name for info in self._node.get_subscriptions_info_by_topic(
                self._node.resolve_topic_name(topic))}
            found += [f'{name} on {topic}' for name in sorted(self._nodes - readers)]
        return found

    def ready(self) -> bool:
        if self._open:
            return True
        missing = self.missing()
        logger = self._node.get_logger()
        if missing:
            now = time.monotonic()
            if self._deadline is None:
                self._deadline = now + self._timeout
            if now < self._deadline:
                return False
            logger.warning(
                f'no subscription of {", ".join(missing)} after {self._timeout_name} '
                f'({self._timeout:g} s): starting anyway; a bag misses these topics or their '
                'first samples')
        else:
            logger.info(f'{sorted(self._nodes)} listen: starting')
        self._open = True
        return True
