"""Simulator node `sim`: the PyBullet world behind a robot-driver interface; it owns time
(docs/sim.md; docs/ARCHITECTURE.md, "Time and lock-step").

At tick t_k it publishes what a robot's sensors measure (`imu`, `joint_states`: the controller
wakes on them) and, for metrics and bags, the truth (`ground_truth/odom`,
`ground_truth/contacts`) and `/clock` (`sim_outputs.py`), runs the next period's lead physics
steps while the controller computes, and steps on with the `joint_torque_cmd` stamped t_k.
When it steps, holds at `stop_time`, republishes a tick, free-runs or damps a robot whose
controller died is `replan_core.sim.modes`'s decision; the wrenches on `external_wrench` act
from their stamps (`replan_core.sim.wrenches.WrenchSchedule`). The realistic robot
(config/profiles/realistic.yaml) is made of separate parameters (actuator dynamics, sensor
noise, model mismatch, compliant feet), each off in config/sim.yaml. Every lock-step tick is
timed by phase (`telemetry.tick_budget`; docs/ARCHITECTURE.md, "Per-tick budget").
"""

from __future__ import annotations

import time

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import WrenchStamped
from rclpy.node import Node
from sensor_msgs.msg import JointState

from replan_core.common.types import JOINT_NAMES
from replan_core.robot.robot_file import default_urdf
from replan_core.robot.variant import perturbed_urdf
from replan_core.sim.modes import (
    ALIVE,
    APPLY,
    DAMPING,
    FREE_RUN,
    LOCK_STEP,
    MAX_CATCH_UP_TICKS,
    RESYNC,
    STEP,
    WAITING,
    ModeChange,
    SimModes,
)
from replan_core.sim.sensors import ImuSensor, JointSensor
from replan_core.sim.world import SimWorld
from replan_core.sim.wrenches import WrenchSchedule
from replan_ros.messages.joint_state import torque_command_from_cdr
from replan_ros.messages.stamps import ns_to_stamp, sec_to_ns
from replan_ros.messages.wrench import wrench_from_msg, wrench_to_msg
from replan_ros.nodes.node_main import (
    ThrottledLog,
    load_node_robot,
    run_node,
    stop_if_domain_shared,
)
from replan_ros.nodes.sim_outputs import TickOutputs
from replan_ros.params import (
    declare_node_parameters,
    imu_noise_params,
    joint_sensor_params,
    world_settings,
)
from replan_ros.params.robot import project_root
from replan_ros.telemetry import diagnostics
from replan_ros.telemetry.real_time_factor import RealTimeFactor
from replan_ros.telemetry.tick_budget import SIM_PHASES, TickBudget
from replan_ros.transport import qos
from replan_ros.transport.direct_take import DirectTake
from replan_ros.transport.stamped_buffer import cdr_header_stamp_ns

_LOG_THROTTLE = 1.0          # wall s between two log lines of the same kind
_WATCHDOG_PERIOD = 0.02      # wall s
_GRAPH_CHECK_PERIOD = 1.0    # wall s between two looks for another graph on the domain


