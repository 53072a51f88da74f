"""Metrics and plots of a recorded run (the bag written by the recorder node).

Reads the mcap bag (``replan_ros.recording.bag_read``: the messages decoded by topic), computes
the metrics with ``replan_core.evaluation.metrics`` and draws the plots with matplotlib (Agg,
headless).
"""

from __future__ import annotations

import math
from collections import defaultdict
from pathlib import Path

import numpy as np

from replan_core.evaluation.metrics import (
    FallLimits,
    command_segments,
    cop_margins,
    detect_fall,
    distance_travelled,
    estimator_errors,
    executed_steps,
    flag_intervals,
    interval_stats,
    peaks_around,
    planned_zmp_at,
    rise_time,
    roll_pitch_yaw,
    settle_time,
    support_inradius_after,
    touchdown_timing,
    tracking_errors,
)
from replan_ros.messages.contacts import contacts_from_msg
from replan_ros.messages.footholds import footholds_from_msg
from replan_ros.messages.joint_state import joint_state_from_msg
from replan_ros.messages.odom import base_state_from_odom
from replan_ros.messages.stamps import stamp_to_ns, stamp_to_sec
from replan_ros.recording.bag_read import TRUTH_TOPIC, read_messages
from replan_ros.recording.completeness import bag_completeness

LEG_LABELS = ('LF', 'RF', 'LH', 'RH')      # replan_core.common.types.LEGS order
JOINT_LABELS = ('HAA', 'HFE', 'KFE')       # per leg, replan_core.common.types.JOINTS_PER_LEG order
GAIT_WINDOW = 6.0     # s of sim time in the detail view of the gait diagram of a long run


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
                dead_nodes=(), wall_time_total: float | None = None,
                plots: bool = True) -> dict:
    data = read_messages(bag)
    metrics: dict = {'scenario': scenario.name,
                     'profile': getattr(scenario, 'profile', None),
                     'launch_exit_code': launch_exit_code,
                     'dead_nodes': list(dead_nodes), 'bag': str(bag)}
    # Measures read from an incomplete bag differ between runs that are the same to the bit:
    # the pages use complete bags only, or say which were not (docs/recording.md).
    try:
        counted = bag_completeness(bag)
        metrics.update(bag_complete=counted.complete, bag_gaps=counted.gaps_text())
    except Exception as err:   # a bag that cannot be counted: no verdict, said so
        metrics.update(bag_complete=None, bag_gaps=f'not counted: {err}')
    truth_topic = TRUTH_TOPIC if data.get(TRUTH_TOPIC) else '/odom'
    odom = first_per_stamp(base_state_from_odom(m) for _, m in data.get(truth_topic, []))
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
    contacts = true_contacts(data)
    edges = [(float(t), int(leg)) for t in sorted(contacts)
             for leg in np.flatnonzero(contacts[t].touchdown)]
    steps = [(actual, leg) for leg, _, _, actual in executed_steps(edges, planned_steps(data))
             if actual is not None]     # each executed step's true touchdown: whole cycles
    tracking = tracking_errors(times, pos, rpy[:, 2], segments, settle=2.0,
                               touchdowns=steps if contacts else None)
    mpc = _diag_values(data.get('/diagnostics', []), 'mpc')
    solve = _first(mpc, 'solve_time_ms', 'solve_ms')
    solve_cpu = _first(mpc, 'solve_cpu_ms')
    iterations = _first(mpc, 'iterations')
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
        mpc_solve_cpu_ms_median=_round(np.median(solve_cpu)) if solve_cpu else None,
        mpc_iterations_median=float(np.median(iterations)) if iterations else None,
        mpc_solves=len(solve),
        replan_wall_ms=replan_wall_latency(data),
        min_zmp_margin_m=_round(min(margins), 5) if margins else None,
        trunk_height_min_m=float(pos[:, 2].min()), trunk_height_max_m=float(pos[:, 2].max()),
        max_roll_rad=float(np.abs(rpy[:, 0]).max()), max_pitch_rad=float(np.abs(rpy[:, 1]).max()),
        pushes=[{'t': t, 'force': list(f), 'duration': d} for t, f, d in scenario.push_events],
        read_errors=[e for _, e in data.get('_errors', [])])
    estimate = (_estimate_against_truth(data, odom) if truth_topic == TRUTH_TOPIC else None)
    metrics['estimator'] = estimate[0] if estimate else None
    balance = _measured_balance(data, contacts, times, rpy, estimate[1] if estimate else None)
    metrics.update(balance[0])
    _add_response_metrics(metrics, contacts, balance[1].get('touchdowns', np.zeros(0)), times,
                          pos, rpy, segments)
    _add_push_velocity(metrics, times, np.array([b.linear_velocity for b in odom]))
    if not plots:
        return metrics
    try:
        metrics['plots'] = plot_run(data, times, pos, rpy, segments, solve, out_dir)
        metrics['plots'] += plot_realism(times, pos, estimate, balance[1], out_dir)
        metrics['plots'] += plot_contacts_and_torques(data, out_dir)
    except Exception as err:  # plots are a convenience; the metrics must survive them
        metrics['plot_error'] = str(err)
    return metrics


