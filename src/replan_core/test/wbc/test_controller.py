"""Closed-loop tests of replan_core.wbc.controller in the PyBullet world (replan_core.sim.world)."""

from pathlib import Path

import numpy as np
import pytest

from replan_core.bench.damping_bench import sit_down
from replan_core.bench.wbc_bench import crawl_plan
from replan_core.common.rotations import yaw_of
from replan_core.common.types import STANDING_POSE, BaseState, JointState, Step
from replan_core.gait.swing import swing_trajectory
from replan_core.wbc.controller import (
    JointStandUp,
    PlanFollower,
    StandHold,
    SwingReference,
    WholeBodyController,
    first_swing_liftoff,
    haptic_reference,
    plan_ends_stand,
    swing_reference,
    trunk_tilt,
)
from replan_core.wbc.settings import WbcParams

ROOT = Path(__file__).resolve().parents[4]
DT = 0.004  # s, control period


def roll_pitch(quaternion) -> tuple[float, float]:
    x, y, z, w = quaternion
    roll = np.arctan2(2 * (w * x + y * z), 1 - 2 * (x * x + y * y))
    pitch = np.arcsin(np.clip(2 * (w * y - z * x), -1.0, 1.0))
    return float(roll), float(pitch)


def run(world, wbc, reference, duration):
    """Close the loop for ``duration`` s; ``reference(t, base, contact)`` gives the compute()
    arguments after the state. Returns one record per tick."""
    log = []
    for _ in range(round(duration / DT)):
        base, joints, contact = world.base_state(), world.joint_state(), world.contact_state()
        com_ref, yaw_ref, stance, swing = reference(world.time, base, contact)
        result = wbc.compute(base, joints, contact.contact, com_ref, yaw_ref, stance, swing)
        assert np.all(np.isfinite(result.torque))
        log.append((world.time, base, contact, result))
        world.step(result.torque)
    return log


def initial_com(world, robot) -> np.ndarray:
    return robot.com_state(world.base_state(), world.joint_state())[0]


def test_standing_still(world, robot):
    """10 s of sim time standing: CoM error < 1 cm, no drift, level trunk, no fallback."""
    wbc = WholeBodyController(robot)
    com0 = initial_com(world, robot)
    ref = (com0, np.zeros(3), np.zeros(3))
    log = run(world, wbc, lambda t, b, c: (ref, 0.0, np.ones(4, bool), ()), 10.0)
    errors = np.array([np.linalg.norm(r.com_error) for *_, r in log])
    assert errors.max() < 0.01
    # No drift: the error over the last second is no larger than after the first one.
    assert abs(errors[-250:].mean() - errors[250:500].mean()) < 0.002
    final_base = log[-1][1]
    assert np.linalg.norm(final_base.position[:2]) < 0.01
    assert max(abs(a) for a in roll_pitch(final_base.quaternion)) < 0.02
    assert all(r.qp_status == 'solved' and not r.fallback for *_, r in log)
    assert log[-1][2].contact.all()


def test_lateral_com_sine(world, robot):
    """A slow lateral sine (5 cm, 0.25 Hz) inside the four-feet polygon: error < 2 cm."""
    wbc = WholeBodyController(robot)
    com0 = initial_com(world, robot)
    amplitude, omega = 0.05, 2 * np.pi * 0.25

    def reference(t, base, contact):
        offset = np.array([0.0, amplitude, 0.0])
        p = com0 + offset * np.sin(omega * t)
        v = offset * omega * np.cos(omega * t)
        a = -offset * omega**2 * np.sin(omega * t)
        return (p, v, a), 0.0, np.ones(4, bool), ()

    log = run(world, wbc, reference, 8.0)
    errors = np.array([np.linalg.norm(r.com_error) for *_, r in log])
    assert errors.max() < 0.02
    # It really moved: the CoM swept most of the sine.
    actual_y = np.array([com0[1] + amplitude * np.sin(omega * t) - r.com_error[1]
                         for t, _, _, r in log])
    assert actual_y.max() - com0[1] > 0.8 * amplitude
    assert com0[1] - actual_y.min() > 0.8 * amplitude
    assert all(not r.fallback for *_, r in log)


