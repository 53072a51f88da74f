"""sensor_msgs/JointState: the sim's joint_states and the controller's joint_torque_cmd, as rclpy
messages and as the lock-step's hand-written CDR.

Each message family has one module holding its rclpy conversion and, where the graph needs speed,
its hand-written CDR codec beside it (docs/ARCHITECTURE.md, "Packages: the map").
"""

from __future__ import annotations

import math
import struct

import numpy as np
from sensor_msgs.msg import JointState as JointStateMsg

from replan_core.common.types import JOINT_NAMES, JointState
from replan_ros.messages.cdr import (
    ENCAPSULATION,
    NS,
    CdrStrings,
    all_finite,
    deserialize_or_raise,
    double_sequences,
    stamp_pair,
)
from replan_ros.messages.stamps import header, stamp_to_ns, stamp_to_sec

_JOINT_NAME_LIST = list(JOINT_NAMES)


def joint_state_to_msg(js: JointState) -> JointStateMsg:
    msg = JointStateMsg()
    msg.header = header(js.stamp, '')
    msg.name = list(JOINT_NAMES)
    msg.position = [float(v) for v in js.position]
    msg.velocity = [float(v) for v in js.velocity]
    msg.effort = [float(v) for v in js.effort]
    return msg


def _reorder(names: list[str], values, what: str) -> np.ndarray:
    if len(values) != len(names):
        raise ValueError(f'{what}: {len(values)} values for {len(names)} names')
    index = {n: i for i, n in enumerate(names)}
    unknown = [n for n in names if n not in JOINT_NAMES]
    if unknown:
        raise ValueError(f'{what}: unknown joints {unknown}')
    missing = [n for n in JOINT_NAMES if n not in index]
    if missing:
        raise ValueError(f'{what}: missing joints {missing}')
    return np.array([values[index[n]] for n in JOINT_NAMES], dtype=float)


def joint_state_from_msg(msg: JointStateMsg) -> JointState:
    """Joint state in JOINT_NAMES order; ValueError if names or sizes do not match or a
    position or velocity is not finite."""
    names = list(msg.name)
    if len(names) != len(JOINT_NAMES):
        raise ValueError(f'joint_states: {len(names)} joints, expected {len(JOINT_NAMES)}')
    n = len(JOINT_NAMES)
    if (names == _JOINT_NAME_LIST and len(msg.position) == n and len(msg.velocity) == n
            and len(msg.effort) in (0, n)):      # the sim's order: no reordering needed
        position = np.array(msg.position, dtype=float)
        velocity = np.array(msg.velocity, dtype=float)
        effort = np.array(msg.effort, dtype=float) if len(msg.effort) else np.zeros(n)
    else:
        position = _reorder(names, msg.position, 'joint_states.position')
        velocity = _reorder(names, msg.velocity, 'joint_states.velocity')
        effort = (_reorder(names, msg.effort, 'joint_states.effort') if len(msg.effort)
                  else np.zeros(n))
    if not (np.all(np.isfinite(position)) and np.all(np.isfinite(velocity))):
        raise ValueError('joint_states: non-finite joint positions or velocities')
    return JointState(stamp_to_sec(msg.header.stamp), position, velocity, effort)


def torque_cmd_to_msg(t: float, torques: np.ndarray) -> JointStateMsg:
    msg = JointStateMsg()
    msg.header = header(t, '')
    msg.name = list(JOINT_NAMES)
    msg.effort = [float(v) for v in torques]
    return msg


def torque_cmd_from_msg(msg: JointStateMsg) -> tuple[int, np.ndarray]:
    """(stamp in ns, torques in JOINT_NAMES order); ValueError on a malformed or non-finite one."""
    names = list(msg.name)
    if len(names) != len(JOINT_NAMES):
        raise ValueError(f'torque command with {len(names)} joints, expected {len(JOINT_NAMES)}')
    torques = _reorder(names, msg.effort, 'torque command effort')
    if not np.all(np.isfinite(torques)):
        bad = [n for n, v in zip(JOINT_NAMES, torques, strict=True) if not math.isfinite(v)]
        raise ValueError(f'torque command with non-finite effort for {bad}')
    return stamp_to_ns(msg.header.stamp), torques


