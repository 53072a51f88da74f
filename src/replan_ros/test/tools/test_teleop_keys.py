"""The keyboard teleop's key -> set-point logic (no terminal, no DDS)."""

from pathlib import Path

import pytest
import yaml

from replan_ros.tools.teleop import (
    DEFAULT_STEP,
    STEP_FRACTIONS,
    Limits,
    SetPoint,
    apply_key,
    split_keys,
    status_line,
)

GAIT_YAML = Path(__file__).resolve().parents[4] / 'config' / 'gaits' / 'crawl.yaml'
LIMITS = Limits(vx=0.2, vy=0.1, wz=0.25)


def press(keys, setpoint=None, limits=LIMITS):
    setpoint = setpoint or SetPoint()
    for key in keys:
        setpoint, quit_now = apply_key(setpoint, key, limits)
        if quit_now:
            return setpoint, True
    return setpoint, False


def test_limits_come_from_the_gait_parameters():
    params = yaml.safe_load(GAIT_YAML.read_text())
    assert Limits.from_gait_file(GAIT_YAML) == Limits(
        params['max_linear_x'], params['max_linear_y'], params['max_angular_z'])


def test_each_key_moves_its_axis_by_one_increment():
    step = STEP_FRACTIONS[DEFAULT_STEP]
    assert press('w')[0] == SetPoint(vx=step * 0.2)
    assert press(['up'])[0] == SetPoint(vx=step * 0.2)
    assert press('s')[0] == press(['down'])[0] == SetPoint(vx=-step * 0.2)
    assert press('a')[0] == press(['left'])[0] == SetPoint(vy=step * 0.1)
    assert press('d')[0] == press(['right'])[0] == SetPoint(vy=-step * 0.1)
    assert press('q')[0] == SetPoint(wz=step * 0.25)
    assert press('e')[0] == SetPoint(wz=-step * 0.25)
    assert press('W')[0] == press('w')[0]           # caps lock
    assert press('ws')[0] == SetPoint()


def test_clamped_at_the_limits_without_rounding_noise():
    setpoint, _ = press('w' * 50 + 'd' * 50 + 'q' * 3)
    assert (setpoint.vx, setpoint.vy, setpoint.wz) == (0.2, -0.1, 0.1875)


def test_increment_steps_and_stop():
    bigger, _ = press('+')
    assert bigger.step == DEFAULT_STEP + 1
    assert press('+' * 20)[0].step == len(STEP_FRACTIONS) - 1
    assert press('-' * 20)[0].step == 0
    assert press('-w')[0].vx == pytest.approx(STEP_FRACTIONS[DEFAULT_STEP - 1] * 0.2)
    stopped, quit_now = press('+wwaq ')
    assert stopped == SetPoint(step=DEFAULT_STEP + 1) and not quit_now
    assert press('zZ?1')[0] == SetPoint()             # unbound keys change nothing


@pytest.mark.parametrize('key', ['x', 'X', '\x03'])
def test_quit_returns_zero(key):
    setpoint, quit_now = press(['w', 'a', 'q', key, 'w'])
    assert quit_now and (setpoint.vx, setpoint.vy, setpoint.wz) == (0.0, 0.0, 0.0)


def test_split_keys_reads_arrows_and_drops_other_escapes():
    assert split_keys('w\x1b[A\x1b[B\x1bOC\x1b[Dq') == ['w', 'up', 'down', 'right', 'left', 'q']
    assert split_keys('\x1b[1;5A') == ['up']                  # Ctrl-Up is still up
    assert split_keys('\x1b[15~a\x1b') == ['a']               # F5 and a lone Esc: nothing
    assert split_keys(' +-') == [' ', '+', '-']


def test_status_line_shows_the_set_point():
    line = status_line(SetPoint(vx=0.05, vy=-0.025, wz=0.1))
    assert 'vx +0.050 m/s' in line and 'vy -0.025 m/s' in line and 'wz +0.100 rad/s' in line
    assert '\n' not in line