def _shift_then_lift(world, robot, wbc, target_offset, haptic):
    """Shift the CoM into the rf-lh-rh triangle, then swing lf to start + target_offset."""
    com0 = initial_com(world, robot)
    feet0 = world.contact_state().foot_position.copy()
    support = feet0[[1, 2, 3]].mean(axis=0)
    com_goal = com0.copy()
    com_goal[:2] += 0.6 * (support[:2] - com0[:2])      # ~7 cm inside the triangle
    t_shift, t_lift, t_td = 1.5, 1.6, 2.2
    step = Step(leg=0, liftoff_time=t_lift, touchdown_time=t_td, target=feet0[0] + target_offset,
                step_height=0.05, haptic=haptic, replan=False, yaw=0.0)
    state = {}

    def reference(t, base, contact):
        s = min(t / t_shift, 1.0)
        blend = s**3 * (10 - 15 * s + 6 * s * s)
        dblend = 30 * s * s * (1 - s) ** 2 / t_shift
        ddblend = 60 * s * (1 - s) * (1 - 2 * s) / t_shift**2
        d = com_goal - com0
        com_ref = (com0 + d * blend, d * dblend, d * ddblend)
        swing = ()
        stance = np.ones(4, bool)
        if t >= t_lift and 'landed' not in state:
            if haptic and t >= t_lift + 0.5 * (t_td - t_lift) and contact.contact[0]:
                state['landed'] = t                     # sensed touchdown: back to stance
            else:
                stance[0] = False
                swing = (swing_reference(step, feet0[0], t, swing_trajectory, 0.15),)
        return com_ref, 0.0, stance, swing

    return step, feet0, reference, state


def test_one_leg_lifted_to_target(world, robot):
    """Three legs stand, lf swings to a target 10 cm away (in the air): reached within 2 cm,
    trunk stays up and level."""
    wbc = WholeBodyController(robot)
    offset = np.array([0.06, 0.0, 0.08])                 # |offset| = 10 cm
    step, feet0, reference, _ = _shift_then_lift(world, robot, wbc, offset, haptic=False)
    log = run(world, wbc, reference, 3.0)
    foot = world.contact_state().foot_position[0]
    assert np.linalg.norm(foot - step.target) < 0.02
    base_z = [b.position[2] for _, b, *_ in log]
    assert min(base_z) > log[0][1].position[2] - 0.03
    for _, b, _, r in log:
        assert max(abs(a) for a in roll_pitch(b.quaternion)) < 0.05
        assert not r.fallback
    # The three stance feet did not slip.
    feet = world.contact_state().foot_position
    assert np.linalg.norm(feet[1:] - feet0[1:], axis=1).max() < 0.01
    assert np.linalg.norm(log[-1][3].com_error) < 0.02


def test_haptic_step_to_ground(world, robot):
    """lf steps 10 cm forward onto the ground; in haptic mode it keeps descending after the
    planned touchdown (target 3 cm above the ground) until contact is sensed."""
    wbc = WholeBodyController(robot)
    offset = np.array([0.10, 0.0, 0.03])
    step, feet0, reference, state = _shift_then_lift(world, robot, wbc, offset, haptic=True)
    log = run(world, wbc, reference, 3.5)
    assert 'landed' in state and state['landed'] > step.touchdown_time
    contact = world.contact_state()
    assert contact.contact.all()
    foot = contact.foot_position[0]
    np.testing.assert_allclose(foot[:2], step.target[:2], atol=0.02)
    assert abs(foot[2] - feet0[0][2]) < 0.01
    assert all(not r.fallback for *_, r in log)


def test_haptic_reference_descends():
    ref = haptic_reference(np.array([0.3, 0.2, 0.05]), 1.0, 1.2, 0.15, leg=2)
    np.testing.assert_allclose(ref.position, [0.3, 0.2, 0.05 - 0.03])
    np.testing.assert_allclose(ref.velocity, [0.0, 0.0, -0.15])
    assert ref.leg == 2
    before = haptic_reference(np.zeros(3), 1.0, 0.5, 0.15, leg=0)
    np.testing.assert_allclose(before.position, np.zeros(3))


def _state(world):
    return world.base_state(), world.joint_state(), world.contact_state()


