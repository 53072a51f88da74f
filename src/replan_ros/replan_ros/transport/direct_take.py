"""The lock-step's fast path: wait for one subscription's next sample without the executor.

In lock-step the sim and the controller each wait for exactly one message per tick (the
command, the tick's ``joint_states``). rclpy's executor, at every wake-up, rebuilds a wait set
of every entity of the node (subscriptions, timers, the parameter services, guard conditions)
in Python and walks it, at every tick of both processes (docs/ARCHITECTURE.md, "Per-tick
budget": what taking it out of the chain gained). So after answering a tick, a node waits here
for the next sample of that subscription, for at most ``wait`` wall seconds, and hands it to
its callback; it goes back to its executor (timers, the other subscriptions, services) when
nothing came in time, when ``keep_going()`` says so, as soon as a sample of a watched
subscription (the controller's plans, the sim's ``external_wrench``) is there, and at least
every ``slice_period`` wall seconds. Nothing is lost meanwhile: the other subscriptions'
samples wait in their DDS queues for the executor, and the watched ones get its next turn, as
they did without the fast path.

rclpy offers this only through the handles its executor uses (as ``wait_for_message`` does);
``on_demand.py`` takes samples the same way.
"""

from __future__ import annotations

import time
from collections.abc import Callable

from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy
from rclpy.node import Node
from rclpy.subscription import Subscription

# The lock-step chain's defaults (sim and wbc): a tick's message normally comes within a few
# ms; the executor gets a turn at least this often, so timers run at most this late.
WAIT = 0.01            # wall s to wait for the next sample before handing back
SLICE = 0.05           # wall s: the longest run of samples between two turns of the executor


class DirectTake:
    """Wait for and take the samples of one subscription of ``node`` outside its executor;
    hand back to the executor as soon as one of the ``watched`` subscriptions has a sample,
    so that those are handled no later than if the executor had run all along."""

    def __init__(self, node: Node, subscription: Subscription,
                 handler: Callable[[object, dict], None],
                 watched: tuple[Subscription, ...] = ()) -> None:
        """``handler(message, message_info)``: what the subscription's callback does."""
        self._context = node.context
        self._subscription = subscription
        self._handler = handler
        self._watched = tuple(watched)
        # The subscriptions only: no guard condition, timer, client, service or event.
        self._wait_set = _rclpy.WaitSet(1 + len(self._watched), 0, 0, 0, 0, 0,
                                        node.context.handle)
        self.active = False                 # inside ``run``: the handler must not re-enter
        self._handles = (subscription.handle, *(w.handle for w in self._watched))

    def take(self, wait: float):
        """The next (message, message info) within ``wait`` wall s; None when nothing came
        or a watched subscription has a sample (the executor's turn)."""
        subscription = self._subscription
        wait_set = self._wait_set
        wait_set.clear_entities()
        handles = self._handles
        # Each handle held (entered) while it is in the wait set, as rclpy's executor does;
        # by hand rather than with an ExitStack, whose bookkeeping cost more than the wait.
        entered = []
        try:
            for handle in handles:
                handle.__enter__()
                entered.append(handle)
                wait_set.add_subscription(handle)
            try:
                wait_set.wait(int(wait * 1e9))
            except Exception:           # rclpy's RCLError: the context shut down meanwhile
                if self._context.ok():
                    raise
                return None
            if self._watched:
                ready = wait_set.get_ready_entities('subscription')
                if any(handle.pointer in ready for handle in handles[1:]):
                    return None
            return subscription.handle.take_message(subscription.msg_type, subscription.raw)
        finally:
            for handle in reversed(entered):
                handle.__exit__(None, None, None)

    def run(self, keep_going: Callable[[], bool], wait: float = WAIT,
            slice_period: float = SLICE) -> int:
        """Hand the samples that come to the handler while ``keep_going()``, each within
        ``wait`` wall s of the last, for at most ``slice_period`` wall s, until a watched
        subscription has a sample; returns how many. A call from inside the handler returns 0
        at once."""
        if self.active:
            return 0
        self.active = True
        handled = 0
        end = time.monotonic() + slice_period
        try:
            while keep_going() and self._context.ok() and time.monotonic() < end:
                sample = self.take(wait)
                if sample is None:
                    break
                self._handler(*sample)
                handled += 1
        finally:
            self.active = False
        return handled
