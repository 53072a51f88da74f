"""scripts/teleop.sh as a user runs it: refused without a terminal; in tmux, keys -> cmd_vel."""

from __future__ import annotations

import os
import shutil
import subprocess
import time

import pytest
from geometry_msgs.msg import Twist
from harness import CONFIG_DIR, REPO_ROOT, graph_env

from replan_ros.tools.teleop import DEFAULT_STEP, STEP_FRACTIONS, Limits
from replan_ros.transport import qos

TELEOP_SH = str(REPO_ROOT / 'scripts' / 'teleop.sh')


def test_refuses_without_a_terminal(ros_domain):
    done = subprocess.run([TELEOP_SH], env=graph_env(ros_domain), stdin=subprocess.DEVNULL,
                          capture_output=True, text=True, timeout=60)
    assert done.returncode == 2
    assert 'stdin is not a terminal' in done.stderr


@pytest.mark.skipif(shutil.which('tmux') is None, reason='tmux is not installed')
@pytest.mark.parametrize('quit_key', ['x', 'C-c'])
def test_keys_in_a_terminal_drive_cmd_vel(probe, ros_domain, tmp_path, quit_key):
    crawl = CONFIG_DIR / 'gaits' / 'crawl.yaml'
    step_vx = STEP_FRACTIONS[DEFAULT_STEP] * Limits.from_gait_file(crawl).vx
    received = probe.subscribe(Twist, '/cmd_vel', qos.COMMAND)
    # Our own tmux server (own socket, no user config), so nothing else of the user's is touched.
    tmux = ['tmux', '-L', f'replan-teleop-{os.getpid()}', '-f', '/dev/null']
    stty_file = tmp_path / 'stty.txt'

    def keys(*names: str) -> None:
        subprocess.run([*tmux, 'send-keys', '-t', 'teleop', *names], check=True, timeout=10)

    def screen() -> str:
        return subprocess.run([*tmux, 'capture-pane', '-p', '-t', 'teleop'], capture_output=True,
                              text=True, timeout=10).stdout

    def last_vx_is(value: float) -> bool:
        return bool(received) and abs(received[-1].linear.x - value) < 1e-9

    subprocess.run([*tmux, 'new-session', '-d', '-s', 'teleop', '-x', '150', '-y', '30',
                    'bash --norc --noprofile'], env=graph_env(ros_domain), check=True, timeout=10)
    try:
        keys(TELEOP_SH, 'Enter')
        assert probe.spin_until(lambda: probe.node.count_publishers('/cmd_vel') > 0, 30), screen()
        assert probe.spin_until(lambda: last_vx_is(0.0), 10), screen()
        keys('w', 'w')
        assert probe.spin_until(lambda: last_vx_is(2 * step_vx), 10), screen()
        keys('Up')
        assert probe.spin_until(lambda: last_vx_is(3 * step_vx), 10), screen()
        assert probe.spin_until(lambda: f'vx {3 * step_vx:+.3f} m/s' in screen(), 5), screen()
        # Still repeated at 10 Hz while no key is pressed.
        count = len(received)
        probe.spin_for(1.0)
        assert len(received) - count >= 5
        keys(quit_key)
        assert probe.spin_until(lambda: 'sent a zero set-point' in screen(), 10), screen()
        assert last_vx_is(0.0)
        # Back at the shell: the terminal must be in its normal (canonical, echoing) mode.
        keys(f'stty -a > {stty_file}', 'Enter')
        end = time.monotonic() + 10
        while not (stty_file.exists() and stty_file.read_text()) and time.monotonic() < end:
            time.sleep(0.1)
        settings = stty_file.read_text().split()
        assert 'icanon' in settings and 'echo' in settings, settings
    finally:
        subprocess.run([*tmux, 'kill-server'], capture_output=True, timeout=10)