def test_nan_inputs_fall_back(world, robot):
    """Non-finite state or reference never gives non-finite torques; the result reports it."""
    wbc = WholeBodyController(robot)
    base, joints, contact = _state(world)
    com0 = robot.com_state(base, joints)[0]
    good = wbc.compute(base, joints, contact.contact, (com0, np.zeros(3), np.zeros(3)), 0.0,
                       np.ones(4, bool))
    assert not good.fallback and good.qp_status == 'solved'
    bad_joints = JointState(joints.stamp, joints.position.copy(), joints.velocity.copy(),
                            joints.effort)
    bad_joints.velocity[4] = np.nan
    res = wbc.compute(base, bad_joints, contact.contact, (com0, np.zeros(3), np.zeros(3)), 0.0,
                      np.ones(4, bool))
    assert res.fallback and np.all(np.isfinite(res.torque)) and 'state' in res.message
    res = wbc.compute(base, joints, contact.contact,
                      (com0 * np.nan, np.zeros(3), np.zeros(3)), 0.0, np.ones(4, bool))
    assert res.fallback and np.all(np.isfinite(res.torque))
    bad_base = BaseState(base.stamp, base.position, np.zeros(4), base.linear_velocity,
                         base.angular_velocity)
    res = wbc.compute(bad_base, joints, contact.contact, (com0, np.zeros(3), np.zeros(3)),
                      0.0, np.ones(4, bool))
    assert res.fallback and np.all(np.isfinite(res.torque))
    # The fallback holds the stance torques (close to the good ones at rest).
    assert np.abs(res.torque - good.torque).max() < 5.0
    # Recovers at once on good input.
    res = wbc.compute(base, joints, contact.contact, (com0, np.zeros(3), np.zeros(3)), 0.0,
                      np.ones(4, bool))
    assert not res.fallback and np.all(np.isfinite(res.torque))


def test_torques_clipped_and_forces_consistent(world, robot):
    """Forces respect the bounds and cones; swing legs get no force; torques within limits."""
    params = WbcParams(friction=0.5, fz_min=15.0)
    wbc = WholeBodyController(robot, params)
    base, joints, contact = _state(world)
    com0 = robot.com_state(base, joints)[0]
    stance = np.array([True, True, True, False])
    feet = contact.foot_position
    swing = (SwingReference(3, feet[3] + [0, 0, 0.5], np.zeros(3), np.zeros(3)),)
    res = wbc.compute(base, joints, contact.contact,
                      (com0, np.zeros(3), np.array([0.0, 3.0, 0.0])), 0.3, stance, swing)
    assert res.qp_status == 'solved'
    np.testing.assert_allclose(res.forces[3], 0.0, atol=1e-6)
    mu = 0.5 / np.sqrt(2)
    for f in res.forces[:3]:
        assert f[2] >= 15.0 - 1e-4
        assert abs(f[0]) <= mu * f[2] + 1e-4 and abs(f[1]) <= mu * f[2] + 1e-4
    assert np.all(np.abs(res.torque) <= robot.effort_limit + 1e-9)
    assert res.swing_error[3] == pytest.approx(0.5, abs=0.01)
    assert res.saturated >= 1                  # a 50 cm swing error saturates the leg


def test_yaw_of():
    for yaw in (-3.0, -0.5, 0.0, 1.2):
        q = np.array([0.0, 0.0, np.sin(yaw / 2), np.cos(yaw / 2)])
        assert yaw_of(q) == pytest.approx(yaw)


def test_plan_follower_crawl(world, robot):
    """A static crawl cycle (4 haptic steps, 8 cm each) through PlanFollower + StepTracker:
    every step touches down by sensed contact, the robot advances, CoM error < 2 cm."""
    wbc = WholeBodyController(robot)
    contacts = world.contact_state()
    com0 = initial_com(world, robot)
    footholds, com_plan = crawl_plan(0.2, contacts.foot_position, com0, cycles=1)
    follower = PlanFollower(footholds, com_plan)

    def reference(t, base, contact):
        follower.update(t, contact)
        return follower.references(t)

    log = run(world, wbc, reference, com_plan.end_time)
    assert follower.tracker.touchdown_reason == ['contact'] * 4
    assert max(np.linalg.norm(r.com_error) for *_, r in log) < 0.02
    assert all(not r.fallback for *_, r in log)
    final = world.contact_state()
    assert final.contact.all()
    np.testing.assert_allclose(final.foot_position[:, 0] - contacts.foot_position[:, 0], 0.08,
                               atol=0.02)
    for _, b, *_ in log:
        assert max(abs(a) for a in roll_pitch(b.quaternion)) < 0.05


