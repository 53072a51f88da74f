"""The wbc node's inputs of a tick besides `joint_states`: the `imu` (realistic profile) or the
sim's `ground_truth/odom` and `ground_truth/contacts` (ideal), taken from their queues by stamp
(`transport.on_demand`), and the tick's base state and contacts, estimated or true, with the
messages that publish them (docs/wbc.md, "Node `wbc`")."""

from __future__ import annotations

import dataclasses
import time

from nav_msgs.msg import Odometry
from sensor_msgs.msg import Imu, PointCloud2

from replan_ros.messages.contacts import contacts_from_cdr, encode_contacts
from replan_ros.messages.imu import imu_from_cdr
from replan_ros.messages.odom import base_state_from_cdr, encode_odom
from replan_ros.transport.on_demand import OnDemandSubscriptions
from replan_ros.transport.qos import CONTACTS, SENSOR

_KEEP = 50          # ticks of inputs kept per topic while waiting for the rest


class TickInputs:
    """Subscribes what the profile needs; ``take`` waits for a tick's samples, ``state``
    turns them (and the tick's joints) into the base state and contacts of the tick."""

    def __init__(self, node, robot, estimator, state_estimation: bool,
                 contact_estimation: bool, budget, warn) -> None:
        self.robot = robot
        self.estimator = estimator                # None: nothing estimated (ideal profile)
        self.state_estimation = state_estimation
        self.contact_estimation = contact_estimation
        self.budget = budget
        self.warn = warn                          # throttled warning, for malformed samples
        # stamp (ns) -> decoded sample; the truth as (message bytes, core state).
        self.imu: dict[int, object] = {}
        self.truth_odom: dict[int, tuple] = {}
        self.truth_contacts: dict[int, tuple] = {}
        self.queues = OnDemandSubscriptions(node)
        self._needed: list[dict] = []
        if estimator is not None:
            self.queues.subscribe(Imu, 'imu', SENSOR, self._on_imu)
            self._needed.append(self.imu)
        if not state_estimation:
            self.queues.subscribe(Odometry, 'ground_truth/odom', SENSOR, self._on_truth_odom)
            self._needed.append(self.truth_odom)
        if not contact_estimation:
            self.queues.subscribe(PointCloud2, 'ground_truth/contacts', CONTACTS,
                                  self._on_truth_contacts)
            self._needed.append(self.truth_contacts)

    def decoded(self, decode, data, what: str):
        """``decode(data)``, or None (and a throttled warning) for a malformed message."""
        try:
            return decode(data)
        except ValueError as error:
            self.warn(f'rejected {what}: {error}')
            return None

    def _on_imu(self, data: bytes) -> None:
        decoded = self.decoded(imu_from_cdr, data, 'imu')
        if decoded is not None:
            self._keep(self.imu, *decoded)

    def _on_truth_odom(self, data: bytes) -> None:
        decoded = self.decoded(base_state_from_cdr, data, 'ground_truth/odom')
        if decoded is not None:    # passed on as it came: the ideal profile's odom
            stamp, base = decoded
            self._keep(self.truth_odom, stamp, (data, base))

    def _on_truth_contacts(self, data: bytes) -> None:
        decoded = self.decoded(contacts_from_cdr, data, 'ground_truth/contacts')
        if decoded is not None:
            stamp, contacts = decoded
            self._keep(self.truth_contacts, stamp, (data, contacts))

    @staticmethod
    def _keep(buffer: dict, stamp: int, value) -> None:
        buffer[stamp] = value
        while len(buffer) > _KEEP:
            del buffer[min(buffer)]

    def take(self, stamp: int, timeout: float) -> bool:
        """Whether the tick's samples are all here, after waiting up to ``timeout`` wall s
        for the late ones (the sim publishes them before joint_states)."""
        self.queues.drain(lambda: all(stamp in buffer for buffer in self._needed),
                          timeout=timeout)
        return all(stamp in buffer for buffer in self._needed)

    def state(self, stamp: int, joints, swinging) -> tuple:
        """(base, contacts, odom message, contacts message) of the tick: estimated (the
        estimator runs once; ``swinging``, the legs the controller swings, anchor nothing) or
        the truth as it came."""
        estimate = None
        if self.estimator is not None:
            t0 = time.perf_counter_ns()
            estimate = self.estimator.update(self.imu[stamp], joints, swinging)
            self.budget.add('wbc_estimator', time.perf_counter_ns() - t0)
        if self.state_estimation:
            base = estimate[0]
            odom_msg = encode_odom(base, stamp)
        else:
            odom_msg, base = self.truth_odom[stamp]
        if not self.contact_estimation:
            contacts_msg, contacts = self.truth_contacts[stamp]
            return base, contacts, odom_msg, contacts_msg
        contacts = estimate[1]
        if not self.state_estimation:      # the estimated forces at the true feet
            contacts = dataclasses.replace(contacts,
                                           foot_position=self.robot.foot_positions(base, joints))
        return base, contacts, odom_msg, encode_contacts(contacts, stamp)

    def forget_before(self, floor: int) -> None:
        """Drop the samples older than ``floor`` (ns)."""
        for buffer in (self.imu, self.truth_odom, self.truth_contacts):
            for old in [s for s in buffer if s < floor]:
                del buffer[old]

    def destroy(self) -> None:
        self.queues.destroy()
