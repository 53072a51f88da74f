"""footholds: a FootholdPlan (the initial feet, then one row per step) as a PointCloud2 table.

Each message family has one module holding its rclpy conversion and, where the graph needs speed,
its hand-written CDR codec beside it (docs/ARCHITECTURE.md, "Packages: the map").
"""

from __future__ import annotations

import numpy as np
from sensor_msgs.msg import PointCloud2

from replan_core.common.types import FootholdPlan, Step
from replan_ros.messages.clouds import cloud_to_table, require_finite, table_to_cloud
from replan_ros.messages.stamps import header, stamp_to_sec

FOOTHOLD_DTYPE = np.dtype([('x', '<f8'), ('y', '<f8'), ('z', '<f8'), ('leg', 'u1'),
                           ('step', '<i4'), ('liftoff_time', '<f8'), ('touchdown_time', '<f8'),
                           ('step_height', '<f8'), ('haptic', 'u1'), ('replan', 'u1'),
                           ('yaw', '<f8'), ('min_swing_fraction', '<f8'),
                           ('max_extension', '<f8'), ('latency', '<f8')])


def footholds_to_msg(plan: FootholdPlan) -> PointCloud2:
    table = np.zeros(4 + len(plan.steps), dtype=FOOTHOLD_DTYPE)
    for leg in range(4):
        p = plan.initial_feet[leg]
        table[leg] = (p[0], p[1], p[2], leg, -1, 0.0, 0.0, 0.0, 0, 0, plan.initial_yaw,
                      plan.min_swing_fraction, plan.max_extension, plan.latency)
    for i, s in enumerate(plan.steps):
        table[4 + i] = (s.target[0], s.target[1], s.target[2], s.leg, i,
                        s.liftoff_time - plan.start_time, s.touchdown_time - plan.start_time,
                        s.step_height, s.haptic, s.replan, s.yaw, plan.min_swing_fraction,
                        plan.max_extension, plan.latency)
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
    require_finite(table, ('x', 'y', 'z', 'liftoff_time', 'touchdown_time', 'step_height',
                            'yaw', 'min_swing_fraction', 'max_extension', 'latency'),
                   'footholds')
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
                        max_extension=float(initial['max_extension'][0]),
                        latency=float(initial['latency'][0]))
