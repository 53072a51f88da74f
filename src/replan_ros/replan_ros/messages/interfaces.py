"""Conversions between common_interfaces messages and the core dataclasses.

The encodings are specified in docs/ARCHITECTURE.md; this module is their single implementation,
used by every producer and consumer so the two sides cannot drift apart.
"""

from __future__ import annotations

import functools
import math

import numpy as np
from builtin_interfaces.msg import Duration, Time
from geometry_msgs.msg import (
    Point,
    PoseStamped,
    Quaternion,
    Transform,
    Twist,
    Vector3,
    WrenchStamped,
)
from nav_msgs.msg import Odometry, Path
from sensor_msgs.msg import Imu, PointCloud2, PointField
from sensor_msgs.msg import JointState as JointStateMsg
from std_msgs.msg import Header
from trajectory_msgs.msg import MultiDOFJointTrajectory, MultiDOFJointTrajectoryPoint

from replan_core import rotations
from replan_core.types import (
    BASE_FRAME,
    JOINT_NAMES,
    WORLD_FRAME,
    BaseState,
    ComPlan,
    ContactState,
    FootholdPlan,
    ImuReading,
    JointState,
    Step,
)

# ---------------------------------------------------------------------------------------------
# Time


def stamp_to_sec(stamp: Time) -> float:
    return stamp.sec + stamp.nanosec * 1e-9


def stamp_to_ns(stamp: Time) -> int:
    return stamp.sec * 1_000_000_000 + stamp.nanosec


def sec_to_ns(t: float) -> int:
    return round(t * 1e9)


def ns_to_sec(ns: int) -> float:
    """The float seconds of a stamp of ``ns`` ns, as every decoder gives the core (the same
    float as ``stamp_to_sec(ns_to_stamp(ns))``), without building a message."""
    sec, nanosec = divmod(ns, 1_000_000_000)
    return sec + nanosec * 1e-9


def ns_to_stamp(ns: int) -> Time:
    return Time(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)


def sec_to_stamp(t: float) -> Time:
    return ns_to_stamp(sec_to_ns(t))


def sec_to_duration(t: float) -> Duration:
    ns = sec_to_ns(t)
    return Duration(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)


def duration_to_sec(d: Duration) -> float:
    return d.sec + d.nanosec * 1e-9


def header(t: float, frame_id: str = WORLD_FRAME) -> Header:
    return Header(stamp=sec_to_stamp(t), frame_id=frame_id)


# ---------------------------------------------------------------------------------------------
# Joint states and torque commands


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


# ---------------------------------------------------------------------------------------------
# Base state <-> nav_msgs/Odometry (twist in the child frame, REP-105)


def odom_values(bs: BaseState) -> tuple[tuple[float, ...], tuple[float, ...]]:
    """(pose: x y z qx qy qz qw, twist in ``base_link``: vx vy vz wx wy wz) of the
    odometry of ``bs`` (REP-105); shared by ``odom_from_base_state`` and ``tick_cdr``."""
    p, q = bs.position, bs.quaternion
    to_base = rotations.conjugate(rotations.normalized(q))     # twist in base_link (REP-105)
    linear = rotations.rotate(to_base, bs.linear_velocity)
    angular = rotations.rotate(to_base, bs.angular_velocity)
    pose = (float(p[0]), float(p[1]), float(p[2]),
            float(q[0]), float(q[1]), float(q[2]), float(q[3]))
    return pose, tuple(float(v) for v in (*linear, *angular))


def odom_from_base_state(bs: BaseState) -> Odometry:
    msg = Odometry()
    msg.header = header(bs.stamp, WORLD_FRAME)
    msg.child_frame_id = BASE_FRAME
    pose, twist = odom_values(bs)
    position, orientation = msg.pose.pose.position, msg.pose.pose.orientation
    position.x, position.y, position.z = pose[:3]
    orientation.x, orientation.y, orientation.z, orientation.w = pose[3:]
    linear, angular = msg.twist.twist.linear, msg.twist.twist.angular
    linear.x, linear.y, linear.z = twist[:3]
    angular.x, angular.y, angular.z = twist[3:]
    return msg


def base_state_from_odom(msg: Odometry) -> BaseState:
    """Base state with the twist in the world frame; ValueError on a non-finite pose or twist
    or a quaternion that is not one."""
    p, o = msg.pose.pose.position, msg.pose.pose.orientation
    lin, ang = msg.twist.twist.linear, msg.twist.twist.angular
    return base_state_from_values(stamp_to_sec(msg.header.stamp),
                                  (p.x, p.y, p.z, o.x, o.y, o.z, o.w),
                                  (lin.x, lin.y, lin.z, ang.x, ang.y, ang.z))


