"""QoS profiles by role (docs/ARCHITECTURE.md, topic table)."""

from rclpy.event_handler import PublisherEventCallbacks, SubscriptionEventCallbacks
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

# Sensor-like streams (joint_states, imu, odom, ground_truth/odom), as REP-2003 asks of a
# driver: read best effort by our own nodes (SENSOR: the newest sample matters, a lost one is
# replaced by the next tick and never waited for), published reliable (SENSOR_PUB),
# so that a subscriber with the default QoS, which is reliable (`ros2 topic echo`, RViz, a
# `create_subscription(..., 10)`), is compatible and receives them. A reliable writer does not
# wait for best-effort readers, and with KEEP_LAST it never blocks on a slow reliable one.
SENSOR = QoSProfile(depth=10, history=HistoryPolicy.KEEP_LAST,
                    reliability=ReliabilityPolicy.BEST_EFFORT,
                    durability=DurabilityPolicy.VOLATILE)
# The writers of the per-tick topics keep the last RECORDED_HISTORY samples (4 s of sim
# time at 250 Hz) for their reliable readers, the recorder's above all: a sample that a busy
# reader missed in transport is sent again from this history instead of being lost, as long
# as the reader is less than RECORDED_HISTORY samples behind (docs/recording.md, "No loss").
# KEEP_LAST: a writer never waits for a reader, so a slow or dead recorder cannot slow or stop
# the robot; best-effort readers (our nodes' SENSOR) are not affected by the writer's depth.
RECORDED_HISTORY = 1000
SENSOR_PUB = QoSProfile(depth=RECORDED_HISTORY, history=HistoryPolicy.KEEP_LAST,
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

# The publishers of recorded per-tick topics whose readers use the profile on the left: the
# same profile with the writer history of RECORDED_HISTORY (see SENSOR_PUB). Only the writer's
# depth differs, which is not part of QoS matching, so every reader stays compatible.
CONTACTS_PUB = with_depth(CONTACTS, RECORDED_HISTORY)
COMMAND_PUB = with_depth(COMMAND, RECORDED_HISTORY)
CLOCK_PUB = with_depth(CLOCK, RECORDED_HISTORY // 5)    # /clock: every 5th tick
# The writers of plans (footholds, com_plan, zmp_plan, com_path, gait_markers: one of each per
# re-plan) keep the last PLAN_HISTORY, for the same reason: with depth 1 a plan the recorder
# missed in transport could be sent again only until the next re-plan replaced it. 20 re-plans
# are 4 s of sim time or more. A late joiner that reads them LATCHED (depth 1) gets them in
# order and the newest last, but not always the newest alone: its depth drops only what it has
# not taken yet, and its executor may take older ones first (benchmarks/late_reader.py). One
# that keeps all (a respawned recorder) gets the history (docs/recording.md, "No loss").
PLAN_HISTORY = 20
LATCHED_PUB = with_depth(LATCHED, PLAN_HISTORY)

# No QoS-event handlers on the topics between our own nodes, whose profiles all come from this
# module and so cannot mismatch. rclpy turns each handler into a waitable that its executor walks
# in Python at every wake-up: 134 us per message with them against 71 us without
# (scripts/bench_rclpy.sh, docs/performance.md). Inputs from users (cmd_vel, cmd_vel_stamped,
# external_wrench) keep rclpy's default handlers, which warn about an incompatible QoS.
INTERNAL_SUB_EVENTS = SubscriptionEventCallbacks(use_default_callbacks=False)
INTERNAL_PUB_EVENTS = PublisherEventCallbacks(use_default_callbacks=False)


def recorder_qos(offered: list[QoSProfile], depth: int = 0) -> tuple[QoSProfile, bool, bool]:
    """The recorder's subscription to a topic whose publishers offer ``offered``, and whether
    it is (reliable, transient local): each only if every publisher is, as rosbag2 does, so it
    matches them all. ``depth`` 0: KEEP_ALL, every sample is kept until the recorder takes it
    (the reader's queue never overwrites one); else KEEP_LAST ``depth``."""
    reliable = all(q.reliability == ReliabilityPolicy.RELIABLE for q in offered)
    latched = all(q.durability == DurabilityPolicy.TRANSIENT_LOCAL for q in offered)
    profile = QoSProfile(
        history=HistoryPolicy.KEEP_ALL if depth <= 0 else HistoryPolicy.KEEP_LAST,
        depth=max(depth, 1),
        reliability=ReliabilityPolicy.RELIABLE if reliable else ReliabilityPolicy.BEST_EFFORT,
        durability=DurabilityPolicy.TRANSIENT_LOCAL if latched else DurabilityPolicy.VOLATILE)
    return profile, reliable, latched
