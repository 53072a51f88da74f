"""Metrics and plots of a recorded run (the bag written by the recorder node).

Reads the mcap bag, decodes the messages with rclpy's deserializer, computes the metrics with
``replan_core.metrics`` and draws the plots with matplotlib (Agg, headless).
"""

from __future__ import annotations

import math
from collections import defaultdict
from pathlib import Path

import numpy as np
from rclpy.serialization import deserialize_message

from replan_core.metrics import (
    FallLimits,
    command_segments,
    detect_fall,
    distance_travelled,
    interval_stats,
    roll_pitch_yaw,
    tracking_errors,
)
from replan_ros.bag_io import iter_raw
from replan_ros.interfaces import base_state_from_odom, footholds_from_msg, stamp_to_sec
from replan_ros.introspection import message_class

TOPICS = ('/clock', '/odom', '/footholds', '/zmp_plan', '/com_plan', '/diagnostics',
          '/velocity_setpoint', '/applied_wrench')


def bag_files(bag: Path) -> list[Path]:
    if bag.is_file():
        return [bag]
    return sorted(bag.glob('*.mcap'))


def read_messages(bag: Path, topics=TOPICS) -> dict[str, list[tuple[int, object]]]:
    """topic -> [(publish_time ns, message)], decoded; unreadable tails are skipped.

    The recorder stores the DDS source timestamp (wall clock at the publisher) as publish_time,
    as rosbag2 does; its log_time is the receive time on its sim-time clock."""
    out: dict[str, list] = defaultdict(list)
    classes: dict[str, type] = {}
    for path in bag_files(bag):
        try:
            for schema, channel, message in iter_raw(path, topics):
                cls = classes.get(schema.name)
                if cls is None:
                    cls = classes[schema.name] = message_class(schema.name)
                out[channel.topic].append(
                    (message.publish_time, deserialize_message(message.data, cls)))
        except Exception as err:   # a truncated file (SIGKILL) still gives what it holds
            out['_errors'].append((0, f'{path.name}: {err}'))
    return out


def _diag_values(messages, name_part: str) -> dict[str, list[float]]:
    values: dict[str, list[float]] = defaultdict(list)
    for _, msg in messages:
        for status in msg.status:
            if name_part not in status.name:
                continue
            for kv in status.values:
                try:
                    values[kv.key].append(float(kv.value))
                except ValueError:
                    continue
    return values


def _first(values: dict[str, list[float]], *keys: str) -> list[float]:
    for key in keys:
        if values.get(key):
            return values[key]
    return []


