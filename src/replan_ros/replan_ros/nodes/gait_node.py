"""Gait node: crawl schedule, the shared touchdown rule and foothold re-planning (issue 4).

- Every tick of ``contacts`` goes through ``contact.StepTracker`` (the rule the controller runs
  too). The ticks are read on demand (``on_demand.py``), in batches: when a ``contact_events``
  edge arrives (a haptic touchdown: at once) and every ``contacts_poll_period`` otherwise. When a
  step with ``replan`` touches down at ``t_k`` (and at the first state seen, the start of a run),
  the footholds are computed from the actual state at ``t_k`` (feet from ``contacts``, base from
  the ``odom`` of that stamp) and published on ``footholds`` stamped ``t_k``, with the set-point
  used on ``velocity_setpoint`` and RViz markers on ``gait_markers``.
- Set-point: ``cmd_vel`` (Twist; clamped; non-finite or absurd values rejected, the last good one
  kept; stand still after ``cmd_vel_timeout`` s of sim time without one) and ``cmd_vel_stamped``
  (TwistStamped, effective from ``header.stamp``, never times out). A re-plan at ``t`` uses the
  most recent of the two: the latest stamped one with stamp <= t, the last good ``cmd_vel`` by
  the sim time it was received at.
- Idle stance (``idle_stance``): a re-plan that finds the set-point zero for ``idle_after`` s
  publishes a stand plan (all four feet down; one zero-length ``replan`` trigger step after
  ``idle_replan_period``), so the re-plans go on, at ticks both trackers agree on, and the one
  after a new set-point walks off (docs/gait.md, "Idle stance").
"""

from __future__ import annotations

import math
import os
import time
from collections import deque

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import Point, Twist, TwistStamped, Vector3
from nav_msgs.msg import Odometry
from rclpy.clock import Clock, ClockType
from rclpy.node import Node
from sensor_msgs.msg import PointCloud2
from std_msgs.msg import ColorRGBA
from visualization_msgs.msg import Marker, MarkerArray

from replan_core.contact import StepTracker
from replan_core.gait import (
    CrawlSchedule,
    GaitParams,
    IdleMonitor,
    clamp_velocity,
    compute_footholds,
    is_idle_trigger,
    is_stand_plan,
    stance_phases,
    stand_plan,
)
from replan_core.inputs import SetpointArbiter
from replan_core.robot_model import RobotModel
from replan_core.rotations import yaw_of
from replan_core.types import LEGS, WORLD_FRAME, ContactState, FootholdPlan
from replan_ros.messages.interfaces import (
    base_state_from_odom,
    footholds_from_msg,
    footholds_to_msg,
    header,
    ns_to_stamp,
    sec_to_stamp,
    stamp_to_ns,
)
from replan_ros.messages.tick_cdr import contacts_from_cdr
from replan_ros.nodes.node_main import run_node
from replan_ros.params import declare_node_parameters, gait_params
from replan_ros.telemetry import diagnostics
from replan_ros.transport.on_demand import OnDemandSubscriptions
from replan_ros.transport.qos import (
    COMMAND,
    CONTACTS,
    INTERNAL_PUB_EVENTS,
    INTERNAL_SUB_EVENTS,
    LATCHED,
    SCHEDULE,
    SENSOR,
    with_depth,
)
from replan_ros.transport.stamped_buffer import RawStampedBuffer, cdr_header_stamp_ns

# Leg colours of the markers (r, g, b), LEGS order.
_LEG_COLOURS = ((0.9, 0.2, 0.2), (0.2, 0.7, 0.2), (0.2, 0.4, 0.9), (0.9, 0.7, 0.1))
# Support polygon corners in cyclic order around the trunk: lf, rf, rh, lh.
_POLYGON_ORDER = (0, 1, 3, 2)
_ODOM_QUEUE = 20         # newest odom samples queued until a re-plan reads them
_CONTACTS_QUEUE = 500    # contacts ticks queued between two reads (2 s at 250 Hz): none lost
_DEFAULT_TICK_NS = 4_000_000   # control period until the stamps have shown it (250 Hz)
_STATE_WAIT = 0.02       # wall s to wait for a due sample (odom of a re-plan, contacts of an
                         # event) before going on; the sim republishes a tick it waits at


