"""The gait node as a real process: touchdown-triggered re-plans and set-point hygiene.

The test plays the simulator: it publishes ``contacts`` and ``odom`` ticks with chosen stamps
(no /clock needed: the node keys everything on the state stamps) and ``cmd_vel``.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from geometry_msgs.msg import Twist, TwistStamped
from harness import CONFIG_DIR
from nav_msgs.msg import Odometry
from sensor_msgs.msg import PointCloud2
from visualization_msgs.msg import MarkerArray

from replan_core.common.types import LEGS, BaseState, ContactState
from replan_core.gait.crawl import GaitParams, clamp_velocity
from replan_ros.messages.contacts import contacts_to_msg
from replan_ros.messages.footholds import footholds_from_msg
from replan_ros.messages.odom import odom_from_base_state
from replan_ros.messages.stamps import sec_to_stamp, stamp_to_ns
from replan_ros.transport.qos import COMMAND, CONTACTS, LATCHED, SCHEDULE, SENSOR

BASE = np.array([0.0, 0.0, 0.599])
FEET = np.array([[0.3708, 0.3241, 0.0215], [0.3708, -0.3241, 0.0215],
                 [-0.3708, 0.3241, 0.0215], [-0.3708, -0.3241, 0.0215]])
LH, LF = LEGS.index('lh'), LEGS.index('lf')

# What these tests are written for, whatever config/gait.yaml says: one step per second, and
# every first foothold about the actual hips (correction_threshold 0, literal section V.B).
TIMING = {'swing_duration': 0.5, 'four_feet_duration': 0.5, 'start_delay': 1.0,
          'correction_threshold': 0.0}


class FakeSim:
    """Test-side publishers of the simulator's state topics and of the user's cmd_vel."""

    def __init__(self, probe):
        self.probe = probe
        node = probe.node
        self.contacts_pub = node.create_publisher(PointCloud2, 'contacts', CONTACTS)
        self.odom_pub = node.create_publisher(Odometry, 'odom', SENSOR)
        self.cmd_pub = node.create_publisher(Twist, 'cmd_vel', COMMAND)
        self.stamped_pub = node.create_publisher(TwistStamped, 'cmd_vel_stamped', SCHEDULE)
        self.footholds = probe.subscribe(PointCloud2, 'footholds', LATCHED)
        self.setpoints = probe.subscribe(TwistStamped, 'velocity_setpoint', SCHEDULE)
        self.markers = probe.subscribe(MarkerArray, 'gait_markers', LATCHED)
        self.feet = FEET.copy()

    def wait_connected(self, launcher):
        node = self.probe.node
        ok = self.probe.spin_until(
            lambda: all(pub.get_subscription_count() > 0 for pub in (
                self.contacts_pub, self.odom_pub, self.cmd_pub, self.stamped_pub))
            and node.count_publishers('footholds') > 0, timeout=30)
        assert ok, launcher.logs()
        self.probe.spin_for(0.3)

    def tick(self, t, contact=(True, True, True, True), base=BASE, odom=True):
        """One simulator tick: odom (best effort) then contacts, both stamped ``t``."""
        if odom:
            self.odom_pub.publish(odom_from_base_state(BaseState(
                t, np.asarray(base, dtype=float), np.array([0.0, 0.0, 0.0, 1.0]),
                np.zeros(3), np.zeros(3))))
        flags = np.array(contact, dtype=bool)
        self.contacts_pub.publish(contacts_to_msg(ContactState(
            stamp=t, foot_position=self.feet.copy(), force=np.outer(flags, [0.0, 0.0, 200.0]),
            contact=flags, touchdown=np.zeros(4, dtype=bool), liftoff=np.zeros(4, dtype=bool))))
        self.probe.spin_for(0.05)

    def cmd_vel(self, vx, vy, wz):
        msg = Twist()
        msg.linear.x, msg.linear.y, msg.angular.z = float(vx), float(vy), float(wz)
        self.cmd_pub.publish(msg)
        self.probe.spin_for(0.1)

    def plans_at(self, t):
        ns = round(t * 1e9)
        return [footholds_from_msg(m) for m in self.footholds
                if stamp_to_ns(m.header.stamp) == ns]

    def setpoint_at(self, t):
        ns = round(t * 1e9)
        found = [m for m in self.setpoints if stamp_to_ns(m.header.stamp) == ns]
        return (None if not found else
                np.array([found[-1].twist.linear.x, found[-1].twist.linear.y,
                          found[-1].twist.angular.z]))

    def replan_at(self, t, launcher, base=BASE, contact=(True, True, True, True)):
        """A touchdown tick at ``t``; waits for the footholds stamped ``t`` (republishing the
        state as the simulator does while it waits)."""
        for _ in range(5):
            self.tick(t, contact, base)
            if self.probe.spin_until(lambda: self.plans_at(t), timeout=2.0):
                break
        plans = self.plans_at(t)
        assert plans, launcher.logs()
        assert self.probe.spin_until(lambda: self.setpoint_at(t) is not None, timeout=5.0)
        return plans[-1]


@pytest.fixture
def sim(launcher, probe):
    # Stepping in place at a zero set-point (a robot never told to walk would stand).
    launcher.start('gait_node', params_file=CONFIG_DIR / 'gait.yaml',
                   params={**TIMING, 'idle_stance': False})
    fake = FakeSim(probe)
    fake.wait_connected(launcher)
    return fake


def test_initial_plan_then_touchdown_triggers_footholds_at_that_tick(sim, launcher):
    plan = sim.replan_at(0.0, launcher)
    assert plan.start_time == 0.0 and len(plan.steps) == 8
    assert [LEGS[s.leg] for s in plan.steps[:4]] == ['lh', 'lf', 'rh', 'rf']
    assert plan.steps[0].liftoff_time == pytest.approx(1.0)       # start_delay: stand first
    np.testing.assert_allclose(plan.initial_feet, FEET)
    for step in plan.steps:                                       # no set-point: stand still
        np.testing.assert_allclose(step.target, FEET[step.leg], atol=5e-3)
        assert step.haptic and step.replan
    np.testing.assert_allclose(sim.setpoint_at(0.0), 0.0)
    assert sim.probe.spin_until(lambda: sim.markers, timeout=5.0)
    namespaces = {m.ns for m in sim.markers[-1].markers}
    assert {'footholds', 'support_polygons'} <= namespaces

    # A stamped set-point effective from 1.1 s is used by the re-plan at the touchdown.
    stamped = TwistStamped()
    stamped.header.stamp = sec_to_stamp(1.1)
    stamped.twist.linear.x = 0.1
    sim.stamped_pub.publish(stamped)
    later = TwistStamped()
    later.header.stamp = sec_to_stamp(50.0)                        # not effective yet
    later.twist.linear.x = -0.1
    sim.stamped_pub.publish(later)

    # lh lifts off at 1.0 (its flag drops), an early contact flag at 1.1 is ignored (before
    # 1.0 + 0.5 * 0.5 s), the sensed touchdown at 1.252 triggers the re-plan stamped 1.252.
    sim.tick(0.5)
    sim.tick(1.0)
    swing = [True, True, False, True]
    sim.tick(1.1, [True, True, True, True])
    sim.tick(1.2, swing)
    sim.probe.spin_for(0.5)
    assert len(sim.footholds) == 1, 'no re-plan before the touchdown'
    pushed = BASE + np.array([0.0, 0.05, 0.0])                            # the trunk has moved
    sim.feet[LH] += [0.05, 0.0, 0.0]
    plan = sim.replan_at(1.252, launcher, base=pushed)
    assert plan.start_time == pytest.approx(1.252, abs=1e-9)
    np.testing.assert_allclose(plan.initial_feet, sim.feet)
    assert LEGS[plan.steps[0].leg] == 'lf'                        # the schedule continues
    assert plan.steps[0].liftoff_time == pytest.approx(1.252 + 0.5)
    np.testing.assert_allclose(sim.setpoint_at(1.252), [0.1, 0.0, 0.0])
    xs = [s.target[0] - FEET[s.leg, 0] for s in plan.steps]
    assert all(x > 0 for x in xs) and xs[-1] > xs[0]              # walking forward
    # Foothold correction: the first footholds follow the hips, pushed 5 cm to the left.
    first = {}
    for s in plan.steps:
        first.setdefault(s.leg, s)
    for leg, s in first.items():
        assert s.target[1] - FEET[leg, 1] == pytest.approx(0.05, abs=5e-3)

    # A republished state of the same tick does not re-plan again.
    sim.tick(1.252, base=pushed)
    sim.probe.spin_for(0.5)
    assert len(sim.plans_at(1.252)) == 1


def test_bad_cmd_vel_is_rejected_or_clamped(sim, launcher):
    sim.replan_at(0.0, launcher)
    sim.tick(1.0)
    good = (0.1, 0.05, 0.1)
    sim.cmd_vel(*good)
    for bad in ((math.nan, 0.0, 0.0), (0.0, math.inf, 0.0), (0.0, 0.0, -math.inf),
                (1e9, 0.0, 0.0), (0.0, -1e9, 0.0)):
        sim.cmd_vel(*bad)
    sim.replan_at(1.3, launcher)          # lh touches down (contact since 1.0 + 0.25 s)
    np.testing.assert_allclose(sim.setpoint_at(1.3), good)

    # Beyond the limits but not absurd: clamped.
    sim.tick(1.8)                         # lf lifts off
    sim.cmd_vel(0.5, -0.3, -0.4)
    plan = sim.replan_at(2.1, launcher)
    used = sim.setpoint_at(2.1)
    # Each component clipped to its limit (0.15, 0.1, 0.25), then the combination scaled to
    # strides the legs can make (crawl.clamp_velocity, the node's defaults).
    node_params = GaitParams(swing_duration=TIMING['swing_duration'],
                             four_feet_duration=TIMING['four_feet_duration'])
    np.testing.assert_allclose(used, clamp_velocity((0.5, -0.3, -0.4), node_params), atol=1e-9)
    assert 0 < used[0] <= 0.2 and -0.1 <= used[1] < 0 and -0.25 <= used[2] < 0
    assert all(np.all(np.isfinite(s.target)) for s in plan.steps)

    # No cmd_vel for more than cmd_vel_timeout (0.5 s of sim time): stand still.
    sim.tick(2.6)
    sim.replan_at(2.9, launcher)
    np.testing.assert_allclose(sim.setpoint_at(2.9), 0.0)
    assert all(proc.alive for proc in launcher.processes), launcher.logs()
    log = launcher.processes[0].log()
    assert 'rejected' in log and 'clamped' in log


def test_non_haptic_replans_at_the_planned_touchdown(launcher, probe):
    launcher.start('gait_node', params_file=CONFIG_DIR / 'gait.yaml',
                   params={**TIMING, 'haptic': False, 'replan_window': 2,
                           'idle_stance': False})   # no set-point: would stand at 2.5 s
    sim = FakeSim(probe)
    sim.wait_connected(launcher)
    plan = sim.replan_at(0.0, launcher)
    assert not any(s.haptic for s in plan.steps)
    assert [s.replan for s in plan.steps] == [False, True] * 4      # K = 2
    swing = [True, True, False, True]
    sim.tick(1.0)
    sim.tick(1.3, [True, True, True, True])   # contact flags do not end a non-haptic swing
    sim.tick(1.5, swing)                      # lh's planned touchdown: no re-plan (K = 2)
    sim.tick(2.0)                             # lf lifts off
    sim.probe.spin_for(0.3)
    assert len(sim.footholds) == 1
    plan = sim.replan_at(2.5, launcher, contact=[False, True, True, True])
    assert LEGS[plan.steps[0].leg] == 'rh'


def test_idle_stance_stands_then_walks_off_at_the_next_trigger(launcher, probe):
    """Zero set-point for idle_after after walking: the plan before it ends at its trigger, the
    re-plan at that touchdown publishes a stand plan (one zero-length replan trigger, no real
    step); the trigger's tick re-plans, and with a new set-point the plan walks off after the
    four-feet phase, the crawl order kept."""
    launcher.start('gait_node', params_file=CONFIG_DIR / 'gait.yaml',
                   params={**TIMING, 'idle_after': 1.0, 'idle_replan_period': 0.5})
    sim = FakeSim(probe)
    sim.wait_connected(launcher)

    def stamped(t, vx):
        msg = TwistStamped()
        msg.header.stamp = sec_to_stamp(t)
        msg.twist.linear.x = vx
        sim.stamped_pub.publish(msg)

    stamped(0.0, 0.1)                                 # walking from the start...
    stamped(0.5, 0.0)                                 # ...then told to stop
    sim.probe.spin_for(0.3)
    walk = sim.replan_at(0.0, launcher)
    assert len(walk.steps) == 8 and LEGS[walk.steps[0].leg] == 'lh'
    sim.tick(1.0)                                     # lh lifts off
    last = sim.replan_at(1.3, launcher)               # lh touches down: the zero run starts
    np.testing.assert_allclose(sim.setpoint_at(1.3), 0.0)
    # Its trigger (lf) touches down 1.0 s into the zero run, when the re-plan will stand:
    # the plan ends there (the MPC brings the CoM to rest during that swing).
    assert len(last.steps) == 1 and LEGS[last.steps[0].leg] == 'lf'
    assert last.steps[0].replan and last.steps[0].step_height > 0.0
    sim.tick(1.8)                                     # lf lifts off
    stand = sim.replan_at(2.3, launcher)              # lf touches down: zero for 1.0 s
    assert len(stand.steps) == 1
    trigger = stand.steps[0]
    assert trigger.liftoff_time == trigger.touchdown_time and trigger.step_height == 0.0
    assert trigger.replan and not trigger.haptic
    assert 2.3 < trigger.liftoff_time < 2.3 + 0.5    # half a tick early
    np.testing.assert_allclose(trigger.target, sim.feet[trigger.leg])

    stamped(2.75, 0.1)
    sim.tick(2.7)                                     # the trigger "lifts off"...
    walk = sim.replan_at(2.8, launcher)               # ...and ends one tick later: re-plan
    np.testing.assert_allclose(sim.setpoint_at(2.8), [0.1, 0.0, 0.0])
    assert len(walk.steps) == 8
    assert LEGS[walk.steps[0].leg] == 'rh'            # the trigger did not advance the crawl
    assert walk.steps[0].liftoff_time == pytest.approx(2.8 + TIMING['four_feet_duration'])
    assert all(s.target[0] > FEET[s.leg, 0] for s in walk.steps)
    assert 'idle stance at t=2.300' in launcher.processes[0].log()


def test_a_robot_never_told_to_walk_stands_from_its_first_plan(launcher, probe):
    launcher.start('gait_node', params_file=CONFIG_DIR / 'gait.yaml', params=TIMING)
    sim = FakeSim(probe)
    sim.wait_connected(launcher)
    first = sim.replan_at(0.0, launcher)
    assert len(first.steps) == 1 and first.steps[0].step_height == 0.0     # a stand plan
    assert 0.0 < first.steps[0].liftoff_time < 0.5
    np.testing.assert_allclose(first.steps[0].target, FEET[first.steps[0].leg])
    assert 'standing still until a non-zero set-point' in launcher.processes[0].log()


def test_no_contacts_after_the_start_says_so_then_plans_when_they_come(launcher, probe):
    """A gait node the sim's contacts do not reach (no sim here) warns, every warn_period,
    that it has none and plans nothing; the first tick then brings the initial plan."""
    launcher.start('gait_node', params_file=CONFIG_DIR / 'gait.yaml',
                   params={**TIMING, 'warn_period': 0.5, 'contacts_wait_warn': 1.0})
    sim = FakeSim(probe)
    assert probe.spin_until(lambda: launcher.logs().count('no contacts received') >= 2, 60), \
        launcher.logs()
    assert not sim.footholds
    sim.wait_connected(launcher)
    plan = sim.replan_at(0.0, launcher)
    assert plan.start_time == 0.0


def test_a_replan_waiting_for_its_odom_says_so_then_plans_when_it_comes(launcher, probe):
    """Contacts without odom (a restarted node whose odom reader is not matched yet): no plan,
    and a warning naming the tick and what odom it holds, then the plan once odom comes."""
    launcher.start('gait_node', params_file=CONFIG_DIR / 'gait.yaml',
                   params={**TIMING, 'warn_period': 0.5})
    sim = FakeSim(probe)
    sim.wait_connected(launcher)
    for _ in range(30):                       # the sim republishes a tick while it waits
        sim.tick(0.0, odom=False)
        if 'has waited' in launcher.logs():
            break
    assert 're-plan at t=0.000 s has waited' in launcher.logs(), launcher.logs()
    assert 'newest odom: none received yet' in launcher.logs()
    assert not sim.footholds
    plan = sim.replan_at(0.0, launcher)
    assert plan.start_time == 0.0
