"""The graph's Fast DDS profile (``config/dds/fastdds.xml``, set by ``scripts/env.sh``), in
real processes over DDS: a reliable reader repairs a sample lost in transport only after the
writer's next heartbeat, and holds every later sample until then; the profile makes that
100 ms instead of Fast DDS's 3 s, so a writer learns within a fraction of a second that every
sample arrived (docs/recording.md, "The end of a run")."""

from __future__ import annotations

import json
import os
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

_WRITER = '''
import json, sys, time
import rclpy
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
from std_msgs.msg import Header
from rclpy.duration import Duration
rclpy.init()
node = rclpy.create_node('acks_writer')
pub = node.create_publisher(Header, sys.argv[1], QoSProfile(
    depth=1000, history=HistoryPolicy.KEEP_LAST, reliability=ReliabilityPolicy.RELIABLE))
while pub.get_subscription_count() == 0:
    time.sleep(0.05)
time.sleep(0.5)
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