def base_state_from_values(stamp: float, pose, twist) -> BaseState:
    """``base_state_from_odom`` of an odometry's pose (x y z qx qy qz qw) and twist in the
    child frame (vx vy vz wx wy wz); shared with ``tick_cdr``."""
    q = tuple(pose[3:7])
    values = (*pose[:3], *twist, *q)
    if not (all(math.isfinite(v) for v in values)
            and abs(math.sqrt(sum(c * c for c in q)) - 1.0) < 0.1):
        raise ValueError('odom: non-finite pose or twist, or not a unit quaternion')
    unit = rotations.normalized(q)
    return BaseState(stamp=stamp, position=np.array(pose[:3]), quaternion=np.array(q),
                     linear_velocity=np.array(rotations.rotate(unit, tuple(twist[:3]))),
                     angular_velocity=np.array(rotations.rotate(unit, tuple(twist[3:6]))))


# ---------------------------------------------------------------------------------------------
# IMU <-> sensor_msgs/Imu (base_link axes; no orientation: REP-145's covariance[0] = -1)


def imu_values(reading: ImuReading, gyro_variance: float = 0.0,
               accel_variance: float = 0.0) -> tuple[float, ...]:
    """The 37 numbers of ``imu_to_msg`` in field order: orientation (x y z w, not provided),
    its covariance (``[0] = -1``), angular velocity, its covariance, linear acceleration, its
    covariance (the variances of one sample on the diagonals); shared with ``tick_cdr``."""
    w, a = reading.angular_velocity, reading.linear_acceleration
    gyro_cov = (gyro_variance, 0.0, 0.0, 0.0, gyro_variance, 0.0, 0.0, 0.0, gyro_variance)
    accel_cov = (accel_variance, 0.0, 0.0, 0.0, accel_variance, 0.0, 0.0, 0.0, accel_variance)
    return ((0.0, 0.0, 0.0, 1.0, -1.0) + (0.0,) * 8
            + (float(w[0]), float(w[1]), float(w[2])) + tuple(float(v) for v in gyro_cov)
            + (float(a[0]), float(a[1]), float(a[2])) + tuple(float(v) for v in accel_cov))


def imu_to_msg(reading: ImuReading, gyro_variance: float = 0.0,
               accel_variance: float = 0.0) -> Imu:
    """The IMU sample in ``base_link``; the variances (per axis, of one sample) fill the
    diagonal covariances; the orientation is marked as not provided."""
    values = imu_values(reading, gyro_variance, accel_variance)
    msg = Imu()
    msg.header = header(reading.stamp, BASE_FRAME)
    o = msg.orientation
    o.x, o.y, o.z, o.w = values[:4]
    msg.orientation_covariance = values[4:13]
    v = msg.angular_velocity
    v.x, v.y, v.z = values[13:16]
    msg.angular_velocity_covariance = values[16:25]
    v = msg.linear_acceleration
    v.x, v.y, v.z = values[25:28]
    msg.linear_acceleration_covariance = values[28:37]
    return msg


def imu_from_msg(msg: Imu) -> ImuReading:
    """ImuReading in the frame of the message (base_link); ValueError on a non-finite value."""
    w, a = msg.angular_velocity, msg.linear_acceleration
    values = (w.x, w.y, w.z, a.x, a.y, a.z)
    if not all(math.isfinite(v) for v in values):
        raise ValueError('imu: non-finite angular velocity or acceleration')
    return ImuReading(stamp=stamp_to_sec(msg.header.stamp),
                      angular_velocity=np.array(values[:3]),
                      linear_acceleration=np.array(values[3:]))


# ---------------------------------------------------------------------------------------------
# sensor_msgs/PointCloud2 as a typed table

_NUMPY_OF_FIELD = {PointField.INT8: 'i1', PointField.UINT8: 'u1', PointField.INT16: '<i2',
                   PointField.UINT16: '<u2', PointField.INT32: '<i4', PointField.UINT32: '<u4',
                   PointField.FLOAT32: '<f4', PointField.FLOAT64: '<f8'}
_FIELD_OF_NUMPY = {np.dtype(v).str: k for k, v in _NUMPY_OF_FIELD.items()}


def wrench_to_msg(stamp_ns: int, force, torque=(0.0, 0.0, 0.0)) -> WrenchStamped:
    """An external wrench on the base (N, N m, world axes) from ``stamp_ns`` on."""
    msg = WrenchStamped()
    msg.header.stamp = ns_to_stamp(stamp_ns)
    msg.header.frame_id = WORLD_FRAME
    msg.wrench.force.x, msg.wrench.force.y, msg.wrench.force.z = map(float, force)
    msg.wrench.torque.x, msg.wrench.torque.y, msg.wrench.torque.z = map(float, torque)
    return msg


