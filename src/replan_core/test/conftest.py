"""Fixtures shared by the core's unit tests."""

import os
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[3]


@pytest.fixture(scope='module')
def urdf() -> str:
    """The project's URDF (``$REPLAN_URDF`` or ``urdf/hyq.urdf``); the test is skipped
    without one."""
    path = os.environ.get('REPLAN_URDF') or str(ROOT / 'urdf' / 'hyq.urdf')
    if not Path(path).is_file():
        pytest.skip(f'no URDF at {path}')
    return path
