"""A robot as a run gets it: its model's facts and every node parameter the launcher derives
for it (``robot_info``). Both plans read it, the experiments' (``plan.node_settings``) and the
robots page's (``robots_plan``), so it depends on neither."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path


@dataclass
class RobotInfo:
    """A robot as a run on the plan's profile gets it."""

    name: str
    mass_kg: float               # the model's (robot_facts), without the profile's payload
    leg_length_m: float
    standing_height_m: float
    com_height_m: float
    min_joint_inertia: float     # kg m^2
    values: dict = field(default_factory=dict)   # node -> {key: value}, as the nodes get them

    def value(self, name: str):
        """A node parameter ``node.key`` as the nodes get it; KeyError if there is none."""
        node, _, key = name.partition('.')
        return self.values[node][key]

    @property
    def cycle_s(self) -> float:
        """The gait's cycle: each step (a group of ``group_size`` legs) a swing and its
        four-feet phase."""
        steps = 4 // int(self.value('gait.group_size'))
        return steps * (float(self.value('gait.swing_duration'))
                        + float(self.value('gait.four_feet_duration')))


def robot_info(config_dir: Path, robot: str, profile: str, gait: str = 'crawl') -> RobotInfo:
    """The robot's facts (``robot_facts`` on its model) and every node parameter as a run on
    ``profile`` in ``gait`` gives it (the launcher's derivation: node files, the gait,
    profile, the scaling rules, the robot file's own parameters). ConfigError for an unknown
    robot or gait or a bad file."""
    from replan_core.robot.robot_file import robot_facts  # pinocchio: only here
    from replan_ros.launch.param_files import (
        check_run_files,
        gait_parameters,
        profile_file,
        robot_parameters,
    )

    profile_path = profile_file(config_dir, profile)
    gait_source = gait_parameters(config_dir, gait)
    layer = robot_parameters(config_dir, robot, profile_path, gait_source)
    values = check_run_files(config_dir, [gait_source, profile_path, layer.derived,
                                          layer.overrides]).values
    facts = robot_facts(layer.spec)
    return RobotInfo(robot, facts.mass, facts.leg_length, facts.standing_height,
                     facts.com_height, facts.min_joint_inertia, values)
