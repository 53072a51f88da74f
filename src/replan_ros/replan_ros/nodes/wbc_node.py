"""Whole-body controller node `wbc`: state estimation and the controller side of the lock-step
and re-plan protocol (docs/wbc.md, "Node `wbc`"; docs/ARCHITECTURE.md, "Time and lock-step",
"Re-plan protocol").

It wakes on the sim's `joint_states`, takes the tick's `imu` (or the truth) from its queue, runs
the state estimator (`replan_core.estimation.estimator`) once per tick, lets the protocol
(`replan_core.wbc.tick_protocol`) decide what the tick tracks, answers with one `joint_torque_cmd`
stamped with the tick and publishes the estimate (`odom`, `contacts`, `contact_events`) while
the sim steps. A republished tick gets the same estimate and command again. A tick the protocol
holds for its plans is answered from the plan callbacks, or by a one-shot wall-clock timer
armed and cancelled as the protocol's ``PlanWait`` says (`plan_timeout`); the estimates and
commands a republished tick gets again are the protocol's ``AnsweredTicks``. After a command,
the next `joint_states` are taken straight from their DDS queue (`transport.direct_take`) until
a tick waits. Every answered tick is timed by phase (`telemetry.tick_budget.PhaseTimer`;
docs/ARCHITECTURE.md, "Per-tick budget").
"""

from __future__ import annotations

import time

from diagnostic_msgs.msg import DiagnosticArray
from nav_msgs.msg import Odometry
from rclpy.clock import Clock, ClockType
from rclpy.node import Node
from sensor_msgs.msg import JointState as JointStateMsg
from sensor_msgs.msg import PointCloud2
from trajectory_msgs.msg import MultiDOFJointTrajectory

from replan_core.estimation.estimator import StateEstimator
from replan_core.robot.model import RobotModel
from replan_core.robot.robot_file import default_urdf
from replan_core.wbc.controller import WholeBodyController
from replan_core.wbc.tick_protocol import AnsweredTicks, ControllerProtocol, PlanWait
from replan_ros.messages.com_plan import com_plan_from_cdr
from replan_ros.messages.contacts import encode_contact_events
from replan_ros.messages.footholds import footholds_from_msg
from replan_ros.messages.joint_state import encode_torque_command, joint_state_from_cdr
from replan_ros.messages.stamps import ns_to_sec, ns_to_stamp, stamp_to_ns
from replan_ros.nodes.node_main import load_node_robot, log_at, run_node
from replan_ros.nodes.wbc_inputs import TickInputs
from replan_ros.params import (
    declare_node_parameters,
    estimator_params,
    protocol_params,
    wbc_params,
)
from replan_ros.params.robot import project_root
from replan_ros.telemetry import diagnostics
from replan_ros.telemetry.tick_budget import WBC_PHASES, PhaseTimer, TickBudget
from replan_ros.telemetry.wbc_status import ControllerStats
from replan_ros.transport.direct_take import DirectTake
from replan_ros.transport.listeners import ListenersGate
from replan_ros.transport.qos import (
    COMMAND,
    COMMAND_PUB,
    CONTACTS_PUB,
    INTERNAL_PUB_EVENTS,
    INTERNAL_SUB_EVENTS,
    LATCHED,
    SENSOR,
    SENSOR_PUB,
)
from replan_ros.transport.stamped_buffer import cdr_header_stamp_ns

_NS = 1_000_000_000
_STATE_WAIT = 0.01       # wall s to wait for the imu / ground truth of a joint_states tick


