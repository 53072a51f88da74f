"""The sim's damping mode (controller dead) from a three-leg stance with a sideways velocity.

Run: ``python -m replan_core.bench.damping_bench [--stiffness N m/rad ...]``; prints one JSON
line: per abduction stiffness, the largest roll (deg) and the final base height (m) of each
case (each leg lifted 8 cm, the CoM moving sideways at -0.3, 0 or 0.3 m/s when the controller
dies), on the realistic robot (5 kg payload off centre, leg masses off by 10 %, actuator lag
and delay, joint friction, compliant feet: config/profiles/realistic.yaml).
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from replan_core.evaluation.metrics import roll_pitch_yaw
from replan_core.robot.model import RobotModel
from replan_core.robot.robot_file import default_urdf
from replan_core.robot.variant import perturbed_urdf
from replan_core.sim.settings import ActuatorParams
from replan_core.sim.world import SimWorld
from replan_core.wbc.controller import SwingReference, WholeBodyController

DT = 0.004              # s, control period
SIDEWAYS = (-0.3, 0.0, 0.3)   # m/s


def sit_down(urdf: str, robot: RobotModel, lifted_leg: int, sideways: float,
             abduction_stiffness: float, damping_gain: float = 40.0) -> tuple[float, float]:
    """Stand, shift the CoM over the other three feet, lift ``lifted_leg``, move sideways at
    ``sideways`` m/s, then 4 s of damping mode. Returns the largest |roll| (deg) over the
    damping and the base height at its end (m)."""
    variant = perturbed_urdf(urdf, payload_mass=5.0, payload_offset=(0.10, 0.05, 0.05),
                             leg_mass_error=0.10)
    world = SimWorld(variant, physics_dt=0.001, control_period=DT,
                     actuator=ActuatorParams(0.003, 0.002, 0.1, 1.0),
                     contact_stiffness=1.0e5, contact_damping=600.0, friction=0.7)
    try:
        wbc = WholeBodyController(robot)
        base, joints = world.base_state(), world.joint_state()
        com0 = robot.com_state(base, joints)[0]
        feet0 = world.contact_state().foot_position.copy()
        stance = np.ones(4, bool)
        stance[lifted_leg] = False
        goal = com0.copy()
        goal[:2] += 0.6 * (feet0[stance, :2].mean(axis=0) - com0[:2])
        lifted = (SwingReference(lifted_leg, feet0[lifted_leg] + [0.0, 0.0, 0.08],
                                 np.zeros(3), np.zeros(3)),)
        for _ in range(round(2.2 / DT)):
            t = world.time
            base, joints, contact = world.base_state(), world.joint_state(), world.contact_state()
            velocity = np.array([0.0, sideways if t > 1.8 else 0.0, 0.0])
            result = wbc.compute(base, joints, contact.contact, (goal, velocity, np.zeros(3)),
                                 0.0, np.ones(4, bool) if t < 1.5 else stance,
                                 () if t < 1.5 else lifted)
            world.step(result.torque)
        if world.contact_state().contact[lifted_leg]:
            raise RuntimeError(f'leg {lifted_leg} did not lift')
        quaternions = []
        for _ in range(round(4.0 / DT)):
            world.step(world.damping_torques(damping_gain, abduction_stiffness))
            quaternions.append(world.base_state().quaternion)
        roll = np.degrees(np.abs(roll_pitch_yaw(np.array(quaternions))[:, 0]).max())
        return float(roll), float(world.base_state().position[2])
    finally:
        world.close()


def main(argv=None) -> None:
    root = Path(__file__).resolve().parents[4]
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('--urdf', default=default_urdf(root))
    parser.add_argument('--stiffness', type=float, nargs='+', default=[0.0, 200.0],
                        help='abduction stiffnesses to compare (N m/rad; 200 is the default)')
    args = parser.parse_args(argv)
    robot = RobotModel(args.urdf)
    out = {}
    for stiffness in args.stiffness:
        cases = [(leg, sideways, *sit_down(args.urdf, robot, leg, sideways, stiffness))
                 for leg in range(4) for sideways in SIDEWAYS]
        out[str(stiffness)] = {
            'max_roll_deg': round(max(c[2] for c in cases), 1),
            'rolled_over': sum(c[2] > 45.0 for c in cases),
            'cases': [{'lifted_leg': leg, 'sideways_mps': v, 'max_roll_deg': round(r, 1),
                       'final_height_m': round(z, 3)} for leg, v, r, z in cases]}
    print(json.dumps(out))


if __name__ == '__main__':
    main()
