from setuptools import find_packages, setup

package_name = 'replan_ros'

setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test']),
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
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
            'sim_node = replan_ros.sim_node:main',
            'gait_node = replan_ros.gait_node:main',
            'mpc_node = replan_ros.mpc_node:main',
            'wbc_node = replan_ros.wbc_node:main',
            'recorder_node = replan_ros.recorder_node:main',
            'replay = replan_ros.tools.replay:main',
            'rerun = replan_ros.tools.rerun:main',
            'scenario = replan_ros.tools.scenario:main',
            'cmd_vel = replan_ros.tools.cmd_vel:main',
            'push = replan_ros.tools.push:main',
            'topic_probe = replan_ros.tools.topic_probe:main',
            'launch_graph = replan_ros.tools.launch_graph:main',
        ],
    },
)
