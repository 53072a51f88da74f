"""Subscriptions read on demand: samples wait in the DDS reader queue until a node asks.

The gait and mpc nodes need the state of one tick per re-plan (about one in 190), and the gait
node's touchdown rule needs every contacts tick but not at once; the simulator publishes every
tick. A subscription spun by the node's executor wakes the Python process for every sample and
walks the executor's wait set each time; on a 2-core machine those wake-ups of the bystanders
took the CPU from the lock-step chain sim -> wbc -> sim: two of them took a sim/controller
round trip from 0.48 to 1.30 ms, two that only queue the samples to 0.62 ms
(scripts/bench_rclpy.sh; docs/performance.md). Here the subscriptions belong to a helper
node that no executor spins: Fast DDS keeps the newest ``depth`` samples of each in its reader
queue (KEEP_LAST), and ``drain`` takes them, oldest first, when the node needs them. This is
rclcpp's ``Subscription::take()`` pattern; rclpy offers it only through the subscription's
handle (what its executor calls), so it is used here and nowhere else.
"""

from __future__ import annotations

import time
from collections.abc import Callable

from rclpy.event_handler import SubscriptionEventCallbacks
from rclpy.node import Node
from rclpy.qos import QoSProfile
from rclpy.subscription import Subscription

_POLL = 0.0002        # wall s between two looks while ``drain`` waits for a sample


def helper_name(owner_name: str) -> str:
    """Name of the node holding the on-demand subscriptions of node ``owner_name``."""
    return f'{owner_name}_on_demand'


class OnDemandSubscriptions:
    """Subscriptions of a helper node (``helper_name``), taken only by ``drain``."""

    def __init__(self, owner: Node) -> None:
        # Not the process's command-line arguments: they name and configure the owner (a
        # `__node:=` remap would give this node the owner's name). Topic names are resolved by
        # the owner instead, remaps included.
        self._owner = owner
        self._node = Node(helper_name(owner.get_name()), namespace=owner.get_namespace(),
                          context=owner.context, use_global_arguments=False,
                          start_parameter_services=False, enable_rosout=False)
        self._readers: list[tuple[Subscription, bool]] = []

    def subscribe(self, msg_type: type, topic: str, qos: QoSProfile,
                  callback: Callable[..., None], raw: bool = True,
                  with_info: bool = False) -> None:
        """Queue the newest ``qos.depth`` samples of ``topic``; ``drain`` gives ``callback``
        each one (its CDR bytes if ``raw``), and its message info dict if ``with_info``."""
        subscription = self._node.create_subscription(
            msg_type, self._owner.resolve_topic_name(topic), callback, qos, raw=raw,
            event_callbacks=SubscriptionEventCallbacks(use_default_callbacks=False))
        self._readers.append((subscription, with_info))

    def _take_all(self) -> None:
        for subscription, with_info in self._readers:
            with subscription.handle:
                while True:
                    sample = subscription.handle.take_message(subscription.msg_type,
                                                              subscription.raw)
                    if sample is None:
                        break
                    if with_info:
                        subscription.callback(*sample)
                    else:
                        subscription.callback(sample[0])

    def drain(self, done: Callable[[], bool] = lambda: True, timeout: float = 0.0) -> bool:
        """Hand every queued sample to its callback; if ``done()`` is still false then, keep
        taking new samples for up to ``timeout`` wall seconds. Returns ``done()``."""
        deadline = time.monotonic() + timeout
        while True:
            self._take_all()
            if done():
                return True
            if time.monotonic() >= deadline:
                return False
            time.sleep(_POLL)

    def destroy(self) -> None:
        self._readers.clear()
        self._node.destroy_node()