_WALL_CLOCK_NS = 10**18     # publish times above this are wall clock (after 2001), not sim


def replan_wall_latency(data) -> dict | None:
    """Wall ms from the controller's estimate of a touchdown tick (``/odom`` out) to that
    re-plan's ``/com_plan`` out, and its two stages (gait node: ``/footholds`` out; mpc node:
    ``/com_plan`` out), per re-plan after the initial one: the planning pipeline's real
    latency (docs/ARCHITECTURE.md, "Re-plan path"), to hold against ``plan_latency`` (sim s).
    From the bag's publish times, the publishers' wall clocks (the recorder's default
    ``publish_time: source``; one machine, one clock); None without them."""
    def first_by_stamp(topic: str) -> dict[int, int]:
        out: dict[int, int] = {}
        for publish_time, msg in data.get(topic, []):
            out.setdefault(stamp_to_ns(msg.header.stamp), publish_time)
        return out

    odom, footholds, com_plan = (first_by_stamp(t) for t in ('/odom', '/footholds',
                                                            '/com_plan'))
    stamps = sorted(s for s in set(odom) & set(footholds) & set(com_plan) if s > 0)
    rows = np.array([(odom[s], footholds[s], com_plan[s]) for s in stamps], dtype=float)
    if not len(rows) or rows.min() < _WALL_CLOCK_NS:
        return None
    total = (rows[:, 2] - rows[:, 0]) * 1e-6
    return {'count': len(rows), 'median': _round(np.median(total), 2),
            'p90': _round(np.percentile(total, 90), 2), 'max': _round(total.max(), 2),
            'estimate_to_footholds_median': _round(np.median(rows[:, 1] - rows[:, 0]) * 1e-6, 2),
            'footholds_to_com_plan_median': _round(np.median(rows[:, 2] - rows[:, 1]) * 1e-6,
                                                   2)}


def true_contacts(data) -> dict:
    """The simulator's contact states by stamp (/ground_truth/contacts, one per stamp)."""
    contacts = {}
    for _, msg in data.get('/ground_truth/contacts', []):
        try:
            state = contacts_from_msg(msg)
        except ValueError:
            continue
        contacts.setdefault(state.stamp, state)
    return contacts


