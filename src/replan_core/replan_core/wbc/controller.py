"""Whole-body controller: CoM/trunk tracking by force distribution + swing-foot impedance.

One ``WholeBodyController`` is built once (pinocchio data through ``RobotModel``, one proxsuite
QP of fixed size) and ``compute`` is called once per control tick (250 Hz):

- stance legs: a QP distributes the ground reaction forces (GRF) ``f`` (4 x 3, world axes) over
  the stance feet to realise the desired CoM acceleration (plan feed-forward + PD on the CoM
  error) and the trunk angular acceleration (PD on the orientation: level roll/pitch, commanded
  yaw), with unilateral contact ``fz >= fz_min`` and inner linearised friction pyramids; swing
  feet are forced to ``f = 0`` by the box bounds, so the QP keeps its 12 variables every tick
  (built once, set up and solved cold each tick: a warm start is not bit-exact). Torques
  ``tau_leg = -J_leg^T f_leg + h_leg``: the foot pushes the ground with ``-f`` and ``h``
  (pinocchio nonLinearEffects) compensates the leg's own gravity and Coriolis terms;
- swing legs: Cartesian impedance ``J^T (Kp e + Kd de)`` plus the feed-forward of the reference
  acceleration through the leg's inverse dynamics, plus ``h_leg``;
- torques are clipped to the URDF effort limits; any non-finite intermediate result gives a
  joint-space stand (PD to the last good posture + gravity), reported in the result.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from functools import partial

import numpy as np
import pinocchio as pin

from replan_core.common.proxqp import aligned, aligned_empty, proxqp
from replan_core.common.rotations import yaw_of
from replan_core.common.types import (
    GRAVITY,
    LEGS,
    STANDING_POSE,
    BaseState,
    ComPlan,
    ContactState,
    FootholdPlan,
    JointState,
    Step,
)
from replan_core.gait.swing import ground_crossing_fraction, swing_trajectory
from replan_core.gait.touchdown import StepEvent, StepTracker
from replan_core.robot.model import RobotModel
from replan_core.wbc.settings import WbcParams

N_LEGS = len(LEGS)
_INF = 1e20  # proxsuite's "no bound"


@dataclass
class SwingReference:
    """Desired world position, velocity and acceleration of one swing foot."""

    leg: int
    position: np.ndarray        # (3,) m
    velocity: np.ndarray        # (3,) m/s
    acceleration: np.ndarray    # (3,) m/s^2


@dataclass
class WbcResult:
    """Torques of one tick and their diagnostics."""

    torque: np.ndarray              # (12,) N m, JOINT_NAMES order, clipped, always finite
    forces: np.ndarray              # (4, 3) N, planned GRF per foot (world axes)
    com_error: np.ndarray           # (3,) m, desired - actual CoM
    com_velocity_error: np.ndarray  # (3,) m/s
    orientation_error: np.ndarray   # (3,) rad, rotation vector desired * actual^T (world)
    swing_error: np.ndarray         # (4,) m, |desired - actual| of swing feet (0 for stance)
    stance: np.ndarray              # (4,) bool, legs in the force distribution
    active_contacts: np.ndarray     # (4,) bool, sensed contact flags
    qp_status: str                  # 'solved', 'max_iter', 'primal_infeasible', ...
    qp_iterations: int
    fallback: bool                  # True: a numerical failure, the safe stand was applied
    message: str                    # why the fallback was used ('' otherwise)
    compute_time: float             # s, wall time of compute()
    saturated: int                  # number of joints clipped to the effort limit


def skew(vector: np.ndarray) -> np.ndarray:
    """Cross-product matrix: skew(a) @ b == a x b."""
    x, y, z = vector
    return np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])


def haptic_reference(touchdown_position: np.ndarray, touchdown_time: float, t: float,
                     velocity: float, leg: int) -> SwingReference:
    """Haptic mode after the planned touchdown: keep descending at ``velocity`` (m/s) until
    contact is sensed (the caller switches the leg to stance then)."""
    dt = max(t - touchdown_time, 0.0)
    position = np.asarray(touchdown_position, dtype=float) + np.array([0.0, 0.0, -velocity * dt])
    return SwingReference(leg, position, np.array([0.0, 0.0, -velocity]), np.zeros(3))


def swing_reference(step: Step, liftoff_position: np.ndarray, t: float,
                    trajectory: Callable[..., tuple[np.ndarray, np.ndarray, np.ndarray]],
                    haptic_velocity: float) -> SwingReference:
    """The controller's reference of the swing foot of ``step`` at time ``t``.

    ``trajectory(start, target, liftoff_time, touchdown_time, step_height, t)`` gives position,
    velocity, acceleration (``replan_core.gait.swing``). Past the planned touchdown a haptic
    step keeps descending (``haptic_reference``); a non-haptic one holds the target.
    """
    if t <= step.touchdown_time:
        p, v, a = trajectory(np.asarray(liftoff_position, dtype=float), step.target,
                             step.liftoff_time, step.touchdown_time, step.step_height, t)
        return SwingReference(step.leg, np.asarray(p, dtype=float), np.asarray(v, dtype=float),
                              np.asarray(a, dtype=float))
    if step.haptic:
        return haptic_reference(step.target, step.touchdown_time, t, haptic_velocity, step.leg)
    return SwingReference(step.leg, np.asarray(step.target, dtype=float), np.zeros(3),
                          np.zeros(3))


Reference = tuple[tuple[np.ndarray, np.ndarray, np.ndarray], float, np.ndarray,
                  tuple[SwingReference, ...]]


class PlanFollower:
    """Turns one (FootholdPlan, ComPlan) pair into ``compute`` arguments, tick by tick.

    Swing/stance comes from ``touchdown.StepTracker`` fed with the sensed contact flags: the same
    rule as the gait node, so both agree on every touchdown and on when a re-plan is due. The
    swing reference starts at the foot position sensed at the actual lift-off tick; a haptic
    swing keeps its planned duration from the actual lift-off, then descends (haptic mode); a
    non-haptic one lands at its planned touchdown time (the tracker ends it there).

    A foot of a group (a trot's pair) that touched down and lost its contact again while the
    rest of its group is still in the air bounced: it carries nothing, and as a stance leg the
    force distribution would push it through the air. Until its contact is back or its group
    is complete it descends again from where it touched down (haptic mode, from the tick it
    lost its contact). A crawl's group is one foot: complete at its touchdown, never held.
    """

    def __init__(self, footholds: FootholdPlan, com_plan: ComPlan,
                 haptic_velocity: float = WbcParams.haptic_velocity,
                 touchdown_depth: float = 0.0) -> None:
        self.footholds = footholds
        self.com_plan = com_plan
        self.tracker = StepTracker(footholds)      # the touchdown rule comes with the plan
        self.haptic_velocity = haptic_velocity
        self.touchdown_depth = touchdown_depth
        self._trajectories: dict[int, partial] = {}    # step index -> its swing trajectory
        self._liftoff_position: dict[int, np.ndarray] = {}
        self._touchdown_position: dict[int, np.ndarray] = {}
        self._bounced: dict[int, float] = {}   # step index -> tick (s) its foot lost contact
        # Trunk yaw reference: a ramp through the plan's yaw at its start and at each planned
        # touchdown. Stepping it at the sensed touchdowns would never turn the robot: each
        # touchdown brings a new plan that starts from the actual (not yet turned) yaw.
        self._yaw_times = np.array([footholds.start_time]
                                   + [s.touchdown_time for s in footholds.steps])
        self._yaw_values = np.unwrap(np.array([footholds.initial_yaw]
                                              + [s.yaw for s in footholds.steps]))

    def update(self, t: float, contacts: ContactState) -> list[StepEvent]:
        """Feed the tick at ``t``; returns its lift-off/touchdown events."""
        events = self.tracker.update(t, contacts.contact)
        for event in events:
            if event.kind == 'liftoff':
                self._liftoff_position[event.step] = np.array(
                    contacts.foot_position[event.leg], dtype=float)
            elif event.reason == 'contact' and not event.completes_group:
                self._touchdown_position[event.step] = np.array(
                    contacts.foot_position[event.leg], dtype=float)
        if events or self._touchdown_position:
            self._update_bounced(t, contacts.contact)
        return events

    def _update_bounced(self, t: float, contact) -> None:
        """The landed feet of the groups still in the air that have lost their contact
        (class docstring), with the tick each lost it."""
        tracker = self.tracker
        airborne_groups = {tracker.group_of[i] for i in tracker.active_steps}
        for index in list(self._touchdown_position):
            if tracker.group_of[index] not in airborne_groups:
                del self._touchdown_position[index]
                self._bounced.pop(index, None)
            elif contact[tracker.plan.steps[index].leg]:
                self._bounced.pop(index, None)
            else:
                self._bounced.setdefault(index, t)

    @property
    def replan_due(self) -> bool:
        """A step with ``replan`` touched down at the last processed tick."""
        return self.tracker.replan_due

    def references(self, t: float) -> Reference:
        """CoM reference, yaw, stance flags (4,) and swing references at ``t``."""
        com_ref = self.com_plan.sample(t)
        stance = np.ones(N_LEGS, dtype=bool)
        swing: tuple[SwingReference, ...] = ()
        # Every leg in swing: one in a crawl, a trot's pair together.
        for index in self.tracker.active_steps:
            step = self.footholds.steps[index]
            liftoff = self.tracker.liftoff_tick[index]
            start = self._liftoff_position.get(index, step.target)
            target = step.target
            if step.haptic and step.touchdown_time > step.liftoff_time:
                # A haptic swing searches: it aims touchdown_depth below its foothold, so it
                # meets the ground by the planned time. A non-haptic swing aims at the foothold
                # itself and stance starts at the planned time wherever the foot is (paper
                # V.A: the foot may load late or early). The idle stance's zero-length trigger
                # step is no swing and keeps its target.
                target = step.target - np.array([0.0, 0.0, self.touchdown_depth])
            if step.haptic:
                touchdown = liftoff + (step.touchdown_time - step.liftoff_time)
            else:
                touchdown = max(step.touchdown_time, liftoff + 1e-3)
            timed = Step(step.leg, liftoff, touchdown, target, step.step_height,
                         step.haptic, step.replan, step.yaw)
            stance[step.leg] = False
            swing += (swing_reference(timed, start, t, self._trajectory(index, step, start),
                                      self.haptic_velocity),)
        for index, lost in self._bounced.items():
            leg = self.footholds.steps[index].leg
            stance[leg] = False
            swing += (haptic_reference(self._touchdown_position[index], lost, t,
                                       self.haptic_velocity, leg),)
        yaw = float(np.interp(t, self._yaw_times, self._yaw_values))
        return com_ref, yaw, stance, swing

    def _trajectory(self, index: int, step: Step, start: np.ndarray):
        """The swing trajectory of step ``index``: a haptic swing's horizontal blend ends
        where its descent meets the foothold's height (``swing.ground_crossing_fraction``),
        so that the foot lands on its foothold, not short of it; computed once per step."""
        if not step.haptic or step.touchdown_time <= step.liftoff_time:
            return swing_trajectory
        trajectory = self._trajectories.get(index)
        if trajectory is None:
            fraction = ground_crossing_fraction(float(start[2]), float(step.target[2]),
                                                step.step_height, self.touchdown_depth)
            trajectory = partial(swing_trajectory, horizontal_fraction=fraction)
            self._trajectories[index] = trajectory
        return trajectory

    def yaw_rate(self, t: float) -> float:
        """Rate of the yaw reference at ``t`` (rad/s): the slope of its ramp there."""
        k = int(np.searchsorted(self._yaw_times, t, side='right'))
        if k <= 0 or k >= len(self._yaw_times):
            return 0.0
        dt = self._yaw_times[k] - self._yaw_times[k - 1]
        return float((self._yaw_values[k] - self._yaw_values[k - 1]) / dt) if dt > 0 else 0.0


class StandHold:
    """Stable stand with the feet where they are: no plan, an old plan or stale inputs.

    Holds the CoM (position at entry, zero velocity) and the trunk yaw at entry; legs in
    contact stand; a leg in the air descends from where it was (haptic descent) until contact,
    then stands for good.
    """

    def __init__(self, t: float, com: np.ndarray, yaw: float, contacts: ContactState,
                 haptic_velocity: float = WbcParams.haptic_velocity) -> None:
        self.start_time = t
        self.com = np.array(com, dtype=float)
        self.yaw = float(yaw)
        self.feet = np.array(contacts.foot_position, dtype=float)
        self.standing = np.array(contacts.contact, dtype=bool)
        self.haptic_velocity = haptic_velocity

    def references(self, t: float, contacts: ContactState) -> Reference:
        self.standing |= np.asarray(contacts.contact, dtype=bool)
        stance = self.standing.copy() if self.standing.any() else np.ones(N_LEGS, dtype=bool)
        swing = tuple(haptic_reference(self.feet[i], self.start_time, t, self.haptic_velocity, i)
                      for i in range(N_LEGS) if not stance[i])
        return (self.com, np.zeros(3), np.zeros(3)), self.yaw, stance, swing


def first_swing_liftoff(footholds: FootholdPlan) -> float | None:
    """s: the planned lift-off of the plan's first real swing (a zero-length trigger step of a
    stand plan moves no foot), None if it has none."""
    return min((s.liftoff_time for s in footholds.steps if s.touchdown_time > s.liftoff_time),
               default=None)


def plan_ends_stand(footholds: FootholdPlan, t: float, max_age: float,
                    min_lead: float) -> bool:
    """Whether the plan pair starting with ``footholds`` may end a stand at ``t`` (s).

    It must be made for about now: at most ``max_age`` s old (one that waited while the sim
    ran on starts seconds into its schedule), and its first swing must lift off at least
    ``min_lead`` s after ``t``. Its CoM reference leaves the held CoM at the plan's start to be
    over the other three feet at that lift-off; adopted later, it jumps there while a foot
    lifts with the CoM still where the stand held it, and the robot tips onto the swing leg.
    """
    if t - footholds.start_time > max_age:
        return False
    liftoff = first_swing_liftoff(footholds)
    return liftoff is None or liftoff - t >= min_lead - 1e-9     # s, float sums of ticks


def _trunk_frame() -> BaseState:
    """The base at the world origin, level and at rest: kinematics in the trunk's axes."""
    return BaseState(0.0, np.zeros(3), np.array([0.0, 0.0, 0.0, 1.0]), np.zeros(3), np.zeros(3))


