"""scripts/topic.sh (replan_ros.tools.topic) against a running sim node, as a user runs it."""

from __future__ import annotations

import subprocess

import pytest
from harness import CONFIG_DIR, REPO_ROOT, graph_env
from rclpy.qos import ReliabilityPolicy
from std_msgs.msg import String

from replan_ros.tools.topic import period_stats, subscription_qos, to_plain, to_yaml
from replan_ros.transport import qos

TOPIC_SH = str(REPO_ROOT / 'scripts' / 'topic.sh')


def topic(domain: int, *args: str, timeout: float = 60.0) -> subprocess.CompletedProcess:
    return subprocess.run([TOPIC_SH, *args], env=graph_env(domain), capture_output=True,
                          text=True, timeout=timeout, stdin=subprocess.DEVNULL)


@pytest.fixture
def sim(launcher, probe):
    node = launcher.start('sim_node', params_file=CONFIG_DIR / 'sim.yaml')
    assert probe.wait_for_topics(['/clock', '/joint_states'], timeout=30), launcher.logs()
    return node


def test_list_echo_info_hz_on_the_sim(sim, ros_domain):
    listed = topic(ros_domain, 'list', '-t')
    assert listed.returncode == 0, listed.stderr
    assert '/joint_states [sensor_msgs/msg/JointState]' in listed.stdout
    assert '/clock [rosgraph_msgs/msg/Clock]' in listed.stdout

    echoed = topic(ros_domain, 'echo', '/clock', '--once')
    assert echoed.returncode == 0, echoed.stderr
    assert echoed.stdout.startswith('clock:\n  sec: '), echoed.stdout
    assert '  nanosec: ' in echoed.stdout and echoed.stdout.rstrip().endswith('---')

    field = topic(ros_domain, 'echo', 'clock', '--once', '--field', 'clock')
    assert field.returncode == 0 and field.stdout.startswith('sec: '), field.stdout

    info = topic(ros_domain, 'info', '/joint_states', '-v')
    assert info.returncode == 0, info.stderr
    assert 'Type: sensor_msgs/msg/JointState' in info.stdout
    assert 'Publisher count: 1' in info.stdout
    assert 'Node name: sim' in info.stdout
    # The sim publishes joint_states reliable (qos.SENSOR_PUB, REP-2003); readers choose.
    assert 'Reliability: RELIABLE' in info.stdout.split('Subscription count')[0]

    # Before the first command the sim only republishes, so the rate is low but not zero.
    rate = topic(ros_domain, 'hz', '/clock', '--duration', '3')
    assert 'average rate: ' in rate.stdout, rate.stdout + rate.stderr


def test_echo_receives_a_latched_message(probe, ros_domain):
    pub = probe.node.create_publisher(String, '/latched_test', qos.LATCHED)
    pub.publish(String(data='published before the tool started'))
    probe.spin_for(0.2)
    echoed = topic(ros_domain, 'echo', '/latched_test', '--once', '--timeout', '20')
    assert echoed.returncode == 0, echoed.stderr
    assert echoed.stdout == 'data: published before the tool started\n---\n'


def test_unknown_topic_and_bad_field(ros_domain):
    missing = topic(ros_domain, 'info', '/no_such_topic', '--wait', '1')
    assert missing.returncode == 1 and 'Unknown topic' in missing.stderr
    nothing = topic(ros_domain, 'echo', '/no_such_topic', '--wait', '1')
    assert nothing.returncode == 1 and 'no publisher of /no_such_topic' in nothing.stderr


def test_subscription_qos_matches_the_publishers():
    latched = subscription_qos([qos.LATCHED, qos.SCHEDULE])
    assert latched.durability == qos.LATCHED.durability
    assert latched.reliability == ReliabilityPolicy.RELIABLE
    assert latched.depth >= qos.SCHEDULE.depth
    mixed = subscription_qos([qos.SENSOR, qos.LATCHED])
    assert mixed.reliability == ReliabilityPolicy.BEST_EFFORT
    assert mixed.durability == qos.SENSOR.durability


def test_yaml_of_a_message():
    from sensor_msgs.msg import JointState
    msg = JointState(name=['a', 'b'], position=[0.5, -1.0])
    msg.header.frame_id = 'x' * 200
    text = to_yaml(to_plain(msg, truncate_length=128))
    assert text.startswith('header:\n  stamp:\n    sec: 0\n    nanosec: 0\n')
    assert "frame_id: " + 'x' * 128 + '...' in text
    assert '- 0.5\n- -1.0' in text and 'velocity: []' in text
    assert to_plain(list(range(5)), truncate_length=3) == [0, 1, 2, '...']
    assert period_stats([0.0, 0.1, 0.2]) == pytest.approx((10.0, 0.1, 0.1, 0.0))
