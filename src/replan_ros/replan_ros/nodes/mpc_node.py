"""MPC node: re-plans the CoM from the actual state at every ``footholds``.

- ``footholds`` stamped ``t_k`` (reliable, transient local) is a re-plan request. The node takes
  the actual CoM state at ``t_k``: position and velocity from pinocchio
  (``RobotModel.com_state``) on the ``joint_states`` and ``odom`` of that very stamp (both best
  effort, the last ~100 stamps buffered), acceleration from its own previous plan sampled at
  ``t_k`` (zero for the first plan). The two state topics are read on demand
  (``on_demand.OnDemandSubscriptions``): their newest samples wait in the DDS queue and are
  taken only when a request comes, so the node does not wake at every tick. Until both states
  of ``t_k`` are there the request stays pending and is retried every ``retry_period``; the
  simulator republishes the state of ``t_k`` while the controller waits for this plan, so it
  does arrive.
- It solves the jerk QP (``replan_core.mpc.lip_mpc``, built once, warm-started) and publishes
  ``com_plan``, ``zmp_plan`` and ``com_path`` stamped ``t_k`` (reliable, transient local, depth 1)
  and a ``/diagnostics`` status: solve time, iterations, status, ZMP margin, fallback flag.
- A failed solve still publishes the core's safe fallback plan (flagged WARN on /diagnostics); a
  rejected request (bad message, non-finite state) is logged (throttled) and, when the core has
  an earlier plan, answered with that plan shifted to ``t_k``.
- No ``contact_events`` subscription: the footholds carry what a re-plan needs; waking at every
  touchdown only to log it took 13 % of the node's busy time in a walk, twice what publishing
  its plans took (py-spy).
"""

from __future__ import annotations

import json
import os
from collections import deque

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray
from nav_msgs.msg import Odometry, Path
from rclpy.clock import Clock, ClockType
from rclpy.node import Node
from sensor_msgs.msg import JointState as JointStateMsg
from sensor_msgs.msg import PointCloud2
from trajectory_msgs.msg import MultiDOFJointTrajectory

from replan_core.common.types import WORLD_FRAME, BaseState, ComPlan, FootholdPlan, JointState
from replan_core.gait.crawl import is_stand_plan
from replan_core.mpc.lip_mpc import LipMpc, MpcResult, replan_start_state
from replan_core.mpc.settings import MpcSettings
from replan_core.mpc.support import implied_velocity
from replan_core.robot.model import RobotModel
from replan_ros.messages.com_plan import encode_com_plan
from replan_ros.messages.footholds import footholds_from_msg
from replan_ros.messages.joint_state import joint_state_from_msg
from replan_ros.messages.odom import base_state_from_odom
from replan_ros.messages.path import encode_path
from replan_ros.messages.stamps import sec_to_ns, sec_to_stamp, stamp_to_ns
from replan_ros.nodes.node_main import ThrottledLog, load_node_robot, run_node
from replan_ros.params import declare_node_parameters, mpc_settings
from replan_ros.telemetry import diagnostics
from replan_ros.transport.on_demand import OnDemandSubscriptions
from replan_ros.transport.qos import (
    COMMAND,
    INTERNAL_PUB_EVENTS,
    INTERNAL_SUB_EVENTS,
    LATCHED,
    LATCHED_PUB,
    SENSOR,
    with_depth,
)
from replan_ros.transport.stamped_buffer import RawStampedBuffer

SOLVE_TIMES_KEPT = 10_000          # re-plans whose solve times the shutdown line summarises
SOLVE_TIMES_LOG = 'mpc solve times:'   # its prefix; the rest is one JSON object