class JointStandUp:
    """Stand-up of a robot that sat down, in joint space.

    A robot that sat down in the sim's damping mode rests on its trunk with the legs folded to
    their limits, and its feet are not where a base estimate started on it puts them: forces
    distributed over such "stance" feet only swing the legs (and drag the estimate away). So it
    stands up without the base state: the joints follow a minimum-jerk path from the sitting
    posture to ``standing`` in ``duration`` s, with the robot's weight on the feet fading in
    along the path, then hold it for ``hold`` s. Then the estimate is started over and the
    force-based stand takes over.
    """

    def __init__(self, t: float, sitting: np.ndarray, standing: np.ndarray = STANDING_POSE,
                 duration: float = 1.5, hold: float = 0.5) -> None:
        if not (duration > 0.0 and hold >= 0.0):
            raise ValueError('duration must be positive and hold non-negative (s)')
        self.start_time = float(t)
        self.sitting = np.array(sitting, dtype=float)
        self.standing = np.array(standing, dtype=float)
        self.duration = float(duration)
        self.hold = float(hold)

    def reference(self, t: float) -> tuple[np.ndarray, np.ndarray, float]:
        """Joint positions (rad) and velocities (rad/s) at ``t``, and the share of the weight
        the feet carry (0 sitting .. 1 standing)."""
        tau = min(max((t - self.start_time) / self.duration, 0.0), 1.0)
        s = tau ** 3 * (10.0 - 15.0 * tau + 6.0 * tau ** 2)             # minimum jerk
        ds = 30.0 * tau ** 2 * (1.0 - tau) ** 2 / self.duration         # 1/s
        delta = self.standing - self.sitting
        return self.sitting + s * delta, ds * delta, s

    def done(self, t: float) -> bool:
        return t >= self.start_time + self.duration + self.hold