def wrench_from_msg(msg: WrenchStamped) -> tuple[int, np.ndarray, np.ndarray]:
    """(stamp ns, force (3,) N, torque (3,) N m); ValueError for another frame than the world
    (or none) or a non-finite value."""
    f, t = msg.wrench.force, msg.wrench.torque
    force, torque = np.array([f.x, f.y, f.z]), np.array([t.x, t.y, t.z])
    if msg.header.frame_id not in ('', WORLD_FRAME):
        raise ValueError(f'frame {msg.header.frame_id!r}: only {WORLD_FRAME!r} (world axes) '
                         'is supported')
    if not (np.all(np.isfinite(force)) and np.all(np.isfinite(torque))):
        raise ValueError('non-finite values')
    return stamp_to_ns(msg.header.stamp), force, torque


@functools.lru_cache(maxsize=16)
def point_fields(dtype: np.dtype) -> tuple[PointField, ...]:
    """The PointField layout of a table dtype, built once (never modified afterwards)."""
    return tuple(PointField(name=name, offset=dtype.fields[name][1],
                            datatype=_FIELD_OF_NUMPY[dtype.fields[name][0].str], count=1)
                 for name in dtype.names)


def table_to_cloud(hdr: Header, table: np.ndarray) -> PointCloud2:
    """Pack a 1-D numpy structured array (no padding) into a PointCloud2."""
    fields = list(point_fields(table.dtype))
    msg = PointCloud2(header=hdr, height=1, width=len(table), fields=fields,
                      is_bigendian=False, point_step=table.dtype.itemsize,
                      row_step=table.dtype.itemsize * len(table), is_dense=True)
    msg.data = table.tobytes()
    return msg


@functools.lru_cache(maxsize=16)
def _table_dtype(fields: tuple[tuple[str, int, int], ...], itemsize: int) -> np.dtype:
    """The numpy dtype of a PointCloud2 layout; a few layouts recur at every message."""
    return np.dtype({'names': [name for name, _, _ in fields],
                     'formats': [_NUMPY_OF_FIELD[datatype] for _, datatype, _ in fields],
                     'offsets': [offset for _, _, offset in fields], 'itemsize': itemsize})


def cloud_to_table(msg: PointCloud2, required: tuple[str, ...] = ()) -> np.ndarray:
    """Unpack a PointCloud2 written by ``table_to_cloud`` (or any little-endian flat one)."""
    if msg.is_bigendian:
        raise ValueError('big-endian PointCloud2 tables are not supported')
    # A malformed layout must give one clear line, not numpy's or a KeyError's words.
    unknown = [f.name for f in msg.fields if f.datatype not in _NUMPY_OF_FIELD or f.count > 1]
    if unknown:
        raise ValueError(f'table fields {unknown} have an unsupported datatype or count')
    try:
        dtype = _table_dtype(tuple((f.name, f.datatype, f.offset) for f in msg.fields),
                             msg.point_step)
    except (ValueError, TypeError) as err:
        raise ValueError(f'table layout does not fit point_step {msg.point_step}: {err}') from None
    missing = [name for name in required if name not in dtype.names]
    if missing:
        raise ValueError(f'table misses fields {missing}')
    count = msg.width * msg.height
    if len(msg.data) < count * msg.point_step:
        raise ValueError(f'table of {count} rows of {msg.point_step} bytes holds only '
                         f'{len(msg.data)} bytes')
    return np.frombuffer(bytes(msg.data), dtype=dtype, count=count)


def _require_finite(table: np.ndarray, names: tuple[str, ...], what: str) -> None:
    bad = [name for name in names if not np.all(np.isfinite(table[name]))]
    if bad:
        raise ValueError(f'{what} table holds non-finite {", ".join(bad)}')


CONTACT_DTYPE = np.dtype([('x', '<f8'), ('y', '<f8'), ('z', '<f8'), ('leg', 'u1'),
                          ('fx', '<f8'), ('fy', '<f8'), ('fz', '<f8'), ('contact', 'u1'),
                          ('touchdown', 'u1'), ('liftoff', 'u1')])

FOOTHOLD_DTYPE = np.dtype([('x', '<f8'), ('y', '<f8'), ('z', '<f8'), ('leg', 'u1'),
                           ('step', '<i4'), ('liftoff_time', '<f8'), ('touchdown_time', '<f8'),
                           ('step_height', '<f8'), ('haptic', 'u1'), ('replan', 'u1'),
                           ('yaw', '<f8'), ('min_swing_fraction', '<f8'),
                           ('max_extension', '<f8')])


