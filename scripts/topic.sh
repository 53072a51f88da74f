#!/usr/bin/env bash
# Inspect the running graph like `ros2 topic` (there is no ros2 CLI in this install):
#   scripts/topic.sh list [-t]                      topics (and types)
#   scripts/topic.sh echo TOPIC [--once] [--count N] [--field a.b]   messages as YAML
#   scripts/topic.sh info TOPIC [-v]                type, endpoints, with -v their QoS
#   scripts/topic.sh hz TOPIC [--window N] [--duration S]            rate and period stats
#   scripts/topic.sh nodes                          node names (ros2 node list)
# Sets up its own environment (no need to source scripts/env.sh); the graph must be on the
# same ROS_DOMAIN_ID. scripts/topic.sh COMMAND --help for each command's options.
source "$(dirname "${BASH_SOURCE[0]}")/preamble.sh"
help_before_setup "$@"
replan_env
exec python -m replan_ros.tools.topic "$@"