class MpcNode(Node):
    """Footholds in, CoM plan out, from the actual state of the footholds' stamp."""

    def __init__(self) -> None:
        super().__init__('mpc')
        p = declare_node_parameters(self, 'mpc', on_change=self._on_parameter_change)
        self.settings = self._settings(p)
        self.model = self._robot_model(p)
        self.mpc = LipMpc(self.settings)                       # QP built once, here
        self.state_buffer = max(int(p['state_buffer']), 2)
        self.state_wait = max(float(p['state_wait']), 0.0)
        self.fallback_window_ns = round(float(p['state_fallback_window']) * 1e9)
        self._warn = ThrottledLog(self.get_logger(), float(p['warn_period']))

        self.com_plan_pub = self.create_publisher(MultiDOFJointTrajectory, 'com_plan',
                                                  LATCHED_PUB, event_callbacks=INTERNAL_PUB_EVENTS)
        self.zmp_pub = self.create_publisher(Path, 'zmp_plan', LATCHED_PUB,
                                             event_callbacks=INTERNAL_PUB_EVENTS)
        self.com_path_pub = self.create_publisher(Path, 'com_path', LATCHED_PUB,
                                                  event_callbacks=INTERNAL_PUB_EVENTS)
        self.diag_pub = self.create_publisher(DiagnosticArray, '/diagnostics', COMMAND,
                                              event_callbacks=INTERNAL_PUB_EVENTS)
        self.create_subscription(PointCloud2, 'footholds', self._on_footholds, LATCHED,
                                 event_callbacks=INTERNAL_SUB_EVENTS)
        # One tick in ~190 is needed: read on demand, kept serialized until then.
        self.joints = RawStampedBuffer(JointStateMsg, joint_state_from_msg, self.state_buffer)
        self.bases = RawStampedBuffer(Odometry, base_state_from_odom, self.state_buffer)
        state_qos = with_depth(SENSOR, self.state_buffer)
        self.state_input = OnDemandSubscriptions(self)
        self.state_input.subscribe(JointStateMsg, 'joint_states', state_qos, self.joints.add)
        self.state_input.subscribe(Odometry, 'odom', state_qos, self.bases.add)
        self.retry_timer = self.create_timer(float(p['retry_period']), self._process,
                                             clock=Clock(clock_type=ClockType.STEADY_TIME))
        self.retry_timer.cancel()
        self.pending: tuple[int, FootholdPlan] | None = None
        self.last_plan: ComPlan | None = None
        self.last_stood = False          # the plan in force was made for a stand plan
        self.last_stamp_ns: int | None = None
        self.replans = 0
        # (wall, CPU) ms of the last re-plans, for the log line at shutdown.
        self._solve_times: deque[tuple[float, float]] = deque(maxlen=SOLVE_TIMES_KEPT)
        self.get_logger().info(
            f'mpc: N={self.mpc.n} per axis ({self.settings.horizon} s / {self.settings.dt} s), '
            f'h={self.settings.com_height} m, R={self.settings.jerk_weight}, '
            f'w_v={self.settings.velocity_weight}, w_p={self.settings.position_weight}, '
            f'margin={self.settings.zmp_margin} m')

    # ----------------------------------------------------------------------------- set-up

    def _on_parameter_change(self, name: str, value) -> None:
        """A run-time change of one of the writable parameters (params.MPC)."""
        if name == 'warn_period':
            self._warn.period = float(value)

    def _settings(self, p) -> MpcSettings:
        # The values were checked against params.MPC; horizon >= dt and a position_sway only
        # with a position_weight tie two together (params.files._node_checks).
        try:
            s = mpc_settings(p)
            if not (s.dt > 0 and s.horizon >= s.dt and s.com_height > 0 and s.gravity > 0
                    and s.jerk_weight > 0 and s.velocity_weight >= 0 and s.position_weight >= 0
                    and not (s.position_sway > 0 and s.position_weight == 0)
                    and s.zmp_margin >= 0
                    and s.eps_abs > 0 and s.max_iter > 0):
                raise ValueError('out of range')
            return s
        except (TypeError, ValueError) as err:
            self.get_logger().fatal(f'config error: mpc: {err}')
            raise SystemExit(2) from None

    def _robot_model(self, p) -> RobotModel:
        robot = load_node_robot(self, p, os.environ.get('REPLAN_URDF', ''))
        path = robot.urdf
        try:
            return RobotModel(path, robot.joints, robot.feet)
        except Exception as err:   # any load error: without a model there is no CoM to plan
            # from; exit non-zero so that the launcher reports it (and respawns, up to a limit)
            self.get_logger().fatal(f'cannot load the URDF {path!r} ({err}): exiting')
            raise SystemExit(1) from None

    # ----------------------------------------------------------------------------- inputs

    def _on_footholds(self, msg: PointCloud2) -> None:
        try:
            plan = footholds_from_msg(msg)
        except ValueError as err:
            self._warn('footholds', f'footholds rejected: {err}; keeping the last plan')
            return
        ns = stamp_to_ns(msg.header.stamp)
        if self.last_stamp_ns is not None and ns == self.last_stamp_ns:
            return                                   # transient-local repeat: already planned
        if self.last_stamp_ns is not None and ns < self.last_stamp_ns:
            self.get_logger().warn(f'footholds stamped {ns * 1e-9:.3f} s before the last plan '
                                   f'({self.last_stamp_ns * 1e-9:.3f} s): a new run, '
                                   'forgetting the previous plan')
            self.mpc.reset()
            self.last_plan = None
        if self.pending is not None and self.pending[0] != ns:
            self._warn('superseded', f'footholds of {self.pending[0] * 1e-9:.3f} s superseded '
                       f'by {ns * 1e-9:.3f} s before their state arrived')
        self.pending = (ns, plan)
        self._process()

    # ----------------------------------------------------------------------------- re-plan

    def _process(self) -> None:
        """Solve the pending request once the joint_states and odom of its stamp are here."""
        if self.pending is None:
            self.retry_timer.cancel()
            return
        ns, plan = self.pending
        state = self._state_at(ns)
        if state is None:                            # look again in retry_period
            if self.retry_timer.is_canceled():
                self.retry_timer.reset()
            return
        self.pending = None
        self.retry_timer.cancel()
        self._replan(ns, plan, *state)

    def _state_at(self, ns: int) -> tuple[BaseState, JointState] | None:
        """The base and joint state stamped ``ns``, None while they are not (validly) here."""
        if not self.state_input.drain(lambda: ns in self.joints and ns in self.bases,
                                      timeout=self.state_wait):
            return self._lost_state(ns)
        try:
            return self.bases.get(ns), self.joints.get(ns)
        except ValueError as err:       # that tick's state is unusable: wait for a re-send
            self._warn('state', f'state at t={ns * 1e-9:.3f} s rejected: {err}')
            return None

    def _lost_state(self, ns: int) -> tuple[BaseState, JointState] | None:
        """The state stamped ``ns`` will never come when both buffers hold newer stamps
        without it: its samples were dropped, or the sim ran on because the controller did not
        wait for this plan (it stands after a planner died, or this node started after the
        request). Then the oldest newer state in both, as the gait node does for odom; a run
        without faults never gets here (the controller waits within the buffers' depth)."""
        newer_joints = {s for s in self.joints.stamps() if s > ns}
        newer_bases = {s for s in self.bases.stamps() if s > ns}
        if not newer_joints or not newer_bases or not newer_joints & newer_bases:
            return None                 # may still come
        stamp = min(newer_joints & newer_bases)
        if stamp - ns > self.fallback_window_ns:
            # Too old to plan from a later state (e.g. the latched footholds of before this
            # node started): drop it, the next footholds come at the next gait re-plan.
            self._warn('state gone', f'no state stamped {ns * 1e-9:.3f} s will come and the '
                       f'oldest newer one is {(stamp - ns) * 1e-9:.3f} s later: request dropped')
            self.pending = None
            return None
        try:
            state = self.bases.get(stamp), self.joints.get(stamp)
        except ValueError as err:
            self._warn('state', f'state at t={stamp * 1e-9:.3f} s rejected: {err}')
            return None
        self._warn('state lost', f'no state stamped {ns * 1e-9:.3f} s will come: planning from '
                   f'the one of {stamp * 1e-9:.3f} s')
        return state

    def _replan(self, ns: int, plan: FootholdPlan, base: BaseState, joints: JointState) -> None:
        t = ns * 1e-9
        if self.model is None:
            self._publish_diag(t, None, 'no robot model (URDF not loaded)')
            return
        try:
            com, vcom = self.model.com_state(base, joints)
        except (ValueError, RuntimeError) as err:
            com, vcom = np.full(3, np.nan), np.full(3, np.nan)
            self._warn('com_state', f'com_state failed at t={t:.3f} s: {err}')
        com, vcom, acc = replan_start_state(t, com, vcom, plan, self.last_plan, self.last_stood)
        v_ref = implied_velocity(plan)
        res = self.mpc.solve(t, com, vcom, acc, plan, v_ref=v_ref)
        self._solve_times.append((res.solve_time_ms, res.solve_cpu_ms))
        self.last_stamp_ns = ns
        self.replans += 1
        if res.status != 'solved':
            self._warn(f'status {res.status}', f'mpc at t={t:.3f} s: {res.status} '
                       f'({res.reason}); fallback: {res.fallback or "none"}')
        if res.plan is not None:
            self.last_plan = res.plan
            self.last_stood = is_stand_plan(plan)
            self._publish_plan(t, res)
        self._publish_diag(t, res, '')

    def _publish_plan(self, t: float, res: MpcResult) -> None:
        # Serialized by hand (messages.com_plan, messages.path: 0.19 ms against 4.05 ms through
        # rclpy's messages, python -m replan_experiments.benchmarks.bench_msgs), the controller's
        # com_plan first: the re-plan waits for it.
        plan = res.plan
        stamp_ns = sec_to_ns(t)                   # exactly the footholds' stamp
        self.com_plan_pub.publish(encode_com_plan(plan, stamp_ns, WORLD_FRAME))
        ground = plan.position[0, 2] - self.settings.com_height
        zmp = np.column_stack([res.zmp, np.full(len(res.zmp), ground)])
        self.zmp_pub.publish(encode_path(stamp_ns, t, plan.dt, zmp, WORLD_FRAME))
        self.com_path_pub.publish(encode_path(stamp_ns, t, plan.dt, plan.position,
                                                  WORLD_FRAME))

    def _publish_diag(self, t: float, res: MpcResult | None, why: str) -> None:
        if res is None:
            st = diagnostics.status('mpc', diagnostics.ERROR, why, {'replans': self.replans})
        else:
            level = (diagnostics.OK if res.ok else
                     diagnostics.WARN if res.plan is not None else diagnostics.ERROR)
            message = res.status if res.ok else f'{res.status}: {res.reason}'
            st = diagnostics.status('mpc', level, message, {
                'stamp': t,
                'solve_time_ms': res.solve_time_ms,
                'solve_cpu_ms': res.solve_cpu_ms,
                'iterations': res.iterations,
                'status': res.status,
                'zmp_margin_m': res.min_zmp_margin_m,
                'max_zmp_violation_m': res.max_zmp_violation_m,
                'fallback': res.is_fallback,
                'fallback_kind': res.fallback or 'none',
                'replans': self.replans,
            })
        self.diag_pub.publish(diagnostics.array(sec_to_stamp(t), st))

    def solve_time_summary(self) -> dict:
        """Wall and CPU time of the kept re-plans (ms): count, median, p99."""
        wall, cpu = np.array(self._solve_times).reshape(-1, 2).T
        summary: dict = {'replans': len(wall)}
        if len(wall):
            for name, values in (('wall', wall), ('cpu', cpu)):
                summary[f'{name}_median_ms'] = round(float(np.median(values)), 3)
                summary[f'{name}_p99_ms'] = round(float(np.percentile(values, 99)), 3)
        return summary

    def destroy_node(self) -> None:
        # One line that benchmarks read (scripts/bench_speed.sh): the solve times in the graph.
        self.get_logger().info(f'{SOLVE_TIMES_LOG} {json.dumps(self.solve_time_summary())}')
        self.state_input.destroy()
        super().destroy_node()


def main(args=None):
    run_node(MpcNode, args)