def _add_response_metrics(metrics: dict, contacts: dict, touchdown_times: np.ndarray, times,
                          pos, rpy, segments) -> None:
    """Per set-point segment, the time and the touchdowns until the velocity is within 10 % of
    the set-point (``settle_time_s``, ``settle_steps``; rise likewise); per push, the least
    support-triangle inradius over the 3 steps after and before it, from the truth.
    ``touchdown_times``: the actual touchdowns of executed steps (not contact edges: a stance
    foot whose load flickers around the threshold has edges too)."""
    stamps = np.array(sorted(contacts))
    by_start = {round(s.start, 6): (i, s) for i, s in enumerate(segments)}

    def steps_within(start: float, seconds: float | None) -> int | None:
        if seconds is None:
            return None
        return int(np.count_nonzero((touchdown_times > start)
                                    & (touchdown_times <= start + seconds)))

    for row in metrics.get('velocity_tracking', []):
        index, seg = by_start.get(round(row['start_s'], 6), (None, None))
        settle = settle_time(times, pos, rpy[:, 2], seg) if seg else None
        row['settle_time_s'] = _round(settle) if settle is not None else None
        row['settle_steps'] = steps_within(seg.start, settle) if seg else None
        # After a change of a non-zero set-point: how promptly it gets to the steady state.
        if index and any(segments[index - 1].command):
            rise = rise_time(times, pos, rpy[:, 2], segments[index - 1], seg,
                             achieved_after=row.get('achieved_steady'))
            row['rise_time_s'] = _round(rise) if rise is not None else None
            row['rise_steps'] = steps_within(seg.start, rise)
    if not len(stamps):
        return
    feet = np.array([contacts[t].foot_position for t in stamps])
    in_contact = np.array([contacts[t].contact for t in stamps])
    for push in metrics.get('pushes', []):
        radius = support_inradius_after(stamps, feet, in_contact, push['t'])
        push['support_inradius_min_m'] = _round(radius, 4) if radius is not None else None
        # The same measure over the 3 steps before the push, for the degeneration ratio.
        earlier = stamps < push['t']
        radius = support_inradius_after(stamps[earlier], feet[earlier], in_contact[earlier],
                                        push['t'] - 3.0, steps=3)
        push['support_inradius_before_m'] = _round(radius, 4) if radius is not None else None


def _add_push_velocity(metrics: dict, times: np.ndarray, velocity: np.ndarray) -> None:
    """Per push, the largest change of the base velocity (truth, world) along the push in the
    second after it starts (``velocity_change_mps``): the part of the impulse the legs did not
    take up at once (a free body of mass m would gain impulse / m)."""
    for push in metrics.get('pushes', []):
        force = np.asarray(push['force'][:2], dtype=float)
        if not np.any(force) or not len(times):
            continue
        axis = force / np.linalg.norm(force)
        t = push['t']
        before = (times >= t - 0.5) & (times < t)
        after = (times >= t) & (times <= t + 1.0)
        if not before.any() or not after.any():
            continue
        along = velocity[:, :2] @ axis
        push['velocity_change_mps'] = _round(along[after].max() - along[before].mean(), 4)


def first_per_stamp(states) -> list:
    """Base states sorted by stamp, one per stamp (the sim republishes a tick while it waits)."""
    seen: dict[float, object] = {}
    for state in states:
        seen.setdefault(state.stamp, state)
    return [seen[t] for t in sorted(seen)]


def _estimate_against_truth(data, truth: list) -> tuple[dict, dict] | None:
    """Estimator errors (/odom against the truth at common stamps) and the series to plot."""
    estimated = {b.stamp: b for b in first_per_stamp(
        base_state_from_odom(m) for _, m in data.get('/odom', []))}
    pairs = [(estimated[b.stamp], b) for b in truth if b.stamp in estimated]
    if len(pairs) < 2:
        return None
    times = np.array([t.stamp for _, t in pairs])
    est = np.array([e.position for e, _ in pairs])
    true = np.array([t.position for _, t in pairs])
    errors = estimator_errors(times, est, true, np.array([e.linear_velocity for e, _ in pairs]),
                              np.array([t.linear_velocity for _, t in pairs]))
    yaw_error = (roll_pitch_yaw(np.array([e.quaternion for e, _ in pairs]))
                 - roll_pitch_yaw(np.array([t.quaternion for _, t in pairs])))
    yaw_error = (yaw_error + np.pi) % (2 * np.pi) - np.pi
    errors['attitude_error_max_deg'] = [float(v) for v in np.degrees(np.abs(yaw_error).max(0))]
    return errors, {'times': times, 'estimated': est, 'true': true}


