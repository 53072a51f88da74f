"""config/ and urdf/ are installed into the package's share directory (ament_index)."""

from pathlib import Path

import pytest
from ament_index_python.packages import get_package_share_directory


@pytest.mark.parametrize('relative', ['config/sim.yaml', 'config/gait.yaml',
                                      'config/profiles/realistic.yaml',
                                      'config/scenarios/forward.yaml', 'urdf/hyq.urdf'])
def test_installed_in_share(relative):
    installed = Path(get_package_share_directory('replan_ros')) / relative
    assert installed.is_file(), f'{installed} missing: rebuild (scripts/setup.sh)'
