"""The graph's Fast DDS profile (``config/dds/fastdds.xml``, set by ``scripts/env.sh``), in
real processes over DDS: a reliable reader repairs a sample lost in transport only after the
writer's next heartbeat, and holds every later sample until then; the profile makes that
100 ms instead of Fast DDS's 3 s, so a writer learns within a fraction of a second that every
sample arrived (docs/recording.md, "The end of a run")."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys

_READER = '''
import sys, time
import rclpy
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
from std_msgs.msg import Header
rclpy.init()
node = rclpy.create_node('acks_reader')
got = []
node.create_subscription(Header, sys.argv[1], got.append, QoSProfile(
    depth=1, history=HistoryPolicy.KEEP_ALL, reliability=ReliabilityPolicy.RELIABLE))
print('ready', flush=True)
end = time.monotonic() + float(sys.argv[2])
while time.monotonic() < end:
    rclpy.spin_once(node, timeout_sec=0.05)
print('received', len(got), flush=True)
'''

# A writer of 100-sample rounds on topic argv[1], once the reader is there (both scripts).
_WRITER_START = '''
import json, sys, time
import rclpy
from rclpy.duration import Duration
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
from std_msgs.msg import Header
rclpy.init()
node = rclpy.create_node('acks_writer')
pub = node.create_publisher(Header, sys.argv[1], QoSProfile(
    depth=1000, history=HistoryPolicy.KEEP_LAST, reliability=ReliabilityPolicy.RELIABLE))
while pub.get_subscription_count() == 0:
    time.sleep(0.05)
time.sleep(0.5)
'''

_WRITER = _WRITER_START + '''
rounds = []
for _ in range(int(sys.argv[2])):
    for _ in range(100):
        pub.publish(Header())
        time.sleep(0.001)
    start = time.monotonic()
    acked = pub.wait_for_all_acked(Duration(seconds=1.0))
    rounds.append([acked, time.monotonic() - start])
    time.sleep(0.3)
print(json.dumps(rounds), flush=True)
'''


def _start_reader(topic: str, seconds: float) -> subprocess.Popen:
    reader = subprocess.Popen([sys.executable, '-c', _READER, topic, str(seconds)],
                              stdout=subprocess.PIPE, text=True)
    assert reader.stdout.readline().strip() == 'ready'
    return reader


def _write(topic: str, rounds: int) -> list[list]:
    """``rounds`` of 100 samples, each followed by a wait of at most 1 s until every sample is
    acknowledged: [acked, wall s] per round."""
    done = subprocess.run([sys.executable, '-c', _WRITER, topic, str(rounds)],
                          capture_output=True, text=True, timeout=60)
    assert done.returncode == 0, done.stderr
    return json.loads(done.stdout.strip().splitlines()[-1])


def test_every_sample_is_acknowledged_within_the_limit(ros_domain):
    assert os.environ['FASTRTPS_DEFAULT_PROFILES_FILE'].endswith('config/dds/fastdds.xml')
    topic = f'acks_test_{os.getpid()}'
    reader = _start_reader(topic, 12.0)
    try:
        rounds = _write(topic, 5)
    finally:
        out, _ = reader.communicate(timeout=30)
    # At Fast DDS's 3 s heartbeat, each round would be acknowledged within the 1 s limit by
    # chance only (about one in three).
    assert all(acked for acked, _ in rounds), rounds
    assert 'received 500' in out, out


_STOPPING_WRITER = _WRITER_START + '''
from replan_ros.nodes.node_main import wait_for_acks
print('writing', flush=True)
sys.stdin.readline()                   # the test has stopped the reader, or not
for _ in range(100):
    pub.publish(Header())
start = time.monotonic()
acked = wait_for_acks(node)
print(json.dumps([acked, time.monotonic() - start]), flush=True)
'''


def _stop_writer(topic: str, reader: subprocess.Popen, freeze: bool) -> tuple[bool, float]:
    """A node's stop (``node_main.wait_for_acks`` before its writers go) after 100 samples,
    with the reader alive or stopped (SIGSTOP) before they are sent."""
    writer = subprocess.Popen([sys.executable, '-c', _STOPPING_WRITER, topic],
                              stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
    try:
        assert writer.stdout.readline().strip() == 'writing'
        if freeze:
            os.kill(reader.pid, signal.SIGSTOP)
        writer.stdin.write('go\n')
        writer.stdin.flush()
        out, _ = writer.communicate(timeout=60)
    finally:
        if freeze:
            os.kill(reader.pid, signal.SIGCONT)
        if writer.poll() is None:
            writer.kill()
    acked, waited = json.loads(out.strip().splitlines()[-1])
    return acked, waited


def test_a_stopping_node_waits_for_its_readers_but_not_for_a_stopped_one(ros_domain):
    """A node's last samples reach a live reader before its writers go (the bag's tail); a
    reader that no longer answers holds the stop at most ACK_LIMIT (1 s), not the reader's own
    life (30 s here)."""
    topic = f'acks_stop_{os.getpid()}'
    reader = _start_reader(topic, 30.0)
    try:
        acked, _ = _stop_writer(topic, reader, freeze=False)
        assert acked
        acked, waited = _stop_writer(topic, reader, freeze=True)
        assert not acked and waited >= 0.9
    finally:
        reader.kill()
        reader.wait()


def _shared_memory_maps(pid: int) -> list[str]:
    """The Fast DDS shared-memory segments process ``pid`` has mapped."""
    with open(f'/proc/{pid}/maps') as maps:
        return sorted({line.split()[-1] for line in maps if '/dev/shm/fastrtps' in line})


def test_the_nodes_talk_over_the_loopback_without_shared_memory(ros_domain):
    """The profile's transport: UDP on the loopback, no shared-memory segment mapped (a node
    killed by SIGKILL can leave those so that its restarted process receives nothing), and a
    reader and a writer in two processes still find each other."""
    assert os.environ['ROS_AUTOMATIC_DISCOVERY_RANGE'] == 'SYSTEM_DEFAULT'
    topic = f'loopback_test_{os.getpid()}'
    reader = _start_reader(topic, 12.0)
    try:
        rounds = _write(topic, 1)
        mapped = _shared_memory_maps(reader.pid)
    finally:
        out, _ = reader.communicate(timeout=30)
    assert mapped == [], mapped
    assert all(acked for acked, _ in rounds), rounds
    assert 'received 100' in out, out