def _measured_balance(data, contacts: dict, times: np.ndarray, rpy: np.ndarray,
                      estimate: dict | None) -> tuple[dict, dict]:
    """Measured CoP margin (true forces, feet in contact), the CoP's deviation from the planned
    ZMP, touchdown timing and the attitude excursions around touchdowns, from
    /ground_truth/contacts, /zmp_plan and /footholds. ``estimate``: the estimated and true base
    series; the plans live in the estimated frame and are moved by the estimation error.
    ``contacts``: ``true_contacts(data)``. The second dict holds the series to plot and the
    actual touchdown times of the executed steps (``touchdowns``)."""
    if not contacts:
        return {}, {}
    stamps = np.array(sorted(contacts))
    feet = np.array([contacts[t].foot_position for t in stamps])
    forces = np.array([contacts[t].force for t in stamps])
    cop, margin = cop_margins(feet, forces)
    valid = margin[np.isfinite(margin)]
    # What the feedback and the noise add to the plan: the measured CoP against the ZMP the
    # newest plan predicted for the same instant.
    zmp_plans = []
    for _, msg in data.get('/zmp_plan', []):
        if msg.poses:
            zmp_plans.append((stamp_to_sec(msg.header.stamp),
                              np.array([stamp_to_sec(p.header.stamp) for p in msg.poses]),
                              np.array([[p.pose.position.x, p.pose.position.y]
                                        for p in msg.poses])))
    planned = planned_zmp_at(stamps, zmp_plans)
    if estimate is not None:
        for axis in (0, 1):
            planned[:, axis] += np.interp(
                stamps, estimate['times'],
                estimate['true'][:, axis] - estimate['estimated'][:, axis])
    deviation = np.linalg.norm(cop - planned, axis=1)
    deviation = deviation[np.isfinite(deviation)]
    touchdowns = [(float(t), int(leg)) for t in stamps
                  for leg in np.flatnonzero(contacts[t].touchdown)]
    timing, events = touchdown_timing(touchdowns, planned_steps(data))
    roll_peaks = peaks_around(times, rpy[:, 0], events)
    pitch_peaks = peaks_around(times, rpy[:, 1], events)
    out = {
        'cop_margin_min_m': _round(valid.min(), 4) if len(valid) else None,
        'cop_margin_p5_m': _round(np.percentile(valid, 5), 4) if len(valid) else None,
        'cop_margin_median_m': _round(np.median(valid), 4) if len(valid) else None,
        'cop_outside_fraction': _round(np.mean(valid < 0), 4) if len(valid) else None,
        'cop_zmp_deviation_m': ({'rms': _round(np.sqrt(np.mean(deviation ** 2)), 4),
                                 'p95': _round(np.percentile(deviation, 95), 4)}
                                if len(deviation) else None),
        'touchdowns': len(events),
        'touchdown_timing_error_s': ({
            'mean': _round(timing.mean(), 4), 'median_abs': _round(np.median(np.abs(timing)), 4),
            'p95_abs': _round(np.percentile(np.abs(timing), 95), 4), 'count': len(timing)}
            if len(timing) else None),
        'touchdown_roll_peak_deg': _peak_stats(roll_peaks),
        'touchdown_pitch_peak_deg': _peak_stats(pitch_peaks),
    }
    return out, {'times': stamps, 'margin': margin, 'touchdowns': events}


def _peak_stats(peaks: np.ndarray) -> dict | None:
    if len(peaks) == 0:
        return None
    degrees = np.degrees(peaks)
    return {'mean': _round(degrees.mean()), 'max': _round(degrees.max()), 'count': len(peaks)}


def plot_realism(times, pos, estimate, balance: dict, out_dir: Path) -> list[str]:
    """estimator.png (estimate against truth) and cop_margin.png (measured margin)."""
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    written = []
    if estimate is not None:
        _, series = estimate
        fig, axes = plt.subplots(3, 1, figsize=(9, 7), sharex=True)
        error = series['estimated'] - series['true']
        for i, label in enumerate(['x', 'y', 'z']):
            axes[i].plot(series['times'], error[:, i] * 100, lw=0.8)
            axes[i].set_ylabel(f'{label} error [cm]')
        axes[0].set_title('Base position: estimate (/odom) minus truth (/ground_truth/odom)')
        axes[-1].set_xlabel('sim time [s]')
        written.append(_save(fig, out_dir / 'estimator.png'))
    if balance:
        fig, ax = plt.subplots(figsize=(9, 4))
        ax.plot(balance['times'], balance['margin'] * 100, lw=0.6)
        ax.axhline(0.0, color='tab:red', lw=0.8)
        ax.set_xlabel('sim time [s]')
        ax.set_ylabel('CoP margin [cm]')
        ax.set_title('Measured centre of pressure in the polygon of the feet in contact '
                     '(< 0: outside)')
        written.append(_save(fig, out_dir / 'cop_margin.png'))
    return written


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


# ------------------------------------------------------------------------------------------
# Gait diagram, ground reaction forces and joint torques


