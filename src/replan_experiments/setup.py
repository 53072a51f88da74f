from setuptools import find_packages, setup

package_name = 'replan_experiments'

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
    description='Scenario runs, their analysis, the experiments, pages and benchmarks of the '
                'quadruped MPC re-planning stack.',
    license='BSD-3-Clause',
    tests_require=['pytest'],
    entry_points={
        'console_scripts': [
            'scenario = replan_experiments.scenario:main',
        ],
    },
)
