"""Gait node: crawl schedule, the shared touchdown rule and foothold re-planning; the
decisions are ``replan_core.gait.replanner``'s, this node reads the messages and publishes.

- Every tick of ``contacts`` goes through ``touchdown.StepTracker`` (the rule the controller runs
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
- Gait (docs/gait.md, "Gait files"): the start gait's parameters come from the launcher
  (``gait``); ``gait_library`` holds every gait of the run scaled for the robot. A request on
  ``gait_command`` (String: a gait's name, from the sim time it arrived at) or
  ``gait_command_stamped`` (Header: the name in ``frame_id``, effective from ``stamp``) switches
  at the next re-plan (a step boundary). The gait of each re-plan goes out on ``gait_in_force``
  (Header stamped with the re-plan) and on diagnostics.
- Idle stance (``idle_stance``): a re-plan that finds the set-point zero for ``idle_after`` s
  publishes a stand plan (all four feet down; one zero-length ``replan`` trigger step after
  ``idle_replan_period``), so the re-plans go on, at ticks both trackers agree on, and the one
  after a new set-point walks off (docs/gait.md, "Idle stance").
"""

from __future__ import annotations

import json
import os
import time
from collections import deque

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import Twist, TwistStamped, Vector3
from nav_msgs.msg import Odometry
from rclpy.clock import Clock, ClockType
from rclpy.node import Node
from sensor_msgs.msg import PointCloud2
from std_msgs.msg import Header, String
from visualization_msgs.msg import MarkerArray

from replan_core.common.types import LEGS, ContactState
from replan_core.gait.crawl import GaitParams
from replan_core.gait.replanner import GaitReplanner, check_setpoint
from replan_core.gait.setpoints import GaitArbiter, SetpointArbiter
from replan_core.robot.model import RobotModel
from replan_ros.messages.contacts import contacts_from_cdr
from replan_ros.messages.footholds import footholds_from_msg, footholds_to_msg
from replan_ros.messages.odom import base_state_from_odom
from replan_ros.messages.stamps import ns_to_stamp, sec_to_stamp, stamp_to_ns
from replan_ros.nodes.node_main import ThrottledLog, load_node_robot, log_at, run_node
from replan_ros.params import declare_node_parameters, gait_params
from replan_ros.telemetry import diagnostics
from replan_ros.transport.on_demand import OnDemandSubscriptions
from replan_ros.transport.qos import (
    COMMAND,
    CONTACTS,
    INTERNAL_PUB_EVENTS,
    INTERNAL_SUB_EVENTS,
    LATCHED_PUB,
    SCHEDULE,
    SENSOR,
    with_depth,
)
from replan_ros.transport.stamped_buffer import RawStampedBuffer, cdr_header_stamp_ns
from replan_ros.view.plan_markers import gait_markers

_ODOM_QUEUE = 20         # newest odom samples queued until a re-plan reads them
_CONTACTS_QUEUE = 500    # contacts ticks queued between two reads (2 s at 250 Hz): none lost
_STATE_WAIT = 0.02       # wall s to wait for a due sample (odom of a re-plan, contacts of an
                         # event) before going on; the sim republishes a tick it waits at