def contact_series(data, topic: str) -> dict | None:
    """Per-tick contacts of ``topic`` (one sample per stamp): 'times' (n,), 'contact' (n, 4),
    'touchdown' (n, 4) bool, 'force' (n, 4, 3) N; None if the bag holds none."""
    by_stamp = {}
    for _, msg in data.get(topic, []):
        try:
            state = contacts_from_msg(msg)
        except ValueError:
            continue
        by_stamp.setdefault(state.stamp, state)
    if not by_stamp:
        return None
    stamps = sorted(by_stamp)
    return {'times': np.array(stamps),
            'contact': np.array([by_stamp[t].contact for t in stamps]),
            'touchdown': np.array([by_stamp[t].touchdown for t in stamps]),
            'force': np.array([by_stamp[t].force for t in stamps])}


def effort_series(data) -> tuple[np.ndarray, np.ndarray] | None:
    """Measured joint torques from /joint_states: times (n,) and efforts (n, 12) N m in
    JOINT_NAMES order, one sample per stamp; None without efforts."""
    by_stamp = {}
    for _, msg in data.get('/joint_states', []):
        if not len(msg.effort):
            continue
        try:
            state = joint_state_from_msg(msg)
        except ValueError:
            continue
        by_stamp.setdefault(state.stamp, state.effort)
    if not by_stamp:
        return None
    stamps = sorted(by_stamp)
    return np.array(stamps), np.array([by_stamp[t] for t in stamps])


def planned_steps(data) -> list[tuple[float, int, float, float]]:
    """(plan stamp, leg, planned lift-off, planned touchdown) of every step of every plan."""
    planned = []
    for _, msg in data.get('/footholds', []):
        try:
            plan = footholds_from_msg(msg)
        except ValueError:
            continue
        planned += [(plan.start_time, s.leg, s.liftoff_time, s.touchdown_time)
                    for s in plan.steps]
    return planned


def plot_contacts_and_torques(data, out_dir: Path) -> list[str]:
    """gait.png, forces.png and torques.png from the topics that are in the bag."""
    written = []
    truth = contact_series(data, '/ground_truth/contacts')
    if truth is not None:
        touchdowns = [(float(truth['times'][k]), int(leg))
                      for k, leg in zip(*np.nonzero(truth['touchdown']), strict=True)]
        steps = executed_steps(touchdowns, planned_steps(data))
        written.append(plot_gait(truth['times'], truth['contact'], steps, out_dir))
        estimate = contact_series(data, '/contacts')
        written.append(plot_forces(
            truth['times'], truth['force'][:, :, 2],
            (estimate['times'], estimate['force'][:, :, 2]) if estimate else None, out_dir))
    efforts = effort_series(data)
    if efforts is not None:
        written.append(plot_torques(*efforts, out_dir))
    return written


def gait_window(times: np.ndarray, steps, window: float = GAIT_WINDOW
                ) -> tuple[float, float] | None:
    """The detail window of a long run's gait diagram: ``window`` s in the middle of the
    walking (from the first planned lift-off to the last planned touchdown); None when the
    whole run is short enough to read at once."""
    start, end = float(times[0]), float(times[-1])
    if end - start <= 1.5 * window:
        return None
    if steps:
        walk_start = min(s[1] for s in steps)
        walk_end = min(max(s[2] for s in steps), end)
        middle = 0.5 * (walk_start + walk_end)
    else:
        middle = 0.5 * (start + end)
    t0 = min(max(middle - 0.5 * window, start), end - window)
    return t0, t0 + window


def _draw_gait(ax, times, contact, steps, markers: bool) -> None:
    for leg in range(4):
        y = 3 - leg        # LF on top
        stance = [(a, b - a) for a, b in flag_intervals(times, contact[:, leg])]
        ax.broken_barh(stance, (y - 0.3, 0.6), facecolor='tab:blue', alpha=0.55,
                       label='stance (true contact)' if leg == 0 else None)
        swings = [(lo, td - lo) for step_leg, lo, td, _ in steps if step_leg == leg]
        ax.broken_barh(swings, (y - 0.3, 0.6), facecolor='none', edgecolor='tab:orange',
                       hatch='///', lw=1.2, label='planned swing' if leg == 0 else None)
        if markers:
            planned_td = [td for step_leg, _, td, _ in steps if step_leg == leg]
            actual_td = [a for step_leg, _, _, a in steps if step_leg == leg and a is not None]
            ax.plot(planned_td, [y + 0.42] * len(planned_td), 'v', color='black', ms=7,
                    label='planned touchdown' if leg == 0 else None)
            ax.plot(actual_td, [y - 0.42] * len(actual_td), '^', color='tab:red', ms=7,
                    label='actual touchdown' if leg == 0 else None)
    ax.set_yticks(range(4), LEG_LABELS[::-1])
    ax.set_ylim(-0.7, 3.7)