def analyse_run(bag: Path, scenario, out_dir: Path, *, launch_exit_code: int = 0,
                dead_nodes=(), wall_time_total: float | None = None) -> dict:
    data = read_messages(bag)
    metrics: dict = {'scenario': scenario.name, 'launch_exit_code': launch_exit_code,
                     'dead_nodes': list(dead_nodes), 'bag': str(bag)}
    odom = [base_state_from_odom(m) for _, m in data.get('/odom', [])]
    clock = data.get('/clock', [])
    if not odom or len(clock) < 2:
        metrics.update(completed=False, fell=None,
                       error='the bag holds no odometry or clock: the graph did not run',
                       read_errors=[e for _, e in data.get('_errors', [])])
        return metrics
    odom.sort(key=lambda b: b.stamp)
    times = np.array([b.stamp for b in odom])
    pos = np.array([b.position for b in odom])
    rpy = roll_pitch_yaw(np.array([b.quaternion for b in odom]))
    limits = FallLimits(**scenario.fall_limits)
    fell, fall_time, why = detect_fall(times, pos[:, 2], rpy, limits)
    sim_times = np.array([stamp_to_sec(m.clock) for _, m in clock])
    wall_ns = np.array([t for t, _ in clock])
    # From the last /clock of the start time (the sim republishes it while it waits for the
    # controller's first command) to the end: the time the graph was actually running.
    first = int(np.flatnonzero(sim_times == sim_times.min())[-1])
    sim_span = float(sim_times.max() - sim_times[first])
    wall_span = float(wall_ns.max() - wall_ns[first]) * 1e-9
    straight, path_length = distance_travelled(pos)
    segments = command_segments(
        [(t, c) for t, c in scenario.cmd_vel_events], end_time=float(times[-1]))
    tracking = tracking_errors(times, pos, rpy[:, 2], segments, settle=2.0)
    mpc = _diag_values(data.get('/diagnostics', []), 'mpc')
    solve = _first(mpc, 'solve_time_ms', 'solve_ms')
    margins = _first(mpc, 'zmp_margin_m', 'min_zmp_margin_m')
    sim_diag = _diag_values(data.get('/diagnostics', []), 'sim')
    metrics.update(
        completed=bool(sim_times.max() >= scenario.duration - 0.05) and launch_exit_code == 0,
        fell=fell, fall_time_s=fall_time, fall_reason=why,
        fall_limits={'min_height_m': limits.min_height, 'max_tilt_rad': limits.max_tilt},
        sim_time_s=float(sim_times.max()), wall_time_s=wall_span,
        wall_time_total_s=wall_time_total,
        real_time_factor=sim_span / wall_span if wall_span > 0 else None,
        sim_reported_rtf_median=(float(np.median(_first(sim_diag, 'real_time_factor')))
                                 if _first(sim_diag, 'real_time_factor') else None),
        distance_m=straight, path_length_m=path_length,
        final_position_m=[float(v) for v in pos[-1]],
        final_yaw_rad=float(rpy[-1, 2]),
        velocity_tracking=tracking,
        mean_linear_tracking_error_mps=_mean([s.get('linear_error_mps') for s in tracking
                                              if any(s['commanded'])]),
        replans=len(data.get('/footholds', [])),
        # Time between re-plans = one step (haptic: between sensed touchdowns); the first two
        # intervals are the initial stand and the walk-off.
        step_period_s=interval_stats(
            np.array([stamp_to_sec(m.header.stamp) for _, m in data.get('/footholds', [])]),
            skip=2),
        mpc_solve_ms_median=_round(np.median(solve)) if solve else None,
        mpc_solve_ms_p99=_round(np.percentile(solve, 99)) if solve else None,
        mpc_solves=len(solve),
        min_zmp_margin_m=_round(min(margins), 5) if margins else None,
        trunk_height_min_m=float(pos[:, 2].min()), trunk_height_max_m=float(pos[:, 2].max()),
        max_roll_rad=float(np.abs(rpy[:, 0]).max()), max_pitch_rad=float(np.abs(rpy[:, 1]).max()),
        pushes=[{'t': t, 'force': list(f), 'duration': d} for t, f, d in scenario.push_events],
        read_errors=[e for _, e in data.get('_errors', [])])
    try:
        metrics['plots'] = plot_run(data, times, pos, rpy, segments, solve, out_dir)
    except Exception as err:  # plots are a convenience; the metrics must survive them
        metrics['plot_error'] = str(err)
    return metrics


def _mean(values) -> float | None:
    values = [v for v in values if v is not None]
    return float(np.mean(values)) if values else None


def _round(value, digits: int = 3) -> float:
    return round(float(value), digits)