def test_stand_hold_lowers_a_lifted_leg(world, robot):
    """StandHold (no plan): a leg caught in the air descends until contact, then all stand."""
    wbc = WholeBodyController(robot)
    com0 = initial_com(world, robot)
    feet0 = world.contact_state().foot_position.copy()
    goal = com0.copy()
    goal[:2] += 0.6 * (feet0[[1, 2, 3], :2].mean(axis=0) - com0[:2])
    lifted = (SwingReference(0, feet0[0] + [0.0, 0.0, 0.08], np.zeros(3), np.zeros(3)),)
    stance = np.array([False, True, True, True])
    run(world, wbc, lambda t, b, c: ((goal, np.zeros(3), np.zeros(3)), 0.0,
                                     np.ones(4, bool) if t < 1.5 else stance,
                                     () if t < 1.5 else lifted), 2.2)
    contacts = world.contact_state()
    assert not contacts.contact[0]
    base, joints = world.base_state(), world.joint_state()
    hold = StandHold(world.time, robot.com_state(base, joints)[0], yaw_of(base.quaternion),
                     contacts)
    log = run(world, wbc, lambda t, b, c: hold.references(t, c), 1.5)
    assert world.contact_state().contact.all()
    assert hold.standing.all()
    assert max(np.linalg.norm(r.com_error) for *_, r in log) < 0.02


def test_plan_ends_stand_only_made_for_about_now():
    feet = np.array([[0.37, 0.3, 0.0], [0.37, -0.3, 0.0], [-0.37, 0.3, 0.0], [-0.37, -0.3, 0.0]])
    footholds, _ = crawl_plan(10.0, feet, np.array([0.0, 0.0, 0.55]), shift_time=0.25)
    assert first_swing_liftoff(footholds) == pytest.approx(10.25)
    assert plan_ends_stand(footholds, 10.1, max_age=0.5, min_lead=0.1)
    assert plan_ends_stand(footholds, 10.15, max_age=0.5, min_lead=0.1)
    assert not plan_ends_stand(footholds, 10.16, max_age=0.5, min_lead=0.1)   # lead 0.09 s
    assert not plan_ends_stand(footholds, 10.256, max_age=0.5, min_lead=0.1)  # lifted already
    assert not plan_ends_stand(footholds, 10.05, max_age=0.04, min_lead=0.1)  # too old
    # A stand plan's zero-length trigger step moves no foot: only the age counts.
    footholds.steps = [Step(0, 10.5, 10.5, feet[0], 0.0, True, True, 0.0)]
    assert first_swing_liftoff(footholds) is None
    assert plan_ends_stand(footholds, 10.49, max_age=0.5, min_lead=0.1)


def _tilt_after_adopting_late(world, robot, late: float) -> tuple[float, bool]:
    """Stand (StandHold) 1 s, then a crawl plan made then, adopted ``late`` s after its
    start: the largest trunk tilt (rad) over 3.5 s, and whether plan_ends_stand allowed it."""
    wbc = WholeBodyController(robot)
    base, joints, contacts = world.base_state(), world.joint_state(), world.contact_state()
    hold = StandHold(world.time, robot.com_state(base, joints)[0], yaw_of(base.quaternion),
                     contacts)
    run(world, wbc, lambda t, b, c: hold.references(t, c), 1.0)
    start = world.time
    footholds, com_plan = crawl_plan(start, world.contact_state().foot_position,
                                     initial_com(world, robot), cycles=1)
    allowed = plan_ends_stand(footholds, start + late, max_age=10.0, min_lead=0.1)
    follower = PlanFollower(footholds, com_plan)

    def reference(t, base, contact):
        if t < start + late - 1e-9:
            return hold.references(t, contact)
        follower.update(t, contact)
        return follower.references(t)

    log = run(world, wbc, reference, 3.5)
    return max(trunk_tilt(b.quaternion) for _, b, *_ in log), allowed