def plot_gait(times: np.ndarray, contact: np.ndarray, steps, out_dir: Path,
              window: float = GAIT_WINDOW) -> str:
    """gait.png: per leg the stance intervals from the true contact flags (bars), the planned
    swings of the executed steps (hatched) and the planned and actual touchdowns (triangles);
    a long run gets an overview and a ``window`` s detail view in steady walking."""
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    detail = gait_window(times, steps, window)
    if detail is None:
        fig, ax = plt.subplots(figsize=(11, 4))
        axes = [ax]
    else:
        fig, axes = plt.subplots(2, 1, figsize=(11, 7), gridspec_kw={'height_ratios': [1, 2]})
        overview = axes[0]
        _draw_gait(overview, times, contact, steps, markers=False)
        overview.axvspan(*detail, color='0.85', zorder=0)
        overview.set_xlim(times[0], times[-1])
        overview.set_title(f'Whole run (grey: the {window:.0f} s shown below)', fontsize=10)
        overview.set_xlabel('sim time [s]')
    ax = axes[-1]
    _draw_gait(ax, times, contact, steps, markers=True)
    ax.set_xlim(*(detail or (times[0], times[-1])))
    ax.set_xlabel('sim time [s]')
    ax.legend(loc='upper center', bbox_to_anchor=(0.5, -0.16), ncol=4, fontsize=8,
              frameon=False)
    fig.suptitle('Gait: stance from /ground_truth/contacts, executed steps from /footholds')
    return _save(fig, out_dir / 'gait.png')


def plot_forces(times: np.ndarray, normal: np.ndarray, estimate, out_dir: Path) -> str:
    """forces.png: per foot the true normal ground reaction force and, dashed, the one the
    state estimator inferred from the joint torques (``estimate``: (times, normal) or None)."""
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(4, 1, figsize=(11, 8), sharex=True, sharey=True)
    for leg, ax in enumerate(axes):
        ax.plot(times, normal[:, leg], color='tab:blue', lw=0.7,
                label='true (/ground_truth/contacts)')
        if estimate is not None:
            ax.plot(estimate[0], estimate[1][:, leg], '--', color='tab:orange', lw=0.7,
                    label='estimated from joint torques (/contacts)')
        ax.set_ylabel(f'{LEG_LABELS[leg]} $F_z$ [N]')
        ax.grid(alpha=0.3)
    # Above the plot: inside, it would hide the stance peaks.
    axes[0].legend(loc='lower right', bbox_to_anchor=(1.0, 1.0), fontsize=8, ncol=2,
                   frameon=False)
    axes[0].set_title('Normal ground reaction force per foot (world z)', loc='left')
    axes[-1].set_xlabel('sim time [s]')
    return _save(fig, out_dir / 'forces.png')


def plot_torques(times: np.ndarray, efforts: np.ndarray, out_dir: Path) -> str:
    """torques.png: measured joint torques (/joint_states effort), one subplot per leg."""
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(4, 1, figsize=(11, 8), sharex=True, sharey=True)
    for leg, ax in enumerate(axes):
        for j, name in enumerate(JOINT_LABELS):
            ax.plot(times, efforts[:, 3 * leg + j], lw=0.6, label=name)
        ax.set_ylabel(f'{LEG_LABELS[leg]} torque [N m]')
        ax.grid(alpha=0.3)
    axes[0].legend(loc='lower right', bbox_to_anchor=(1.0, 1.0), fontsize=8, ncol=3,
                   frameon=False)
    axes[0].set_title('Measured joint torques (/joint_states effort)', loc='left')
    axes[-1].set_xlabel('sim time [s]')
    return _save(fig, out_dir / 'torques.png')
