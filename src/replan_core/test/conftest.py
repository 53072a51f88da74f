"""Fixtures shared by the core's unit tests: the URDF, its model and a simulated world."""

import os
from pathlib import Path

import pytest

from replan_core.robot.model import RobotModel
from replan_core.sim.world import SimWorld

ROOT = Path(__file__).resolve().parents[3]
CONTROL_PERIOD = 0.004      # s, the world fixture's control tick


@pytest.fixture(scope='module')
def urdf() -> str:
    """The project's URDF (``$REPLAN_URDF`` or ``urdf/hyq.urdf``); the test is skipped
    without one."""
    path = os.environ.get('REPLAN_URDF') or str(ROOT / 'urdf' / 'hyq.urdf')
    if not Path(path).is_file():
        pytest.skip(f'no URDF at {path}')
    return path


@pytest.fixture(scope='module')
def robot(urdf) -> RobotModel:
    """The model of the project's URDF, built once per test module."""
    return RobotModel(urdf)


@pytest.fixture
def world(urdf):
    """A fresh PyBullet world of the project's URDF on flat ground (1 ms physics, 4 ms control
    ticks), closed after the test."""
    sim = SimWorld(urdf, physics_dt=0.001, control_period=CONTROL_PERIOD)
    yield sim
    sim.close()