def trunk_tilt(quaternion) -> float:
    """rad in [0, pi]: the angle between the trunk's z axis and the world's vertical, for a
    unit quaternion (x, y, z, w) base to world (0 upright, pi upside down)."""
    x, y, _, _ = (float(v) for v in quaternion)
    cos_tilt = 1.0 - 2.0 * (x * x + y * y)          # R[2, 2]
    return math.acos(min(max(cos_tilt, -1.0), 1.0))


class WholeBodyController:
    """Force-distribution QP + swing impedance; build once, ``compute`` every tick."""

    def __init__(self, robot: RobotModel | str, params: WbcParams | None = None) -> None:
        self.robot = robot if isinstance(robot, RobotModel) else RobotModel(robot)
        self.params = params if params is not None else WbcParams()
        self.model = self.robot.model
        self.data = self.robot.data
        self.mass = self.robot.total_mass
        self._leg_v = self.robot.leg_v_index           # (4, 3) columns of each leg in v
        # Fancy index picking each leg's (3, 3) block out of the (4, 3, nv) foot Jacobians, and
        # each leg's (3, 3) block of the mass matrix: built once, not per tick.
        self._leg_pick = (np.arange(N_LEGS)[:, None, None], np.arange(3)[None, :, None],
                          self._leg_v[:, None, :])
        self._leg_mass_ix = tuple(np.ix_(cols, cols) for cols in self._leg_v)
        self._swing_damping = 1e-4 * np.eye(3)        # of the swing feed-forward's J^T J
        self._limit = self.robot.effort_limit.copy()
        self._neg_limit = -self._limit
        self._hold_q: np.ndarray | None = None         # last good posture for the fallback
        self._hold_torque = np.zeros(len(self._limit))  # last good stance torque (feed-forward)
        self._build_qp()

    # ------------------------------------------------------------------------------ QP setup
    def _build_qp(self) -> None:
        """One dense QP, 12 force variables, 16 friction rows, box bounds; built once."""
        p = self.params
        mu = p.friction / np.sqrt(2.0)      # inner pyramid of the friction cone
        c = np.zeros((4 * N_LEGS, 3 * N_LEGS))
        for i in range(N_LEGS):
            rows = slice(4 * i, 4 * i + 4)
            c[rows, 3 * i:3 * i + 3] = [[1.0, 0.0, -mu], [-1.0, 0.0, -mu],
                                        [0.0, 1.0, -mu], [0.0, -1.0, -mu]]
        # Every array proxsuite reads is aligned (proxqp.py: a solve then does not depend on
        # where the heap put its inputs); H and g are computed into buffers built once.
        self._c = aligned(c)
        self._l = aligned(np.full(4 * N_LEGS, -_INF))
        self._u = aligned(np.zeros(4 * N_LEGS))         # |fx|, |fy| <= mu fz
        self._h = aligned_empty((3 * N_LEGS, 3 * N_LEGS))
        self._g = aligned_empty(3 * N_LEGS)
        self._wrench_map = np.zeros((6, 3 * N_LEGS))    # [sum f; sum (p_i - c) x f_i]
        for i in range(N_LEGS):
            self._wrench_map[0:3, 3 * i:3 * i + 3] = np.eye(3)
        self._weights = np.array([p.weight_force] * 3 + [p.weight_moment] * 3)
        # skew(r_i) blocks of the moment rows as one scatter: entry (row, col) of the flat
        # wrench map takes sign * (feet - com).ravel()[source], the other entries stay zero.
        dst, src, sign = [], [], []
        for i in range(N_LEGS):
            for row, col, axis, factor in ((0, 1, 2, -1.0), (0, 2, 1, 1.0), (1, 0, 2, 1.0),
                                           (1, 2, 0, -1.0), (2, 0, 1, -1.0), (2, 1, 0, 1.0)):
                dst.append((3 + row) * 3 * N_LEGS + 3 * i + col)
                src.append(3 * i + axis)
                sign.append(factor)
        self._skew_dst = np.array(dst)
        self._skew_src = np.array(src)
        self._skew_sign = np.array(sign)
        self._bounds_cache: dict[tuple[bool, ...], tuple[np.ndarray, np.ndarray]] = {}
        self._qp = proxqp.dense.QP(3 * N_LEGS, 0, 4 * N_LEGS, True)
        self._qp.settings.eps_abs = p.qp_eps_abs
        self._qp.settings.eps_rel = 0.0
        self._qp.settings.max_iter = p.qp_max_iter
        self._qp.settings.verbose = False
        self._qp.settings.initial_guess = _COLD_START

    def _bounds(self, stance: tuple[bool, ...]) -> tuple[np.ndarray, np.ndarray]:
        """Box bounds of the forces for a stance set; 16 sets at most, each built once
        (proxsuite copies them, so the cached arrays are never changed). Like the friction
        rows of ``_build_qp``, they take the params as they were at construction."""
        bounds = self._bounds_cache.get(stance)
        if bounds is None:
            bounds = self._bounds_cache[stance] = self._build_bounds(stance)
        return bounds

    def _build_bounds(self, stance: tuple[bool, ...]) -> tuple[np.ndarray, np.ndarray]:
        p = self.params
        lower = np.zeros(3 * N_LEGS)
        upper = np.zeros(3 * N_LEGS)
        for i in range(N_LEGS):
            if stance[i]:
                tangential = p.friction * p.fz_max
                lower[3 * i:3 * i + 3] = (-tangential, -tangential, p.fz_min)
                upper[3 * i:3 * i + 3] = (tangential, tangential, p.fz_max)
        return aligned(lower), aligned(upper)

    def _solve_forces(self, feet: np.ndarray, com: np.ndarray, wrench: np.ndarray,
                      stance: np.ndarray) -> tuple[np.ndarray, str, int]:
        """GRF (4, 3) realising ``wrench`` = [force; moment about the CoM] on the stance feet."""
        a = self._wrench_map
        # a[3:6, 3i:3i+3] = skew(feet[i] - com) for the four feet in one scatter.
        a.ravel()[self._skew_dst] = (feet - com).ravel()[self._skew_src] * self._skew_sign
        aw = a.T * self._weights
        h = np.matmul(aw, a, out=self._h)
        h.ravel()[::3 * N_LEGS + 1] += self.params.regularization    # the diagonal, a view
        g = np.negative(np.matmul(aw, wrench, out=self._g), out=self._g)
        lower, upper = self._bounds(tuple(stance.tolist()))
        # Set up and solved cold every tick, never warm-started: a warm start from the last
        # tick's forces is not bit-exact. In config/scenarios/knock_over.yaml (tick 3.136 s) the
        # same two QPs, solved in a row, gave 'solved' in 15 iterations or 'max_iter' after
        # 300 000 (1 s, non-finite forces) depending on the heap alone; a cold solve of every
        # tick of that run gave the same bits under heap noise (test_proxqp.py). It costs about
        # 30 us more per tick (docs/wbc.md, "The force QP").
        qp = self._qp
        qp.init(h, g, None, None, self._c, self._l, self._u, lower, upper)
        qp.solve()
        results = qp.results            # each attribute access builds a new wrapper: once
        info = results.info
        status = info.status
        name = _STATUS_NAMES.get(status)
        if name is None:                # str() of the enum costs ~4 us: only when needed
            name = str(status)
        # x is a view of the solver's memory, which the next solve overwrites: a copy.
        return results.x.reshape(N_LEGS, 3).copy(), name, int(info.iter)

    # ------------------------------------------------------------------------------ per tick
    def compute(self, base: BaseState, joints: JointState, contact: np.ndarray,
                com_reference: tuple[np.ndarray, np.ndarray, np.ndarray], yaw_reference: float,
                stance: Sequence[bool] | np.ndarray,
                swing: Sequence[SwingReference] = (), *,
                yaw_rate_reference: float = 0.0) -> WbcResult:
        """Joint torques (JOINT_NAMES order) for one tick.

        ``com_reference`` = desired CoM position, velocity, acceleration (world, e.g.
        ``ComPlan.sample``); ``yaw_reference`` trunk yaw (rad) and ``yaw_rate_reference`` its rate
        (rad/s, feed-forward: a turning reference is then tracked without lag), roll and pitch
        are kept level; ``stance`` (4,) legs carrying the robot; ``swing`` one reference per
        swing leg (a leg neither in stance nor in ``swing`` gets gravity compensation only).
        """
        start = time.perf_counter()
        stance = np.asarray(stance, dtype=bool).copy()
        contact = np.asarray(contact, dtype=bool).copy()
        try:
            result = self._compute(base, joints, contact, com_reference, yaw_reference, stance,
                                   swing, float(yaw_rate_reference))
        except (ValueError, FloatingPointError, np.linalg.LinAlgError, RuntimeError) as error:
            result = self._fallback(joints, contact, stance, f'exception: {error}')
        result.compute_time = time.perf_counter() - start
        return result

    def _compute(self, base: BaseState, joints: JointState, contact: np.ndarray,
                 com_reference: tuple[np.ndarray, np.ndarray, np.ndarray], yaw_reference: float,
                 stance: np.ndarray, swing: Sequence[SwingReference],
                 yaw_rate_reference: float = 0.0) -> WbcResult:
        p = self.params
        # One isfinite over everything (numpy call overhead dominates at this size).
        values = np.concatenate([
            np.asarray(base.position, dtype=float), np.asarray(base.quaternion, dtype=float),
            np.asarray(base.linear_velocity, dtype=float),
            np.asarray(base.angular_velocity, dtype=float),
            np.asarray(joints.position, dtype=float), np.asarray(joints.velocity, dtype=float)])
        if not np.isfinite(values).all() or values[3:7] @ values[3:7] < 1e-12:
            return self._fallback(joints, contact, stance, 'non-finite state')
        com_des, vcom_des, acom_des = (np.asarray(x, dtype=float) for x in com_reference)
        if not (np.isfinite(np.concatenate([com_des, vcom_des, acom_des])).all()
                and np.isfinite(yaw_reference)):
            return self._fallback(joints, contact, stance, 'non-finite reference')

        model, data = self.model, self.data
        _, v = self.robot.update(base, joints)     # one pinocchio pass per tick
        com = data.com[0].copy()
        vcom = data.vcom[0].copy()
        nle = data.nle
        lwa = pin.LOCAL_WORLD_ALIGNED
        # (4, 3, nv) translational foot Jacobians, world axes: one array, so that the legs'
        # blocks and products below are one call each instead of one per leg.
        foot_ids = self.robot.foot_frame_ids
        jacobians = np.array([pin.getFrameJacobian(model, data, f, lwa)[:3] for f in foot_ids])
        j_legs = jacobians[self._leg_pick]                  # (4, 3, 3) J_leg, world axes
        oMf = data.oMf                  # each data.oMf access builds a new wrapper: once
        feet = np.array([oMf[f].translation for f in foot_ids])

        # Desired CoM acceleration: plan feed-forward + PD on the CoM error (world).
        com_error = com_des - com
        vcom_error = vcom_des - vcom
        acc = acom_des + p.com_kp * com_error + p.com_kd * vcom_error
        # Trunk: level roll/pitch, commanded yaw; PD on the rotation vector (world axes).
        rotation = self.robot.rotation          # of base.quaternion, from robot.update
        cy, sy = math.cos(yaw_reference), math.sin(yaw_reference)
        rotation_des = np.array(((cy, -sy, 0.0), (sy, cy, 0.0), (0.0, 0.0, 1.0)))
        orientation_error = pin.log3(rotation_des @ rotation.T)
        omega = np.asarray(base.angular_velocity, dtype=float)
        # Gains are given about the trunk's roll/pitch/yaw axes: Rz diag(k) Rz^T e, done as
        # Rz (k * (Rz^T e)) on floats (3-vectors: numpy's call overhead outweighs the maths).
        yaw = yaw_of(values[3:7])
        c, s = math.cos(yaw), math.sin(yaw)
        ex, ey, ez = orientation_error.tolist()
        wx, wy, wz = omega.tolist()
        dx, dy, dz = -wx, -wy, yaw_rate_reference - wz        # omega_ref - omega
        kpx, kpy, kpz = np.asarray(p.trunk_kp, dtype=float).tolist()
        kdx, kdy, kdz = np.asarray(p.trunk_kd, dtype=float).tolist()
        ux = kpx * (c * ex + s * ey) + kdx * (c * dx + s * dy)       # in the trunk's yaw axes
        uy = kpy * (c * ey - s * ex) + kdy * (c * dy - s * dx)
        omega_dot = (c * ux - s * uy, s * ux + c * uy, kpz * ez + kdz * dz)
        inertia = data.Ig.inertia               # centroidal composite inertia, world axes
        # Rows I omega_dot and I omega in one product.
        (mx, my, mz), (ix, iy, iz) = (np.array((omega_dot, (wx, wy, wz))) @ inertia.T).tolist()
        ax, ay, az = acc.tolist()
        mass = self.mass
        wrench = np.array((
            mass * ax, mass * ay, mass * (az + GRAVITY),            # sum f = m (a + g)
            mx + (wy * iz - wz * iy), my + (wz * ix - wx * iz), mz + (wx * iy - wy * ix)))

        forces = np.zeros((N_LEGS, 3))
        qp_status, qp_iter = 'no_stance', 0
        if stance.any():
            forces, qp_status, qp_iter = self._solve_forces(feet, com, wrench, stance)
            if qp_status not in ('solved', 'max_iter') or not np.isfinite(forces).all():
                return self._fallback(joints, contact, stance, f'force QP {qp_status}')
            forces[~stance] = 0.0

        swing_error = np.zeros(N_LEGS)
        # Every leg: gravity + Coriolis (h), minus J^T f of the stance feet (the foot pushes
        # the ground with -f); one batched product: the other legs' forces are zero here.
        legs_tau = nle[self._leg_v] - (j_legs.transpose(0, 2, 1) @ forces[..., None])[..., 0]
        swing_legs = {s.leg: s for s in swing}
        for i in range(N_LEGS):
            ref = swing_legs.get(i)
            if ref is None or stance[i]:
                continue
            j_leg = j_legs[i]
            foot_velocity = jacobians[i] @ v
            error = np.asarray(ref.position, dtype=float) - feet[i]
            derror = np.asarray(ref.velocity, dtype=float) - foot_velocity
            swing_error[i] = math.sqrt(error.dot(error))   # np.linalg.norm's own steps
            force = p.swing_kp * error + p.swing_kd * derror
            # Feed-forward: leg inverse dynamics of the reference acceleration minus the
            # velocity-product drift, through a damped inverse of the (3, 3) leg Jacobian.
            drift = pin.getFrameClassicalAcceleration(
                model, data, self.robot.foot_frame_ids[i], lwa).linear
            a_task = np.asarray(ref.acceleration, dtype=float) - drift
            qdd = np.linalg.solve(j_leg.T @ j_leg + self._swing_damping, j_leg.T @ a_task)
            m_leg = data.M[self._leg_mass_ix[i]]
            legs_tau[i] += j_leg.T @ force + m_leg @ qdd
        torque = legs_tau.ravel()           # leg-major: JOINT_NAMES order

        if not np.isfinite(torque).all():
            return self._fallback(joints, contact, stance, 'non-finite torque')
        # np.clip's wrapper costs more than the two ufuncs it calls (torque is finite here).
        clipped = np.minimum(np.maximum(torque, self._neg_limit), self._limit)
        saturated = int(np.count_nonzero(clipped != torque))
        self._hold_q = np.asarray(joints.position, dtype=float).copy()
        self._hold_torque = np.where(stance.repeat(3), clipped, 0.0)
        return WbcResult(
            torque=clipped, forces=forces, com_error=com_error, com_velocity_error=vcom_error,
            orientation_error=orientation_error, swing_error=swing_error, stance=stance,
            active_contacts=contact, qp_status=qp_status, qp_iterations=qp_iter,
            fallback=False, message='', compute_time=0.0, saturated=saturated)

    def leg_heights(self, joints: JointState) -> np.ndarray:
        """(4,) m: base_link above each foot along the trunk's z axis (joint kinematics only)."""
        return -self.robot.foot_positions(_trunk_frame(), joints)[:, 2]

    def stand_up(self, joints: JointState, stand_up: JointStandUp, t: float,
                 contact: np.ndarray) -> WbcResult:
        """Torques of a joint-space stand-up tick (``JointStandUp``): PD on the path plus
        ``-J^T f`` with f the weight share on each foot, trunk taken level."""
        start = time.perf_counter()
        p = self.params
        q = np.asarray(joints.position, dtype=float)
        qd = np.asarray(joints.velocity, dtype=float)
        q_ref, qd_ref, load = stand_up.reference(t)
        jacobians = self.robot.foot_jacobians(_trunk_frame(), joints)  # (4, 3, nv)
        foot_force = np.array([0.0, 0.0, load * self.mass * GRAVITY / N_LEGS])   # N, each foot
        weight = np.zeros(len(self._limit))
        for i in range(N_LEGS):
            weight[3 * i:3 * i + 3] = -jacobians[i][:, self._leg_v[i]].T @ foot_force
        torque = weight + p.stand_up_kp * (q_ref - q) + p.stand_up_kd * (qd_ref - qd)
        if not np.all(np.isfinite(torque)):
            return self._fallback(joints, np.asarray(contact, bool), np.ones(N_LEGS, bool),
                                  'non-finite stand-up torque')
        clipped = np.clip(torque, -self._limit, self._limit)
        self._hold_q = q_ref.copy()          # a failure meanwhile holds the path, not the sit
        self._hold_torque = weight
        return WbcResult(
            torque=clipped, forces=np.tile(foot_force, (N_LEGS, 1)), com_error=np.zeros(3),
            com_velocity_error=np.zeros(3), orientation_error=np.zeros(3),
            swing_error=np.zeros(N_LEGS), stance=np.ones(N_LEGS, bool),
            active_contacts=np.asarray(contact, bool), qp_status='stand_up', qp_iterations=0,
            fallback=False, message='', compute_time=time.perf_counter() - start,
            saturated=int(np.count_nonzero(clipped != torque)))

    def fallen(self, joints: JointState, contact: np.ndarray) -> WbcResult:
        """Torques of a fallen robot: joint damping only (``fall_damping``), so the legs
        neither flail nor hold a posture that loads them; finite for any input."""
        start = time.perf_counter()
        qd = np.nan_to_num(np.asarray(joints.velocity, dtype=float), nan=0.0, posinf=0.0,
                           neginf=0.0)
        torque = -self.params.fall_damping * qd
        clipped = np.clip(torque, -self._limit, self._limit)
        contact = np.asarray(contact, bool)
        return WbcResult(
            torque=clipped, forces=np.zeros((N_LEGS, 3)), com_error=np.zeros(3),
            com_velocity_error=np.zeros(3), orientation_error=np.zeros(3),
            swing_error=np.zeros(N_LEGS), stance=np.zeros(N_LEGS, bool),
            active_contacts=contact, qp_status='fallen', qp_iterations=0, fallback=False,
            message='', compute_time=time.perf_counter() - start,
            saturated=int(np.count_nonzero(clipped != torque)))

    def _fallback(self, joints: JointState, contact: np.ndarray, stance: np.ndarray,
                  message: str) -> WbcResult:
        """Safe stand: joint PD to the last good posture + the last good stance torques."""
        p = self.params
        q = np.asarray(joints.position, dtype=float)
        qd = np.asarray(joints.velocity, dtype=float)
        if self._hold_q is None and np.all(np.isfinite(q)):
            self._hold_q = q.copy()
        hold = self._hold_q if self._hold_q is not None else np.zeros(len(self._limit))
        torque = self._hold_torque + p.fallback_kp * (hold - q) - p.fallback_kd * qd
        torque = np.nan_to_num(torque, nan=0.0, posinf=0.0, neginf=0.0)
        torque = np.clip(torque, -self._limit, self._limit)
        return WbcResult(
            torque=torque, forces=np.zeros((N_LEGS, 3)), com_error=np.zeros(3),
            com_velocity_error=np.zeros(3), orientation_error=np.zeros(3),
            swing_error=np.zeros(N_LEGS), stance=stance, active_contacts=contact,
            qp_status='fallback', qp_iterations=0, fallback=True, message=message,
            compute_time=0.0, saturated=0)


# proxsuite's enum values, looked up once (an attribute chain per tick costs ~2 us).
_COLD_START = proxqp.InitialGuess.NO_INITIAL_GUESS
_STATUS_NAMES = {
    proxqp.QPSolverOutput.PROXQP_SOLVED: 'solved',
    proxqp.QPSolverOutput.PROXQP_MAX_ITER_REACHED: 'max_iter',
    proxqp.QPSolverOutput.PROXQP_PRIMAL_INFEASIBLE: 'primal_infeasible',
    proxqp.QPSolverOutput.PROXQP_SOLVED_CLOSEST_PRIMAL_FEASIBLE: 'closest_feasible',
    proxqp.QPSolverOutput.PROXQP_DUAL_INFEASIBLE: 'dual_infeasible',
    proxqp.QPSolverOutput.PROXQP_NOT_RUN: 'not_run',
}
