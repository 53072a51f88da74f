"""run_analysis: gait.png, forces.png and torques.png from a small synthetic bag."""

import numpy as np
from rclpy.serialization import serialize_message
from rosgraph_msgs.msg import Clock

from replan_core.common.types import (
    BaseState,
    ComPlan,
    ContactState,
    FootholdPlan,
    JointState,
    Step,
)
from replan_experiments.analysis import (
    GAIT_WINDOW,
    analyse_run,
    gait_window,
    replan_wall_latency,
)
from replan_experiments.scenario import parse_scenario
from replan_ros.messages.com_plan import com_plan_to_msg
from replan_ros.messages.contacts import contacts_to_msg
from replan_ros.messages.footholds import footholds_to_msg
from replan_ros.messages.joint_state import joint_state_to_msg
from replan_ros.messages.odom import odom_from_base_state
from replan_ros.messages.stamps import sec_to_stamp, stamp_to_ns
from replan_ros.recording.bag_writer import BagWriter

TICK = 0.004          # s
SWING = 0.5           # s
FEET = np.array([[0.4, 0.3, 0.0], [0.4, -0.3, 0.0], [-0.4, 0.3, 0.0], [-0.4, -0.3, 0.0]])


def _write_bag(path, duration: float = 3.0) -> None:
    """A crawl in place: one leg swings at a time (lh, lf, rh, rf), a plan at each touchdown,
    the true and estimated contacts, joint torques and odometry at every tick."""
    writer = BagWriter(path)
    channels = {topic: writer.add_channel(topic, kind) for topic, kind in (
        ('/clock', 'rosgraph_msgs/msg/Clock'), ('/ground_truth/odom', 'nav_msgs/msg/Odometry'),
        ('/ground_truth/contacts', 'sensor_msgs/msg/PointCloud2'),
        ('/contacts', 'sensor_msgs/msg/PointCloud2'),
        ('/joint_states', 'sensor_msgs/msg/JointState'),
        ('/footholds', 'sensor_msgs/msg/PointCloud2'))}

    def write(topic, msg, t):
        ns = round(t * 1e9)
        writer.write(channels[topic], serialize_message(msg), ns, ns)

    order = (2, 0, 3, 1)
    for k in range(int(duration / 0.75)):
        # Plan k at the (planned) touchdown of step k - 1; step j lifts off at 0.25 + 0.75 j.
        start = 0.0 if k == 0 else 0.25 + 0.75 * (k - 1) + SWING
        steps = [Step(leg=order[j % 4], liftoff_time=0.25 + 0.75 * j,
                      touchdown_time=0.25 + 0.75 * j + SWING, target=FEET[order[j % 4]],
                      step_height=0.1, haptic=True, replan=j == k, yaw=0.0)
                 for j in range(k, k + 3)]
        write('/footholds', footholds_to_msg(FootholdPlan(start, FEET, 0.0, steps)), start)
    previous = np.ones(4, dtype=bool)
    for n in range(int(duration / TICK)):
        t = n * TICK
        phase = (t - 0.25) % 0.75
        contact = np.ones(4, dtype=bool)
        if t >= 0.25 and phase < SWING - 0.02:      # touches down 20 ms early
            contact[order[int((t - 0.25) / 0.75) % 4]] = False
        force = np.zeros((4, 3))
        force[contact, 2] = 850.0 / contact.sum()
        state = ContactState(t, FEET, force, contact, contact & ~previous, previous & ~contact)
        previous = contact
        write('/ground_truth/contacts', contacts_to_msg(state), t)
        estimate = ContactState(t, FEET, force * 0.95, contact, state.touchdown, state.liftoff)
        write('/contacts', contacts_to_msg(estimate), t)
        write('/ground_truth/odom', odom_from_base_state(BaseState(
            t, np.array([0.01 * t, 0.0, 0.6]), np.array([0.0, 0.0, 0.0, 1.0]),
            np.zeros(3), np.zeros(3))), t)
        effort = np.sin(t + np.arange(12)) * 50.0
        write('/joint_states', joint_state_to_msg(JointState(t, np.zeros(12), np.zeros(12),
                                                             effort)), t)
        if n % 5 == 0:
            write('/clock', Clock(clock=sec_to_stamp(t)), t)
    writer.close()


