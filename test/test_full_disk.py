"""A recorded walk whose disk fills up mid-run: the real graph (``scripts/scenario.sh``) records
into a tmpfs of 800 KiB, about a third of what the 7 s walk writes (2.5 MB), mounted in a mount
namespace of the test's own (``unshare -m``), so no disk of the machine fills. DDS is not
affected: the namespace shares the network with the test's probe, which watches the truth.

What must hold (docs/recording.md, "A full disk or an unwritable folder"): the robot walks on
to the scenario's end without falling, the recorder says it in one line naming the bag and the
cause, and the bag written so far is read by the project's tools, counted incomplete.
"""

from __future__ import annotations

import shlex
import subprocess
from pathlib import Path

import pytest
from harness import REPO_ROOT, graph_env
from nav_msgs.msg import Odometry

from replan_ros.messages.stamps import stamp_to_sec
from replan_ros.recording.bag_open import iter_raw_files, readable_files
from replan_ros.recording.completeness import TICK_TOPICS, count_files
from replan_ros.transport.qos import SENSOR

DURATION = 7.0              # s of sim time
WALK = f"""name: full_disk
duration: {DURATION}
events:
  - {{t: 0.5, cmd_vel: [0.15, 0.0, 0.0]}}
"""
TMPFS = '800k'              # a third of the walk's bag: full after about 2 s of sim time
STANDING_Z = 0.5            # m: the base above this is standing (0.61 walking, ~0.34 sat down)


def _own_mount_namespace() -> bool:
    try:
        return subprocess.run(['unshare', '-m', 'true'], capture_output=True,
                              timeout=30).returncode == 0
    except (OSError, subprocess.TimeoutExpired):
        return False


def test_a_disk_that_fills_mid_walk_stops_the_recording_with_one_line_and_the_robot_walks_on(
        ros_domain, probe, tmp_path):
    if not _own_mount_namespace():
        pytest.skip('unshare -m is not permitted here: no mount namespace for a small tmpfs')
    scenario = tmp_path / 'walk.yaml'
    scenario.write_text(WALK)
    out, saved = tmp_path / 'run', tmp_path / 'saved'
    bag = out / 'bag'
    bag.mkdir(parents=True)
    saved.mkdir()
    # The tmpfs lives as long as the namespace: its bag is copied out before the shell exits.
    # Private mounts, so the tmpfs is not seen outside the namespace.
    script = (f'mount --make-rprivate / && mount -t tmpfs -o size={TMPFS} tmpfs {bag} && '
              f'{{ {shlex.quote(str(REPO_ROOT / "scripts" / "scenario.sh"))} {scenario} '
              f'--out {out} --no-plots --quiet; code=$?; cp {bag}/*.mcap {saved}/; '
              'exit $code; }')
    truth: list[tuple[float, float, float]] = []      # (t, x, z)

    def on_truth(msg: Odometry) -> None:
        p = msg.pose.pose.position
        truth.append((stamp_to_sec(msg.header.stamp), p.x, p.z))

    probe.node.create_subscription(Odometry, 'ground_truth/odom', on_truth, SENSOR)
    env = graph_env(ros_domain)
    # The run's analysis recovers the bag into the temporary folder (no room beside it).
    env['TMPDIR'] = str(tmp_path)
    run = subprocess.Popen(['unshare', '-m', 'sh', '-c', script], env=env,
                           stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    try:
        probe.spin_until(lambda: run.poll() is not None, 300.0)
    finally:
        if run.poll() is None:
            run.kill()
    output = run.stdout.read()
    log = (out / 'logs' / 'recorder.log').read_text()

    # The robot walked on: the sim ran to the scenario's end, standing and moving forward.
    assert f'reached {DURATION} s of sim time' in output, output
    assert 'died' not in output and 'all nodes stopped' in output, output
    assert truth and truth[-1][0] >= DURATION - 0.01, (truth[-1:], output)
    assert min(z for t, _, z in truth if t >= 0.5) > STANDING_Z, output
    assert truth[-1][1] - truth[0][1] > 0.6, truth[-1]          # 0.15 m/s for 6.5 s: 0.9 m

    # One line, naming the bag and the cause; no traceback, no other error.
    stopped = [ln for ln in log.splitlines() if 'recording stopped:' in ln]
    files = sorted(saved.glob('*.mcap'))
    assert len(files) == 1, (files, output)
    assert len(stopped) == 1, log
    assert f'cannot write {bag / files[0].name}: No space left on device' in stopped[0], log
    assert [ln for ln in log.splitlines() if ln.startswith('[ERROR]')] == stopped, log
    assert 'Traceback' not in log + output, log + output
    assert 'incomplete: nothing written after the write that failed' in log, log

    # The run's summary says the bag is incomplete (its analysis read what there is of it).
    assert 'bag incomplete:' in output and 'ends early' in output, output

    # The bag so far opens (recovered on the way) and holds the ticks up to the full disk.
    lines: list[str] = []
    readable = readable_files(files[0], lines.append)
    assert len(lines) == 1 and 'recovered' in lines[0], lines
    stamps: dict[str, list[int]] = {}
    for _, channel, message in iter_raw_files(readable, TICK_TOPICS):
        stamps.setdefault(channel.topic, []).append(message.log_time)
    assert set(stamps) == TICK_TOPICS, sorted(stamps)
    ends = [max(times) / 1e9 for times in stamps.values()]
    assert all(1.0 < end < DURATION - 1.0 for end in ends), ends     # filled mid-run
    assert not count_files(readable).complete


def test_the_tmpfs_is_the_test_s_own(tmp_path):
    """What the namespace mounts is not seen outside it."""
    if not _own_mount_namespace():
        pytest.skip('unshare -m is not permitted here: no mount namespace for a small tmpfs')
    folder = tmp_path / 'mnt'
    folder.mkdir()
    subprocess.run(['unshare', '-m', 'sh', '-c', 'mount --make-rprivate / && mount -t tmpfs '
                    f'-o size=64k tmpfs {folder} && touch {folder}/inside'], check=True,
                   timeout=30)
    assert not (folder / 'inside').exists()
    assert Path('/proc/self/mounts').read_text().count(str(folder)) == 0