class GaitNode(Node):
    """Runs the touchdown rule on ``contacts`` and publishes footholds at every re-plan."""

    def __init__(self) -> None:
        super().__init__('gait')
        p = declare_node_parameters(self, 'gait', on_change=self._on_parameter_change)
        self.params = self._gait_params(p)
        self.min_swing_fraction = float(p['min_swing_fraction'])
        self.max_extension = float(p['max_extension'])
        self.start_delay = max(float(p['start_delay']), 0.0)
        # Set-points, stamped and live (cmd_vel: from the sim time it arrived at).
        self.setpoints = SetpointArbiter(float(p['cmd_vel_timeout']))
        self.reject_above = float(p['cmd_vel_reject_above'])
        self.warn_period = float(p['warn_period'])
        self.model = self._robot_model(p['urdf_path'])

        self.footholds_pub = self.create_publisher(PointCloud2, 'footholds', LATCHED,
                                                   event_callbacks=INTERNAL_PUB_EVENTS)
        self.setpoint_pub = self.create_publisher(TwistStamped, 'velocity_setpoint', SCHEDULE,
                                                  event_callbacks=INTERNAL_PUB_EVENTS)
        self.markers_pub = self.create_publisher(MarkerArray, 'gait_markers', LATCHED,
                                                 event_callbacks=INTERNAL_PUB_EVENTS)
        self.diag_pub = self.create_publisher(DiagnosticArray, '/diagnostics', COMMAND,
                                              event_callbacks=INTERNAL_PUB_EVENTS)
        self.create_subscription(Twist, 'cmd_vel', self._on_cmd_vel, COMMAND)
        self.create_subscription(TwistStamped, 'cmd_vel_stamped', self._on_cmd_vel_stamped,
                                 SCHEDULE)
        # The per-tick state is read on demand (on_demand.py): every contacts tick goes through
        # the tracker, but in batches, when a contact event says a touchdown may have come or
        # every contacts_poll_period; odom only at a re-plan.
        self.state_input = OnDemandSubscriptions(self)
        self.state_input.subscribe(PointCloud2, 'contacts', with_depth(CONTACTS, _CONTACTS_QUEUE),
                                   self._on_contacts)
        self.state_input.subscribe(Odometry, 'odom', with_depth(SENSOR, _ODOM_QUEUE),
                                   self._on_odom)
        self.create_subscription(PointCloud2, 'contact_events', self._on_contact_events,
                                 CONTACTS, event_callbacks=INTERNAL_SUB_EVENTS, raw=True)
        self.create_timer(float(p['contacts_poll_period']), self._poll,
                          clock=Clock(clock_type=ClockType.STEADY_TIME))

        self.latest_stamp = 0.0        # s, newest state stamp seen (sim time for cmd_vel)
        self.rejected = 0
        self.forced = 0
        self._warned: dict[str, float] = {}
        self._odom_wait: tuple[int, float] | None = None   # (re-plan stamp ns, wall s since)
        self._reset('start')
        self.get_logger().info(
            f'gait: crawl {"-".join(LEGS[i] for i in self.params.sequence)}, swing '
            f'{self.params.swing_duration} s + four feet {self.params.four_feet_duration} s, '
            f'{self.params.n_footholds} footholds, K={self.params.replan_window}, '
            f'haptic={self.params.haptic}, correction={self.params.foothold_correction}')

    # ----------------------------------------------------------------------------- set-up

    def _on_parameter_change(self, name: str, value) -> None:
        """A run-time change of one of the writable parameters (params.GAIT)."""
        if name == 'cmd_vel_timeout':
            self.setpoints.timeout = float(value)
        elif name == 'cmd_vel_reject_above':
            self.reject_above = float(value)
        elif name == 'warn_period':
            self.warn_period = float(value)

    def _gait_params(self, p) -> GaitParams:
        try:
            params = gait_params(p)
            params.validate()
            return params
        except ValueError as err:
            # The tables check each value; this is what they cannot see (combinations).
            self.get_logger().fatal(f'config error: gait: {err}')
            raise SystemExit(2) from None

    def _robot_model(self, urdf_path: str):
        path = urdf_path or os.environ.get('REPLAN_URDF', '')
        if not path:
            self.get_logger().warn('no urdf_path and no $REPLAN_URDF: hips from the nominal '
                                   'HyQ offsets')
            return None
        try:
            model = RobotModel(path)
        except Exception as err:   # any load error: fall back to the nominal hips, keep running
            self.get_logger().error(f'cannot load {path} ({err}): hips from the nominal HyQ '
                                    'offsets')
            return None
        offsets = model.hip_offsets[:, :2]
        self.params.hip_offsets = tuple((float(x), float(y)) for x, y in offsets)
        return model

    def _reset(self, why: str) -> None:
        """Forget the run (start, or sim time went backwards: a new run)."""
        if why != 'start':
            self.get_logger().warn(f'gait: {why}; starting over with a new initial plan')
        self.schedule = CrawlSchedule(self.params.sequence)
        self.plan: FootholdPlan | None = None
        self.tracker: StepTracker | None = None
        self.last_tick_ns: int | None = None
        self.tick_ns: int | None = None    # the control period, as seen in the stamps
        self.pending: tuple[int, ContactState, bool] | None = None   # (stamp, contacts, initial)
        self.unprocessed: deque[ContactState] = deque()
        self.odom = RawStampedBuffer(Odometry, base_state_from_odom, _ODOM_QUEUE)
        self.replans = 0
        # Half a step of slack: the zero run is timed from re-plan (touchdown) ticks, which
        # jitter by a few ms (gait.IdleMonitor).
        self.idle = IdleMonitor(self.params.idle_after, self.params.idle_stance,
                                0.5 * self.params.step_period)

    def _warn(self, key: str, text: str) -> None:
        """Warning throttled per ``key`` (rclpy's throttle is per call site, and all of these
        share one), at most one every ``warn_period`` wall seconds."""
        now = time.monotonic()
        if now - self._warned.get(key, -math.inf) >= self.warn_period:
            self._warned[key] = now
            self.get_logger().warn(text)

    # ----------------------------------------------------------------------------- set-point

    def _validate(self, values, source: str) -> np.ndarray | None:
        v = np.array(values, dtype=float)
        if not np.all(np.isfinite(v)) or np.any(np.abs(v) > self.reject_above):
            self.rejected += 1
            self._warn(f'{source} rejected',
                       f'{source}: rejected (vx, vy, wz) = {v.tolist()}: non-finite or above '
                       f'{self.reject_above}; keeping the last good set-point')
            return None
        clamped = clamp_velocity(v, self.params)
        if not np.array_equal(clamped, v):
            self._warn(f'{source} clamped',
                       f'{source}: (vx, vy, wz) = {v.tolist()} clamped to {clamped.tolist()}')
        return clamped

    def _on_cmd_vel(self, msg: Twist) -> None:
        v = self._validate((msg.linear.x, msg.linear.y, msg.angular.z), 'cmd_vel')
        if v is not None:
            # Sim time of its arrival: the newest state stamp, once the queued ones are taken
            # (they are only queued here, processed at the next poll). Not the node's clock:
            # use_sim_time would wake the node at every /clock (config/gait.yaml).
            self.state_input.drain()
            self.setpoints.set_live(v, self.latest_stamp)

    def _on_cmd_vel_stamped(self, msg: TwistStamped) -> None:
        t = msg.twist
        v = self._validate((t.linear.x, t.linear.y, t.angular.z), 'cmd_vel_stamped')
        if v is not None:
            self.setpoints.add_stamped(stamp_to_ns(msg.header.stamp), v)

    # ----------------------------------------------------------------------------- state

    def _on_odom(self, cdr: bytes) -> None:
        ns = self.odom.add(cdr)
        if ns is None:
            self._warn('odom', 'odom rejected: no readable header stamp')
            return
        self.latest_stamp = max(self.latest_stamp, ns * 1e-9)

    def _on_contacts(self, cdr: bytes) -> None:
        try:
            _, cs = contacts_from_cdr(cdr)
            if not np.all(np.isfinite(cs.foot_position)):
                raise ValueError('non-finite foot positions')
        except ValueError as err:
            self._warn('contacts', f'contacts rejected: {err}')
            return
        self.latest_stamp = max(self.latest_stamp, cs.stamp)
        self.unprocessed.append(cs)

    def _on_contact_events(self, cdr: bytes) -> None:
        """A contact edge at t_k: read the contacts up to t_k now, not at the next poll."""
        ns = cdr_header_stamp_ns(cdr)
        if ns is None:
            self._warn('contact_events', 'contact_events rejected: no readable header stamp')
            return
        self.state_input.drain(lambda: round(self.latest_stamp * 1e9) >= ns,
                               timeout=_STATE_WAIT)
        self._process()

    def _poll(self) -> None:
        self.state_input.drain()
        self._process()

    def _process(self) -> None:
        """Run the ticks in order; a re-plan waits for the odom of its stamp."""
        while True:
            if self.pending is not None and not self._replan():
                return
            if not self.unprocessed:
                return
            self._tick(self.unprocessed.popleft())

    def _tick(self, cs: ContactState) -> None:
        ns = round(cs.stamp * 1e9)
        if self.last_tick_ns is not None and ns < self.last_tick_ns:
            self._reset(f'sim time went back from {self.last_tick_ns * 1e-9:.3f} s to '
                        f'{cs.stamp:.3f} s')
        if self.last_tick_ns is not None and ns == self.last_tick_ns:
            return                          # a republished state: already decided
        if self.last_tick_ns is not None:
            gap = ns - self.last_tick_ns
            self.tick_ns = min(self.tick_ns or gap, gap)
            if gap > 1.5 * self.tick_ns:    # the queue overflowed (this node was starved)
                self._warn('ticks lost',
                           f'contacts ticks lost between {self.last_tick_ns * 1e-9:.3f} s and '
                           f'{cs.stamp:.3f} s: the touchdown rule may disagree with the '
                           'controller until the next plan')
        self.last_tick_ns = ns
        if self.tracker is None:
            self.pending = (ns, cs, True)  # the first state seen: the initial plan
            return
        for event in self.tracker.update(cs.stamp, cs.contact):
            if event.kind != 'touchdown' or is_idle_trigger(self.plan.steps[event.step]):
                continue                    # a stand plan's trigger moves no leg
            self.schedule.touched_down(event.leg)
            if event.reason == 'forced':
                self.forced += 1
                self.get_logger().warn(
                    f'{LEGS[event.leg]} touchdown forced at t={event.time:.3f} s: no contact '
                    f'{self.max_extension} s after the planned touchdown')
        if self.tracker.replan_due:
            self.pending = (ns, cs, False)

    def _replan(self) -> bool:
        """Compute and publish the plan of the pending tick; False while its odom is missing."""
        ns, cs, initial = self.pending
        self.state_input.drain(lambda: ns in self.odom, timeout=_STATE_WAIT)
        stamps = self.odom.stamps()
        base = None
        if ns in self.odom:
            try:
                base = self.odom.get(ns)
            except ValueError as err:
                self._warn('odom', f'odom rejected: {err}')
                return False               # wait for the sim to send that tick again
        if base is None:
            if not stamps or max(stamps) <= ns:
                # May still come: the sim republishes while it waits, and the contacts of
                # that republish bring us back here.
                self._note_odom_wait(ns, stamps)
                return False
            # A newer odom came: the one of this stamp was lost (best effort, free-run mode).
            nearest = min(stamps, key=lambda s: abs(s - ns))
            try:
                base = self.odom.get(nearest)
            except ValueError as err:
                self._warn('odom', f'odom rejected: {err}')
                return False
            self._warn('odom lost', f'no odom stamped {ns * 1e-9:.3f} s: re-planning with the '
                       f'one of {nearest * 1e-9:.3f} s')
        t = cs.stamp                       # the very float the controller gets from the stamp
        feet = cs.foot_position.copy()
        if self.plan is not None:
            # A foot whose touchdown was forced is still in the air: plan it at ground height.
            targets = {s.leg: s.target for s in self.plan.steps
                       if s.touchdown_time <= t + 1e-9}
            for leg in range(4):
                if not cs.contact[leg] and leg in targets:
                    feet[leg, 2] = targets[leg][2]
        yaw = yaw_of(base.quaternion)
        hips = self.model.hip_positions(base) if self.model is not None else None
        setpoint, source = self.setpoints.at(ns)
        stand = self.idle.update(t, setpoint) and not initial
        was_standing = self.plan is not None and is_stand_plan(self.plan)
        try:
            if stand:
                plan = stand_plan(feet, yaw, t, self.schedule.next_leg, self._trigger_time(t))
            else:
                # Walking off from a stand, as at the start: the reference trunk stands
                # through the four-feet phase, so the first strides are partial.
                delay = (self.start_delay if initial
                         else self.params.four_feet_duration if was_standing else 0.0)
                plan = compute_footholds(setpoint, feet, base.position, yaw, hips,
                                         self.schedule.next_leg, t, self.params, delay=delay)
        except ValueError as err:
            self.get_logger().error(f'footholds at t={t:.3f} s failed ({err}); keeping the '
                                    'previous plan')
            self.pending = None
            return True
        # The touchdown rule travels with the plan: the controller applies the same values.
        plan.min_swing_fraction = self.min_swing_fraction
        plan.max_extension = self.max_extension
        msg = footholds_to_msg(plan)
        # Track the plan exactly as the controller decodes it from the message, so both trackers
        # compare bit-identical times.
        self.plan = footholds_from_msg(msg)
        self.tracker = StepTracker(self.plan)
        self.pending = None
        self.replans += 1
        stamp = ns_to_stamp(ns)
        self.footholds_pub.publish(msg)
        sp = TwistStamped()
        sp.header.stamp = stamp
        sp.header.frame_id = 'base_link'
        sp.twist.linear = Vector3(x=float(setpoint[0]), y=float(setpoint[1]), z=0.0)
        sp.twist.angular = Vector3(x=0.0, y=0.0, z=float(setpoint[2]))
        self.setpoint_pub.publish(sp)
        self.markers_pub.publish(self._markers(plan))
        self._publish_diagnostics(t, source)
        if initial:
            self.get_logger().info(f'initial plan at t={t:.3f} s: stand {self.start_delay} s, '
                                   f'then {LEGS[self.schedule.next_leg]} first')
        elif stand and not was_standing:
            self.get_logger().info(f'idle stance at t={t:.3f} s: set-point zero since '
                                   f'{self.idle.zero_since:.3f} s, all four feet down')
        elif was_standing and not stand:
            self.get_logger().info(f'walking again at t={t:.3f} s ({source} '
                                   f'{setpoint.tolist()}), {LEGS[self.schedule.next_leg]} '
                                   'first')
        return True

    def _note_odom_wait(self, ns: int, stamps) -> None:
        """Say so when a re-plan has waited long for its odom (wall s): a restarted node
        that never gets it would otherwise sit silent."""
        now = time.monotonic()
        if self._odom_wait is None or self._odom_wait[0] != ns:
            self._odom_wait = (ns, now)
            return
        waited = now - self._odom_wait[1]
        if waited >= self.warn_period:
            newest = f'{max(stamps) * 1e-9:.3f} s' if stamps else 'none received yet'
            self._warn('odom wait', f're-plan at t={ns * 1e-9:.3f} s has waited {waited:.1f} '
                       f'wall s for the odom of its tick (newest odom: {newest})')

    def _trigger_time(self, t: float) -> float:
        """When a stand plan's trigger lifts off: ``idle_replan_period`` after ``t``, half a
        control tick early. The trackers lift it off at the next tick (on the tick grid) and
        end it one tick later; half a tick off the grid it is never an MPC sample, so the
        support stays four feet at every sample (gait.stand_plan)."""
        tick = (self.tick_ns or _DEFAULT_TICK_NS) * 1e-9
        return t + self.params.idle_replan_period - 0.5 * tick

    # ----------------------------------------------------------------------------- output

    def _publish_diagnostics(self, t: float, source: str) -> None:
        level = diagnostics.WARN if self.forced else diagnostics.OK
        standing = self.plan is not None and is_stand_plan(self.plan)
        values = {'replans': self.replans, 'last_replan_time': t, 'setpoint_source': source,
                  'idle_stance': standing,
                  'rejected_cmd_vel': self.rejected, 'forced_touchdowns': self.forced,
                  'next_leg': LEGS[self.schedule.next_leg]}
        message = 'forced touchdowns happened' if self.forced else 'ok'
        self.diag_pub.publish(diagnostics.array(
            sec_to_stamp(t), diagnostics.status('gait', level, message, values)))

    def _markers(self, plan: FootholdPlan) -> MarkerArray:
        hdr = header(plan.start_time, WORLD_FRAME)
        markers = [Marker(header=hdr, action=Marker.DELETEALL)]
        feet = Marker(header=hdr, ns='initial_feet', id=0, type=Marker.SPHERE_LIST,
                      action=Marker.ADD)
        feet.scale = Vector3(x=0.05, y=0.05, z=0.05)
        feet.pose.orientation.w = 1.0
        for p in plan.initial_feet:
            feet.points.append(Point(x=float(p[0]), y=float(p[1]), z=float(p[2])))
            feet.colors.append(ColorRGBA(r=0.5, g=0.5, b=0.5, a=1.0))
        markers.append(feet)
        holds = Marker(header=hdr, ns='footholds', id=0, type=Marker.SPHERE_LIST,
                       action=Marker.ADD)
        holds.scale = Vector3(x=0.04, y=0.04, z=0.04)
        holds.pose.orientation.w = 1.0
        for k, step in enumerate(plan.steps):
            r, g, b = _LEG_COLOURS[step.leg]
            holds.points.append(Point(x=float(step.target[0]), y=float(step.target[1]),
                                      z=float(step.target[2])))
            fade = 1.0 - 0.6 * k / max(len(plan.steps), 1)   # later footholds paler
            holds.colors.append(ColorRGBA(r=r, g=g, b=b, a=fade))
        markers.append(holds)
        for k, (_t0, _t1, positions, stance) in enumerate(stance_phases(plan)):
            poly = Marker(header=hdr, ns='support_polygons', id=k, type=Marker.LINE_STRIP,
                          action=Marker.ADD)
            poly.scale.x = 0.005
            poly.pose.orientation.w = 1.0
            three = int(stance.sum()) == 3
            poly.color = (ColorRGBA(r=1.0, g=0.5, b=0.0, a=0.8) if three
                          else ColorRGBA(r=0.1, g=0.8, b=0.3, a=0.5))
            corners = [leg for leg in _POLYGON_ORDER if stance[leg]]
            for leg in [*corners, corners[0]]:
                p = positions[leg]
                poly.points.append(Point(x=float(p[0]), y=float(p[1]),
                                         z=float(p[2]) + 0.002 * k))   # stacked, readable
            markers.append(poly)
        return MarkerArray(markers=markers)

    def destroy_node(self) -> None:
        self.state_input.destroy()
        super().destroy_node()


def main(args=None):
    run_node(GaitNode, args)
