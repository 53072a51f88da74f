"""Former name of ``replan_ros.tools.topic`` (scripts/topic.sh), kept as an alias.

``python -m replan_ros.tools.topic_probe list|echo|info|hz|nodes|talk`` and the console script
``topic_probe`` (the test harness's talker) run the same tool. Note that ``hz --window`` now
counts messages, as in ros2 topic hz; ``--duration S`` bounds the measurement in wall seconds.
"""

import sys

from replan_ros.tools.topic import main as _main


def main(argv=None) -> int:
    return _main(argv, prog='topic_probe')


if __name__ == '__main__':
    sys.exit(main())