def plot_run(data, times, pos, rpy, segments, solve, out_dir: Path) -> list[str]:
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    written = []
    # 1. Top view: CoM (base) path, planned ZMP, support polygons of the footholds.
    fig, ax = plt.subplots(figsize=(8, 6))
    for _, msg in data.get('/footholds', []):
        try:
            plan = footholds_from_msg(msg)
        except ValueError:
            continue
        feet = plan.initial_feet[[0, 1, 3, 2, 0]]   # lf rf rh lh: around the polygon
        ax.plot(feet[:, 0], feet[:, 1], color='0.8', lw=0.6)
    zmp_x, zmp_y = [], []
    zmp_msgs = data.get('/zmp_plan', [])
    for i, (_, msg) in enumerate(zmp_msgs):
        t_next = (stamp_to_sec(zmp_msgs[i + 1][1].header.stamp) if i + 1 < len(zmp_msgs)
                  else math.inf)
        for pose in msg.poses:
            if stamp_to_sec(pose.header.stamp) < t_next:
                zmp_x.append(pose.pose.position.x)
                zmp_y.append(pose.pose.position.y)
    if zmp_x:
        ax.plot(zmp_x, zmp_y, '.', ms=2, color='tab:red', label='planned ZMP (executed part)')
    ax.plot(pos[:, 0], pos[:, 1], color='tab:blue', label='base (odom)')
    ax.plot([], [], color='0.8', label='support polygon at each re-plan')
    ax.set_aspect('equal')
    ax.set_xlabel('x [m]')
    ax.set_ylabel('y [m]')
    ax.legend(loc='best', fontsize=8)
    ax.set_title('Top view')
    written.append(_save(fig, out_dir / 'top_view.png'))
    # 2. Velocity commanded vs achieved (body frame, finite differences smoothed over 0.5 s).
    fig, axes = plt.subplots(3, 1, figsize=(9, 7), sharex=True)
    vel = _body_velocity(times, pos, rpy[:, 2], window=0.5)
    for i, label in enumerate(['vx [m/s]', 'vy [m/s]', 'wz [rad/s]']):
        axes[i].plot(times, vel[:, i], color='tab:blue', lw=0.8, label='achieved (0.5 s mean)')
        for seg in segments:
            axes[i].hlines(seg.command[i], seg.start, seg.end, color='tab:orange',
                           label='commanded' if seg is segments[0] else None)
        axes[i].set_ylabel(label)
    axes[0].legend(fontsize=8)
    axes[-1].set_xlabel('sim time [s]')
    written.append(_save(fig, out_dir / 'velocity.png'))
    # 3. Trunk height and attitude.
    fig, axes = plt.subplots(2, 1, figsize=(9, 6), sharex=True)
    axes[0].plot(times, pos[:, 2])
    axes[0].set_ylabel('trunk height [m]')
    for i, name in enumerate(['roll', 'pitch', 'yaw']):
        axes[1].plot(times, np.degrees(rpy[:, i]), label=name)
    axes[1].set_ylabel('attitude [deg]')
    axes[1].set_xlabel('sim time [s]')
    axes[1].legend(fontsize=8)
    written.append(_save(fig, out_dir / 'trunk.png'))
    # 4. Solve times.
    fig, ax = plt.subplots(figsize=(8, 4))
    if solve:
        ax.plot(solve, '.-')
    ax.set_xlabel('re-plan')
    ax.set_ylabel('QP solve time [ms]')
    ax.set_title('MPC solve times')
    written.append(_save(fig, out_dir / 'solve_times.png'))
    return written


def _save(fig, path: Path) -> str:
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    import matplotlib.pyplot as plt
    plt.close(fig)
    return str(path)


def _body_velocity(times, pos, yaw, window: float) -> np.ndarray:
    out = np.zeros((len(times), 3))
    yaw_u = np.unwrap(yaw)
    j = 0
    for i in range(len(times)):
        while times[i] - times[j] > window:
            j += 1
        span = times[i] - times[j]
        if span <= 0:
            continue
        d = pos[i, :2] - pos[j, :2]
        h = 0.5 * (yaw_u[i] + yaw_u[j])
        out[i, 0] = (math.cos(h) * d[0] + math.sin(h) * d[1]) / span
        out[i, 1] = (-math.sin(h) * d[0] + math.cos(h) * d[1]) / span
        out[i, 2] = (yaw_u[i] - yaw_u[j]) / span
    return out
