"""scripts/launch.sh and scripts/cmd_vel.sh as users run them: respawn, --no-respawn, steering."""

from __future__ import annotations

import contextlib
import os
import re
import signal
import subprocess
import threading
import time

from geometry_msgs.msg import TwistStamped
from harness import REPO_ROOT, graph_env

from replan_ros.launch.domain import HELD_ENV, claim
from replan_ros.transport.qos import SCHEDULE


class LaunchProcess:
    """scripts/launch.sh in its own process group, its output collected line by line."""

    def __init__(self, args: list[str], domain: int) -> None:
        self.process = subprocess.Popen(
            [str(REPO_ROOT / 'scripts' / 'launch.sh'), *args], env=graph_env(domain),
            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, start_new_session=True)
        self.lines: list[str] = []
        self._reader = threading.Thread(target=self._read, daemon=True)
        self._reader.start()

    def _read(self) -> None:
        for line in self.process.stdout:
            self.lines.append(line.rstrip())

    @property
    def output(self) -> str:
        return '\n'.join(self.lines)

    def wait_for(self, pattern: str, timeout: float) -> re.Match | None:
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            for line in list(self.lines):
                match = re.search(pattern, line)
                if match:
                    return match
            time.sleep(0.1)
        return None

    def node_pids(self, names) -> dict[str, int]:
        """name -> pid of each node, from the launcher's 'started' lines."""
        pids = {}
        for name in names:
            match = self.wait_for(rf'started {name} \(pid (\d+)\)', 60)
            assert match, self.output
            pids[name] = int(match.group(1))
        return pids

    def stop(self) -> None:
        if self.process.poll() is None:
            os.killpg(self.process.pid, signal.SIGINT)
            try:
                self.process.wait(30)
            except subprocess.TimeoutExpired:
                os.killpg(self.process.pid, signal.SIGKILL)
                self.process.wait(5)


def _pid_alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    return True


def test_dead_node_is_reported_and_respawned_and_cmd_vel_steers(ros_domain, tmp_path, probe):
    # 30 s of sim time: room for the checks, the steering and the respawn below on a fast
    # machine too (at a real-time factor of 1, 12 s ran out before the set-point arrived).
    launch = LaunchProcess(['--run-dir', str(tmp_path / 'run'), '--duration', '30'], ros_domain)
    try:
        started = launch.wait_for(r'started mpc \(pid (\d+)\)', 60)
        assert started, launch.output
        assert launch.wait_for(r'started wbc', 60), launch.output
        # The default (realistic) graph: no control node reads the simulator's truth.
        assert probe.spin_until(lambda: probe.node.get_subscriptions_info_by_topic('/imu'),
                                30), launch.output
        probe.spin_for(1.0)
        for topic in ('/ground_truth/odom', '/ground_truth/contacts'):
            readers = {info.node_name for info in
                       probe.node.get_subscriptions_info_by_topic(topic)}
            assert not readers, (topic, readers)
        assert any(info.node_name == 'wbc_on_demand'
                   for info in probe.node.get_subscriptions_info_by_topic('/imu'))
        setpoints = probe.subscribe(TwistStamped, 'velocity_setpoint', SCHEDULE)
        steer = subprocess.run(
            [str(REPO_ROOT / 'scripts' / 'cmd_vel.sh'), '0.1', '0', '0', '--for', '3'],
            env=graph_env(ros_domain), capture_output=True, text=True, timeout=120)
        assert steer.returncode == 0, steer.stdout + steer.stderr
        assert 'cmd_vel: gait subscribes' in steer.stdout, steer.stdout
        assert probe.spin_until(lambda: any(abs(m.twist.linear.x - 0.1) < 1e-9
                                            for m in setpoints), 30), launch.output
        os.kill(int(started.group(1)), signal.SIGKILL)
        assert launch.wait_for(r'node mpc died \(exit code -9\)', 30), launch.output
        assert launch.wait_for(r'respawned mpc', 30), launch.output
        launch.process.wait(180)
        assert launch.process.returncode == 0, launch.output
        assert 'reached 30.0 s of sim time' in launch.output
        assert (tmp_path / 'run' / 'logs' / 'mpc.log').read_text().count('start #') == 2
        # The CPU time of every node per sim s, the respawned mpc's new process included.
        cpu = re.search(r'CPU time per sim s since the first tick: (.*); all (\d+) ms',
                        launch.output)
        assert cpu, launch.output
        per_node = {name: int(ms) for name, ms in re.findall(r'(\w+) (\d+) ms', cpu.group(1))}
        assert set(per_node) == {'sim', 'gait', 'mpc', 'wbc'}, cpu.group(0)
        assert all(ms > 0 for ms in per_node.values()), cpu.group(0)
        assert sum(per_node.values()) <= int(cpu.group(2)) + len(per_node), cpu.group(0)
    finally:
        launch.stop()