def contact_rows(cs: ContactState, rows: np.ndarray) -> np.ndarray:
    """The contact table's rows ``rows`` (legs) of ``cs``; shared with ``tick_cdr``."""
    table = np.zeros(len(rows), dtype=CONTACT_DTYPE)
    position, force = np.asarray(cs.foot_position)[rows], np.asarray(cs.force)[rows]
    table['x'], table['y'], table['z'] = position[:, 0], position[:, 1], position[:, 2]
    table['leg'] = rows
    table['fx'], table['fy'], table['fz'] = force[:, 0], force[:, 1], force[:, 2]
    table['contact'] = np.asarray(cs.contact)[rows]
    table['touchdown'] = np.asarray(cs.touchdown)[rows]
    table['liftoff'] = np.asarray(cs.liftoff)[rows]
    return table


def contacts_to_msg(cs: ContactState) -> PointCloud2:
    return table_to_cloud(header(cs.stamp), contact_rows(cs, np.arange(4)))


def contact_events_to_msg(cs: ContactState) -> PointCloud2 | None:
    """Rows of the feet whose contact flag changed at this tick; None if none did."""
    rows = np.flatnonzero(np.asarray(cs.touchdown) | np.asarray(cs.liftoff))
    if len(rows) == 0:
        return None
    return table_to_cloud(header(cs.stamp), contact_rows(cs, rows))


def contacts_from_msg(msg: PointCloud2) -> ContactState:
    return contacts_from_table(stamp_to_sec(msg.header.stamp),
                               cloud_to_table(msg, CONTACT_DTYPE.names))


def contacts_from_table(stamp: float, table: np.ndarray) -> ContactState:
    """``contacts_from_msg`` of an unpacked table; shared with ``tick_cdr``."""
    if len(table) != 4 or sorted(table['leg']) != [0, 1, 2, 3]:
        raise ValueError(f'contacts table must have one row per leg, got legs {list(table["leg"])}')
    _require_finite(table, ('x', 'y', 'z', 'fx', 'fy', 'fz'), 'contacts')
    table = table[np.argsort(table['leg'])]
    return ContactState(
        stamp=stamp,
        foot_position=np.stack([table['x'], table['y'], table['z']], axis=1).astype(float),
        force=np.stack([table['fx'], table['fy'], table['fz']], axis=1).astype(float),
        contact=table['contact'].astype(bool), touchdown=table['touchdown'].astype(bool),
        liftoff=table['liftoff'].astype(bool))


def contact_events_from_msg(msg: PointCloud2) -> list[tuple[int, str, np.ndarray, np.ndarray]]:
    """Events as (leg, 'touchdown' | 'liftoff', position (3,), force (3,))."""
    table = cloud_to_table(msg, CONTACT_DTYPE.names)
    if np.any(table['leg'] > 3):
        raise ValueError('contact_events table names a leg outside 0..3')
    events = []
    for row in table:
        kind = 'touchdown' if row['touchdown'] else 'liftoff'
        events.append((int(row['leg']), kind, np.array([row['x'], row['y'], row['z']]),
                       np.array([row['fx'], row['fy'], row['fz']])))
    return events


# ---------------------------------------------------------------------------------------------
# Footholds and contact schedule


def footholds_to_msg(plan: FootholdPlan) -> PointCloud2:
    table = np.zeros(4 + len(plan.steps), dtype=FOOTHOLD_DTYPE)
    for leg in range(4):
        p = plan.initial_feet[leg]
        table[leg] = (p[0], p[1], p[2], leg, -1, 0.0, 0.0, 0.0, 0, 0, plan.initial_yaw,
                      plan.min_swing_fraction, plan.max_extension)
    for i, s in enumerate(plan.steps):
        table[4 + i] = (s.target[0], s.target[1], s.target[2], s.leg, i,
                        s.liftoff_time - plan.start_time, s.touchdown_time - plan.start_time,
                        s.step_height, s.haptic, s.replan, s.yaw, plan.min_swing_fraction,
                        plan.max_extension)
    return table_to_cloud(header(plan.start_time), table)