@pytest.mark.parametrize('late, allowed', [(0.7, True), (0.806, False)])
def test_a_plan_adopted_from_a_stand_after_its_first_liftoff_tips_the_robot(world, robot, late,
                                                                           allowed):
    """Why plan_ends_stand asks for a lead: the crawl plan's CoM shifts over 0.8 s to the
    three stance feet before the first lift-off. Adopted 0.1 s before that lift-off, the CoM
    reference jumps the last part and the robot crawls on level; adopted 6 ms after it (a
    restarted MPC's first plan in CI), the foot lifts with the CoM between the four
    and the trunk tips over the swing leg (48 deg)."""
    tilt, ok = _tilt_after_adopting_late(world, robot, late)
    assert ok is allowed
    if allowed:
        assert np.degrees(tilt) < 5.0
    else:
        assert np.degrees(tilt) > 20.0


def test_plan_follower_yaw_ramps_through_the_planned_touchdowns():
    """Turning: the yaw reference moves between touchdowns, not only at them (each re-plan
    starts from the actual yaw, so a stepwise reference would never turn the robot)."""
    from replan_core.common.types import ComPlan, FootholdPlan
    from replan_core.wbc.controller import PlanFollower

    feet = np.array([[0.37, 0.32, 0.02], [0.37, -0.32, 0.02], [-0.37, 0.32, 0.02],
                     [-0.37, -0.32, 0.02]])
    steps = [Step(leg, 5.25 + 0.75 * i, 5.75 + 0.75 * i, feet[leg], 0.1, True, i == 0,
                  0.1 + 0.2 * (0.75 + 0.75 * i)) for i, leg in enumerate([2, 0, 3, 1])]
    plan = FootholdPlan(5.0, feet, 0.1, steps)
    com = ComPlan(5.0, 0.04, np.zeros((201, 3)), np.zeros((201, 3)), np.zeros((201, 3)))
    follower = PlanFollower(plan, com)
    for t in (5.0, 5.3, 5.75, 6.0, 7.1):
        expected = 0.1 + 0.2 * (t - 5.0)          # 0.2 rad/s from 0.1 rad
        assert follower.references(t)[1] == pytest.approx(expected, abs=1e-9)
        assert follower.yaw_rate(t) == pytest.approx(0.2, abs=1e-9)
    assert follower.yaw_rate(4.0) == 0.0 and follower.yaw_rate(9.0) == 0.0


def test_joint_stand_up_path_starts_sitting_ends_standing_at_rest():
    sitting = STANDING_POSE + 0.7
    stand_up = JointStandUp(2.0, sitting, STANDING_POSE, duration=1.5, hold=0.5)
    q, qd, load = stand_up.reference(1.0)               # before its start: the sitting pose
    np.testing.assert_allclose(q, sitting)
    assert load == 0.0 and not qd.any()
    q, qd, load = stand_up.reference(2.75)              # half way: half the path, fastest
    np.testing.assert_allclose(q, sitting - 0.35)
    assert load == pytest.approx(0.5)
    np.testing.assert_allclose(qd, -0.7 * 1.875 / 1.5)  # min-jerk peak rate 15/8 per duration
    q, qd, load = stand_up.reference(3.6)
    np.testing.assert_allclose(q, STANDING_POSE)
    assert load == 1.0 and not qd.any()
    assert not stand_up.done(3.99) and stand_up.done(4.0)
    with pytest.raises(ValueError):
        JointStandUp(0.0, sitting, duration=0.0)


def test_joint_stand_up_raises_a_robot_that_sat_down(world, robot):
    """The sim's damping mode sits the robot down on its trunk; the stand-up needs no base
    state and ends standing, level, on all four feet, where it sat."""
    wbc = WholeBodyController(robot, WbcParams())
    standing = np.median(wbc.leg_heights(JointState(0.0, STANDING_POSE, np.zeros(12),
                                                    np.zeros(12))))
    for _ in range(round(3.0 / DT)):
        world.step(world.damping_torques(40.0))
    sat = world.base_state().position.copy()
    assert sat[2] < 0.4
    assert np.median(wbc.leg_heights(world.joint_state())) < standing - 0.1
    stand_up = JointStandUp(world.time, world.joint_state().position, STANDING_POSE, 1.5, 0.5)
    while not stand_up.done(world.time):
        result = wbc.stand_up(world.joint_state(), stand_up, world.time,
                              world.contact_state().contact)
        assert not result.fallback and result.qp_status == 'stand_up'
        world.step(result.torque)
    base = world.base_state()
    assert base.position[2] > 0.58                     # standing: 0.599 m at spawn
    assert np.linalg.norm(base.position[:2] - sat[:2]) < 0.05
    assert abs(base.quaternion[0]) < 0.02 and abs(base.quaternion[1]) < 0.02    # level
    assert world.contact_state().contact.all()
    np.testing.assert_allclose(wbc.leg_heights(world.joint_state()), standing, atol=0.02)


