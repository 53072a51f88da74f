"""QoS profiles by role (docs/ARCHITECTURE.md, topic table)."""

from rclpy.event_handler import PublisherEventCallbacks, SubscriptionEventCallbacks
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

# Sensor-like streams (joint_states, imu, odom, ground_truth/odom), as REP-2003 asks of a
# driver: read best effort by our own nodes (SENSOR: the newest sample matters, a lost one is
# replaced by the next tick and never waited for), published reliable (SENSOR_PUB, same depth),
# so that a subscriber with the default QoS, which is reliable (`ros2 topic echo`, RViz, a
# `create_subscription(..., 10)`), is compatible and receives them. A reliable writer does not
# wait for best-effort readers, and with KEEP_LAST it never blocks on a slow reliable one.
SENSOR = QoSProfile(depth=10, history=HistoryPolicy.KEEP_LAST,
                    reliability=ReliabilityPolicy.BEST_EFFORT,
                    durability=DurabilityPolicy.VOLATILE)
SENSOR_PUB = QoSProfile(depth=SENSOR.depth, history=HistoryPolicy.KEEP_LAST,
                        reliability=ReliabilityPolicy.RELIABLE,
                        durability=DurabilityPolicy.VOLATILE)

# Contact sensing drives the touchdown rule in two nodes that must agree tick by tick, so no
# sample may be lost; depth covers a subscriber that is busy for a re-plan.
CONTACTS = QoSProfile(depth=50, history=HistoryPolicy.KEEP_LAST,
                      reliability=ReliabilityPolicy.RELIABLE,
                      durability=DurabilityPolicy.VOLATILE)

# Commands and events: every message counts.
COMMAND = QoSProfile(depth=10, history=HistoryPolicy.KEEP_LAST,
                     reliability=ReliabilityPolicy.RELIABLE,
                     durability=DurabilityPolicy.VOLATILE)

# Input schedules (stamped set-points, pushes) are sent in a burst ahead of time, often before
# the node that consumes them is up: transient local, so a late joiner still gets them all.
# Publishers and subscribers of these topics must both use this profile.
SCHEDULE = QoSProfile(depth=100, history=HistoryPolicy.KEEP_LAST,
                      reliability=ReliabilityPolicy.RELIABLE,
                      durability=DurabilityPolicy.TRANSIENT_LOCAL)

# Plans and footholds: a late joiner gets the last one.
LATCHED = QoSProfile(depth=1, history=HistoryPolicy.KEEP_LAST,
                     reliability=ReliabilityPolicy.RELIABLE,
                     durability=DurabilityPolicy.TRANSIENT_LOCAL)

def with_depth(profile: QoSProfile, depth: int) -> QoSProfile:
    """``profile`` with another history depth (a reader queue sized for its consumer)."""
    return QoSProfile(depth=depth, history=profile.history, reliability=profile.reliability,
                      durability=profile.durability)


CLOCK = QoSProfile(depth=1, history=HistoryPolicy.KEEP_LAST,
                   reliability=ReliabilityPolicy.RELIABLE,
                   durability=DurabilityPolicy.VOLATILE)

# No QoS-event handlers on the topics between our own nodes, whose profiles all come from this
# module and so cannot mismatch. rclpy turns each handler into a waitable that its executor walks
# in Python at every wake-up: 134 us per message with them against 71 us without
# (scripts/bench_rclpy.sh, docs/performance.md). Inputs from users (cmd_vel, cmd_vel_stamped,
# external_wrench) keep rclpy's default handlers, which warn about an incompatible QoS.
INTERNAL_SUB_EVENTS = SubscriptionEventCallbacks(use_default_callbacks=False)
INTERNAL_PUB_EVENTS = PublisherEventCallbacks(use_default_callbacks=False)
