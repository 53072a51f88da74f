"""reproduce (scripts/rerun.sh): reading a bag's inputs, configuration and trajectory; comparing
trajectories."""

import json

import numpy as np
import pytest
from builtin_interfaces.msg import Time
from geometry_msgs.msg import TwistStamped, WrenchStamped
from nav_msgs.msg import Odometry
from rclpy.serialization import serialize_message

from replan_ros.recording.bag_writer import BagWriter
from replan_ros.tools.reproduce import (
    compare_trajectories,
    load_run,
    report,
    schedule_inputs,
    write_config,
)

TICK_NS = 4_000_000


def _time(ns: int) -> Time:
    return Time(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)


def _odom(ns: int, x: float) -> Odometry:
    msg = Odometry(child_frame_id='base_link')
    msg.header.stamp, msg.header.frame_id = _time(ns), 'odom'
    msg.pose.pose.position.x, msg.pose.pose.position.z = x, 0.6
    return msg


def _setpoint(ns: int, vx: float) -> TwistStamped:
    msg = TwistStamped()
    msg.header.stamp = _time(ns)
    msg.twist.linear.x = vx
    return msg


def _wrench(ns: int, fy: float) -> WrenchStamped:
    msg = WrenchStamped()
    msg.header.stamp, msg.header.frame_id = _time(ns), 'odom'
    msg.wrench.force.y = fy
    return msg


def _bag(path, ticks=250, bump=None, configs=None):
    """A recorded run: odom per tick (x = 1 mm per tick, + ``bump`` at one tick), set-points at
    re-plans, a push, and the configuration metadata."""
    writer = BagWriter(path)
    odom = writer.add_channel('/odom', 'nav_msgs/msg/Odometry')
    sp = writer.add_channel('/velocity_setpoint', 'geometry_msgs/msg/TwistStamped')
    wr = writer.add_channel('/applied_wrench', 'geometry_msgs/msg/WrenchStamped')
    configs = configs if configs is not None else {
        '/x/config/sim.yaml': 'sim:\n  ros__parameters: {physics_dt: 0.001}\n',
        '/x/config/gait.yaml': 'gait:\n  ros__parameters: {haptic: true}\n',
        '/x/run/params.yaml': 'sim:\n  ros__parameters: {terrain: flat}\n'}
    writer.add_metadata('replan_run', {'git_revision': 'abc123',
                                       'config_files': json.dumps(list(configs))})
    writer.add_metadata('replan_config', configs)
    for k in range(ticks):
        t = k * TICK_NS
        x = 0.001 * k + (bump[1] if bump and bump[0] == k else 0.0)
        writer.write(odom, serialize_message(_odom(t, x)), t, t)
        if k % 50 == 0:   # a re-plan: the same set-point twice, then a change
            writer.write(sp, serialize_message(_setpoint(t, 0.1 if k < 100 else 0.2)), t, t)
        if k == 60:
            writer.write(odom, serialize_message(_odom(t, x)), t, t)   # a re-published state
    for k, fy in ((120, 150.0), (170, 0.0)):
        writer.write(wr, serialize_message(_wrench(k * TICK_NS, fy)), k * TICK_NS, k * TICK_NS)
    writer.close()


def test_load_run_reads_inputs_configuration_and_trajectory(tmp_path):
    _bag(tmp_path / 'a.mcap')
    run = load_run(tmp_path / 'a.mcap')
    assert len(run.odom) == 250   # the duplicate of tick 60 counted once
    assert run.duration == pytest.approx(249 * 0.004)
    assert run.config_files == ['/x/config/sim.yaml', '/x/config/gait.yaml', '/x/run/params.yaml']
    assert run.run_info['git_revision'] == 'abc123'
    setpoints, wrenches = schedule_inputs(run)
    # Five re-plans, two distinct values: only the changes are sent, with their stamps.
    assert [(m.header.stamp.nanosec, m.twist.linear.x) for m in setpoints] == \
        [(0, 0.1), (100 * TICK_NS % 1_000_000_000, 0.2)]
    assert [m.wrench.force.y for m in wrenches] == [150.0, 0.0]
    assert [m.header.stamp.nanosec for m in wrenches] == [480_000_000, 680_000_000]


def test_write_config_rebuilds_the_config_folder_and_extra_files(tmp_path):
    _bag(tmp_path / 'a.mcap')
    run = load_run(tmp_path / 'a.mcap')
    current = tmp_path / 'current'
    current.mkdir()
    for node in ('sim', 'wbc', 'mpc', 'gait', 'recorder'):
        (current / f'{node}.yaml').write_text(f'{node}: {{ros__parameters: {{current: true}}}}\n')
    notes = []
    config_dir, extra = write_config(run, tmp_path / 'out', current, log=notes.append)
    assert (config_dir / 'sim.yaml').read_text() == run.config_text['/x/config/sim.yaml']
    assert (config_dir / 'gait.yaml').read_text() == run.config_text['/x/config/gait.yaml']
    assert 'current: true' in (config_dir / 'wbc.yaml').read_text()   # not recorded: current
    assert (config_dir / 'recorder.yaml').is_file()
    assert [p.read_text() for p in extra] == [run.config_text['/x/run/params.yaml']]
    assert any('wbc.yaml' in n for n in notes) and any('mpc.yaml' in n for n in notes)


def test_identical_runs_match_and_a_deviation_is_found_where_it_is(tmp_path):
    _bag(tmp_path / 'ref.mcap')
    _bag(tmp_path / 'same.mcap')
    _bag(tmp_path / 'bumped.mcap', bump=(137, 0.0025))
    ref = load_run(tmp_path / 'ref.mcap').odom
    same = compare_trajectories(ref, load_run(tmp_path / 'same.mcap').odom)
    assert same.max_deviation == 0.0 and same.matched == 250 and same.missing == 0
    assert report(same, 1e-3)[1]

    bumped = compare_trajectories(ref, load_run(tmp_path / 'bumped.mcap').odom)
    assert bumped.max_deviation == pytest.approx(0.0025, abs=1e-12)
    assert bumped.at_stamp == pytest.approx(137 * 0.004)
    text, ok = report(bumped, 1e-3)
    assert not ok and '0.0025 m at t = 0.548 s' in text


def test_a_shorter_rerun_is_not_a_match(tmp_path):
    _bag(tmp_path / 'ref.mcap')
    _bag(tmp_path / 'short.mcap', ticks=200)
    result = compare_trajectories(load_run(tmp_path / 'ref.mcap').odom,
                                  load_run(tmp_path / 'short.mcap').odom)
    assert result.max_deviation == 0.0 and result.missing == 50
    assert not report(result, 1e-3)[1]
    empty = compare_trajectories({0: np.zeros(3)}, {})
    assert empty.max_deviation == float('inf') and not report(empty, 1e-3)[1]
