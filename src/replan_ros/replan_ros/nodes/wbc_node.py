"""Whole-body controller node `wbc`: state estimation and the controller side of the lock-step
and re-plan protocol.

docs/ARCHITECTURE.md, "Time and lock-step", "State estimation" and "Re-plan protocol":
- it wakes on the simulator's `joint_states` and takes the tick's `imu` from its queue; the
  state estimator (`replan_core.estimator`, in this process so that estimation adds no DDS
  hop to the tick) turns them into the base pose and twist and the foot contacts (forces
  estimated from the joint torques and the model), which it publishes as `odom`, `contacts`
  and `contact_events` for the gait and mpc nodes right after its command (while the sim
  steps), or before it waits when it holds the tick for plans. With
  `state_estimation` / `contact_estimation` false (the ideal profile) the simulator's
  `ground_truth/odom` / `ground_truth/contacts` of the tick take their place;
- each tick is answered by one `joint_torque_cmd` stamped with it; a republished tick gets the
  same estimate and command again (the estimator runs once per tick); older stamps are ignored;
  nothing is ever extrapolated;
- `contact.StepTracker` (through `wbc.PlanFollower`), fed with the plan and the contacts of
  every tick, decides swing/stance; when a `replan` step touches down at t_k, the plans stamped
  t_k take effect at t_k + `plan_latency` (rounded up to ticks; the old plans are tracked
  meanwhile, with no new lift-off), and that tick is answered only once `footholds` and
  `com_plan` stamped t_k have arrived, or after `plan_timeout` wall seconds (then with the old
  plans, WARN). Waiting is event-driven: the plan callbacks answer, a one-shot wall-clock timer
  handles the timeout;
- at the first tick it waits for the first plans the same way (timeout: stand);
- after a command, the next `joint_states` are taken straight from their DDS queue, outside
  the executor (`direct_take.py`), until a tick must wait for plans or for at most 50 ms wall;
- no plan, a plan older than `plan_max_age` (sim s) or past its horizon, or stale inputs (a gap
  of more than `stale_ticks` control periods between answered ticks, e.g. after the sim
  free-ran): it holds a stable stand with the feet where they are (`wbc.StandHold`) until a new
  plan pair arrives.

Every answered tick is timed by phase (tick_budget.py; docs/ARCHITECTURE.md, "Per-tick budget"):
the `joint_states` DDS transport and this process's wake-up (from the message info), decoding,
the take of the tick's queued samples, estimator, messages, publishes, plan logic, controller
maths, the command; in /diagnostics (`tick_<phase>_median_ms`, `tick_<phase>_mean_ms`) and in one
log line at shutdown.
"""

from __future__ import annotations

import dataclasses
import math
import os
import time
from collections import deque
from pathlib import Path

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray
from nav_msgs.msg import Odometry
from rclpy.clock import Clock, ClockType
from rclpy.node import Node
from sensor_msgs.msg import Imu, PointCloud2
from sensor_msgs.msg import JointState as JointStateMsg
from trajectory_msgs.msg import MultiDOFJointTrajectory

from replan_core.estimator import StateEstimator
from replan_core.robot_model import RobotModel
from replan_core.rotations import yaw_of
from replan_core.types import ComPlan, ContactState, FootholdPlan, JointState
from replan_core.wbc import (
    JointStandUp,
    PlanFollower,
    StandHold,
    WholeBodyController,
    plan_ends_stand,
    trunk_tilt,
)
from replan_ros.messages.cdr import com_plan_from_cdr
from replan_ros.messages.interfaces import (
    footholds_from_msg,
    ns_to_sec,
    ns_to_stamp,
    sec_to_ns,
    stamp_to_ns,
)
from replan_ros.messages.tick_cdr import (
    base_state_from_cdr,
    contacts_from_cdr,
    encode_contact_events,
    encode_contacts,
    encode_odom,
    encode_torque_command,
    imu_from_cdr,
    joint_state_from_cdr,
)
from replan_ros.nodes.node_main import run_node
from replan_ros.params import declare_node_parameters, estimator_params, wbc_params
from replan_ros.telemetry import diagnostics
from replan_ros.telemetry.tick_budget import TickBudget
from replan_ros.transport.direct_take import DirectTake
from replan_ros.transport.on_demand import OnDemandSubscriptions
from replan_ros.transport.qos import (
    COMMAND,
    CONTACTS,
    INTERNAL_PUB_EVENTS,
    INTERNAL_SUB_EVENTS,
    LATCHED,
    SENSOR,
    SENSOR_PUB,
)
from replan_ros.transport.stamped_buffer import cdr_header_stamp_ns

_NS = 1_000_000_000
_KEEP_PLANS = 8          # plans kept per topic, by stamp (a few re-plans ahead of the ticks)
_KEEP_COMMANDS = 8       # answered commands kept for duplicates of their stamp
_KEEP_STATES = 50        # ticks of inputs kept per topic while waiting for the rest
_STATE_WAIT = 0.01       # wall s to wait for the imu / ground truth of a joint_states tick
# Phases of an answered tick, from the sim's joint_states write to our command's publish.
BUDGET_PHASES = (
    'wbc_transport_in',      # joint_states: the sim's DDS write -> our DDS reader
    'wbc_wake',              # our DDS reader -> _on_joint_states (executor, take, deserialize)
    'wbc_decode',            # joint_states to the core joint state
    'wbc_take',              # the tick's queued imu / ground truth taken and decoded
    'wbc_estimator',         # state estimator update
    'wbc_state_msgs',        # odom, contacts and contact_events messages built
    'wbc_logic',             # plan following, adoption, stand decisions
    'wbc_plan_wait',         # a re-plan tick held until its plans arrived
    'wbc_controller',        # whole-body controller maths (pinocchio, proxsuite)
    'wbc_command',           # joint_torque_cmd built and published
    'wbc_publish_state',     # then odom, contacts (and contact_events) published
    'wbc_estimator_next',    # then the estimator's next covariance step (prepare_next)
)