class SimNode(Node):
    """PyBullet simulator: torques in, sensed state, contact events and /clock out."""

    def __init__(self) -> None:
        super().__init__('sim')
        # Declared from params.SIM (defaults, units, ranges); a bad value exits with 2.
        p = declare_node_parameters(self, 'sim', on_change=self._on_parameter_change)
        # The robot file's model; its names map to the project's (topics keep those).
        robot = load_node_robot(self, p, default_urdf(project_root()))
        urdf = model_urdf = robot.urdf
        # Time steps, spawn pose, terrain, contacts and actuators (params.world_settings).
        settings = world_settings(p)
        try:
            # The simulated robot: the model, or a copy with a payload and leg mass errors.
            urdf = perturbed_urdf(urdf, payload_mass=p['payload_mass'],
                                  payload_offset=np.array(p['payload_offset'], dtype=float),
                                  leg_mass_error=p['leg_mass_error'], seed=p['noise_seed'],
                                  base_link=robot.root_link)
            self.world = SimWorld.from_settings(
                urdf, settings, joint_names=robot.joints, foot_frames=robot.feet,
                **robot.foot_contact())
        except Exception as err:   # a missing or malformed URDF (PyBullet, XML, OS errors)
            self.get_logger().fatal(f'cannot load the URDF {urdf!r} ({err}): exiting')
            raise SystemExit(1) from None
        dt = p['control_period']
        imu_noise = imu_noise_params(p)
        self.budget = TickBudget(SIM_PHASES)
        # The sensors, the truth and /clock of each tick (sim_outputs.py).
        self.outputs = TickOutputs(
            self, self.world, ImuSensor(imu_noise, dt, p['noise_seed']),
            JointSensor(joint_sensor_params(p), dt, p['noise_seed']),
            (imu_noise.gyro_noise_density ** 2 / dt, imu_noise.accel_noise_density ** 2 / dt),
            self.budget, max(1, round(p['clock_period'] / dt)))
        self._tick_start_ns: int | None = None     # perf_counter_ns of the last lock-step
        # When it steps, holds, free-runs or damps (replan_core.sim.modes); it holds at the
        # first tick at or after stop_time (0: never): a run ends at one tick.
        self.modes = SimModes(p['lock_step'], p['command_timeout'],
                              sec_to_ns(p['stop_time']) if p['stop_time'] > 0.0 else None,
                              time.monotonic())
        self._held_logged = False
        self.republish_period: float = p['republish_period']
        self.damping_gain: float = p['damping_gain']
        self.damping_abduction_stiffness: float = p['damping_abduction_stiffness']
        self.rtf_target: float = max(p['real_time_factor'], 1e-3)

        self.applied_pub = self.create_publisher(WrenchStamped, 'applied_wrench', qos.SCHEDULE,
                                                 event_callbacks=qos.INTERNAL_PUB_EVENTS)
        self.diag_pub = self.create_publisher(DiagnosticArray, '/diagnostics', qos.COMMAND,
                                              event_callbacks=qos.INTERNAL_PUB_EVENTS)
        command_sub = self.create_subscription(
            JointState, 'joint_torque_cmd', self._on_command, qos.COMMAND,
            event_callbacks=qos.INTERNAL_SUB_EVENTS, raw=True)
        wrench_sub = self.create_subscription(WrenchStamped, 'external_wrench', self._on_wrench,
                                              qos.SCHEDULE)
        # A wrench goes to the executor as soon as it comes (direct_take.py).
        self._direct_commands = DirectTake(self, command_sub, self._on_command,
                                           watched=(wrench_sub,))

        self.command = np.zeros(len(JOINT_NAMES))     # last accepted (safe) command, N m
        self.rejected = 0
        self.ignored = 0
        self._log_throttled = ThrottledLog(self.get_logger(), _LOG_THROTTLE)
        self.wrenches = WrenchSchedule()
        self.rtf = RealTimeFactor()

        self.free_timer = self.create_timer(p['control_period'] / self.rtf_target,
                                            self._on_free_run_timer)
        self.free_timer.cancel()
        self.create_timer(_WATCHDOG_PERIOD, self._on_watchdog)
        self.create_timer(_GRAPH_CHECK_PERIOD, lambda: stop_if_domain_shared(self, '/clock'))
        self.create_timer(p['diagnostics_period'], self._on_diagnostics)
        self.outputs.sense()
        self.outputs.sense_truth()
        self.outputs.publish_state(with_clock=True)
        stepping = 'lock-step' if self.modes.lock_step else 'free-run'
        variant = '' if urdf == model_urdf else f' (the controller\'s model: {model_urdf})'
        self.get_logger().info(
            f'sim: {urdf}{variant} on {p["terrain"]} terrain, {stepping}, tick '
            f'{p["control_period"]} s, physics {p["physics_dt"]} s; '
            'waiting for the first joint_torque_cmd')

    # ------------------------------------------------------------------ parameters
    def _on_parameter_change(self, name: str, value) -> None:
        """A run-time change of one of the writable parameters (params.SIM)."""
        if name == 'damping_gain':
            self.damping_gain = float(value)
        elif name == 'damping_abduction_stiffness':
            self.damping_abduction_stiffness = float(value)

    # ------------------------------------------------------------------ helpers
    @property
    def now_ns(self) -> int:
        """Current sim time (the state stamp), ns."""
        return sec_to_ns(self.world.time)

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
        self.rtf.stepped(time.monotonic(), self.world.time)
        self.outputs.sense()
        # The tick it holds at goes out with /clock even off the clock grid: the launcher ends
        # the run once /clock says stop_time, and the held tick is not republished once
        # answered (modes.SimModes.waits_for_command).
        self.outputs.publish_state(timed=True, with_clock=self.modes.holding(self.now_ns))
        if self.modes.mode == LOCK_STEP:
            self._begin_next()

    def _mode_changed(self, change: ModeChange | None) -> None:
        """Carry out a mode change of the machine: who reads the truth, the free-run timer,
        the log."""
        if change is None:
            return
        if change.new == LOCK_STEP:          # the first command, or a controller back
            self.outputs.truth_first = self.outputs.controller_reads_truth()
        if change.new in (FREE_RUN, DAMPING):
            if self.free_timer.is_canceled():
                self.free_timer.reset()
        else:
            self.free_timer.cancel()
        if change.new == DAMPING:
            self.get_logger().error(
                f'no joint_torque_cmd for {self.modes.command_timeout} s (controller dead): '
                f'free-running in real time with joint damping {self.damping_gain} N m s/rad '
                f'at t = {self.world.time:.3f} s')
        elif change.old == DAMPING:
            self.get_logger().info(f'controller back: {change.new} at '
                                   f't = {self.world.time:.3f} s')

    def _mode_args(self) -> tuple:
        """(sim ns, wall s, tick, sim s): where the machine stands now."""
        return self.now_ns, time.monotonic(), self.world.tick, self.world.time

    # ------------------------------------------------------------------ inputs
    def _on_command(self, data: bytes, info: dict) -> None:
        """A serialized ``joint_torque_cmd`` (subscribed raw: messages.joint_state decodes it)."""
        start_ns = time.perf_counter_ns()
        start_wall_ns = time.time_ns()
        try:
            stamp_ns, torques = torque_command_from_cdr(data)
        except ValueError as err:
            self.rejected += 1
            stamp = cdr_header_stamp_ns(data)
            stamped = f' stamped {stamp * 1e-9:.3f} s' if stamp is not None else ''
            self._log_throttled(
                f'reject:{err}',
                f'rejected joint_torque_cmd{stamped}: {err}; keeping the previous '
                f'command ({self.rejected} rejected so far)')
            return
        self._holding()
        now_ns, wall, tick, sim_time = self._mode_args()
        was_lock_step = self.modes.mode == LOCK_STEP
        action, change = self.modes.command(stamp_ns, now_ns, wall, tick, sim_time)
        if action == APPLY:
            self.command = torques
            self._mode_changed(change)
        elif action == STEP:
            self._begin_budget_tick(start_ns, start_wall_ns, info, was_lock_step)
            self.command = torques
            self._mode_changed(change)
            self._advance(torques)
            # The next commands straight from their DDS queue, not through the executor
            # (direct_take.py); the executor runs again when one is late or the slice ends.
            self._direct_commands.run(lambda: self.modes.mode == LOCK_STEP)
        elif action == RESYNC:
            self.ignored += 1
            self._mode_changed(change)
            self.outputs.publish_state(with_clock=True)
        elif action != ALIVE:
            self.ignored += 1
            self._log_throttled(
                'stale', f'ignored joint_torque_cmd stamped {stamp_ns * 1e-9:.3f} s '
                f'(state is {self.world.time:.3f} s)', level='debug')

    def _holding(self) -> bool:
        """True at or after ``stop_time``: no more steps (logged once)."""
        if not self.modes.holding(self.now_ns):
            return False
        if not self._held_logged:
            self._held_logged = True
            self.free_timer.cancel()
            self.get_logger().info(f'reached stop_time: holding at t = {self.world.time:.3f} s')
        return True

    def _begin_budget_tick(self, start_ns: int, start_wall_ns: int, info: dict,
                           was_lock_step: bool) -> None:
        """An accepted lock-step command: close the previous tick with its wait, open this
        one with the command's transport, wake-up and decoding. The first command (it waited
        for the first plans) and one after free-running open a tick only."""
        budget = self.budget
        if was_lock_step and self.outputs.published_ns is not None:
            budget.add('sim_wait', start_ns - self.outputs.published_ns)
            budget.add('sim_tick', start_ns - self._tick_start_ns)
            budget.end_tick()
        else:
            budget.discard_tick()
        self._tick_start_ns = start_ns
        self.outputs.published_ns = None
        budget.add_delivery(info, start_wall_ns, 'sim_transport_cmd', 'sim_wake')
        budget.add('sim_decode', time.perf_counter_ns() - start_ns)

    def _on_wrench(self, msg: WrenchStamped) -> None:
        try:
            stamp_ns, force, torque = wrench_from_msg(msg)
        except ValueError as err:
            self._log_throttled(f'wrench:{err}', f'rejected external_wrench: {err}')
            return
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
        self.applied_pub.publish(wrench_to_msg(now_ns, force, torque))
        self.get_logger().info(f'external wrench F={force.tolist()} N, M={torque.tolist()} N m '
                               f'applied at t = {now_ns * 1e-9:.3f} s')

    # ------------------------------------------------------------------ timers
    def _on_watchdog(self) -> None:
        self._holding()
        self._mode_changed(self.modes.watchdog(*self._mode_args()))
        if (self.modes.waits_for_command
                and time.monotonic() - self.outputs.last_publish_wall >= self.republish_period):
            # Lost messages heal: the state of t_k again, with /clock (same time, so late
            # joiners learn it while the sim waits).
            self.outputs.publish_state(with_clock=True)

    def _on_free_run_timer(self) -> None:
        self._holding()
        todo = self.modes.free_run_ticks(self.now_ns, time.monotonic(), self.world.tick,
                                         self.world.control_period, self.rtf_target)
        for _ in range(min(todo, MAX_CATCH_UP_TICKS)):
            torques = (self.world.damping_torques(self.damping_gain,
                                                  self.damping_abduction_stiffness)
                       if self.modes.mode == DAMPING else self.command)
            self._advance(torques)
            self.budget.discard_tick()        # only lock-step ticks are budgeted
            self.outputs.published_ns = None
            if not self.modes.free_running:
                return
        if todo > MAX_CATCH_UP_TICKS:
            self.modes.slip(time.monotonic(), self.world.tick)

    def _on_diagnostics(self) -> None:
        mode = self.modes.mode
        if mode == DAMPING:
            level = diagnostics.ERROR
            message = (f'controller dead: no joint_torque_cmd (wbc) since '
                       f't = {self.modes.damping_since:.3f} s, damping mode (robot sits down)')
        elif mode == WAITING:
            level, message = diagnostics.OK, 'waiting for the first joint_torque_cmd'
        else:
            level, message = diagnostics.OK, mode.replace('_', '-')
        if self._held_logged:
            message += f', holding at stop_time ({self.world.time:.3f} s)'
        values = {'mode': mode, 'sim_time': self.world.time, 'tick': self.world.tick,
                  'holding_at_stop_time': self._held_logged,
                  'truth_first': self.outputs.truth_first,
                  'real_time_factor': self.rtf.value(time.monotonic(), self.world.time),
                  'commands_rejected': self.rejected, 'commands_ignored': self.ignored,
                  'damping_since_s': self.modes.damping_since if mode == DAMPING else '',
                  'wall_s_since_command': time.monotonic() - self.modes.last_command_wall,
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
