"""Run a command in network and process namespaces of its own, with only the loopback up.

    python -m replan_experiments.benchmarks.loopback CMD [ARG ...]

What the Ray tests and benchmark run their cluster in: Ray takes the machine's interface
address for a node even when told ``--node-ip-address=127.0.0.1`` (intended,
ray-project/ray#26293), but where ``lo`` is the only interface it uses 127.0.0.1, so no cluster
traffic leaves the machine. The process namespace ends everything the command started (Ray's
daemons, graphs) when the command ends or this is killed. Needs root, or unprivileged user
namespaces (then it maps the caller to root inside).
"""

from __future__ import annotations

import fcntl
import os
import socket
import struct
import sys

_SIOCGIFFLAGS, _SIOCSIFFLAGS, _IFF_UP = 0x8913, 0x8914, 0x1
_INSIDE = '--inside'


def command(cmd: list[str]) -> list[str]:
    """``cmd`` wrapped to run in namespaces of its own with only ``lo`` up."""
    user = [] if os.geteuid() == 0 else ['--map-root-user']
    return ['unshare', '--net', '--pid', '--fork', '--kill-child', '--mount-proc', *user,
            sys.executable, '-m', 'replan_experiments.benchmarks.loopback', _INSIDE, *cmd]


def loopback_up() -> None:
    """Bring ``lo`` up (what ``ip link set lo up`` does, without needing iproute2)."""
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
        request = struct.pack('16sH14x', b'lo', 0)
        flags = struct.unpack('16sH14x', fcntl.ioctl(sock, _SIOCGIFFLAGS, request))[1]
        fcntl.ioctl(sock, _SIOCSIFFLAGS, struct.pack('16sH14x', b'lo', flags | _IFF_UP))


def main(argv: list[str] | None = None) -> int:
    args = list(sys.argv[1:] if argv is None else argv)
    if not args or args[0] in ('-h', '--help'):
        print(__doc__)
        return 0 if args else 2
    if args[0] != _INSIDE:
        cmd = command(args)
        os.execvp(cmd[0], cmd)
    loopback_up()
    os.execvp(args[1], args[1:])
    return 1        # not reached: execvp replaces this process


if __name__ == '__main__':
    sys.exit(main())