@pytest.mark.parametrize('lifted_leg, sideways', [(3, 0.3), (0, -0.3), (2, 0.3), (1, -0.3)])
def test_damping_mode_sits_down_without_rolling_over(urdf, robot, lifted_leg, sideways):
    """The controller dies while a leg is in the air and the trunk moves sideways (the
    realistic robot: payload, leg mass errors, actuators, compliant feet). With the abduction
    joints held the robot sits down upright. (With damping alone one case of twelve rolls over,
    which one is chaotic: python -m replan_core.bench.damping_bench compares them.)"""
    roll, sat = sit_down(urdf, robot, lifted_leg, sideways, abduction_stiffness=200.0)
    assert roll < 15.0 and 0.25 < sat < 0.4, (roll, sat)


@pytest.mark.parametrize(('quaternion', 'tilt'), [
    ((0.0, 0.0, 0.0, 1.0), 0.0),                                        # upright
    ((0.0, 0.0, np.sin(0.6), np.cos(0.6)), 0.0),                        # yaw only
    ((np.sin(0.25), 0.0, 0.0, np.cos(0.25)), 0.5),                      # roll 0.5 rad
    ((0.0, np.sin(0.5), 0.0, np.cos(0.5)), 1.0),                        # pitch 1 rad
    ((1.0, 0.0, 0.0, 0.0), np.pi),                                      # on its back
])
def test_trunk_tilt_is_the_angle_of_the_trunk_z_axis_to_the_vertical(quaternion, tilt):
    assert trunk_tilt(np.array(quaternion)) == pytest.approx(tilt, abs=1e-12)


def test_fallen_torques_only_damp_the_joints(world, robot):
    """A fallen robot's legs get -fall_damping * qd, within the limits, finite for NaN input;
    never a posture to hold or a force to push with."""
    wbc = WholeBodyController(robot, WbcParams(fall_damping=4.0))
    _, joints, contact = _state(world)
    rng = np.random.default_rng(3)
    velocity = rng.uniform(-2.0, 2.0, 12)
    moving = JointState(joints.stamp, joints.position, velocity, joints.effort)
    result = wbc.fallen(moving, contact.contact)
    np.testing.assert_allclose(result.torque, -4.0 * velocity, rtol=0, atol=1e-12)
    assert result.qp_status == 'fallen' and not result.fallback and result.saturated == 0
    assert not result.stance.any() and not result.forces.any()
    fast = JointState(joints.stamp, joints.position, np.full(12, 1e3), joints.effort)
    clipped = wbc.fallen(fast, contact.contact)
    assert clipped.saturated == 12 and np.all(clipped.torque < 0.0)
    assert np.all(np.abs(clipped.torque) <= world.effort_limit + 1e-9)
    broken = JointState(joints.stamp, joints.position, np.full(12, np.nan), joints.effort)
    assert np.all(wbc.fallen(broken, contact.contact).torque == 0.0)


def test_fallen_torques_let_a_tipped_robot_come_to_rest(world, robot):
    """Rolled over in the simulator (a torque about the trunk's x axis) and given the fallen
    torques, the robot comes to rest: the joints slow down instead of swinging at their
    limits."""
    wbc = WholeBodyController(robot)
    speeds = []
    for k in range(round(3.0 / DT)):
        world.set_external_wrench(np.zeros(3), np.array([600.0 if k * DT < 0.3 else 0.0, 0, 0]))
        joints = world.joint_state()
        result = wbc.fallen(joints, world.contact_state().contact)
        world.step(result.torque)
        speeds.append(float(np.abs(joints.velocity).max()))
    assert trunk_tilt(world.base_state().quaternion) > WbcParams().fall_tilt
    assert max(speeds[-50:]) < 0.2, max(speeds[-50:])


