"""A recorded run's bag read back: every message of the chosen topics decoded with rclpy's
deserializer, by topic, for the analysis of a run, the benchmarks and the node-graph tests.
A bag directory's files (splits) are read as one; a killed recorder's file is recovered first
(``bag_open``), saying so in one line on stderr."""

from __future__ import annotations

import sys
from collections import defaultdict
from pathlib import Path

from rclpy.serialization import deserialize_message

from replan_ros.messages.introspection import message_class
from replan_ros.recording.bag_io import iter_raw
from replan_ros.recording.bag_open import readable_files

# The simulator's truth is what the robot did; /odom is what the robot believed (the
# estimate), compared with the truth. Bags from before the estimator hold the truth on /odom.
TRUTH_TOPIC = '/ground_truth/odom'
# What a run's analysis reads: read_messages' default.
TOPICS = ('/clock', TRUTH_TOPIC, '/odom', '/ground_truth/contacts', '/footholds', '/zmp_plan',
          '/com_plan', '/diagnostics', '/velocity_setpoint', '/applied_wrench',
          '/contacts', '/joint_states')


def _say(line: str) -> None:
    print(f'[bag] {line}', file=sys.stderr, flush=True)


def read_messages(bag: Path, topics=TOPICS) -> dict[str, list[tuple[int, object]]]:
    """topic -> [(publish_time ns, message)], decoded; unreadable tails are skipped.

    The recorder stores the DDS source timestamp (wall clock at the publisher) as publish_time,
    as rosbag2 does; its log_time is the receive time on its sim-time clock."""
    out: dict[str, list] = defaultdict(list)
    classes: dict[str, type] = {}
    for path in readable_files(bag, _say):
        try:
            for schema, channel, message in iter_raw(path, topics):
                cls = classes.get(schema.name)
                if cls is None:
                    cls = classes[schema.name] = message_class(schema.name)
                out[channel.topic].append(
                    (message.publish_time, deserialize_message(message.data, cls)))
        except Exception as err:   # a truncated file (SIGKILL) still gives what it holds
            out['_errors'].append((0, f'{path.name}: {err}'))
    return out