class WbcNode(Node):
    """Answers every state stamp of the simulator with joint torques."""

    def __init__(self) -> None:
        super().__init__('wbc')
        # The parameters and their ranges: params.WBC, estimator.<field> included.
        p = declare_node_parameters(self, 'wbc', on_change=self._on_parameter_change)
        self.state_estimation = bool(p['state_estimation'])
        self.contact_estimation = bool(p['contact_estimation'])
        # The robot file's model; its names map to the project's (topics keep those).
        robot = load_node_robot(self, p, default_urdf(project_root()))
        urdf = robot.urdf
        try:
            self.robot = RobotModel(urdf, robot.joints, robot.feet)
        except Exception as err:   # any load error: without a model there is nothing to control
            # with; exit non-zero so that the launcher reports it (and respawns, up to a limit)
            self.get_logger().fatal(f'cannot load the URDF {urdf!r} ({err}): exiting')
            raise SystemExit(1) from None
        self.wbc = WholeBodyController(self.robot, wbc_params(p))
        # The decisions of every tick (plans, waits, stand, stand-up, fall).
        self.protocol = ControllerProtocol(self.wbc, protocol_params(p),
                                           p['standing_joint_positions'], log=self._log)
        # The wall-clock timeout of a held tick: which ROS timer to arm or cancel.
        self.plan_wait = PlanWait(self.protocol, float(p['plan_timeout']),
                                  float(p['first_plan_timeout']))
        self._wait_timer = None
        self.period_ns = self.protocol.period_ns
        self.estimator: StateEstimator | None = None
        if self.state_estimation or self.contact_estimation:
            # The controller's model: the estimator keeps a pinocchio data of its own.
            try:
                self.estimator = StateEstimator(self.robot, estimator_params(p),
                                                dt=self.period_ns / _NS)
            except ValueError as err:   # a combination the tables cannot see (gain vs rate)
                self.get_logger().fatal(f'config error: wbc: {err} (control_rate '
                                        f'{p["control_rate"]} Hz)')
                raise SystemExit(2) from None

        # Each estimated tick's (base, joints, contacts) and (odom, contacts) messages, and the
        # serialized commands answered.
        self.ticks = AnsweredTicks()
        self._wall = Clock(clock_type=ClockType.STEADY_TIME)
        self.stats = ControllerStats()         # /diagnostics figures over a period
        self.budget = TickBudget(WBC_PHASES)
        self.timing = PhaseTimer(self.budget)
        # (stamp, odom, contacts, events) of the last estimated tick, not yet published
        self._unpublished: tuple | None = None
        self._joint_states_received = 0      # since start, for /diagnostics

        self.cmd_pub = self.create_publisher(JointStateMsg, 'joint_torque_cmd', COMMAND_PUB,
                                             event_callbacks=INTERNAL_PUB_EVENTS)
        self.diag_pub = self.create_publisher(DiagnosticArray, '/diagnostics', COMMAND,
                                              event_callbacks=INTERNAL_PUB_EVENTS)
        self.odom_pub = self.create_publisher(Odometry, 'odom', SENSOR_PUB,
                                              event_callbacks=INTERNAL_PUB_EVENTS)
        self.contacts_pub = self.create_publisher(PointCloud2, 'contacts', CONTACTS_PUB,
                                                  event_callbacks=INTERNAL_PUB_EVENTS)
        self.events_pub = self.create_publisher(PointCloud2, 'contact_events', CONTACTS_PUB,
                                                event_callbacks=INTERNAL_PUB_EVENTS)
        # The first command lets the sim move: only once these nodes listen to the estimate
        # and the commands, and only then is the estimate published (_publish_estimate).
        try:
            self._listeners = ListenersGate(
                self, {'odom': self.odom_pub, 'contacts': self.contacts_pub,
                       'contact_events': self.events_pub, 'joint_torque_cmd': self.cmd_pub},
                p['first_command_waits_for'], float(p['first_command_wait_timeout']))
        except ValueError as err:
            self.get_logger().fatal(f'config error: wbc: first_command_waits_for: {err}')
            raise SystemExit(2) from None
        # One wake-up per tick, on joint_states: the sim publishes the imu (and, to a controller
        # that reads it, the truth) before them, so they are queued by then, and are taken from
        # their queues (on_demand.py; waited for up to _STATE_WAIT if late).
        joint_states_sub = self.create_subscription(
            JointStateMsg, 'joint_states', self._on_joint_states, SENSOR,
            event_callbacks=INTERNAL_SUB_EVENTS, raw=True)
        self.inputs = TickInputs(self, self.robot, self.estimator, self.state_estimation,
                                 self.contact_estimation, self.budget, self._warn)
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
            f'wbc ready: {urdf}, mass {self.robot.total_mass:.2f} kg, {sources}, plan_timeout '
            f'{self.plan_wait.plan_timeout} s')

    def _on_parameter_change(self, name: str, value) -> None:
        """A run-time change of one of the writable parameters (params.WBC)."""
        if name == 'plan_timeout':
            self.plan_wait.plan_timeout = float(value)

    def _warn(self, text: str) -> None:
        self.get_logger().warning(text, throttle_duration_sec=2.0)

    def _log(self, level: str, text: str) -> None:
        """The protocol's log lines (tick_protocol.Log)."""
        if level == 'warning_throttled':
            self._warn(text)
        else:
            log_at(self.get_logger(), level, text)

    # ------------------------------------------------------------------------------ inputs
    def _on_joint_states(self, data: bytes, info: dict) -> None:
        """A serialized ``joint_states`` (subscribed raw: messages.joint_state decodes it)."""
        timing = self.timing
        timing.mark()
        wall0 = time.time_ns()
        self._joint_states_received += 1
        stamp = cdr_header_stamp_ns(data)
        if stamp is None:
            self._warn('rejected joint_states: too short for a header')
            return
        estimate = self.ticks.estimate(stamp)
        if estimate is not None:
            # The sim republished a tick we have estimated: the same state and command again
            # (a lost odom, contacts or command heals; the estimator never runs twice). An
            # estimate held back for the listeners goes out now if they are there.
            if self._unpublished is not None and self._unpublished[0] == stamp:
                self._publish_estimate()
            elif self._unpublished is None:
                odom_msg, contacts_msg = estimate
                self.odom_pub.publish(odom_msg)
                self.contacts_pub.publish(contacts_msg)
            self._on_state(stamp)
            return
        if not self.ticks.is_new(stamp):
            return                                   # an old stamp: nothing to answer
        timing.open(stamp)
        self.budget.add_delivery(info, wall0, 'wbc_transport_in', 'wbc_wake')
        decoded = self.inputs.decoded(joint_state_from_cdr, data, 'joint_states')
        if decoded is None:
            return
        joints = decoded[1]
        timing.lap('wbc_decode')
        # The tick's other samples were published before joint_states; should one have been
        # lost (best effort), the sim's republish of the tick brings it again.
        complete = self.inputs.take(stamp, timeout=_STATE_WAIT)
        timing.lap('wbc_take')
        if not complete:
            self._warn(f'tick {stamp / _NS:.3f} s: imu or ground truth missing, waiting for '
                       'the republish')
            return
        base, contacts, odom_msg, contacts_msg = self.inputs.state(stamp, joints,
                                                                   self.protocol.swinging_legs)
        timing.mark()
        events = encode_contact_events(contacts, stamp)
        timing.lap('wbc_state_msgs')
        # Published right after the command (_command), so that the sim steps while they go
        # out; a tick not answered now (held for its plans) publishes them below, before the
        # wait: the planners need this tick's state to make those plans.
        self._unpublished = (stamp, odom_msg, contacts_msg, events)
        self.ticks.estimated(stamp, (base, joints, contacts), (odom_msg, contacts_msg))
        self._on_state(stamp)
        self._publish_estimate()
        if self.protocol.last_answered == stamp:
            # The next ticks' joint_states straight from their DDS queue, not through the
            # executor (direct_take.py). A tick that must wait for its plans hands back to
            # the executor, which delivers them (footholds, com_plan).
            self._direct_states.run(lambda: self.protocol.waiting is None)

    def _publish_estimate(self) -> None:
        """odom, contacts (and contact_events) of the last estimated tick, once. Held back
        until the nodes of ``first_command_waits_for`` listen and are matched: a sample
        published before a reader matched never reaches it, so whether the bag holds the
        estimate of t = 0 would depend on when the recorder matched. The sim republishes the tick
        it waits at, which brings the estimate back here; the first command waits for the
        same listeners, so the estimate of every answered tick goes out."""
        if self._unpublished is None or not self._listeners.ready():
            return
        start = self.timing.clock()
        _stamp, odom_msg, contacts_msg, events = self._unpublished
        self._unpublished = None
        self.odom_pub.publish(odom_msg)
        self.contacts_pub.publish(contacts_msg)
        if events is not None:
            self.events_pub.publish(events)
        self.timing.add_since('wbc_publish_state', start)

    def _on_footholds(self, msg: PointCloud2) -> None:
        plan = self.inputs.decoded(footholds_from_msg, msg, 'footholds')
        if plan is not None:
            self._answer_held(self.protocol.add_footholds(stamp_to_ns(msg.header.stamp), plan))

    def _on_com_plan(self, data: bytes) -> None:
        # Raw: decoding the 201 points from the bytes takes 0.29 ms, through rclpy's message
        # 4.38 ms (python -m replan_experiments.benchmarks.bench_msgs).
        decoded = self.inputs.decoded(com_plan_from_cdr, data, 'com_plan')
        if decoded is not None:
            self._answer_held(self.protocol.add_com_plan(*decoded))

    def _answer_held(self, stamp: int | None) -> None:
        """Event-driven end of a wait: the held tick whose plans arrived, answered now."""
        self._sync_wait()
        if stamp is not None:
            self._answer(stamp)

    # ------------------------------------------------------------------------------ ticks
    def _on_state(self, stamp: int) -> None:
        self.timing.mark()
        command = self.ticks.command(stamp)
        if command is not None:                      # duplicate: the same command again
            self.cmd_pub.publish(command)
            return
        answer = self.protocol.on_tick(stamp, *self.ticks.state(stamp),
                                       may_start=self._listeners.ready)
        self._sync_wait()
        if answer:
            self._answer(stamp)

    def _sync_wait(self) -> None:
        """Cancel and arm the wall-clock timer of a held tick as ``PlanWait`` says; a wait
        that ends goes into the budget (a re-plan tick's, not the first tick's, which waits
        for the planners' start)."""
        timing = self.timing
        change = self.plan_wait.sync(timing.clock())
        if change is None:
            return
        if change.ended is not None:
            if timing.counts(change.ended):
                if change.ended_first:
                    timing.drop()
                else:
                    self.budget.add('wbc_plan_wait', change.waited_ns)
            self.destroy_timer(self._wait_timer)
            self._wait_timer = None
        if change.arm is not None:
            timing.lap('wbc_logic')
            timing.unmark()
            self._wait_timer = self.create_timer(change.arm, self._on_wait_timeout,
                                                 clock=self._wall)

    def _on_wait_timeout(self) -> None:
        stamp = self.plan_wait.timed_out()
        self._sync_wait()
        if stamp is not None:
            self.stats.timed_out()
            self._answer(stamp)

    def _answer(self, stamp: int) -> None:
        timing = self.timing
        if timing.mark_ns is None:
            timing.mark()                            # answered after a wait
        timing.lap('wbc_logic')
        result = self.protocol.control(stamp)
        timing.lap('wbc_controller')
        self._command(stamp, result)
        # A stand-up that ended: the base estimate starts over (the protocol adopts plans
        # made from the next tick on).
        if self.protocol.answered(stamp) and self.estimator is not None:
            self.estimator.restart()

    def _command(self, stamp: int, result) -> None:
        """Publish and keep the torques answering tick ``stamp``; the per-tick bookkeeping."""
        msg = encode_torque_command(stamp, result.torque)     # exactly the stamp answered
        self.cmd_pub.publish(msg)
        timing = self.timing
        counted = timing.counts(stamp)
        if counted:
            timing.lap('wbc_command')
        self._publish_estimate()
        if self.estimator is not None:
            # The next tick's covariance work, while the sim steps (prepare_next), for the
            # stamp's float seconds as the decoders will give them to the estimator.
            start = timing.clock()
            self.estimator.prepare_next(ns_to_sec(stamp + self.period_ns))
            if counted:
                timing.add_since('wbc_estimator_next', start)
        if counted:
            timing.close()
        timing.unmark()
        # Older ticks can no longer be answered, nor answered again: their inputs go.
        self.ticks.answered(stamp, msg)
        self.inputs.forget_before(stamp)
        self.stats.answered(result)
        if result.fallback:
            self._warn(f'wbc fallback (safe stand torques): {result.message}')

    # ------------------------------------------------------------------------------ diagnostics
    def _publish_diagnostics(self) -> None:
        protocol = self.protocol
        level, message, values = self.stats.status(protocol, {
            'state_estimation': self.state_estimation,
            'contact_estimation': self.contact_estimation,
            'joint_states_received': self._joint_states_received,
            # Estimator updates that used the covariance step prepared after the last
            # command (StateEstimator.prepare_next); most of the ticks while walking.
            'estimator_prepared_steps': (self.estimator.prepared_used
                                         if self.estimator is not None else 0),
        })
        if self.stats.ticks:
            values.update(self.budget.period_values())
        stamp = (ns_to_stamp(protocol.last_answered) if protocol.last_answered is not None
                 else self.get_clock().now().to_msg())
        self.diag_pub.publish(diagnostics.array(stamp, diagnostics.status('wbc', level, message,
                                                                          values)))

    def destroy_node(self) -> None:
        if self.budget.ticks:
            self.get_logger().info(self.budget.log_line('wbc'))
        self.inputs.destroy()
        super().destroy_node()


def main(args=None):
    run_node(WbcNode, args)


if __name__ == '__main__':
    main()