@pytest.mark.parametrize('name', ['go1', 'anymal_c'])
def test_the_wbc_bench_crawls_another_robot(name):
    """``scripts/bench_wbc.sh --robot``: the robot's model and names, HyQ's controller values
    scaled to it by config/robots/scaling.yaml (each as the launcher derives it), and the
    crawl; one cycle closes every haptic step with the CoM tracked to 1 cm and no force-QP
    fallback."""
    from replan_core.bench import bench_robots
    from replan_core.bench.wbc_bench import bench_robot, run
    from replan_core.robot.robot_file import robot_facts
    from replan_core.robot.scaling import derived_parameters

    spec, reference, rules = bench_robots(name, ROOT)
    robot = bench_robot(spec, reference, rules)
    assert robot.params.fz_max < WbcParams().fz_max            # lighter than HyQ
    # Every WbcParams field the rules name is scaled as the launcher scales it from the same
    # reference value.
    base = WbcParams()
    named = [k.split('.', 1)[1] for keys in rules['rules'].values() for k in keys
             if k.startswith('wbc.') and hasattr(base, k.split('.', 1)[1])]
    assert {'fz_min', 'fz_max', 'swing_kp', 'swing_kd', 'haptic_velocity'} <= set(named)
    launcher = derived_parameters(robot_facts(spec), robot_facts(reference),
                                  {'wbc': {n: np.asarray(getattr(base, n)).tolist()
                                           for n in named}},
                                  {'rules': {s: [k for k in keys if k[4:] in named]
                                             for s, keys in rules['rules'].items()}},
                                  measure=False)['wbc']
    for field_name in named:
        assert np.allclose(getattr(robot.params, field_name), launcher[field_name]), field_name
    figures = run('', 1, quiet=True, robot=robot)
    assert figures['steps_done'] == figures['steps'] == 4
    assert figures['fallbacks'] == 0
    assert figures['com_error_max_m'] < 0.01
    assert figures['advance_m'] > 0.5 * robot.crawl['step_length']


def _pair_follower(**kwargs):
    """A trot's pair LF + RH lifting off at 5.1 s, 0.1 m forward, down at 5.4 s: the standing
    feet and the PlanFollower of that plan (``kwargs`` to it)."""
    from replan_core.common.types import ComPlan, FootholdPlan
    from replan_core.wbc.controller import PlanFollower

    feet = np.array([[0.37, 0.32, 0.02], [0.37, -0.32, 0.02], [-0.37, 0.32, 0.02],
                     [-0.37, -0.32, 0.02]])
    steps = [Step(leg, 5.1, 5.4, feet[leg] + [0.1, 0.0, 0.0], 0.08, True, True, 0.0)
             for leg in (0, 3)]
    plan = FootholdPlan(5.0, feet, 0.0, steps)
    com = ComPlan(5.0, 0.04, np.zeros((201, 3)), np.zeros((201, 3)), np.zeros((201, 3)))
    return feet, PlanFollower(plan, com, **kwargs)


def test_plan_follower_swings_both_legs_of_a_pair():
    """A trot's pair: both legs swing from their own lift-off points, the others stand."""
    from replan_core.common.types import ContactState

    feet, follower = _pair_follower()
    down = ContactState(5.1, feet.copy(), np.zeros((4, 3)), np.ones(4, bool),
                        np.zeros(4, bool), np.zeros(4, bool))
    events = follower.update(5.1, down)
    assert [(e.kind, e.leg) for e in events] == [('liftoff', 0), ('liftoff', 3)]
    _, _, stance, swing = follower.references(5.25)
    assert stance.tolist() == [False, True, True, False]
    assert sorted(s.leg for s in swing) == [0, 3]