class GaitNode(Node):
    """Runs the touchdown rule on ``contacts`` and publishes footholds at every re-plan."""

    def __init__(self) -> None:
        super().__init__('gait')
        p = declare_node_parameters(self, 'gait', on_change=self._on_parameter_change)
        self.params = self._gait_params(p)
        self.gait_name = str(p['gait'])
        self.gaits = self._gait_library(p)
        self.gait_requests = GaitArbiter(self.gait_name)
        # Set-points, stamped and live (cmd_vel: from the sim time it arrived at).
        self.setpoints = SetpointArbiter(float(p['cmd_vel_timeout']))
        self.reject_above = float(p['cmd_vel_reject_above'])
        self._warn = ThrottledLog(self.get_logger(), float(p['warn_period']))
        self.contacts_wait_warn = float(p['contacts_wait_warn'])    # wall s
        self._started = time.monotonic()
        self.model = self._robot_model(p)

        self.footholds_pub = self.create_publisher(PointCloud2, 'footholds', LATCHED_PUB,
                                                   event_callbacks=INTERNAL_PUB_EVENTS)
        self.setpoint_pub = self.create_publisher(TwistStamped, 'velocity_setpoint', SCHEDULE,
                                                  event_callbacks=INTERNAL_PUB_EVENTS)
        self.markers_pub = self.create_publisher(MarkerArray, 'gait_markers', LATCHED_PUB,
                                                 event_callbacks=INTERNAL_PUB_EVENTS)
        self.diag_pub = self.create_publisher(DiagnosticArray, '/diagnostics', COMMAND,
                                              event_callbacks=INTERNAL_PUB_EVENTS)
        self.gait_pub = self.create_publisher(Header, 'gait_in_force', SCHEDULE,
                                              event_callbacks=INTERNAL_PUB_EVENTS)
        self.create_subscription(String, 'gait_command', self._on_gait_command, COMMAND)
        self.create_subscription(Header, 'gait_command_stamped', self._on_gait_command_stamped,
                                 SCHEDULE)
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
        self._odom_wait: tuple[int, float] | None = None   # (re-plan stamp ns, wall s since)
        # The touchdown rule, re-plan trigger and foothold planning (replan_core.gait.replanner).
        self.replanner = GaitReplanner(
            self.params, float(p['min_swing_fraction']), float(p['max_extension']),
            float(p['start_delay']), log=self._log, warn=self._warn,
            plan_latency=float(p['plan_latency']))
        self.unprocessed: deque[ContactState] = deque()
        self.odom = RawStampedBuffer(Odometry, base_state_from_odom, _ODOM_QUEUE)
        steps = ' '.join('+'.join(LEGS[i] for i in group) for group in self.params.swing_groups)
        self.get_logger().info(
            f'gait: {self.gait_name} {steps}, swing '
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
            self._warn.period = float(value)

    def _gait_params(self, p) -> GaitParams:
        try:
            params = gait_params(p)
            params.validate()
            return params
        except ValueError as err:
            # The tables check each value; this is what they cannot see (combinations).
            self.get_logger().fatal(f'config error: gait: {err}')
            raise SystemExit(2) from None

    def _gait_library(self, p) -> dict[str, GaitParams]:
        """The run's gaits (``gait_library``: name -> the gait node's values for this robot),
        each on top of this node's other parameters; the start gait as the run set it."""
        gaits = {self.gait_name: self.params}
        try:
            library = json.loads(p['gait_library']) if p['gait_library'] else {}
            for name, values in library.items():
                if name != self.gait_name:
                    gaits[name] = gait_params({**p, **values})
                    gaits[name].validate()
        except (ValueError, TypeError, KeyError, AttributeError) as err:
            self.get_logger().fatal(f'config error: gait: gait_library: {err}')
            raise SystemExit(2) from None
        return gaits

    def _on_gait_command(self, msg: String) -> None:
        if self._known_gait(msg.data, 'gait_command'):
            self.state_input.drain()        # from the sim time it arrived at, as cmd_vel
            self.gait_requests.add(round(self.latest_stamp * 1e9), msg.data)

    def _on_gait_command_stamped(self, msg: Header) -> None:
        if self._known_gait(msg.frame_id, 'gait_command_stamped'):
            self.gait_requests.add(stamp_to_ns(msg.stamp), msg.frame_id)

    def _known_gait(self, name: str, source: str) -> bool:
        if name in self.gaits:
            return True
        self._warn(f'{source} unknown', f'{source}: unknown gait {name!r} ignored; gaits of '
                   f'this run: {", ".join(sorted(self.gaits))}')
        return False

    def _robot_model(self, p):
        robot = load_node_robot(self, p, os.environ.get('REPLAN_URDF', ''))
        path = robot.urdf
        if not path:
            self.get_logger().warn('no urdf_path and no $REPLAN_URDF: hips from the nominal '
                                   'HyQ offsets')
            return None
        try:
            model = RobotModel(path, robot.joints, robot.feet)
        except Exception as err:   # any load error: fall back to the nominal hips, keep running
            self.get_logger().error(f'cannot load {path} ({err}): hips from the nominal HyQ '
                                    'offsets')
            return None
        offsets = model.hip_offsets[:, :2]
        self.params.hip_offsets = tuple((float(x), float(y)) for x, y in offsets)
        return model

    def _log(self, level: str, text: str) -> None:
        """The re-planner's log lines (replanner.Log)."""
        log_at(self.get_logger(), level, text)

    # ----------------------------------------------------------------------------- set-point

    def _validate(self, values, source: str) -> np.ndarray | None:
        v, problem = check_setpoint(values, self.reject_above, list(self.gaits.values()))
        if v is None:
            self.rejected += 1
        if problem:
            self._warn(f'{source} {"rejected" if v is None else "clamped"}',
                       f'{source}: {problem}')
        return v

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
        if self.replanner.last_tick_ns is None:
            self._note_no_contacts()

    def _note_no_contacts(self) -> None:
        """Say so while no contacts tick has come since the start (wall s): a (restarted) node
        that the sim's contacts do not reach would otherwise wait silently."""
        waited = time.monotonic() - self._started
        if waited >= self.contacts_wait_warn:
            self._warn('no contacts', f'no contacts received {waited:.1f} wall s after the '
                       'start: no plan until the sim\'s contacts come (is the sim running?)')

    def _process(self) -> None:
        """Run the ticks in order; a re-plan waits for the odom of its stamp."""
        while True:
            if self.replanner.pending is not None and not self._replan():
                return
            if not self.unprocessed:
                return
            if self.replanner.tick(self.unprocessed.popleft()):    # a new run
                self.odom = RawStampedBuffer(Odometry, base_state_from_odom, _ODOM_QUEUE)

    def _replan(self) -> bool:
        """Compute and publish the plan of the pending tick; False while its odom is missing."""
        ns, t = self.replanner.pending.stamp, self.replanner.pending.contacts.stamp
        base = self._odom_of(ns)
        if base is None:
            return False
        hips = self.model.hip_positions(base) if self.model is not None else None
        setpoint, source = self.setpoints.at(ns)
        gait = self.gait_requests.at(ns)
        if gait != self.gait_name:
            self.replanner.switch_gait(self.gaits[gait])     # applied by this very re-plan
            self.gait_name = gait
        plan = self.replanner.plan_pending(base, hips, setpoint, source)
        if plan is None:
            return True
        msg = footholds_to_msg(plan)
        # Track the plan exactly as the controller decodes it from the message, so both trackers
        # compare bit-identical times.
        self.replanner.adopt(footholds_from_msg(msg))
        stamp = ns_to_stamp(ns)
        self.footholds_pub.publish(msg)
        sp = TwistStamped()
        sp.header.stamp = stamp
        sp.header.frame_id = 'base_link'
        sp.twist.linear = Vector3(x=float(setpoint[0]), y=float(setpoint[1]), z=0.0)
        sp.twist.angular = Vector3(x=0.0, y=0.0, z=float(setpoint[2]))
        self.setpoint_pub.publish(sp)
        self.markers_pub.publish(gait_markers(plan))
        self.gait_pub.publish(Header(stamp=stamp, frame_id=self.gait_name))
        self._publish_diagnostics(t, source)
        return True

    def _odom_of(self, ns: int):
        """The base state of tick ``ns`` (waited for up to _STATE_WAIT), or the nearest one if
        a newer came (this one was lost); None while it may still come."""
        self.state_input.drain(lambda: ns in self.odom, timeout=_STATE_WAIT)
        stamps = self.odom.stamps()
        if ns in self.odom:
            try:
                return self.odom.get(ns)
            except ValueError as err:
                self._warn('odom', f'odom rejected: {err}')
                return None                # wait for the sim to send that tick again
        if not stamps or max(stamps) <= ns:
            # May still come: the sim republishes while it waits, and the contacts of
            # that republish bring us back here.
            self._note_odom_wait(ns, stamps)
            return None
        # A newer odom came: the one of this stamp was lost (best effort, free-run mode).
        nearest = min(stamps, key=lambda s: abs(s - ns))
        try:
            base = self.odom.get(nearest)
        except ValueError as err:
            self._warn('odom', f'odom rejected: {err}')
            return None
        self._warn('odom lost', f'no odom stamped {ns * 1e-9:.3f} s: re-planning with the '
                   f'one of {nearest * 1e-9:.3f} s')
        return base

    def _note_odom_wait(self, ns: int, stamps) -> None:
        """Say so when a re-plan has waited long for its odom (wall s): a restarted node
        that never gets it would otherwise sit silent."""
        now = time.monotonic()
        if self._odom_wait is None or self._odom_wait[0] != ns:
            self._odom_wait = (ns, now)
            return
        waited = now - self._odom_wait[1]
        if waited >= self._warn.period:
            newest = f'{max(stamps) * 1e-9:.3f} s' if stamps else 'none received yet'
            self._warn('odom wait', f're-plan at t={ns * 1e-9:.3f} s has waited {waited:.1f} '
                       f'wall s for the odom of its tick (newest odom: {newest})')

    # ----------------------------------------------------------------------------- output

    def _publish_diagnostics(self, t: float, source: str) -> None:
        replanner = self.replanner
        level = diagnostics.WARN if replanner.forced else diagnostics.OK
        values = {'gait': self.gait_name, 'replans': replanner.replans, 'last_replan_time': t,
                  'setpoint_source': source, 'idle_stance': replanner.standing,
                  'rejected_cmd_vel': self.rejected, 'forced_touchdowns': replanner.forced,
                  'next_leg': LEGS[replanner.schedule.next_leg],
                  # m, body frame: the velocity feedback's stride correction (docs/gait.md)
                  'stride_correction_x': float(replanner.speed.correction[0]),
                  'stride_correction_y': float(replanner.speed.correction[1]),
                  # s: the step period measured over the last cycle (0: not yet), and the
                  # stretch of the strides it gives (docs/gait.md, "Step timing")
                  'measured_step_period': replanner.timing.measured_period or 0.0,
                  'stride_time_scale': replanner.stride_time_scale}
        message = 'forced touchdowns happened' if replanner.forced else 'ok'
        self.diag_pub.publish(diagnostics.array(
            sec_to_stamp(t), diagnostics.status('gait', level, message, values)))

    def destroy_node(self) -> None:
        self.state_input.destroy()
        super().destroy_node()


def main(args=None):
    run_node(GaitNode, args)
