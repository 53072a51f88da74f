"""Crawl gait schedule and foothold planner (Algorithm 1: gaitSchedule.next, compFootholds).

A crawl moves one leg at a time, in a fixed sequence (default LH, LF, RH, RF), with a
four-feet phase of ``four_feet_duration`` before every swing of ``swing_duration``. A re-plan
at time ``t0`` (a touchdown) asks for the next ``n`` steps starting with the leg after the one
that just touched down. Other gaits swing groups of legs together (``GaitParams.groups``: a
trot's diagonal pairs, with a short four-feet phase between them or none; gait files,
gait_file.py): a step is then a group, every leg of it with the group's times and its own
foothold, placed as in the crawl.

Footholds come from a reference trunk trajectory: the actual base pose at ``t0`` moved with the
velocity set-point (vx, vy in the body frame, wz), i.e. along an arc. The reference foot of a
leg is its hip plus the nominal stance offset, both rotated by the reference yaw about the
reference base position. Each foothold is the reference foot at the middle of the coming
stance (Raibert-style: the hip position at touchdown plus half the distance the trunk travels
while the foot is on the ground, evaluated along the arc, so turning is exact), so the foot
stays symmetric about its hip over its stance.

Foothold correction (section V.B): the first foothold of each leg in the horizon is placed about
the *actual* hip; without it, it is the foot's previous (actual) position plus one stride. The
later footholds of a leg are its previous foothold plus one stride in both cases.

Idle stance: after ``idle_after`` s of zero set-point the crawl stops at a re-plan
(a touchdown, so all four feet are down) and a *stand plan* follows: no real step, only a
zero-length, ``replan`` "trigger" step every ``idle_replan_period``. The shared touchdown rule
(``touchdown.StepTracker``) ends it one tick after its lift-off tick, so both the gait node and
the controller see the same re-plan tick and the simulator waits for its plans, exactly as for
a touchdown: a set-point that becomes non-zero is picked up at the next trigger,
deterministically (docs/gait.md, "Idle stance").
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from replan_core.common.types import LEGS, FootholdPlan, Step
from replan_core.gait.touchdown import step_groups

# HyQ hips (haa joints) in the base frame, m, leg order LF, RF, LH, RH.
HYQ_HIP_OFFSETS: tuple[tuple[float, float], ...] = (
    (0.3735, 0.207), (0.3735, -0.207), (-0.3735, 0.207), (-0.3735, -0.207))

# Nominal feet about the hips, base frame xy, m: HyQ standing with haa = -0.2 rad.
HYQ_STANCE_OFFSETS: tuple[tuple[float, float], ...] = (
    (0.0, 0.117), (0.0, -0.117), (0.0, 0.117), (0.0, -0.117))

# Default crawl sequence LH, LF, RH, RF as leg indices.
DEFAULT_SEQUENCE: tuple[int, ...] = (LEGS.index('lh'), LEGS.index('lf'),
                                     LEGS.index('rh'), LEGS.index('rf'))

# Whose hips the foothold correction places the feet about (GaitParams.correction_hips).
CORRECTION_HIPS: tuple[str, ...] = ('sway_free', 'actual')

_EPS = 1e-9


@dataclass
class GaitParams:
    """Crawl parameters. Times in s, lengths in m, velocities in m/s and rad/s.

    Defaults (as config/gait.yaml): a step every 0.75 s (0.5 s swing + 0.25 s four-feet phase),
    a 3 s cycle, so the paper's 8 footholds span 6 s of its 8 s MPC horizon (the last stance
    holds to its end). At the 0.2 m/s limit each foot moves 0.6 m per cycle and stays within
    about +-0.26 m of its hip (reach 0.61 m of 0.70 m at a 0.55 m trunk height). Velocity
    limits keep a full cycle inside the step-length limits: 0.2 * 3 = 0.6 <= 0.65 and
    0.1 * 3 = 0.3 <= 0.45. The paper's one step per second would need 0.8 m at 0.2 m/s.
    """

    swing_duration: float = 0.5            # s, one swing
    four_feet_duration: float = 0.25       # s, all four feet down before each swing
    step_height: float = 0.10              # m, apex above the higher of lift-off and target
    sequence: tuple[int, ...] = DEFAULT_SEQUENCE   # swing order, leg indices
    # Legs that lift off and touch down together, in swing order (a trot: the diagonal pairs);
    # empty: one leg at a time in ``sequence`` order (the crawl). When given, ``sequence`` must
    # list the same legs in the same order (gait_file.py writes both).
    groups: tuple[tuple[int, ...], ...] = ()
    hip_offsets: tuple[tuple[float, float], ...] = HYQ_HIP_OFFSETS   # m, base frame xy
    # m, nominal foot about its hip, base frame xy: the simulator's standing pose (config/sim.yaml,
    # haa -0.2 rad) puts the feet 0.117 m outside the hips, a wider base for the support triangles.
    stance_offsets: tuple[tuple[float, float], ...] = HYQ_STANCE_OFFSETS
    max_step_length_x: float = 0.65        # m, |foot displacement| per step, body x
    max_step_length_y: float = 0.45        # m, |foot displacement| per step, body y
    max_linear_x: float = 0.2              # m/s, |vx| limit of the set-point
    max_linear_y: float = 0.10             # m/s, |vy| limit
    max_angular_z: float = 0.25            # rad/s, |wz| limit
    n_footholds: int = 8                   # steps per plan (paper: 8 over an 8 s horizon)
    replan_window: int = 1                 # K: re-plan at every K-th touchdown (paper: 1)
    haptic: bool = True                    # swings end at sensed contact (section V.A)
    foothold_correction: bool = True       # section V.B
    # m, a push: with correction_hips 'sway_free', the whole foot pattern follows the hips only
    # when its common offset from them exceeds this (its shape is restored at every step); with
    # 'actual', a first foothold moves to the hip only when the hip-relative and foot-relative
    # placements differ by more than this (0 = always: V.B literally).
    correction_threshold: float = 0.10
    # About whose hips (docs/gait.md, "Foothold correction about a sway-free trunk"): 'actual',
    # the trunk's now, with its sway (which alone parts the two placements by up to 15 cm on
    # HyQ); 'sway_free', the trunk's trend over the last crawl cycle
    # (speed_feedback.trunk_trend; the replanner passes compute_footholds its trend_shift).
    correction_hips: str = 'sway_free'
    # Idle stance: stop stepping after idle_after s of zero set-point (one crawl
    # cycle, 4 * 0.75 s); while standing, re-plan every idle_replan_period s so that a new
    # set-point is picked up within idle_replan_period + four_feet_duration (0.75 s, one step).
    idle_stance: bool = True
    idle_after: float = 3.0                # s of zero set-point before the crawl stands still
    idle_replan_period: float = 0.5        # s between two re-plan triggers while standing
    # Velocity feedback in foot placement (speed_feedback.py): the stride correction grows by
    # gain * (set-point - mean velocity over the last cycle) * dt at each re-plan (per cycle:
    # the remaining error shrinks by about 1 - gain); 0 = off. limit: m, its largest norm.
    velocity_feedback_gain: float = 0.5
    velocity_feedback_limit: float = 0.10
    velocity_feedback_max_error: float = 0.03    # m/s: a larger error is a disturbance (a push)
    # Strides laid out for the step period measured over the last cycle (touchdowns come later
    # than planned; speed_feedback.StepTiming); False: for the planned step period.
    measured_step_period: bool = True

    @property
    def step_period(self) -> float:
        """s, time from one touchdown to the next."""
        return self.swing_duration + self.four_feet_duration

    @property
    def swing_groups(self) -> tuple[tuple[int, ...], ...]:
        """The steps of one cycle: the legs of each, in swing order."""
        return self.groups if self.groups else tuple((leg,) for leg in self.sequence)

    @property
    def steps_per_cycle(self) -> int:
        """Steps (groups of legs) in one cycle: 4 for the crawl, 2 for a trot."""
        return len(self.swing_groups)

    @property
    def cycle_duration(self) -> float:
        """s, time between two lift-offs of the same leg."""
        return self.steps_per_cycle * self.step_period

    @property
    def stance_duration(self) -> float:
        """s, time a foot stays on the ground between its touchdown and its next lift-off."""
        return self.cycle_duration - self.swing_duration

    def validate(self) -> None:
        """ValueError on inconsistent parameters."""
        if sorted(self.sequence) != [0, 1, 2, 3]:
            raise ValueError(f'sequence must hold each leg once, got {self.sequence}')
        if self.groups:
            flat = tuple(leg for group in self.groups for leg in group)
            if flat != tuple(self.sequence) or not all(self.groups):
                raise ValueError(f'groups {self.groups} must be non-empty and list the legs '
                                 f'of sequence {self.sequence} in its order')
        if self.swing_duration <= 0 or self.four_feet_duration < 0:
            raise ValueError('swing_duration must be > 0 and four_feet_duration >= 0')
        if self.n_footholds < 1 or self.replan_window < 1:
            raise ValueError('n_footholds and replan_window must be >= 1')
        if self.correction_hips not in CORRECTION_HIPS:
            raise ValueError(f'correction_hips must be one of {", ".join(CORRECTION_HIPS)}, '
                             f'got {self.correction_hips!r}')
        if len(self.hip_offsets) != 4 or len(self.stance_offsets) != 4:
            raise ValueError('hip_offsets and stance_offsets need one (x, y) per leg')
        values = (self.step_height, self.max_step_length_x, self.max_step_length_y,
                  self.max_linear_x, self.max_linear_y, self.max_angular_z,
                  self.correction_threshold, self.idle_after, self.velocity_feedback_gain,
                  self.velocity_feedback_limit, self.velocity_feedback_max_error)
        if not (math.isfinite(self.idle_replan_period) and self.idle_replan_period > 0):
            raise ValueError('idle_replan_period must be finite, > 0')
        if not all(math.isfinite(v) and v >= 0 for v in values):
            raise ValueError('heights, step-length and velocity limits, the correction '
                             'threshold, idle_after and the velocity feedback gain and limit '
                             'must be finite, >= 0')


@dataclass
class CrawlSchedule:
    """gaitSchedule of Algorithm 1: which leg (or group of legs) swings next; survives
    re-plans. ``next_leg`` names a group by its first leg."""

    sequence: tuple[int, ...] = DEFAULT_SEQUENCE
    next_leg: int = field(default=-1)
    groups: tuple[tuple[int, ...], ...] = ()      # as GaitParams.groups; empty: one leg each

    def __post_init__(self) -> None:
        if not self.groups:
            self.groups = tuple((leg,) for leg in self.sequence)
        if self.next_leg < 0:
            self.next_leg = self.groups[0][0]

    def successor(self, leg: int) -> int:
        """The first leg of the group that swings after the group of ``leg``."""
        k = group_index(self.groups, leg)
        return self.groups[(k + 1) % len(self.groups)][0]

    def touched_down(self, leg: int) -> int:
        """Record that ``leg`` ended its swing; returns the next leg to swing."""
        self.next_leg = self.successor(leg)
        return self.next_leg


def group_index(groups: tuple[tuple[int, ...], ...], leg: int) -> int:
    """Index of the group that holds ``leg``; ValueError if none does."""
    for k, group in enumerate(groups):
        if leg in group:
            return k
    raise ValueError(f'leg {leg} is in none of the swing groups {groups}')


def _cycle_displacements(twist: np.ndarray, params: GaitParams) -> np.ndarray:
    """(4, 2) displacement of each nominal foot over one cycle at a constant ``twist``, in the
    body frame at the end of the cycle (the same for every cycle)."""
    ref = ReferenceTrajectory(0.0, np.zeros(2), 0.0, twist)
    nominal = np.asarray(params.hip_offsets, dtype=float) + np.asarray(params.stance_offsets)
    _, yaw = ref.pose(params.cycle_duration)
    return np.array([_rot(yaw).T @ (ref.foot(params.cycle_duration, off) - ref.foot(0.0, off))
                     for off in nominal])


def clamp_velocity(set_point, params: GaitParams) -> np.ndarray:
    """(vx, vy, wz) within the limits; ValueError if a value is not finite.

    Each component is clipped to its limit; then, if the combination asks for steps longer than
    the step-length limits (e.g. walking and turning at once: the outer feet travel further),
    the whole twist is scaled down (same turning radius) until every foot's stride fits.
    """
    v = np.asarray(set_point, dtype=float).reshape(3)
    if not np.all(np.isfinite(v)):
        raise ValueError(f'non-finite velocity set-point {v.tolist()}')
    limits = np.array([params.max_linear_x, params.max_linear_y, params.max_angular_z])
    v = np.clip(v, -limits, limits)
    step_limits = np.array([params.max_step_length_x, params.max_step_length_y]) + _EPS

    def fits(scale: float) -> bool:
        return bool(np.all(np.abs(_cycle_displacements(scale * v, params)) <= step_limits))

    if fits(1.0):
        return v
    low, high = 0.0, 1.0          # bisection on the scale: fits(low) holds, fits(high) not
    for _ in range(40):
        mid = 0.5 * (low + high)
        if fits(mid):
            low = mid
        else:
            high = mid
    return v * low


def _rot(yaw: float) -> np.ndarray:
    c, s = math.cos(yaw), math.sin(yaw)
    return np.array([[c, -s], [s, c]])


@dataclass
class ReferenceTrajectory:
    """Trunk reference: pose at ``t0`` moved with a constant body twist (vx, vy, wz) from
    ``t0 + delay`` on (an arc). Before that it stands; with ``delay == 0`` it extends backward
    along the same arc (used for the previous stride of a foot)."""

    t0: float
    position: np.ndarray              # (2,) m, world xy at t0
    yaw: float                        # rad at t0
    twist: np.ndarray                 # (3,) vx, vy (m/s, body), wz (rad/s)
    delay: float = 0.0                # s

    def _moving_time(self, t: float) -> float:
        s = t - self.t0 - self.delay
        return max(s, 0.0) if self.delay > 0.0 else s

    def pose(self, t: float) -> tuple[np.ndarray, float]:
        """Reference base xy (2,) and yaw at sim time ``t``."""
        s = self._moving_time(t)
        vx, vy, wz = self.twist
        yaw = self.yaw + wz * s
        theta = wz * s
        # Integral of R(yaw0 + wz u) du over [0, s] = R(yaw0) @ [[a, -b], [b, a]] * s with
        # a = sin(theta) / theta, b = (1 - cos(theta)) / theta; series near theta = 0.
        if abs(theta) < 1e-6:
            a, b = 1.0 - theta**2 / 6.0, theta / 2.0
        else:
            a, b = math.sin(theta) / theta, (1.0 - math.cos(theta)) / theta
        local = np.array([a * vx - b * vy, b * vx + a * vy]) * s
        return self.position + _rot(self.yaw) @ local, yaw

    def foot(self, t: float, offset_xy: np.ndarray) -> np.ndarray:
        """World xy of a point fixed to the reference trunk at ``offset_xy`` (base frame)."""
        p, yaw = self.pose(t)
        return p + _rot(yaw) @ offset_xy


def _clamp_step(prev_xy: np.ndarray, target_xy: np.ndarray, yaw: float,
                params: GaitParams) -> np.ndarray:
    """Limit the foot displacement per step, in the reference body frame."""
    d_body = _rot(yaw).T @ (target_xy - prev_xy)
    d_body = np.clip(d_body, [-params.max_step_length_x, -params.max_step_length_y],
                     [params.max_step_length_x, params.max_step_length_y])
    return prev_xy + _rot(yaw) @ d_body


def compute_footholds(velocity_set_point, initial_feet: np.ndarray, base_position: np.ndarray,
                      base_yaw: float, hips: np.ndarray | None, next_leg: int,
                      start_time: float, params: GaitParams, n: int | None = None,
                      delay: float = 0.0, stride_correction=None,
                      stride_time_scale: float = 1.0, trend_shift=None,
                      placed_twists=None, placed_until=None,
                      placed_poses=None, rest_offset=None) -> FootholdPlan:
    """compFootholds of Algorithm 1: the next ``n`` steps from the actual state at ``start_time``.

    velocity_set_point: (vx, vy, wz), body frame, m/s and rad/s; clamped to the limits.
    initial_feet: (4, 3) actual feet, world, all in stance at ``start_time``.
    base_position, base_yaw: actual base (3,) world and yaw (rad) at ``start_time``.
    hips: (4, 3) actual hip positions, world (used by foothold correction); None: from the base
        pose and ``params.hip_offsets``.
    next_leg: the leg that swings first, with the rest of its group (``params.swing_groups``;
        their lift-off comes after a four-feet phase).
    delay: s of standing before the first lift-off and before the reference starts to move
        (the start of a run); 0 for a re-plan at a touchdown.
    stride_correction: (2,) m, body frame, added to every stride (velocity feedback,
        speed_feedback.SpeedFeedback); None: none.
    stride_time_scale: the measured over the planned step period (speed_feedback.StepTiming):
        footholds are laid out along the reference as it will be at the actual, later
        touchdowns (the twist times this scale over the planned times); the plan's times and
        trunk yaw reference keep the planned timing. 1.0: as planned.
    trend_shift: (2,) m, world: the trunk's trend (its sway averaged out,
        speed_feedback.trunk_trend) minus the base. The hips are moved by it, and foothold
        correction then restores the shape of the foot pattern about them at every step and
        moves the whole pattern with them only by more than ``params.correction_threshold`` (a
        push); a smaller common offset of the feet from the hips (the trunk lagging its feet)
        is the velocity feedback's. None: the actual hips, corrected about beyond the threshold
        only (their sway alone reaches it).
    placed_twists: (4, 3) per leg, the (vx, vy, wz) set-point its foot was placed for (zeros
        for a foot placed standing); None: the set-point of this plan. placed_until (4,) s and
        placed_poses (4, 3) (x m, y m, yaw rad, world): per leg, the re-plan that first planned
        another set-point and the actual base then. A leg whose twist is not this plan's takes
        its first stride from its foot back along the old twist's reference from that base to
        its last mid-stance, and along the new one from this base to its next (feed-forward of
        a set-point change, docs/gait.md, "Response to a set-point change"): the pattern takes
        the new set-point's shape at once, about where the trunk has actually got to since.
    rest_offset: (2,) m, body frame: added once to each leg's first foothold, the later ones
        following it (a stopping plan's: where the trunk moving now comes to rest,
        ``replanner.capture_offset``); None: none. A stopping plan corrects each first
        foothold about its hip in full (below ``correction_threshold`` too): the feet come to
        rest about the trunk.
    Footholds keep each foot's actual height (flat terrain).
    """
    params.validate()
    n = params.n_footholds if n is None else int(n)
    feet = np.asarray(initial_feet, dtype=float).reshape(4, 3).copy()
    base_xy = np.asarray(base_position, dtype=float).reshape(-1)[:2]
    hip_offsets = np.asarray(params.hip_offsets, dtype=float)
    stance = np.asarray(params.stance_offsets, dtype=float)
    if hips is None:
        hips_xy = base_xy + hip_offsets @ _rot(base_yaw).T
    else:
        hips_xy = np.asarray(hips, dtype=float).reshape(4, 3)[:, :2]
    if trend_shift is not None:
        hips_xy = hips_xy + np.asarray(trend_shift, dtype=float).reshape(2)
    twist = clamp_velocity(velocity_set_point, params)
    correction = (np.zeros(2) if stride_correction is None
                  else np.asarray(stride_correction, dtype=float).reshape(2))
    rest_shift = (np.zeros(2) if rest_offset is None
                  else _rot(base_yaw) @ np.asarray(rest_offset, dtype=float).reshape(2))
    if not (math.isfinite(stride_time_scale) and stride_time_scale > 0):
        raise ValueError(f'stride_time_scale must be finite, > 0, got {stride_time_scale}')
    # ref: the trunk reference in planned time (the steps' yaw); placed: the same reference
    # stretched to the step period actually walked, for where the feet go.
    ref = ReferenceTrajectory(start_time, base_xy.copy(), float(base_yaw), twist, float(delay))
    # The set-point limits bound the stretched strides too: at the top speed the strides stay
    # those the limits allow (a stretched 0.2 m/s stride stumbled once: measured, docs/gait.md).
    placed = ReferenceTrajectory(start_time, base_xy.copy(), float(base_yaw),
                                 clamp_velocity(twist * float(stride_time_scale), params),
                                 float(delay))
    half_stance = 0.5 * params.stance_duration

    plan = FootholdPlan(start_time=start_time, initial_feet=feet.copy(),
                        initial_yaw=float(base_yaw))
    last_xy = {leg: feet[leg, :2].copy() for leg in range(4)}   # previous foothold per leg
    last_mid: dict[int, float] = {}                             # its mid-stance time
    groups = params.swing_groups
    if next_leg not in params.sequence:
        raise ValueError(f'next_leg {next_leg} is not in the sequence {params.sequence}')
    k0 = group_index(groups, next_leg)
    # The steps' times: the first lift-off comes after a four-feet phase (or the standing delay
    # at the start); mid: the middle of the coming stance. A step of a group is one entry per
    # leg, all with the group's times; step_of: the index of each entry's step (its group).
    timing = []
    step_of = []
    next_liftoff = start_time + max(float(delay), params.four_feet_duration)
    for j in range(n):
        touchdown = next_liftoff + params.swing_duration
        for leg in groups[(k0 + j) % len(groups)]:
            timing.append((leg, next_liftoff, touchdown, touchdown + half_stance))
            step_of.append(j)
        next_liftoff = touchdown + params.four_feet_duration
    previous = _previous_references(placed_twists, placed_until, placed_poses, twist, placed,
                                    stride_time_scale, params)
    first_targets = _first_footholds(timing, feet, hips_xy, placed, previous, params,
                                     sway_free=trend_shift is not None,
                                     stopping=rest_offset is not None)
    for j, (leg, liftoff, touchdown, mid) in zip(step_of, timing, strict=True):
        offset = hip_offsets[leg] + stance[leg]
        _, yaw_td = ref.pose(touchdown)
        shift = _rot(yaw_td) @ correction             # velocity feedback, world frame
        if leg in last_mid:
            # Later footholds of a leg: previous foothold plus one stride of the reference.
            target = (last_xy[leg] + placed.foot(mid, offset) - placed.foot(last_mid[leg], offset)
                      + shift)
        else:
            target = first_targets[leg] + shift + rest_shift
        target = _clamp_step(last_xy[leg], target, yaw_td, params)
        last_xy[leg] = target
        last_mid[leg] = mid
        plan.steps.append(Step(
            leg=leg, liftoff_time=liftoff, touchdown_time=touchdown,
            target=np.array([target[0], target[1], feet[leg, 2]]),
            step_height=params.step_height, haptic=params.haptic,
            replan=(j + 1) % params.replan_window == 0, yaw=yaw_td))
    return plan


def _previous_references(placed_twists, placed_until, placed_poses, twist: np.ndarray,
                         placed: ReferenceTrajectory, stride_time_scale: float,
                         params: GaitParams) -> list[ReferenceTrajectory]:
    """Per leg, the reference its foot was placed along: the plan's own (``placed``) when the
    leg's twist is this plan's, else the old twist's from the base of the re-plan that
    replaced it (zero twist: the trunk stood there)."""
    if placed_twists is None:
        return [placed] * 4
    old = np.asarray(placed_twists, dtype=float).reshape(4, 3)
    until = np.full(4, np.inf) if placed_until is None else np.asarray(
        placed_until, dtype=float).reshape(4)
    poses = np.full((4, 3), np.nan) if placed_poses is None else np.asarray(
        placed_poses, dtype=float).reshape(4, 3)
    refs = []
    for leg in range(4):
        if np.array_equal(old[leg], twist):
            refs.append(placed)
            continue
        if not (math.isfinite(until[leg]) and np.all(np.isfinite(poses[leg]))):
            raise ValueError(f'leg {leg}: placed for another set-point, but no re-plan and base '
                             'where it changed')
        if not np.any(old[leg]):
            # Placed standing: the trunk stood at the base of that re-plan.
            refs.append(ReferenceTrajectory(float(until[leg]), poses[leg, :2].copy(),
                                            float(poses[leg, 2]), np.zeros(3)))
            continue
        # Placed walking: the old reference, continued from where the new one, run back from
        # this base, puts the trunk at the change (a trunk lagging its reference does not
        # shift the pattern back).
        position, yaw = placed.pose(float(until[leg]))
        stretched = clamp_velocity(old[leg] * float(stride_time_scale), params)
        refs.append(ReferenceTrajectory(float(until[leg]), position, yaw, stretched))
    return refs


def _first_footholds(timing: list[tuple[int, float, float, float]], feet: np.ndarray,
                     hips_xy: np.ndarray, placed: ReferenceTrajectory,
                     previous: list[ReferenceTrajectory], params: GaitParams,
                     sway_free: bool, stopping: bool = False) -> dict[int, np.ndarray]:
    """The first foothold (xy, world) of each leg in ``timing`` ((leg, lift-off, touchdown,
    mid-stance) per step), before the velocity feedback's shift: the foot's actual position
    plus one stride (along ``previous[leg]`` back to its last mid-stance, along ``placed`` on
    to its next), and the foothold correction (V.B) about the hips."""
    hip_offsets = np.asarray(params.hip_offsets, dtype=float)
    stance = np.asarray(params.stance_offsets, dtype=float)
    targets: dict[int, np.ndarray] = {}
    gaps: dict[int, np.ndarray] = {}          # hip-relative minus foot-relative, m, world
    for leg, _, _, mid in timing:
        if leg in targets:
            continue
        offset = hip_offsets[leg] + stance[leg]
        prev_mid = mid - params.cycle_duration
        targets[leg] = (feet[leg, :2] + placed.foot(mid, offset)
                        - previous[leg].foot(prev_mid, offset))
        if not params.foothold_correction:
            continue
        # About the hip, moved as the reference hip moves (V.B).
        hip_now = placed.foot(placed.t0, hip_offsets[leg])
        hip_mid = placed.foot(mid, hip_offsets[leg])
        _, yaw_mid = placed.pose(mid)
        gaps[leg] = (hips_xy[leg] + (hip_mid - hip_now) + _rot(yaw_mid) @ stance[leg]
                     - targets[leg])
    if not params.foothold_correction:
        return targets
    if stopping:
        # Coming to rest, the feet go about the hips whatever the pattern's common offset:
        # kept, the trunk stood that far off the centre of its feet and the stand plan moved
        # it there after the stop (B1's walking trot: 4 cm sideways over 1.2 s).
        return {leg: targets[leg] + gaps[leg] for leg in targets}
    if sway_free:
        # The shape of the pattern about the sway-free hips at every step; the whole pattern
        # only beyond the threshold (a push): a smaller common offset is the trunk lagging
        # or leading its feet, which placement about the hips would feed back into the speed.
        common = np.mean(list(gaps.values()), axis=0)
        if np.linalg.norm(common) <= params.correction_threshold:
            return {leg: targets[leg] + gaps[leg] - common for leg in targets}
        return {leg: targets[leg] + gaps[leg] for leg in targets}
    # The actual hips sway: only beyond the threshold (a push). Below it the foot-relative
    # placement stands: hip-relative placement at every step feeds the crawl's sway and lag
    # back into the feet, and the walk settles ~20 % slower than commanded (docs/gait.md).
    return {leg: targets[leg] + gaps[leg] if np.linalg.norm(gaps[leg])
            > params.correction_threshold else targets[leg] for leg in targets}


def stance_phases(plan: FootholdPlan) -> list[tuple[float, float, np.ndarray, np.ndarray]]:
    """Support phases of a plan: (t_start, t_end, feet (4, 3), in_stance (4,) bool) each.

    Phases follow the planned times: four feet, then three during each swing of a crawl (two
    during each swing of a trot's pair, ``step_groups``), ...; the last four-feet phase has
    ``t_end = inf`` (the final stance holds). With no four-feet phase between two groups (a
    trot) one two-feet phase follows the other. Idle triggers (zero-length steps of a stand
    plan) move no foot and add no phase.
    """
    feet = plan.initial_feet.copy()
    phases = []
    t = plan.start_time
    for group in step_groups(plan.steps):
        steps = [plan.steps[i] for i in group]
        if is_idle_trigger(steps[0]):
            continue                 # moves no foot: the four-feet phase goes on
        first = steps[0]
        all_down = np.ones(4, dtype=bool)
        if first.liftoff_time > t + _EPS:
            phases.append((t, first.liftoff_time, feet.copy(), all_down))
        swing = all_down.copy()
        for step in steps:
            swing[step.leg] = False
        phases.append((first.liftoff_time, first.touchdown_time, feet.copy(), swing))
        for step in steps:
            feet[step.leg] = step.target
        t = first.touchdown_time
    phases.append((t, math.inf, feet.copy(), np.ones(4, dtype=bool)))
    return phases


# ------------------------------------------------------------------------------ idle stance
def is_idle_trigger(step: Step) -> bool:
    """A stand plan's re-plan trigger: zero duration, zero height (it moves no foot)."""
    return step.touchdown_time <= step.liftoff_time + _EPS and step.step_height == 0.0


def is_stand_plan(plan: FootholdPlan) -> bool:
    """True if the plan has no real step: all four feet stay down over the whole horizon."""
    return all(is_idle_trigger(s) for s in plan.steps)


def stand_plan(initial_feet: np.ndarray, base_yaw: float, start_time: float,
               trigger_leg: int | None, trigger_time: float | None) -> FootholdPlan:
    """A plan that keeps all four feet where they are (idle stance).

    trigger_leg, trigger_time: the optional zero-length ``replan`` step (lift-off = touchdown =
    ``trigger_time``, target = the foot itself, height 0, not haptic) that makes both trackers
    re-plan one control tick after ``trigger_time``; None: no step at all. Put
    ``trigger_time`` between two ticks (the node uses half a tick early): the MPC samples lie on
    the tick grid, and ``support.support_schedule`` takes a leg out of the polygon on the closed
    interval [lift-off, touchdown], so a trigger on a sample would cost it one triangle.
    """
    feet = np.asarray(initial_feet, dtype=float).reshape(4, 3).copy()
    plan = FootholdPlan(start_time=start_time, initial_feet=feet.copy(),
                        initial_yaw=float(base_yaw))
    if trigger_leg is not None and trigger_time is not None:
        if not trigger_time > start_time:
            raise ValueError(f'trigger at {trigger_time} s is not after the plan start '
                             f'{start_time} s')
        plan.steps.append(Step(leg=int(trigger_leg), liftoff_time=float(trigger_time),
                               touchdown_time=float(trigger_time),
                               target=feet[int(trigger_leg)].copy(), step_height=0.0,
                               haptic=False, replan=True, yaw=float(base_yaw)))
    return plan


@dataclass
class IdleMonitor:
    """Decides, at each re-plan, whether the crawl stands still.

    Until the first non-zero set-point of a run the robot stands from its first re-plan on.
    After walking, the zero run starts at the first re-plan tick whose set-point is zero and
    ends at the first one whose set-point is not; the crawl stands at the first re-plan at
    least ``idle_after - tolerance`` later. With the defaults (3 s, half a step) that is the
    fifth touchdown after the change: the four steps of a cycle stepped in place, each leg
    once; the tolerance keeps a few ms of haptic touchdown jitter over those four steps from
    costing a fifth.
    Re-plan ticks, not the set-point's own stamp: ``scripts/rerun.sh`` replays a bag's
    set-points stamped with the re-plans that used them (``velocity_setpoint``), so the re-run
    reaches the same decisions. A non-zero set-point that came and went between two re-plans
    (less than a step) is not seen, as by any re-plan.
    """

    idle_after: float = 3.0                 # s
    enabled: bool = True
    tolerance: float = 0.0                  # s
    zero_since: float | None = None         # s, re-plan tick that started the zero run
    # No non-zero set-point yet in this run: the robot has not been told to walk, so it
    # stands from the first re-plan on (no step in place, no sway: nothing to wait for).
    never_walked: bool = True

    def update(self, t: float, set_point) -> bool:
        """The re-plan at sim time ``t`` uses ``set_point`` (vx, vy, wz); True: stand still."""
        if np.any(np.asarray(set_point, dtype=float) != 0.0):
            self.zero_since = None
            self.never_walked = False
            return False
        if self.zero_since is None:
            self.zero_since = float(t)
        return self.stands_at(t)

    def stands_at(self, t: float) -> bool:
        """True if a re-plan at sim time ``t`` would stand still, the set-point staying zero
        until then (``update`` has seen the zero run start)."""
        if not self.enabled or self.zero_since is None:
            return False
        return (self.never_walked
                or t - self.zero_since >= self.idle_after - self.tolerance - _EPS)