class JointStateCodec:
    """``sensor_msgs/JointState`` with ``frame_id`` and ``names`` fixed and ``counts`` values
    of position, velocity and effort (0: an empty sequence)."""

    def __init__(self, counts: tuple[int, int, int], names: tuple[str, ...] = JOINT_NAMES,
                 frame_id: str = '') -> None:
        self.counts = counts
        strings = CdrStrings(8, frame_id, tuple(names))
        sequences, _ = double_sequences(strings.end, counts)
        self._struct = struct.Struct(f'<4siI{strings.fmt}{sequences}')
        self._constant = strings.values
        # Where the constant strings, each value sequence's count and its values are in the
        # unpacked tuple.
        index = 3 + len(strings.values)
        self._strings = slice(3, index)
        self._slices = []
        for count in counts:
            self._slices.append((index, slice(index + 1, index + 1 + count)))
            index += 1 + count

    def encode(self, stamp_ns: int, *arrays) -> bytes:
        """The message stamped ``stamp_ns`` with the ``counts`` non-empty arrays in order
        (position, velocity, effort; one per non-zero count)."""
        values = [ENCAPSULATION, *stamp_pair(stamp_ns), *self._constant]
        given = iter(arrays)
        for count in self.counts:
            values.append(count)
            if count:
                values.extend(np.asarray(next(given), dtype=float).tolist())
        return self._struct.pack(*values)

    def decode(self, data: bytes) -> tuple[int, tuple[tuple[float, ...], ...]] | None:
        """(stamp ns, (position, velocity, effort)) as tuples, empty for an empty sequence;
        None for any other layout. Bytes after the message are ignored (rclpy's serializer
        leaves some after empty sequences)."""
        if len(data) < self._struct.size or bytes(data[:2]) != ENCAPSULATION[:2]:
            return None
        values = self._struct.unpack_from(data)
        if values[self._strings] != self._constant:
            return None
        sequences = []
        for (index, values_slice), count in zip(self._slices, self.counts, strict=True):
            if values[index] != count:
                return None
            sequences.append(values[values_slice])
        return values[1] * NS + values[2], tuple(sequences)


_N = len(JOINT_NAMES)


JOINT_STATES = JointStateCodec((_N, _N, _N))      # the sim's joint_states


TORQUE_COMMAND = JointStateCodec((0, 0, _N))      # the controller's joint_torque_cmd


def encode_joint_state(js: JointState) -> bytes:
    """``joint_state_to_msg(js)`` serialized."""
    return JOINT_STATES.encode(round(js.stamp * 1e9), js.position, js.velocity, js.effort)


def joint_state_from_cdr(data: bytes) -> tuple[int, JointState]:
    """(stamp ns, joint state) of a serialized ``JointState``; ``ValueError`` as
    ``joint_state_from_msg`` gives it."""
    decoded = JOINT_STATES.decode(data)
    if decoded is None:
        msg = deserialize_or_raise(data, JointStateMsg)
        js = joint_state_from_msg(msg)
        return msg.header.stamp.sec * NS + msg.header.stamp.nanosec, js
    stamp_ns, (position, velocity, effort) = decoded
    if not all_finite(position + velocity):
        raise ValueError('joint_states: non-finite joint positions or velocities')
    sec, nanosec = divmod(stamp_ns, NS)
    return stamp_ns, JointState(sec + nanosec * 1e-9, np.array(position), np.array(velocity),
                                np.array(effort))


def encode_torque_command(stamp_ns: int, torques: np.ndarray) -> bytes:
    """``torque_cmd_to_msg`` stamped exactly ``stamp_ns``, serialized."""
    return TORQUE_COMMAND.encode(stamp_ns, torques)


def torque_command_from_cdr(data: bytes) -> tuple[int, np.ndarray]:
    """(stamp ns, torques in ``JOINT_NAMES`` order); ``ValueError`` as
    ``torque_cmd_from_msg`` gives it."""
    decoded = TORQUE_COMMAND.decode(data)
    if decoded is None:
        return torque_cmd_from_msg(deserialize_or_raise(data, JointStateMsg))
    stamp_ns, (_, _, torques) = decoded
    if not all_finite(torques):
        return torque_cmd_from_msg(deserialize_or_raise(data, JointStateMsg))   # its message
    return stamp_ns, np.array(torques)
