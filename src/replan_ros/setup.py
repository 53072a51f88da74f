import os
from pathlib import Path

from setuptools import find_packages, setup

package_name = 'replan_ros'
HERE = Path(__file__).resolve().parent
REPO = HERE.parents[1]


def shared_tree(folder: str) -> list[tuple[str, list[str]]]:
    """data_files entries installing REPO/folder, subfolders included, under share/replan_ros.

    The nodes find config/ and urdf/ through REPLAN_CONFIG and REPLAN_URDF (scripts/env.sh);
    installed, they are also under get_package_share_directory('replan_ros').
    """
    entries = []
    for directory in sorted([REPO / folder, *(REPO / folder).rglob('*')]):
        files = sorted(p for p in directory.glob('*') if p.is_file()) if directory.is_dir() else []
        if files:
            target = Path('share', package_name, directory.relative_to(REPO))
            # Relative to this file's folder, where setuptools resolves data_files.
            entries.append((str(target), [os.path.relpath(f, HERE) for f in files]))
    return entries


setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test']),
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
        *shared_tree('config'),
        *shared_tree('urdf'),
    ],
    install_requires=['setuptools'],
    zip_safe=True,
    maintainer='replan developers',
    maintainer_email='dev@replan.invalid',
    description='rclpy nodes and tools of the quadruped MPC re-planning stack.',
    license='BSD-3-Clause',
    tests_require=['pytest'],
    entry_points={
        'console_scripts': [
            'sim_node = replan_ros.nodes.sim_node:main',
            'gait_node = replan_ros.nodes.gait_node:main',
            'mpc_node = replan_ros.nodes.mpc_node:main',
            'wbc_node = replan_ros.nodes.wbc_node:main',
            'recorder_node = replan_ros.nodes.recorder_node:main',
            'replay = replan_ros.tools.replay:main',
            'rerun = replan_ros.tools.reproduce:main',
            'cmd_vel = replan_ros.tools.cmd_vel:main',
            'push = replan_ros.tools.push:main',
            'topic = replan_ros.tools.topic:main',
            'topic_probe = replan_ros.tools.topic_probe:main',
            'teleop = replan_ros.tools.teleop:main',
            'launch_graph = replan_ros.launch.launch_graph:main',
        ],
    },
)
