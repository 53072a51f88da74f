"""Simulator node `sim`: the PyBullet world behind a robot-driver interface; it owns time.

It publishes what a robot's sensors measure: `imu` (gyro and accelerometer with noise and bias)
and `joint_states` (encoders and joint torque sensors with noise), and, for metrics and bags
only, the truth: `ground_truth/odom` and `ground_truth/contacts` (the simulator's exact pose,
twist and ground reaction forces; built and published only while someone reads them, as is
the `imu`). The state estimator lives in the controller's process
(wbc_node), which publishes the estimated `odom` and `contacts` the planners use.

Lock-step (docs/ARCHITECTURE.md, "Time and lock-step"): at tick t_k it publishes imu and
joint_states (the controller wakes on them), then, while the controller computes, /clock,
ground_truth/odom and ground_truth/contacts, all stamped t_k, and runs the first physics steps
of the next period that the actuator delay keeps from the coming command; it waits for the
joint_torque_cmd stamped t_k (straight from its DDS queue, outside the executor, for runs of
ticks: direct_take.py), applies it for the rest of the control period and publishes t_{k+1}.
Without that command it republishes the same samples of t_k every `republish_period` (the
noise is drawn once per tick, so a republish is identical); after `command_timeout` wall
seconds without one (the controller is dead) it free-runs in real time with joint damping so
the robot sits down, reports ERROR on /diagnostics, and returns to lock-step as soon as the
controller answers again. Before the first command the sim does not advance.

The realistic robot (config/profiles/realistic.yaml) is made of separate parameters, each off
in config/sim.yaml (the ideal world): actuator lag, delay, joint friction and torque limits;
IMU and joint sensor noise (seeded by `noise_seed`); a payload and leg mass errors that the
controller's model does not know; compliant feet.

Every lock-step tick is timed by phase (tick_budget.py; docs/ARCHITECTURE.md, "Per-tick
budget"): the command's DDS transport and this process's wake-up (from the message info),
decoding, physics, sensing, conversion to messages, each publish, the work done while the
controller computes, and the wait from the `joint_states` publish to the next command (the
round trip through the controller); the
figures are in /diagnostics (`tick_<phase>_median_ms`, `tick_<phase>_mean_ms`) and in one log
line at shutdown.
"""

from __future__ import annotations

import math
import os
import time
from collections import deque
from pathlib import Path

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import WrenchStamped
from nav_msgs.msg import Odometry
from rclpy.node import Node
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import Imu, JointState, PointCloud2

from replan_core.inputs import WrenchSchedule
from replan_core.robot_variant import perturbed_urdf
from replan_core.sensors import ImuSensor, JointSensor
from replan_core.sim_world import STANDING_POSE, SimWorld
from replan_core.types import JOINT_NAMES, WORLD_FRAME
from replan_ros.messages.interfaces import ns_to_stamp, sec_to_ns, stamp_to_ns
from replan_ros.messages.tick_cdr import (
    encode_contacts,
    encode_imu,
    encode_joint_state,
    encode_odom,
    torque_command_from_cdr,
)
from replan_ros.nodes.node_main import run_node
from replan_ros.params import (
    actuator_params,
    declare_node_parameters,
    imu_noise_params,
    joint_sensor_params,
)
from replan_ros.telemetry import diagnostics
from replan_ros.telemetry.tick_budget import TickBudget
from replan_ros.transport import qos
from replan_ros.transport.direct_take import DirectTake
from replan_ros.transport.on_demand import helper_name
from replan_ros.transport.stamped_buffer import cdr_header_stamp_ns

