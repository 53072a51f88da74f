"""state_view.robot_state_view: the view of every robot of config/robots/, and one line (a
ConfigError) for a model whose links it cannot place, which stops the recorder and the live
view (exit code 2) rather than leave a bag without /robot_description and /tf. No DDS."""

from __future__ import annotations

from pathlib import Path

import pytest

from replan_core.robot.robot_file import robot_names
from replan_ros.params import ConfigError
from replan_ros.params.robot import NodeRobot, config_dir, node_robot
from replan_ros.view.state_view import DESCRIPTION_TOPIC, robot_state_view

ROOT = Path(__file__).resolve().parents[4]
# An unactuated revolute joint: the view has no angle for it, so no transform of its link.
HEAD = """  <link name="head"/>
  <joint name="head_pan" type="revolute">
    <parent link="base_link"/><child link="head"/>
    <origin xyz="0.5 0 0.1"/><axis xyz="0 0 1"/>
    <limit lower="-1" upper="1" effort="10" velocity="1"/>
  </joint>
</robot>"""


@pytest.mark.parametrize('name', robot_names(config_dir()))
def test_every_robot_has_a_view_with_its_urdf(name):
    robot = node_robot(name, '', '')
    view = robot_state_view(robot)
    description = view.description()
    assert description.topic == DESCRIPTION_TOPIC
    assert view.urdf == Path(robot.urdf).read_text()
    assert robot.root_link in view.frames.links and 'base_link' in view.frames.links


def test_a_model_the_view_cannot_place_is_one_config_error_line(tmp_path):
    urdf = tmp_path / 'hyq_head.urdf'
    urdf.write_text((ROOT / 'urdf' / 'hyq.urdf').read_text().replace('</robot>', HEAD))
    hyq = node_robot('hyq', '', '')
    robot = NodeRobot(str(urdf), hyq.joints, hyq.feet, hyq.root_link, hyq.spec)
    with pytest.raises(ConfigError) as raised:
        robot_state_view(robot)
    text = str(raised.value)
    assert '\n' not in text
    assert text == (f'cannot derive /robot_description and /tf of hyq: {urdf}: joint head_pan '
                    'is not actuated')
    missing = NodeRobot(str(tmp_path / 'none.urdf'), hyq.joints, hyq.feet, hyq.root_link, None)
    with pytest.raises(ConfigError, match='cannot derive /robot_description and /tf of the robot'):
        robot_state_view(missing)