class WbcNode(Node):
    """Answers every state stamp of the simulator with joint torques."""

    def __init__(self) -> None:
        super().__init__('wbc')
        # The parameters and their ranges: params.WBC, estimator.<field> included.
        p = declare_node_parameters(self, 'wbc', on_change=self._on_parameter_change)
        params = wbc_params(p)
        self.plan_timeout = float(p['plan_timeout'])
        self.missed_replans_to_stand = int(p['missed_replans_to_stand'])
        self.first_plan_timeout = float(p['first_plan_timeout'])
        self.plan_max_age = float(p['plan_max_age'])
        self.sat_down_height = float(p['sat_down_height'])
        self.stand_adopt_age = float(p['stand_adopt_age'])
        self.stand_adopt_lead = float(p['stand_adopt_lead'])
        self.fall_time_ns = sec_to_ns(float(p['fall_time']))
        self.stale_gap_ns = sec_to_ns(int(p['stale_ticks']) / float(p['control_rate']))
        self.haptic_velocity = params.haptic_velocity
        self.touchdown_depth = params.touchdown_depth
        self.state_estimation = bool(p['state_estimation'])
        self.contact_estimation = bool(p['contact_estimation'])
        period_ns = sec_to_ns(1.0 / float(p['control_rate']))
        self.period_ns = period_ns
        latency = float(p['plan_latency'])         # within [0, 0.99] s (params.WBC)
        self.latency_ns = math.ceil(sec_to_ns(latency) / period_ns - 1e-9) * period_ns
        self.first_command_waits_for = set(p['first_command_waits_for'])
        self.first_command_wait_timeout = float(p['first_command_wait_timeout'])
        self._listeners_ready = not self.first_command_waits_for
        self._listeners_deadline: float | None = None     # time.monotonic(), set at 1st tick

        urdf = p['urdf_path'] or os.environ.get('REPLAN_URDF') or str(
            Path(__file__).resolve().parents[4] / 'urdf' / 'hyq.urdf')
        try:
            self.robot = RobotModel(urdf)
        except Exception as err:   # any load error: without a model there is nothing to control
            # with; exit non-zero so that the launcher reports it (and respawns, up to a limit)
            self.get_logger().fatal(f'cannot load the URDF {urdf!r} ({err}): exiting')
            raise SystemExit(1) from None
        self.wbc = WholeBodyController(self.robot, params)
        self.standing_pose = np.array(p['standing_joint_positions'], float)   # rad, the sim's
        standing = JointState(0.0, self.standing_pose.copy(), np.zeros(12), np.zeros(12))
        self._standing_leg_height = float(np.median(self.wbc.leg_heights(standing)))
        self.estimator: StateEstimator | None = None
        if self.state_estimation or self.contact_estimation:
            # The controller's model: the estimator keeps a pinocchio data of its own.
            self.estimator = StateEstimator(
                self.robot, estimator_params(p),
                dt=period_ns / _NS)

        # Inputs of a tick taken from their queues: stamp (ns) -> (message, core state).
        self._imu: dict[int, object] = {}
        self._truth_odom: dict[int, tuple] = {}
        self._truth_contacts: dict[int, tuple] = {}
        # The state of each processed tick: stamp (ns) -> core state.
        self._joints: dict[int, object] = {}
        self._odom: dict[int, object] = {}
        self._contacts: dict[int, ContactState] = {}
        self._state_msgs: dict[int, tuple] = {}       # stamp -> (odom, contacts) published
        self._last_estimated: int | None = None
        self._pending: tuple[int, int] | None = None  # (plan stamp, tick it takes effect)
        self._footholds: dict[int, FootholdPlan] = {}
        self._com_plans: dict[int, ComPlan] = {}
        self._commands: dict[int, bytes] = {}    # serialized
        self._last_answered: int | None = None
        self._started = False
        self._follower: PlanFollower | None = None
        self._plan_stamp: int | None = None       # stamp of the active plan pair
        self._stand: StandHold | None = None
        self._stand_reason = 'no plan yet'
        self._stand_since = 0.0                   # sim s the current stand began
        self._stand_up: JointStandUp | None = None   # a robot that sat down standing up
        self._fallen: tuple[float, float] | None = None   # (sim s, tilt rad) of the fall
        self._tilt = 0.0                                # rad, trunk tilt of the last tick
        self._tilted_since: int | None = None           # ns, first tick beyond fall_tilt
        self._stand_floor = 0                     # ns: a stand ends with plans from here on
        self._waiting: int | None = None          # tick (ns) held until its plans arrive
        self._waiting_first = False               # the wait is the first tick's
        self._wait_timer = None
        self._wall = Clock(clock_type=ClockType.STEADY_TIME)
        # Diagnostics accumulated over a period.
        self._times: deque[float] = deque(maxlen=2000)
        self._com_errors: deque[float] = deque(maxlen=2000)
        self._last_result = None
        self._plan_timeouts = 0
        self._period_timeouts = 0
        # Due re-plans in a row whose plans never came, and what was missing at the last one
        # (a planner that is gone, not slow: issue 15, "faults while walking").
        self._missed_replans = 0
        self._missing = ''
        self._fallbacks = 0
        self._period_fallbacks = 0
        self._ticks = 0
        self.budget = TickBudget(BUDGET_PHASES)
        self._unpublished: tuple | None = None   # (odom, contacts, events) not yet published
        self._wait_started_ns = 0          # perf_counter_ns when a tick began to wait for plans
        self._budget_tick: int | None = None   # the stamp whose phases the budget gathers
        self._logic_start_ns: int | None = None  # perf_counter_ns the current phase began

        self.cmd_pub = self.create_publisher(JointStateMsg, 'joint_torque_cmd', COMMAND,
                                             event_callbacks=INTERNAL_PUB_EVENTS)
        self.diag_pub = self.create_publisher(DiagnosticArray, '/diagnostics', COMMAND,
                                              event_callbacks=INTERNAL_PUB_EVENTS)
        self.odom_pub = self.create_publisher(Odometry, 'odom', SENSOR_PUB,
                                              event_callbacks=INTERNAL_PUB_EVENTS)
        self.contacts_pub = self.create_publisher(PointCloud2, 'contacts', CONTACTS,
                                                  event_callbacks=INTERNAL_PUB_EVENTS)
        self.events_pub = self.create_publisher(PointCloud2, 'contact_events', CONTACTS,
                                                event_callbacks=INTERNAL_PUB_EVENTS)
        # One wake-up per tick, on joint_states: the sim publishes the imu (and, to a controller
        # that reads it, the truth) before them, so they are queued by then, and are taken from
        # their queues (on_demand.py; waited for up to _STATE_WAIT if late).
        joint_states_sub = self.create_subscription(
            JointStateMsg, 'joint_states', self._on_joint_states, SENSOR,
            event_callbacks=INTERNAL_SUB_EVENTS, raw=True)
        self.state_input = OnDemandSubscriptions(self)
        self._needed: list[dict] = []
        if self.estimator is not None:
            self.state_input.subscribe(Imu, 'imu', SENSOR, self._on_imu)
            self._needed.append(self._imu)
        if not self.state_estimation:
            self.state_input.subscribe(Odometry, 'ground_truth/odom', SENSOR,
                                       self._on_truth_odom)
            self._needed.append(self._truth_odom)
        if not self.contact_estimation:
            self.state_input.subscribe(PointCloud2, 'ground_truth/contacts', CONTACTS,
                                       self._on_truth_contacts)
            self._needed.append(self._truth_contacts)
        footholds_sub = self.create_subscription(
            PointCloud2, 'footholds', self._on_footholds, LATCHED,
            event_callbacks=INTERNAL_SUB_EVENTS)
        com_plan_sub = self.create_subscription(
            MultiDOFJointTrajectory, 'com_plan', self._on_com_plan, LATCHED,
            event_callbacks=INTERNAL_SUB_EVENTS, raw=True)
        # Plans go to the executor as soon as they come (direct_take.py).
        self._direct_states = DirectTake(self, joint_states_sub, self._on_joint_states,
                                         watched=(footholds_sub, com_plan_sub))
        self.create_timer(float(p['diagnostics_period']), self._publish_diagnostics,
                          clock=self._wall)
        base_source = 'the estimator' if self.state_estimation else 'ground truth'
        contact_source = 'joint torques' if self.contact_estimation else 'ground truth'
        sources = f'base state from {base_source}, contacts from {contact_source}'
        self.get_logger().info(
            f'wbc ready: {urdf}, mass {self.robot.total_mass:.2f} kg, {sources}, plan latency '
            f'{self.latency_ns / _NS:.3f} s, plan_timeout {self.plan_timeout} s')

    def _on_parameter_change(self, name: str, value) -> None:
        """A run-time change of one of the writable parameters (params.WBC)."""
        if name == 'plan_timeout':
            self.plan_timeout = float(value)

    def _warn(self, text: str) -> None:
        self.get_logger().warning(text, throttle_duration_sec=2.0)

    # ------------------------------------------------------------------------------ inputs
    def _decoded(self, decode, msg, what: str):
        """``decode(msg)``, or None (and a throttled warning) for a malformed message."""
        try:
            return decode(msg)
        except ValueError as error:
            self._warn(f'rejected {what}: {error}')
            return None

    def _on_imu(self, data: bytes) -> None:
        decoded = self._decoded(imu_from_cdr, data, 'imu')
        if decoded is not None:
            self._keep_input(self._imu, *decoded)

    def _on_truth_odom(self, data: bytes) -> None:
        decoded = self._decoded(base_state_from_cdr, data, 'ground_truth/odom')
        if decoded is not None:    # passed on as it came: the ideal profile's odom
            stamp, base = decoded
            self._keep_input(self._truth_odom, stamp, (data, base))

    def _on_truth_contacts(self, data: bytes) -> None:
        decoded = self._decoded(contacts_from_cdr, data, 'ground_truth/contacts')
        if decoded is not None:
            stamp, contacts = decoded
            self._keep_input(self._truth_contacts, stamp, (data, contacts))

    @staticmethod
    def _keep_input(buffer: dict, stamp: int, value) -> None:
        buffer[stamp] = value
        while len(buffer) > _KEEP_STATES:
            del buffer[min(buffer)]

    def _on_joint_states(self, data: bytes, info: dict) -> None:
        """A serialized ``joint_states`` (subscribed raw: tick_cdr.py decodes it)."""
        clock = time.perf_counter_ns
        t0 = clock()
        wall0 = time.time_ns()
        stamp = cdr_header_stamp_ns(data)
        if stamp is None:
            self._warn('rejected joint_states: too short for a header')
            return
        if stamp in self._state_msgs:
            # The sim republished a tick we have estimated: the same state and command again
            # (a lost odom, contacts or command heals; the estimator never runs twice).
            odom_msg, contacts_msg = self._state_msgs[stamp]
            self.odom_pub.publish(odom_msg)
            self.contacts_pub.publish(contacts_msg)
            self._on_state(stamp)
            return
        if self._last_estimated is not None and stamp <= self._last_estimated:
            return                                   # an old stamp: nothing to answer
        budget = self.budget
        budget.discard_tick()                        # a tick never answered is not counted
        self._budget_tick = stamp
        budget.add_delivery(info, wall0, 'wbc_transport_in', 'wbc_wake')
        decoded = self._decoded(joint_state_from_cdr, data, 'joint_states')
        if decoded is None:
            return
        joints = decoded[1]
        t1 = clock()
        # The tick's other samples were published before joint_states; should one have been
        # lost (best effort), the sim's republish of the tick brings it again.
        self.state_input.drain(lambda: all(stamp in buffer for buffer in self._needed),
                               timeout=_STATE_WAIT)
        t2 = clock()
        budget.add('wbc_decode', t1 - t0)
        budget.add('wbc_take', t2 - t1)
        if not all(stamp in buffer for buffer in self._needed):
            self._warn(f'tick {stamp / _NS:.3f} s: imu or ground truth missing, waiting for '
                       'the republish')
            return
        base, contacts, odom_msg, contacts_msg = self._estimate(stamp, joints)
        t3 = clock()
        events = encode_contact_events(contacts, stamp)
        budget.add('wbc_state_msgs', clock() - t3)
        # Published right after the command (_command), so that the sim steps while they go
        # out; a tick not answered now (held for its plans) publishes them below, before the
        # wait: the planners need this tick's state to make those plans.
        self._unpublished = (odom_msg, contacts_msg, events)
        self._last_estimated = stamp
        self._state_msgs[stamp] = (odom_msg, contacts_msg)
        self._joints[stamp], self._odom[stamp], self._contacts[stamp] = joints, base, contacts
        self._on_state(stamp)
        self._publish_estimate()
        if self._last_answered == stamp:
            # The next ticks' joint_states straight from their DDS queue, not through the
            # executor (direct_take.py). A tick that must wait for its plans hands back to
            # the executor, which delivers them (footholds, com_plan).
            self._direct_states.run(lambda: self._waiting is None)

    def _publish_estimate(self) -> None:
        """odom, contacts (and contact_events) of the last estimated tick, once."""
        if self._unpublished is None:
            return
        t0 = time.perf_counter_ns()
        odom_msg, contacts_msg, events = self._unpublished
        self._unpublished = None
        self.odom_pub.publish(odom_msg)
        self.contacts_pub.publish(contacts_msg)
        if events is not None:
            self.events_pub.publish(events)
        self.budget.add('wbc_publish_state', time.perf_counter_ns() - t0)

    def _estimate(self, stamp: int, joints) -> tuple:
        """Base state and contacts of the tick (estimated or true) and their messages."""
        estimate = None
        if self.estimator is not None:
            t0 = time.perf_counter_ns()
            estimate = self.estimator.update(self._imu[stamp], joints)
            self.budget.add('wbc_estimator', time.perf_counter_ns() - t0)
        if self.state_estimation:
            base = estimate[0]
            odom_msg = encode_odom(base, stamp)
        else:
            odom_msg, base = self._truth_odom[stamp]
        if not self.contact_estimation:
            contacts_msg, contacts = self._truth_contacts[stamp]
            return base, contacts, odom_msg, contacts_msg
        contacts = estimate[1]
        if not self.state_estimation:      # the estimated forces at the true feet
            contacts = dataclasses.replace(contacts,
                                           foot_position=self.robot.foot_positions(base, joints))
        contacts_msg = encode_contacts(contacts, stamp)
        return base, contacts, odom_msg, contacts_msg

    def _forget_states_before(self, floor: int) -> None:
        """Drop the inputs and states older than ``floor`` (they can no longer be answered,
        nor answered again)."""
        for buffer in (self._joints, self._odom, self._contacts, self._state_msgs, self._imu,
                       self._truth_odom, self._truth_contacts):
            for old in [s for s in buffer if s < floor]:
                del buffer[old]

    def _on_footholds(self, msg: PointCloud2) -> None:
        plan = self._decoded(footholds_from_msg, msg, 'footholds')
        if plan is not None:
            self._keep(self._footholds, stamp_to_ns(msg.header.stamp), plan)
            self._plans_arrived()

    def _on_com_plan(self, data: bytes) -> None:
        # Raw: decoding the 201 points from the bytes takes 0.29 ms, through rclpy's message
        # 4.38 ms (python -m replan_ros.benchmarks.bench_msgs).
        decoded = self._decoded(com_plan_from_cdr, data, 'com_plan')
        if decoded is not None:
            self._keep(self._com_plans, *decoded)
            self._plans_arrived()

    @staticmethod
    def _keep(buffer: dict, stamp: int, value) -> None:
        buffer[stamp] = value
        while len(buffer) > _KEEP_PLANS:
            del buffer[min(buffer)]

    def _pair_stamps(self) -> list[int]:
        """Stamps (ns) with both footholds and com_plan, ascending."""
        return sorted(set(self._footholds) & set(self._com_plans))

    def _plans_arrived(self) -> None:
        """Event-driven end of a wait: answer the held tick once its plans are here."""
        if self._waiting is None:
            return
        pairs = self._pair_stamps()
        if self._waiting_first:
            ready = [s for s in pairs if s <= self._waiting]
        else:
            ready = [s for s in pairs if self._pending is not None and s == self._pending[0]]
        if not ready:
            return
        stamp = self._waiting
        self._end_wait()
        self._pending = None
        self._adopt(ready[-1], stamp, announced=not self._waiting_first)
        self._answer(stamp)

    def _wait_ended(self, stamp: int) -> None:
        """A held tick is answered now: its wait for plans goes into the budget."""
        if self._budget_tick != stamp:
            return
        if self._waiting_first:     # the first tick waits for the planners' start: not a tick
            self._budget_tick = None
        else:
            self.budget.add('wbc_plan_wait', time.perf_counter_ns() - self._wait_started_ns)

    # ------------------------------------------------------------------------------ ticks
    def _on_state(self, stamp: int) -> None:
        self._logic_start_ns = time.perf_counter_ns()
        if stamp in self._commands:                  # duplicate: the same command again
            self.cmd_pub.publish(self._commands[stamp])
            return
        if self._waiting is not None:
            if stamp <= self._waiting:
                return                               # still waiting for this tick's plans
            # The sim moved on without us (free-run): stop waiting, the inputs are stale.
            self._end_wait()
        if self._last_answered is not None and stamp <= self._last_answered:
            return                                   # an old stamp: nothing to answer
        if not self._listeners_ready and not self._listeners_subscribed():
            return          # the sim's republish of the tick (every 0.1 s) asks again
        self._tilt = trunk_tilt(self._odom[stamp].quaternion)
        if self._tilt <= self.wbc.params.fall_tilt:
            self._tilted_since = None
        elif self._tilted_since is None:
            self._tilted_since = stamp
        # Tilted for fall_time: one odd estimate is not a fall.
        if (self._fallen is None and self._tilted_since is not None
                and stamp - self._tilted_since >= self.fall_time_ns):
            self._fall(stamp)
        if self._fallen is not None:        # latched: no plan can right a fallen robot
            self._started = True
            self._answer_fallen(stamp)
            return
        t = stamp / _NS
        contacts = self._contacts[stamp]
        if not self._started:
            self._started = True
            pairs = [s for s in self._pair_stamps() if s <= stamp]
            if self._sat_down(stamp):
                # Started (again) on a robot that sat down in the sim's damping mode.
                self._enter_stand(stamp, 'started on a robot sitting: standing up first')
            elif pairs and self._ends_stand(pairs[-1], stamp):
                self._adopt(pairs[-1], stamp)
            elif pairs:
                self._enter_stand(stamp, 'started mid-plan: waiting for plans made for now')
            else:
                self._budget_logic()
                self._wait(stamp, first=True)
                return
        elif (self._last_answered is not None and stamp - self._last_answered > self.stale_gap_ns
              and self._stand is None):
            self._enter_stand(stamp, f'stale inputs: {(stamp - self._last_answered) / _NS:.3f} s '
                                     'since the last answered tick')
        # A newer plan pair than the active one (e.g. not announced by a touchdown we saw):
        # adopt it; this is also how a stand ends.
        # While a re-plan is pending its plans are not adopted before their time.
        newer = [s for s in self._pair_stamps()
                 if s <= stamp and (self._plan_stamp is None or s > self._plan_stamp)]
        if self._stand is not None:
            # Leave a stand only for a plan made for about now (wbc.plan_ends_stand).
            # After a stand-up, only plans made from the estimate started over then.
            newer = [s for s in newer
                     if s >= self._stand_floor and self._ends_stand(s, stamp)]
        # A robot that sat down (the sim's damping mode) stands up before it walks: a plan
        # from the low posture asks the MPC for a CoM it cannot keep in the support.
        if newer and self._pending is None and self._stand_up is None and (
                self._stand is not None or self._follower is not None):
            self._adopt(newer[-1], stamp)
        if self._follower is not None and self._stand is None:
            if self._pending is None:
                # Frozen while a re-plan is pending: the old plan's next lift-off waits for
                # the new plan (whose first lift-off is a four-feet phase after its trigger).
                self._follower.update(t, contacts)
                if self._follower.replan_due:
                    self._pending = (stamp, stamp + self.latency_ns)
            if self._pending is not None and stamp >= self._pending[1]:
                plan_stamp = self._pending[0]
                if plan_stamp in self._footholds and plan_stamp in self._com_plans:
                    self._pending = None
                    self._adopt(plan_stamp, stamp, announced=True)
                else:
                    self._budget_logic()
                    self._wait(stamp, first=False)
                    return
        self._answer(stamp)

    def _fall(self, stamp: int) -> None:
        """The trunk tilted beyond ``fall_tilt``: damp the joints from now on, until the
        node is restarted (docs/usage.md, "Faults and recovery")."""
        p = self.wbc.params
        self._fallen = (stamp / _NS, self._tilt)
        self._follower = None
        self._pending = None
        self._stand = None
        self._stand_up = None
        self.get_logger().error(
            f'fallen at t = {stamp / _NS:.3f} s: the trunk is tilted '
            f'{math.degrees(self._tilt):.0f} deg from upright (fall_tilt '
            f'{math.degrees(p.fall_tilt):.0f} deg): joints damped ({p.fall_damping:g} N m s/rad), '
            'plans ignored; restart the wbc once the robot is upright')

    def _answer_fallen(self, stamp: int) -> None:
        self._budget_logic()
        result = self.wbc.fallen(self._joints[stamp], self._contacts[stamp].contact)
        self._controller_done()
        self._command(stamp, result)

    def _budget_logic(self) -> None:
        """The plan logic of the tick so far (from _on_state or a wait's end)."""
        now = time.perf_counter_ns()
        self.budget.add('wbc_logic', now - self._logic_start_ns)
        self._logic_start_ns = now

    def _listeners_subscribed(self) -> bool:
        """True once every node of ``first_command_waits_for`` (e.g. the recorder's on-demand
        helper) subscribes to the estimate's topics: the sim does not move before our first
        command, so a bag then holds them from t = 0. After ``first_command_wait_timeout``
        wall s (a recorder told to leave one of them out, or one that died) it starts anyway
        and says which node does not listen to which topic: never a graph that waits forever."""
        missing = []
        for topic in ('odom', 'contacts', 'contact_events'):
            readers = {info.node_name for info in
                       self.get_subscriptions_info_by_topic(self.resolve_topic_name(topic))}
            missing += [f'{node} on {topic}'
                        for node in sorted(self.first_command_waits_for - readers)]
        if missing:
            now = time.monotonic()
            if self._listeners_deadline is None:
                self._listeners_deadline = now + self.first_command_wait_timeout
            if now < self._listeners_deadline:
                return False
            self.get_logger().warning(
                f'no subscription of {", ".join(missing)} after '
                f'first_command_wait_timeout ({self.first_command_wait_timeout:g} s): starting '
                'anyway; a bag misses these topics or their first samples')
        else:
            self.get_logger().info(f'{sorted(self.first_command_waits_for)} listen: starting')
        self._listeners_ready = True
        return True

    def _wait(self, stamp: int, first: bool) -> None:
        self._wait_started_ns = time.perf_counter_ns()
        self._logic_start_ns = None
        self._waiting = stamp
        self._waiting_first = first
        timeout = self.first_plan_timeout if first else self.plan_timeout
        self._wait_timer = self.create_timer(timeout, self._on_wait_timeout, clock=self._wall)

    def _end_wait(self) -> None:
        if self._waiting is not None:
            self._wait_ended(self._waiting)
        self._waiting = None
        if self._wait_timer is not None:
            self.destroy_timer(self._wait_timer)
            self._wait_timer = None

    def _on_wait_timeout(self) -> None:
        stamp = self._waiting
        if stamp is None:
            return
        first = self._waiting_first
        self._end_wait()
        self._plan_timeouts += 1
        self._period_timeouts += 1
        if first or self._follower is None:
            self.get_logger().warning(
                f'no plans after {self.first_plan_timeout if first else self.plan_timeout} s '
                f'at t = {stamp / _NS:.3f}: standing')
            self._enter_stand(stamp, 'no plan yet (plan_timeout)')
        else:
            plan_stamp = self._pending[0] if self._pending is not None else stamp
            self._pending = None
            self._missed_replans += 1
            self._missing = self._missing_plans(plan_stamp)
            if self._missed_replans >= self.missed_replans_to_stand:
                # The feet are all down at a re-plan touchdown: the safest moment to stop.
                self.get_logger().error(
                    f're-plan due at t = {stamp / _NS:.3f} s: {self._missing} missing '
                    f'{self._missed_replans} re-plans in a row (after {self.plan_timeout} s '
                    'each): a planner is gone')
                self._enter_stand(stamp, f'no {self._missing} for {self._missed_replans} '
                                         're-plans')
            else:
                self.get_logger().warning(
                    f're-plan due at t = {stamp / _NS:.3f} s: {self._missing} not there after '
                    f'{self.plan_timeout} s, going on with the old plans')
        self._answer(stamp)

    def _missing_plans(self, plan_stamp: int) -> str:
        """Which plans stamped ``plan_stamp`` never came, with the node that sends them."""
        missing = [f'{topic} ({node})' for topic, node, buffer in
                   (('footholds', 'gait', self._footholds), ('com_plan', 'mpc', self._com_plans))
                   if plan_stamp not in buffer]
        return ' and '.join(missing) or 'footholds/com_plan'

    def _adopt(self, plan_stamp: int, stamp: int, announced: bool = False) -> None:
        """Make the pair stamped ``plan_stamp`` active at tick ``stamp`` (``announced``: the
        re-plan our tracker expected, after the plan latency)."""
        footholds, com_plan = self._footholds[plan_stamp], self._com_plans[plan_stamp]
        self._follower = PlanFollower(footholds, com_plan, self.haptic_velocity,
                                      self.touchdown_depth)
        if stamp > plan_stamp:       # late: the plan latency, the first tick, or unannounced
            self._follower.update(stamp / _NS, self._contacts[stamp])
            if not announced:
                self.get_logger().info(f'adopted plans stamped {plan_stamp / _NS:.3f} s at '
                                       f'tick {stamp / _NS:.3f} s')
            first_liftoff = min((step.liftoff_time for step in footholds.steps), default=None)
            if announced and first_liftoff is not None and first_liftoff < stamp / _NS - 1e-9:
                self._warn(f'plan latency {self.latency_ns / _NS:.3f} s is longer than the '
                           'four-feet phase: the first swing of the plan stamped '
                           f'{plan_stamp / _NS:.3f} s starts late')
        self._plan_stamp = plan_stamp
        self._missed_replans = 0
        self._missing = ''
        if self._stand is not None:
            self.get_logger().info(f'plans stamped {plan_stamp / _NS:.3f} s: leaving the stand')
        self._stand = None

    def _ends_stand(self, plan_stamp: int, stamp: int) -> bool:
        return plan_ends_stand(self._footholds[plan_stamp], stamp / _NS, self.stand_adopt_age,
                               self.stand_adopt_lead)

    def _sat_down(self, stamp: int) -> bool:
        """The legs are folded (joint kinematics alone: the base estimate of a robot that
        sat down is not to be trusted)."""
        height = float(np.median(self.wbc.leg_heights(self._joints[stamp])))
        return height < self._standing_leg_height - self.sat_down_height

    def _enter_stand(self, stamp: int, reason: str) -> None:
        base, joints = self._odom[stamp], self._joints[stamp]
        com, _ = self.robot.com_state(base, joints)
        self._stand = StandHold(stamp / _NS, com, yaw_of(base.quaternion), self._contacts[stamp],
                                self.haptic_velocity)
        self._stand_reason = reason
        self._stand_since = stamp / _NS
        if self._stand_up is None and self._sat_down(stamp):
            p = self.wbc.params
            self._stand_up = JointStandUp(stamp / _NS, joints.position, self.standing_pose,
                                          p.stand_up_time, p.stand_up_hold)
            self.get_logger().warning(
                f'standing up at t = {stamp / _NS:.3f} s: the legs are folded (median '
                f'{np.median(self.wbc.leg_heights(joints)):.3f} m, standing '
                f'{self._standing_leg_height:.3f} m); joint-space stand-up in '
                f'{p.stand_up_time + p.stand_up_hold:.1f} s')
        self._follower = None
        self._pending = None
        self.get_logger().warning(f'standing at t = {stamp / _NS:.3f} s: {reason}')

    def _answer(self, stamp: int) -> None:
        if self._logic_start_ns is None:
            self._logic_start_ns = time.perf_counter_ns()   # answered after a wait
        t = stamp / _NS
        base, joints, contacts = self._odom[stamp], self._joints[stamp], self._contacts[stamp]
        if self._stand is None and self._follower is not None:
            plan = self._follower.com_plan
            if t - plan.start_time > self.plan_max_age or t > plan.end_time:
                self._enter_stand(stamp, f'plan stamped {plan.start_time:.3f} s is too old')
        if self._stand is None and self._follower is None:
            self._enter_stand(stamp, self._stand_reason)
        if self._stand_up is not None:
            self._answer_stand_up(stamp, joints, contacts)
            return
        if self._stand is not None:
            com_ref, yaw, stance, swing = self._stand.references(t, contacts)
            yaw_rate = 0.0
        else:
            com_ref, yaw, stance, swing = self._follower.references(t)
            yaw_rate = self._follower.yaw_rate(t)
        self._budget_logic()
        result = self.wbc.compute(base, joints, contacts.contact, com_ref, yaw, stance, swing,
                                  yaw_rate_reference=yaw_rate)
        self._controller_done()
        self._command(stamp, result)

    def _controller_done(self) -> None:
        now = time.perf_counter_ns()
        self.budget.add('wbc_controller', now - self._logic_start_ns)
        self._logic_start_ns = now

    def _answer_stand_up(self, stamp: int, joints, contacts: ContactState) -> None:
        """A tick of the joint-space stand-up; its last tick starts the base estimate over
        and the force-based stand takes over at the next tick, from the new estimate."""
        t = stamp / _NS
        self._budget_logic()
        result = self.wbc.stand_up(joints, self._stand_up, t, contacts.contact)
        self._controller_done()
        self._command(stamp, result)
        if self._stand_up.done(t):
            self._stand_up = None
            if self.estimator is not None:
                self.estimator.restart()
            self._stand = None
            self._stand_reason = 'stood up: waiting for plans made from here on'
            self._stand_floor = stamp + self.period_ns
            self.get_logger().info(f'stood up at t = {t:.3f} s: the base estimate starts over, '
                                   'plans stamped from the next tick on are adopted')

    def _command(self, stamp: int, result) -> None:
        """Publish and keep the torques answering tick ``stamp``; the per-tick bookkeeping."""
        msg = encode_torque_command(stamp, result.torque)     # exactly the stamp answered
        self.cmd_pub.publish(msg)
        counted = self._budget_tick == stamp
        if counted:
            self.budget.add('wbc_command', time.perf_counter_ns() - self._logic_start_ns)
        self._publish_estimate()
        if self.estimator is not None:
            # The next tick's covariance work, while the sim steps (prepare_next), for the
            # stamp's float seconds as the decoders will give them to the estimator.
            t0 = time.perf_counter_ns()
            self.estimator.prepare_next(ns_to_sec(stamp + self.period_ns))
            if counted:
                self.budget.add('wbc_estimator_next', time.perf_counter_ns() - t0)
        if counted:
            self.budget.end_tick()
            self._budget_tick = None
        self._logic_start_ns = None
        self._commands[stamp] = msg
        while len(self._commands) > _KEEP_COMMANDS:
            del self._commands[min(self._commands)]
        self._last_answered = stamp
        self._forget_states_before(stamp)
        self._ticks += 1
        self._times.append(result.compute_time)
        self._com_errors.append(float(np.linalg.norm(result.com_error)))
        self._last_result = result
        if result.fallback:
            self._fallbacks += 1
            self._period_fallbacks += 1
            self._warn(f'wbc fallback (safe stand torques): {result.message}')

    # ------------------------------------------------------------------------------ diagnostics
    def _publish_diagnostics(self) -> None:
        result = self._last_result
        if result is None:
            level, message = diagnostics.WARN, 'no state answered yet'
            values = {'waiting_for_plans': self._waiting is not None}
        else:
            # Figures over the period; a period without ticks (waiting) repeats the last one.
            times = np.array(self._times or [result.compute_time]) * 1e3
            errors = np.array(self._com_errors or [float(np.linalg.norm(result.com_error))])
            mode = ('fallen' if self._fallen is not None
                    else 'stand_up' if self._stand_up is not None
                    else 'stand' if self._stand is not None else 'plan')
            values = {
                'mode': mode,
                'trunk_tilt_deg': math.degrees(self._tilt),
                'fallen_at_s': self._fallen[0] if self._fallen is not None else '',
                'stand_reason': self._stand_reason if self._stand is not None else '',
                'stand_since_s': self._stand_since if self._stand is not None else '',
                'compute_time_ms': times[-1],
                'compute_time_median_ms': float(np.median(times)),
                'compute_time_max_ms': float(times.max()),
                'com_error_m': errors[-1],
                'com_error_max_m': float(errors.max()),
                'active_contacts': ''.join(str(int(c)) for c in result.active_contacts),
                'stance_legs': ''.join(str(int(c)) for c in result.stance),
                'qp_status': result.qp_status,
                'qp_iterations': result.qp_iterations,
                'saturated_joints': result.saturated,
                'plan_stamp': (self._plan_stamp / _NS if self._plan_stamp is not None else ''),
                'last_tick': self._last_answered / _NS,
                'ticks': self._ticks,
                'plan_timeouts': self._plan_timeouts,
                'missed_replans': self._missed_replans,
                'missing_plans': self._missing,
                'state_estimation': self.state_estimation,
                'contact_estimation': self.contact_estimation,
                'plan_latency_s': self.latency_ns / _NS,
                'plan_pending': self._pending is not None,
                'fallbacks': self._fallbacks,
                'waiting_for_plans': self._waiting is not None,
                # Estimator updates that used the covariance step prepared after the last
                # command (StateEstimator.prepare_next); most of the ticks while walking.
                'estimator_prepared_steps': (self.estimator.prepared_used
                                             if self.estimator is not None else 0),
            }
            if self._fallen is not None:
                level, message = diagnostics.ERROR, (
                    f'fallen at t = {self._fallen[0]:.3f} s (trunk tilted '
                    f'{math.degrees(self._fallen[1]):.0f} deg): joints damped, plans ignored; '
                    'restart the wbc once the robot is upright')
            elif self._period_fallbacks:
                level, message = diagnostics.ERROR, f'{self._period_fallbacks} fallback ticks'
            elif self._stand is not None and self._missed_replans:
                level, message = diagnostics.ERROR, f'standing: {self._stand_reason}'
            elif self._period_timeouts:
                level, message = (diagnostics.WARN, f'plan timeout: no '
                                  f'{self._missing or "footholds/com_plan"} in time, went on '
                                  'with the old plans')
            elif self._stand is not None:
                level, message = diagnostics.WARN, f'standing: {self._stand_reason}'
            else:
                level, message = diagnostics.OK, 'tracking the plan'
            values.update(self.budget.period_values())
        self._times.clear()
        self._com_errors.clear()
        self._period_timeouts = 0
        self._period_fallbacks = 0
        stamp = (ns_to_stamp(self._last_answered) if self._last_answered is not None
                 else self.get_clock().now().to_msg())
        self.diag_pub.publish(diagnostics.array(stamp, diagnostics.status('wbc', level, message,
                                                                          values)))

    def destroy_node(self) -> None:
        if self.budget.ticks:
            self.get_logger().info(self.budget.log_line('wbc'))
        self.state_input.destroy()
        super().destroy_node()


def main(args=None):
    run_node(WbcNode, args)


if __name__ == '__main__':
    main()