WAITING, LOCK_STEP, FREE_RUN, DAMPING = 'waiting_first_command', 'lock_step', 'free_run', 'damping'
_LOG_THROTTLE = 1.0          # wall s between two log lines of the same kind
_MAX_CATCH_UP_TICKS = 25     # free-run: ticks stepped at most per timer call before slipping
_WATCHDOG_PERIOD = 0.02      # wall s
# Phases of a lock-step tick, from the command's arrival to the next one (tick_budget.py).
BUDGET_PHASES = (
    'sim_transport_cmd',          # joint_torque_cmd: wbc's DDS write -> our DDS reader
    'sim_wake',                   # our DDS reader -> _on_command (executor, take, deserialize)
    'sim_decode',                 # the command to torques
    'sim_physics',                # the physics steps of one control period after the lead ones
    'sim_sensing',                # IMU and joint sensor models
    'sim_conversion',             # imu and joint_states messages built
    'sim_publish_imu',
    'sim_publish_joint_states',
    'sim_truth_first',            # truth_first: the truth sensed, built and published first
    'sim_wait',                   # joint_states published -> the next command's callback
    # While the controller works (after joint_states, inside sim_wait):
    'sim_truth_sensing',          # the simulator's exact base state and contact forces
    'sim_truth_conversion',       # their messages built
    'sim_publish_truth_odom',
    'sim_publish_truth_contacts',
    'sim_publish_clock',
    'sim_lead_physics',           # due wrenches, the next period's lead physics steps
    'sim_tick',                   # wall time between two commands' callbacks
)


def _default_urdf() -> str:
    env = os.environ.get('REPLAN_URDF', '')
    if env:
        return env
    return str(Path(__file__).resolve().parents[4] / 'urdf' / 'hyq.urdf')