def test_analyse_run_writes_gait_forces_and_torques(tmp_path):
    (tmp_path / 'bag').mkdir()
    _write_bag(tmp_path / 'bag' / 'run.mcap')
    scenario = parse_scenario('duration: 3.0\n', 'synthetic.yaml')
    metrics = analyse_run(tmp_path / 'bag', scenario, tmp_path)
    assert 'plot_error' not in metrics, metrics.get('plot_error')
    for name in ('gait.png', 'forces.png', 'torques.png', 'cop_margin.png'):
        path = tmp_path / name
        assert path.is_file() and path.stat().st_size > 10_000, name
        assert str(path) in metrics['plots']
    assert metrics['touchdowns'] > 0
    assert abs(metrics['touchdown_timing_error_s']['median_abs'] - 0.02) < 0.01


def test_gait_window_short_run_whole_long_run_middle_of_the_walk():
    steps = [(0, 1.0 + k, 1.5 + k, 1.48 + k) for k in range(20)]
    assert gait_window(np.linspace(0.0, 8.0, 100), steps) is None
    start, end = gait_window(np.linspace(0.0, 30.0, 100), steps)
    assert end - start == GAIT_WINDOW
    assert abs(0.5 * (start + end) - 0.5 * (1.0 + 20.5)) < 1e-9
    start, end = gait_window(np.linspace(0.0, 30.0, 100), [])
    assert (start, end) == (15.0 - GAIT_WINDOW / 2, 15.0 + GAIT_WINDOW / 2)


def test_replan_wall_latency_from_the_publishers_clocks():
    """Per re-plan after the initial one: /odom out -> /footholds out -> /com_plan out, from
    the publish times (wall ns); None when they are sim times (publish_time: header)."""
    wall = 1_795_000_000_000_000_000          # ns, Nov 2026
    plan = ComPlan(0.0, 0.04, np.zeros((3, 3)), np.zeros((3, 3)), np.zeros((3, 3)))
    data = {'/odom': [], '/footholds': [], '/com_plan': []}
    delays = [(2.0, 3.0), (4.0, 5.0), (1.0, 2.0)]      # ms: gait, mpc, per re-plan
    for k, (gait_ms, mpc_ms) in enumerate([(50.0, 60.0), *delays]):   # k = 0: initial plan
        t = 0.75 * k
        out = wall + k * 10**9
        base = BaseState(t, np.zeros(3), np.array([0.0, 0.0, 0.0, 1.0]), np.zeros(3),
                         np.zeros(3))
        data['/odom'].append((out, odom_from_base_state(base)))
        data['/odom'].append((out + 10**8, odom_from_base_state(base)))   # a republish
        data['/footholds'].append((out + round(gait_ms * 1e6), footholds_to_msg(
            FootholdPlan(t, FEET, 0.0, []))))
        msg = com_plan_to_msg(plan)
        msg.header.stamp = sec_to_stamp(t)
        data['/com_plan'].append((out + round((gait_ms + mpc_ms) * 1e6), msg))
    latency = replan_wall_latency(data)
    assert latency == {'count': 3, 'median': 5.0, 'p90': 8.2, 'max': 9.0,
                       'estimate_to_footholds_median': 2.0,
                       'footholds_to_com_plan_median': 3.0}
    sim_times = {topic: [(stamp_to_ns(m.header.stamp), m) for _, m in rows]
                 for topic, rows in data.items()}
    assert replan_wall_latency(sim_times) is None
    assert replan_wall_latency({}) is None