def test_a_killed_launcher_leaves_no_node_running(ros_domain, tmp_path):
    """SIGKILL of the launcher alone (as a test's timeout or `kill -9` does): its nodes, each
    in a session of its own, get SIGTERM from the kernel (parent-death signal) and end. Before,
    they ran on, and a stray sim published into the next run on the same domain."""
    launch = LaunchProcess(['--run-dir', str(tmp_path / 'run')], ros_domain)
    pids: dict[str, int] = {}
    try:
        pids = launch.node_pids(('sim', 'gait', 'mpc', 'wbc'))
        assert all(_pid_alive(pid) for pid in pids.values()), launch.output
        os.kill(launch.process.pid, signal.SIGKILL)        # the launcher, not its nodes
        launch.process.wait(10)
        end = time.monotonic() + 20.0
        while time.monotonic() < end and any(_pid_alive(pid) for pid in pids.values()):
            time.sleep(0.2)
        assert not any(_pid_alive(pid) for pid in pids.values()), \
            {name: pid for name, pid in pids.items() if _pid_alive(pid)}
    finally:
        launch.stop()
        for pid in pids.values():
            with contextlib.suppress(ProcessLookupError):
                os.kill(pid, signal.SIGKILL)


def test_no_respawn_stops_the_others_and_exits_non_zero(ros_domain, tmp_path):
    launch = LaunchProcess(['--run-dir', str(tmp_path / 'run'), '--no-respawn'], ros_domain)
    try:
        pids = launch.node_pids(('sim', 'gait', 'mpc', 'wbc'))
        time.sleep(2.0)
        os.kill(pids['gait'], signal.SIGKILL)
        launch.process.wait(60)
        assert launch.process.returncode != 0, launch.output
        assert 'node gait died' in launch.output and '--no-respawn' in launch.output
        assert not any(_pid_alive(pid) for pid in pids.values()), launch.output
    finally:
        launch.stop()


def test_a_second_graph_on_a_claimed_domain_is_refused_in_one_line(ros_domain, tmp_path):
    """Two graphs on one domain mix their topics without an error; started at once, the sim's
    check for a second /clock comes too late. A script that starts a graph claims its domain
    first (replan_ros/launch/domain.py) and refuses one that is held, before any node starts;
    a script started by the holder (REPLAN_DOMAIN_HELD) passes the claim. The holder here is
    this test session (harness.DomainReservation claims its domain)."""
    assert claim(ros_domain) is None, f'the test session does not hold domain {ros_domain}'
    stranger = {key: value for key, value in graph_env(ros_domain).items() if key != HELD_ENV}
    refused = subprocess.run(
        [str(REPO_ROOT / 'scripts' / 'scenario.sh'), str(REPO_ROOT / 'config' / 'scenarios'
         / 'stand.yaml'), '--out', str(tmp_path / 'refused')],
        env=stranger, capture_output=True, text=True, timeout=60)
    assert refused.returncode == 3, refused.stdout + refused.stderr
    lines = refused.stderr.strip().splitlines()
    assert len(lines) == 1 and f'another graph runs on ROS_DOMAIN_ID {ros_domain}' in lines[0]
    assert 'started' not in refused.stdout and not (tmp_path / 'refused').exists()
    helped = subprocess.run([str(REPO_ROOT / 'scripts' / 'launch.sh'), '--help'],
                            env=stranger, capture_output=True, text=True, timeout=60)
    assert helped.returncode == 0 and 'usage: launch.sh' in helped.stdout    # no graph
    # The holder's child passes the claim and goes on to its own checks (here a robot that
    # does not exist: exit 2, not 3), without starting a graph.
    held = subprocess.run(
        [str(REPO_ROOT / 'scripts' / 'launch.sh'), '--robot', 'nosuch', '--duration', '1',
         '--run-dir', str(tmp_path / 'held')],
        env=graph_env(ros_domain), capture_output=True, text=True, timeout=120)
    assert held.returncode == 2, held.stdout + held.stderr
    assert "config error: unknown robot 'nosuch'" in held.stdout + held.stderr