class SimNode(Node):
    """PyBullet simulator: torques in, sensed state, contact events and /clock out."""

    def __init__(self) -> None:
        super().__init__('sim')
        p = self._declare_parameters()
        urdf = p['urdf_path'] or _default_urdf()
        terrain_params = {
            'step_x': p['terrain_step_x'], 'step_height': p['terrain_step_height'],
            'step_length': p['terrain_step_length'], 'width': p['terrain_width'],
            'rough_start_x': p['terrain_rough_start_x'],
            'rough_length': p['terrain_rough_length'],
            'rough_amplitude': p['terrain_rough_amplitude'],
            'rough_resolution': p['terrain_rough_resolution']}
        standing = np.array(p['standing_joint_positions'], dtype=float)
        if standing.shape != (len(JOINT_NAMES),) or not np.all(np.isfinite(standing)):
            self.get_logger().error(
                f'standing_joint_positions needs {len(JOINT_NAMES)} finite values; '
                'using HyQ standing pose')
            standing = STANDING_POSE.copy()
        model_urdf = urdf
        actuator = actuator_params(p)
        try:
            urdf = self._robot_urdf(urdf, p)
            self.world = SimWorld(
                urdf, physics_dt=p['physics_dt'], control_period=p['control_period'],
                actuator=actuator, contact_stiffness=p['contact_stiffness'],
                contact_damping=p['contact_damping'],
                initial_joint_positions=standing,
                initial_base_height=p['initial_base_height'] or None,
                terrain=p['terrain'], terrain_params=terrain_params,
                contact_threshold=p['contact_threshold'], debounce_ticks=p['debounce_ticks'],
                friction=p['friction'], gui=p['gui'], seed=p['seed'])
        except Exception as err:   # a missing or malformed URDF (PyBullet, XML, OS errors)
            self.get_logger().fatal(f'cannot load the URDF {urdf!r} ({err}): exiting')
            raise SystemExit(1) from None
        dt = p['control_period']
        imu_noise = imu_noise_params(p)
        self.imu_sensor = ImuSensor(imu_noise, dt, p['noise_seed'])
        self.joint_sensor = JointSensor(joint_sensor_params(p), dt, p['noise_seed'])
        # Variances of one sample, for the Imu message's covariances.
        self._gyro_variance = imu_noise.gyro_noise_density ** 2 / dt
        self._accel_variance = imu_noise.accel_noise_density ** 2 / dt
        self._tick_messages: list = []      # the samples of the current tick, drawn once
        self._tick_sources: list = []
        self.budget = TickBudget(BUDGET_PHASES)
        self._tick_start_ns: int | None = None     # perf_counter_ns of the last lock-step
        self._published_ns: int | None = None      # command, and of its joint_states publish
        self.lock_step: bool = p['lock_step']
        # Hold at the first tick at or after stop_time (0: never): a run ends at one tick.
        self._stop_ns = sec_to_ns(p['stop_time']) if p['stop_time'] > 0.0 else None
        self._held_logged = False
        # Whether the controller reads the truth (the ideal world): then the truth goes out
        # before imu/joint_states, so that it does not wait for it. Derived from the graph
        # when lock-step starts (_controller_reads_truth), not configured.
        self.truth_first = False
        self.republish_period: float = p['republish_period']
        self.command_timeout: float = p['command_timeout']
        self.damping_gain: float = p['damping_gain']
        self.damping_abduction_stiffness: float = p['damping_abduction_stiffness']
        self.rtf_target: float = max(p['real_time_factor'], 1e-3)

        self.clock_pub = self.create_publisher(Clock, '/clock', qos.CLOCK,
                                               event_callbacks=qos.INTERNAL_PUB_EVENTS)
        self.truth_odom_pub = self.create_publisher(Odometry, 'ground_truth/odom', qos.SENSOR_PUB,
                                                    event_callbacks=qos.INTERNAL_PUB_EVENTS)
        self.truth_contacts_pub = self.create_publisher(
            PointCloud2, 'ground_truth/contacts', qos.CONTACTS,
            event_callbacks=qos.INTERNAL_PUB_EVENTS)
        self.imu_pub = self.create_publisher(Imu, 'imu', qos.SENSOR_PUB,
                                             event_callbacks=qos.INTERNAL_PUB_EVENTS)
        self.joint_pub = self.create_publisher(JointState, 'joint_states', qos.SENSOR_PUB,
                                               event_callbacks=qos.INTERNAL_PUB_EVENTS)
        self.applied_pub = self.create_publisher(WrenchStamped, 'applied_wrench', qos.SCHEDULE,
                                                 event_callbacks=qos.INTERNAL_PUB_EVENTS)
        self.diag_pub = self.create_publisher(DiagnosticArray, '/diagnostics', qos.COMMAND,
                                              event_callbacks=qos.INTERNAL_PUB_EVENTS)
        self.cmd_topic = self.resolve_topic_name('joint_torque_cmd')
        command_sub = self.create_subscription(
            JointState, 'joint_torque_cmd', self._on_command, qos.COMMAND,
            event_callbacks=qos.INTERNAL_SUB_EVENTS, raw=True)
        wrench_sub = self.create_subscription(WrenchStamped, 'external_wrench', self._on_wrench,
                                              qos.SCHEDULE)
        # A wrench goes to the executor as soon as it comes (direct_take.py).
        self._direct_commands = DirectTake(self, command_sub, self._on_command,
                                           watched=(wrench_sub,))

        self.mode = WAITING
        self.command = np.zeros(len(JOINT_NAMES))     # last accepted (safe) command, N m
        self.last_command_wall = time.monotonic()
        self.last_publish_wall = 0.0
        self.rejected = 0
        self.ignored = 0
        self._log_times: dict[str, float] = {}
        self.wrenches = WrenchSchedule()
        self._rtf_samples: deque[tuple[float, float]] = deque()
        self._free_ref = (0.0, 0)                     # (wall, tick) where free-running began
        self._damping_since = 0.0                     # sim s the last damping mode began

        self._clock_every = max(1, round(p['clock_period'] / p['control_period']))
        self.free_timer = self.create_timer(p['control_period'] / self.rtf_target,
                                            self._on_free_run_timer)
        self.free_timer.cancel()
        self.create_timer(_WATCHDOG_PERIOD, self._on_watchdog)
        self.create_timer(p['diagnostics_period'], self._on_diagnostics)
        self._sense()
        self._sense_truth()
        self._publish_state(with_clock=True)
        stepping = 'lock-step' if self.lock_step else 'free-run'
        variant = '' if urdf == model_urdf else f' (the controller\'s model: {model_urdf})'
        self.get_logger().info(
            f'sim: {urdf}{variant} on {p["terrain"]} terrain, {stepping}, tick '
            f'{p["control_period"]} s, physics {p["physics_dt"]} s; '
            'waiting for the first joint_torque_cmd')

    def _robot_urdf(self, urdf: str, p: dict) -> str:
        """The simulated robot: the model, or a copy with a payload and leg mass errors
        (payload_offset: 3 values within [-1, 1] m, checked by params.SIM)."""
        return perturbed_urdf(urdf, payload_mass=p['payload_mass'],
                              payload_offset=np.array(p['payload_offset'], dtype=float),
                              leg_mass_error=p['leg_mass_error'], seed=p['noise_seed'])

    # ------------------------------------------------------------------ parameters
    def _declare_parameters(self) -> dict:
        """Declared from params.SIM (defaults, units, ranges); a bad value exits with 2."""
        return declare_node_parameters(self, 'sim', on_change=self._on_parameter_change)

    def _on_parameter_change(self, name: str, value) -> None:
        """A run-time change of one of the writable parameters (params.SIM)."""
        if name == 'damping_gain':
            self.damping_gain = float(value)
        elif name == 'damping_abduction_stiffness':
            self.damping_abduction_stiffness = float(value)

    # ------------------------------------------------------------------ helpers
    def _log_throttled(self, level: str, key: str, text: str) -> None:
        now = time.monotonic()
        if now - self._log_times.get(key, -math.inf) >= _LOG_THROTTLE:
            self._log_times[key] = now
            getattr(self.get_logger(), level)(text)

    @property
    def now_ns(self) -> int:
        """Current sim time (the state stamp), ns."""
        return sec_to_ns(self.world.time)

    def _sense(self) -> None:
        """Measure the current tick's sensors once (drawn once, republished as they are)."""
        w = self.world
        t0 = time.perf_counter_ns()
        omega_body, specific_force = w.imu_truth()
        imu = self.imu_sensor.measure(w.time, omega_body, specific_force)
        joints = self.joint_sensor.measure(w.joint_state())
        t1 = time.perf_counter_ns()
        # Serialized when first published to a reader: a topic nobody reads (the truth without
        # the recorder, the imu in the ideal profile) costs nothing (volatile topics: a sample
        # published to no reader is lost anyway). The samples are drawn all the same. The
        # messages are CDR bytes written by hand (tick_cdr.py), which rclpy publishes as they
        # are.
        self._tick_sources = [
            None, None, (self.imu_pub, encode_imu,
                         (imu, self._gyro_variance, self._accel_variance))]
        self._tick_messages = [None, None, None, encode_joint_state(joints)]
        self._tick_message(2)
        budget = self.budget
        budget.add('sim_sensing', t1 - t0)
        budget.add('sim_conversion', time.perf_counter_ns() - t1)

    def _sense_truth(self, timed: bool = True) -> None:
        """The current tick's truth (read before the next period's lead physics steps)."""
        w = self.world
        t0 = time.perf_counter_ns()
        self._tick_sources[0] = (self.truth_odom_pub, encode_odom, (w.base_state(),))
        self._tick_sources[1] = (self.truth_contacts_pub, encode_contacts, (w.contact_state(),))
        t1 = time.perf_counter_ns()
        self._tick_message(0)
        self._tick_message(1)
        if timed:
            budget = self.budget
            budget.add('sim_truth_sensing', t1 - t0)
            budget.add('sim_truth_conversion', time.perf_counter_ns() - t1)

    def _tick_message(self, k: int):
        """Message ``k`` (truth odom, truth contacts, imu) of the tick if ``k``'s topic has a
        reader now, built once; None otherwise."""
        message = self._tick_messages[k]
        if message is None:
            publisher, build, args = self._tick_sources[k]
            if publisher.get_subscription_count() > 0:
                message = self._tick_messages[k] = build(*args)
        return message

    def _publish_state(self, with_clock: bool = False, timed: bool = False) -> None:
        """State of the current tick: first what the controller waits for (with
        ``truth_first`` the truth, then imu and joint_states: it wakes on them), then the
        truth otherwise and /clock (on its grid, clock_period, or when forced), which nobody
        waits for. ``timed``: a tick's first publish, whose phases go into the budget (a
        republish does not); it senses the truth after the controller's inputs are out, or
        before them with ``truth_first``."""
        clock = time.perf_counter_ns
        t0 = clock()
        if not timed:                 # a republish: a reader may have come meanwhile
            for k in range(3):
                self._tick_message(k)
        elif self.truth_first:
            self._sense_truth(timed=False)
        if self.truth_first:
            self._publish_truth()
        t1 = clock()
        imu, joints = self._tick_messages[2:]
        if imu is not None:
            self.imu_pub.publish(imu)
        t2 = clock()
        self.joint_pub.publish(joints)
        t3 = clock()
        self.last_publish_wall = time.monotonic()
        odom_ns = contacts_ns = 0
        if not self.truth_first:
            if timed:
                self._sense_truth()
            odom_ns, contacts_ns = self._publish_truth()
        t4 = clock()
        if with_clock or self.world.tick % self._clock_every == 0:
            self.clock_pub.publish(Clock(clock=ns_to_stamp(self.now_ns)))
        t5 = clock()
        if timed:
            add = self.budget.add
            add('sim_truth_first', t1 - t0)
            add('sim_publish_imu', t2 - t1)
            add('sim_publish_joint_states', t3 - t2)
            add('sim_publish_truth_odom', odom_ns)
            add('sim_publish_truth_contacts', contacts_ns)
            add('sim_publish_clock', t5 - t4)
            self._published_ns = t3

    def _publish_truth(self) -> tuple[int, int]:
        """Publish the truth messages that have a reader; wall ns of each publish."""
        clock = time.perf_counter_ns
        truth_odom, truth_contacts = self._tick_messages[:2]
        t0 = clock()
        if truth_odom is not None:
            self.truth_odom_pub.publish(truth_odom)
        t1 = clock()
        if truth_contacts is not None:
            self.truth_contacts_pub.publish(truth_contacts)
        return t1 - t0, clock() - t1

    def _controller_reads_truth(self) -> bool:
        """True if a node that publishes joint_torque_cmd (or its on-demand helper) reads
        ground_truth/odom or ground_truth/contacts: the ideal world's controller."""
        controllers = {info.node_name for info in self.get_publishers_info_by_topic(
            self.cmd_topic)}
        controllers |= {helper_name(name) for name in controllers}
        return any(info.node_name in controllers
                   for pub in (self.truth_odom_pub, self.truth_contacts_pub)
                   for info in self.get_subscriptions_info_by_topic(pub.topic_name))

    def _begin_next(self) -> None:
        """Start the next control period: the wrenches due at this tick, then the physics
        steps the actuator delay keeps from the coming command (SimWorld.begin_step), which
        run while the controller computes that command."""
        if self.world.begun:
            return
        t0 = time.perf_counter_ns()
        self._apply_due_wrenches()
        self.world.begin_step()
        self.budget.add('sim_lead_physics', time.perf_counter_ns() - t0)

    def _advance(self, torques: np.ndarray) -> None:
        """One control tick: due wrenches, physics, state out; in lock-step, the next
        period's lead physics steps while the controller works."""
        t1 = time.perf_counter_ns()
        self._begin_next()              # done already after the previous tick in lock-step
        try:
            self.world.finish_step(torques)
        except ValueError as err:       # never reached with validated commands; be safe
            self.get_logger().error(f'step failed ({err}); applying zero torques')
            self.world.finish_step(np.zeros(len(JOINT_NAMES)))
        budget = self.budget
        budget.add('sim_physics', time.perf_counter_ns() - t1)
        now = time.monotonic()
        self._rtf_samples.append((now, self.world.time))
        while len(self._rtf_samples) > 2 and now - self._rtf_samples[1][0] >= 1.0:
            self._rtf_samples.popleft()
        self._sense()
        self._publish_state(timed=True)
        if self.mode == LOCK_STEP:
            self._begin_next()

    def _set_mode(self, mode: str) -> None:
        if mode == self.mode:
            return
        if mode == LOCK_STEP:          # the first command, or a controller back
            self.truth_first = self._controller_reads_truth()
        if mode in (FREE_RUN, DAMPING):
            self._free_ref = (time.monotonic(), self.world.tick)
            if self.free_timer.is_canceled():
                self.free_timer.reset()
        else:
            self.free_timer.cancel()
        if mode == DAMPING:
            self._damping_since = self.world.time
            self.get_logger().error(
                f'no joint_torque_cmd for {self.command_timeout} s (controller dead): '
                f'free-running in real time with joint damping {self.damping_gain} N m s/rad '
                f'at t = {self.world.time:.3f} s')
        elif self.mode == DAMPING:
            self.get_logger().info(f'controller back: {mode} at t = {self.world.time:.3f} s')
        self.mode = mode

    # ------------------------------------------------------------------ inputs
    def _on_command(self, data: bytes, info: dict) -> None:
        """A serialized ``joint_torque_cmd`` (subscribed raw: tick_cdr.py decodes it)."""
        start_ns = time.perf_counter_ns()
        start_wall_ns = time.time_ns()
        try:
            stamp_ns, torques = torque_command_from_cdr(data)
        except ValueError as err:
            self.rejected += 1
            stamp = cdr_header_stamp_ns(data)
            stamped = f' stamped {stamp * 1e-9:.3f} s' if stamp is not None else ''
            self._log_throttled(
                'warn', f'reject:{err}',
                f'rejected joint_torque_cmd{stamped}: {err}; keeping the previous '
                f'command ({self.rejected} rejected so far)')
            return
        if not self.lock_step:
            self.command = torques
            self.last_command_wall = time.monotonic()
            if self.mode != FREE_RUN and not self._holding():
                self._set_mode(FREE_RUN)
            return
        if stamp_ns == self.now_ns:
            if self._holding():
                self.last_command_wall = time.monotonic()   # alive: no damping mode
                return
            self._begin_budget_tick(start_ns, start_wall_ns, info)
            self.command = torques
            self.last_command_wall = time.monotonic()
            self._set_mode(LOCK_STEP)
            self._advance(torques)
            # The next commands straight from their DDS queue, not through the executor
            # (direct_take.py); the executor runs again when one is late or the slice ends.
            self._direct_commands.run(lambda: self.mode == LOCK_STEP)
            return
        self.ignored += 1
        if self.mode == DAMPING and stamp_ns < self.now_ns:
            # The controller is alive again but answers an older state: stop here and wait
            # for its command of the current stamp (it gets command_timeout to send it).
            self.last_command_wall = time.monotonic()
            self._set_mode(LOCK_STEP)
            self._publish_state(with_clock=True)
            return
        self._log_throttled(
            'debug', 'stale', f'ignored joint_torque_cmd stamped {stamp_ns * 1e-9:.3f} s '
            f'(state is {self.world.time:.3f} s)')

    def _holding(self) -> bool:
        """True at or after ``stop_time``: no more steps (logged once)."""
        if self._stop_ns is None or self.now_ns < self._stop_ns:
            return False
        if not self._held_logged:
            self._held_logged = True
            self.free_timer.cancel()
            self.get_logger().info(f'reached stop_time: holding at t = {self.world.time:.3f} s')
        return True

    def _begin_budget_tick(self, start_ns: int, start_wall_ns: int, info: dict) -> None:
        """An accepted lock-step command: close the previous tick with its wait, open this
        one with the command's transport, wake-up and decoding. The first command (it waited
        for the first plans) and one after free-running open a tick only."""
        budget = self.budget
        if self.mode == LOCK_STEP and self._published_ns is not None:
            budget.add('sim_wait', start_ns - self._published_ns)
            budget.add('sim_tick', start_ns - self._tick_start_ns)
            budget.end_tick()
        else:
            budget.discard_tick()
        self._tick_start_ns = start_ns
        self._published_ns = None
        budget.add_delivery(info, start_wall_ns, 'sim_transport_cmd', 'sim_wake')
        budget.add('sim_decode', time.perf_counter_ns() - start_ns)

    def _on_wrench(self, msg: WrenchStamped) -> None:
        f, t = msg.wrench.force, msg.wrench.torque
        force, torque = np.array([f.x, f.y, f.z]), np.array([t.x, t.y, t.z])
        if msg.header.frame_id not in ('', WORLD_FRAME):
            self._log_throttled('warn', 'wrench-frame',
                                f'rejected external_wrench in frame {msg.header.frame_id!r}: '
                                f'only {WORLD_FRAME!r} (world axes) is supported')
            return
        if not (np.all(np.isfinite(force)) and np.all(np.isfinite(torque))):
            self._log_throttled('warn', 'wrench-nan', 'rejected non-finite external_wrench')
            return
        stamp_ns = stamp_to_ns(msg.header.stamp)
        if stamp_ns == 0:                  # zero stamp: from now on
            stamp_ns = self.now_ns
        self.wrenches.add(stamp_ns, force, torque)
        self.get_logger().info(
            f'external_wrench F={force.tolist()} N, M={torque.tolist()} N m from '
            f't = {stamp_ns * 1e-9:.3f} s queued')

    def _apply_due_wrenches(self) -> None:
        """Make the latest wrench stamped at or before the current tick the active one."""
        now_ns = self.now_ns
        due = self.wrenches.due(now_ns)
        if due is None:
            return
        force, torque = due
        self.world.set_external_wrench(force, torque)
        out = WrenchStamped()
        out.header.stamp = ns_to_stamp(now_ns)
        out.header.frame_id = WORLD_FRAME
        out.wrench.force.x, out.wrench.force.y, out.wrench.force.z = map(float, force)
        out.wrench.torque.x, out.wrench.torque.y, out.wrench.torque.z = map(float, torque)
        self.applied_pub.publish(out)
        self.get_logger().info(f'external wrench F={force.tolist()} N, M={torque.tolist()} N m '
                               f'applied at t = {now_ns * 1e-9:.3f} s')

    # ------------------------------------------------------------------ timers
    def _on_watchdog(self) -> None:
        now = time.monotonic()
        silent = now - self.last_command_wall
        if (self.mode in (LOCK_STEP, FREE_RUN) and silent > self.command_timeout
                and not self._holding()):
            self._set_mode(DAMPING)
        waiting = self.mode in (WAITING, LOCK_STEP)
        if waiting and now - self.last_publish_wall >= self.republish_period:
            # Lost messages heal: the state of t_k again, with /clock (same time, so late
            # joiners learn it while the sim waits).
            self._publish_state(with_clock=True)

    def _on_free_run_timer(self) -> None:
        if self.mode not in (FREE_RUN, DAMPING) or self._holding():
            return
        wall0, tick0 = self._free_ref
        period = self.world.control_period
        due = tick0 + int((time.monotonic() - wall0) * self.rtf_target / period)
        todo = due - self.world.tick
        for _ in range(min(todo, _MAX_CATCH_UP_TICKS)):
            torques = (self.world.damping_torques(self.damping_gain,
                                                  self.damping_abduction_stiffness)
                       if self.mode == DAMPING else self.command)
            self._advance(torques)
            self.budget.discard_tick()        # only lock-step ticks are budgeted
            self._published_ns = None
            if self.mode not in (FREE_RUN, DAMPING):
                return
        if todo > _MAX_CATCH_UP_TICKS:    # too slow for the target RTF: slip, do not spiral
            self._free_ref = (time.monotonic(), self.world.tick)

    def _rtf(self) -> float:
        if len(self._rtf_samples) < 2:
            return 0.0
        now = time.monotonic()
        wall0, sim0 = self._rtf_samples[0]
        if now - self._rtf_samples[-1][0] > 1.0:      # nothing stepped in the last second
            return 0.0
        return (self.world.time - sim0) / max(now - wall0, 1e-9)

    def _on_diagnostics(self) -> None:
        if self.mode == DAMPING:
            level = diagnostics.ERROR
            message = (f'controller dead: no joint_torque_cmd (wbc) since '
                       f't = {self._damping_since:.3f} s, damping mode (robot sits down)')
        elif self.mode == WAITING:
            level, message = diagnostics.OK, 'waiting for the first joint_torque_cmd'
        else:
            level, message = diagnostics.OK, self.mode.replace('_', '-')
        if self._held_logged:
            message += f', holding at stop_time ({self.world.time:.3f} s)'
        values = {'mode': self.mode, 'sim_time': self.world.time, 'tick': self.world.tick,
                  'holding_at_stop_time': self._held_logged,
                  'truth_first': self.truth_first,
                  'real_time_factor': self._rtf(), 'commands_rejected': self.rejected,
                  'commands_ignored': self.ignored,
                  'damping_since_s': self._damping_since if self.mode == DAMPING else '',
                  'wall_s_since_command': time.monotonic() - self.last_command_wall,
                  **self.budget.period_values()}
        self.diag_pub.publish(diagnostics.array(
            ns_to_stamp(self.now_ns), diagnostics.status('sim', level, message, values)))

    def destroy_node(self) -> None:
        if self.budget.ticks:
            self.get_logger().info(self.budget.log_line('sim'))
        self.world.close()
        super().destroy_node()


def main(args=None):
    run_node(SimNode, args)