def test_a_haptic_swing_is_over_its_foothold_when_it_reaches_the_foothold_height():
    """The controller's swing reference of a haptic step aims ``touchdown_depth`` below the
    foothold; at the fraction of the swing where it passes the foothold's height its x, y are
    the foothold's, at rest (the foot lands on its foothold, not short of it). Without depth
    the blend takes the whole swing."""
    from replan_core.common.types import ComPlan, ContactState, FootholdPlan
    from replan_core.gait.swing import ground_crossing_fraction
    from replan_core.wbc.controller import PlanFollower

    feet = np.array([[0.37, 0.32, 0.02], [0.37, -0.32, 0.02], [-0.37, 0.32, 0.02],
                     [-0.37, -0.32, 0.02]])
    target = feet[0] + [0.12, 0.03, 0.0]
    com = ComPlan(5.0, 0.04, np.zeros((201, 3)), np.zeros((201, 3)), np.zeros((201, 3)))
    down = ContactState(5.1, feet.copy(), np.zeros((4, 3)), np.ones(4, bool),
                        np.zeros(4, bool), np.zeros(4, bool))
    for depth in (0.015, 0.0):
        plan = FootholdPlan(5.0, feet, 0.0, [Step(0, 5.1, 5.6, target, 0.1, True, True, 0.0)])
        follower = PlanFollower(plan, com, touchdown_depth=depth)
        follower.update(5.1, down)
        fraction = ground_crossing_fraction(0.02, 0.02, 0.1, depth)
        t = 5.1 + fraction * 0.5
        (swing,) = follower.references(t)[3]
        if depth:
            assert 0.8 < fraction < 0.9
            assert swing.position[2] == pytest.approx(target[2], abs=1e-9)
            assert swing.position[:2] == pytest.approx(target[:2], abs=1e-12)
            assert swing.velocity[:2] == pytest.approx([0.0, 0.0], abs=1e-9)
        else:
            assert fraction == 1.0
            (halfway,) = follower.references(5.35)[3]
            assert halfway.position[0] == pytest.approx(0.5 * (feet[0, 0] + target[0]))


def test_the_tick_bench_tells_an_identical_tick_from_a_changed_one():
    """``tick_bench --against``: the same closed-loop ticks give the same bytes, and a
    recording one bit off is found at its tick."""
    from replan_core.bench.tick_bench import first_difference, run
    from replan_core.robot.robot_file import default_urdf

    _, first = run(default_urdf(), ticks=60)
    _, second = run(default_urdf(), ticks=60)
    assert first_difference(second, first) is None
    changed = first.copy()
    changed[42, 3] = np.nextafter(changed[42, 3], np.inf)
    assert first_difference(second, changed) == 42
    assert first_difference(second, first[:50]) == 50


def test_a_foot_of_a_pair_that_bounces_off_searches_again_where_it_touched_down():
    """A trot's pair: LF touches down, loses its contact while RH is still in the air and is
    out of the force distribution, descending again from its touchdown point (it drifted in
    between); back in contact it stands. A foot that loses its contact after its pair is
    complete is left to the force distribution, as a crawl's foot always is."""
    from replan_core.common.types import ContactState

    feet, follower = _pair_follower(haptic_velocity=1.0)

    def tick(t, contact, lf_at):
        at = feet.copy()
        at[0] = lf_at
        follower.update(t, ContactState(t, at, np.zeros((4, 3)), np.array(contact),
                                        np.zeros(4, bool), np.zeros(4, bool)))
        return follower.references(t)

    landed = feet[0] + np.array([0.1, 0.0, -0.05])
    tick(5.1, [True] * 4, feet[0])
    _, _, stance, _ = tick(5.3, [True, True, True, False], landed)
    assert stance.tolist() == [True, True, True, False]
    drifted = landed + np.array([0.01, 0.0, 0.005])
    _, _, stance, swing = tick(5.32, [False, True, True, False], drifted)
    assert stance.tolist() == [False, True, True, False]
    lf = next(s for s in swing if s.leg == 0)
    assert lf.position == pytest.approx(landed, abs=1e-12)      # from where it touched down
    drifted = landed + np.array([0.02, 0.0, 0.005])
    _, _, stance, swing = tick(5.34, [False, True, True, False], drifted)
    lf = next(s for s in swing if s.leg == 0)
    assert lf.position == pytest.approx(landed + np.array([0.0, 0.0, -0.02]), abs=1e-12)
    assert lf.velocity == pytest.approx([0.0, 0.0, -1.0])
    _, _, stance, _ = tick(5.36, [True, True, True, False], landed + np.array([0.0, 0.0, -0.01]))
    assert stance.tolist() == [True, True, True, False]              # down again: stands
    tick(5.38, [False, True, True, False], landed)
    _, _, stance, swing = tick(5.40, [False, True, True, True], landed)
    assert follower.replan_due and stance.all() and swing == ()      # the pair is complete