def footholds_from_msg(msg: PointCloud2) -> FootholdPlan:
    table = cloud_to_table(msg, FOOTHOLD_DTYPE.names)
    t0 = stamp_to_sec(msg.header.stamp)
    initial = table[table['step'] < 0]
    if len(initial) != 4 or sorted(initial['leg']) != [0, 1, 2, 3]:
        raise ValueError('footholds table must start with the four initial feet')
    initial = initial[np.argsort(initial['leg'])]
    steps_table = table[table['step'] >= 0]
    steps_table = steps_table[np.argsort(steps_table['step'], kind='stable')]
    _require_finite(table, ('x', 'y', 'z', 'liftoff_time', 'touchdown_time', 'step_height',
                            'yaw', 'min_swing_fraction', 'max_extension'), 'footholds')
    if np.any(table['leg'] > 3):
        raise ValueError('footholds table names a leg outside 0..3')
    steps = [Step(leg=int(r['leg']), liftoff_time=t0 + float(r['liftoff_time']),
                  touchdown_time=t0 + float(r['touchdown_time']),
                  target=np.array([r['x'], r['y'], r['z']], dtype=float),
                  step_height=float(r['step_height']), haptic=bool(r['haptic']),
                  replan=bool(r['replan']), yaw=float(r['yaw']))
             for r in steps_table]
    return FootholdPlan(start_time=t0,
                        initial_feet=np.stack([initial['x'], initial['y'], initial['z']],
                                              axis=1).astype(float),
                        initial_yaw=float(initial['yaw'][0]), steps=steps,
                        min_swing_fraction=float(initial['min_swing_fraction'][0]),
                        max_extension=float(initial['max_extension'][0]))


# ---------------------------------------------------------------------------------------------
# CoM plan and paths


def _vec(v: np.ndarray) -> Vector3:
    return Vector3(x=float(v[0]), y=float(v[1]), z=float(v[2]))


def com_plan_to_msg(plan: ComPlan) -> MultiDOFJointTrajectory:
    msg = MultiDOFJointTrajectory()
    msg.header = header(plan.start_time)
    msg.joint_names = ['com']
    for k in range(len(plan.position)):
        p = plan.position[k]
        point = MultiDOFJointTrajectoryPoint()
        point.transforms = [Transform(translation=_vec(p),
                                      rotation=Quaternion(x=0.0, y=0.0, z=0.0, w=1.0))]
        point.velocities = [Twist(linear=_vec(plan.velocity[k]))]
        point.accelerations = [Twist(linear=_vec(plan.acceleration[k]))]
        point.time_from_start = sec_to_duration(k * plan.dt)
        msg.points.append(point)
    return msg


def com_plan_from_msg(msg: MultiDOFJointTrajectory) -> ComPlan:
    if list(msg.joint_names) != ['com'] or len(msg.points) < 2:
        raise ValueError('com_plan must have joint_names ["com"] and at least two points')
    def xyz(v):
        return (v.x, v.y, v.z)
    pos = np.array([xyz(pt.transforms[0].translation) for pt in msg.points])
    vel = np.array([xyz(pt.velocities[0].linear) for pt in msg.points])
    acc = np.array([xyz(pt.accelerations[0].linear) for pt in msg.points])
    times = np.array([duration_to_sec(pt.time_from_start) for pt in msg.points])
    return com_plan_from_arrays(stamp_to_sec(msg.header.stamp), times, pos, vel, acc)


def com_plan_from_arrays(start_time: float, times: np.ndarray, position: np.ndarray,
                         velocity: np.ndarray, acceleration: np.ndarray) -> ComPlan:
    """A ``com_plan``'s samples (``times`` from its start, s) checked: evenly spaced and
    finite (``ValueError`` otherwise). Shared by both decoders (this module, ``cdr.py``)."""
    dt = float(times[1] - times[0])
    if dt <= 0 or not np.allclose(np.diff(times), dt, atol=1e-6):
        raise ValueError('com_plan samples must be evenly spaced')
    if not (np.all(np.isfinite(position)) and np.all(np.isfinite(velocity))
            and np.all(np.isfinite(acceleration))):
        raise ValueError('com_plan holds non-finite values')
    return ComPlan(start_time=start_time, dt=dt, position=position, velocity=velocity,
                   acceleration=acceleration)


def path_msg(start_time: float, dt: float, points: np.ndarray,
             frame_id: str = WORLD_FRAME) -> Path:
    """nav_msgs/Path with one pose per row of ``points`` (n, 2 or 3), stamped every ``dt``."""
    msg = Path(header=header(start_time, frame_id))
    for k, p in enumerate(points):
        pose = PoseStamped(header=header(start_time + k * dt, frame_id))
        pose.pose.position = Point(x=float(p[0]), y=float(p[1]),
                                   z=float(p[2]) if len(p) > 2 else 0.0)
        pose.pose.orientation.w = 1.0
        msg.poses.append(pose)
    return msg
