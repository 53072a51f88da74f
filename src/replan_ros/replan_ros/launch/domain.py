"""One graph per ROS domain on a machine: a lock file per (network namespace, ROS_DOMAIN_ID).

Two graphs on one domain mix their topics without an error (each controller answers both
simulators; docs/usage.md, "Two graphs on one machine"). The simulator's check for a second
``/clock`` publisher comes too late when both start at once. So whatever starts a graph claims
its domain first: the scripts that start one (``claim_domain`` of scripts/preamble.sh, through
``python -m replan_ros.launch.domain path``) and the experiment runners (``domain_slot``); the
test harness only skips a domain that is claimed. A claim is ``flock`` on the domain's lock
file, held by an open file: it ends when the last process holding that file ends, a crash
included, and a child that inherits the file (``pass_fds``, or a shell's ``exec``) keeps it.

The lock files are per network namespace: DDS discovery does not cross one (a Ray test in
``unshare -n`` uses the same domain numbers as the machine without meeting its graphs).
``HELD_ENV`` tells a child script that its parent holds the claim of the domain it was given
(a benchmark script that calls launch.sh and scenario.sh).

Starts no graph and decides nothing of a run: outside the code fingerprint
(replan_experiments/runs.py).
"""

from __future__ import annotations

import contextlib
import fcntl
import os
import sys
import tempfile
import time
from pathlib import Path

HELD_ENV = 'REPLAN_DOMAIN_HELD'    # ROS_DOMAIN_ID whose claim the parent holds
MAX_DOMAIN = 232                   # the largest ROS_DOMAIN_ID with valid DDS ports on Linux
DOMAIN_POOL = 16                   # domains domain_slot tries, from its base up


def loopback_dds(env: dict[str, str], config_dir: Path,
                 keep_set: bool = True) -> dict[str, str]:
    """``env`` with DDS on this machine's loopback, as scripts/env.sh sets it for every script:
    ``ROS_AUTOMATIC_DISCOVERY_RANGE`` SYSTEM_DEFAULT, which leaves the transports to the
    profile, and ``FASTRTPS_DEFAULT_PROFILES_FILE`` ``config_dir/dds/fastdds.xml``, whose
    participant talks UDP on 127.0.0.1 only (without it, SYSTEM_DEFAULT would be Fast DDS's own
    defaults, the network included; docs/usage.md, "DDS"). ``keep_set``: a range or profile
    already in ``env`` (the user's) stays."""
    wanted = {'ROS_AUTOMATIC_DISCOVERY_RANGE': 'SYSTEM_DEFAULT',
              'FASTRTPS_DEFAULT_PROFILES_FILE': str(config_dir / 'dds' / 'fastdds.xml')}
    return {**wanted, **env} if keep_set else {**env, **wanted}


def lock_folder() -> Path:
    """The folder of the lock files: the user's runtime folder, else one per user in /tmp."""
    runtime = os.environ.get('XDG_RUNTIME_DIR')
    if runtime and os.path.isdir(runtime):
        return Path(runtime) / 'replan-domains'
    return Path(tempfile.gettempdir()) / f'replan-domains-{os.getuid()}'


def lock_path(domain: int, folder: Path | None = None) -> Path:
    """The lock file of ``domain`` in this process's network namespace."""
    if not 0 <= domain <= MAX_DOMAIN:
        raise ValueError(f'ROS_DOMAIN_ID must be within 0..{MAX_DOMAIN}, got {domain}')
    namespace = os.stat('/proc/self/ns/net').st_ino
    return (folder or lock_folder()) / f'net{namespace}-domain{domain}.lock'


def claim(domain: int, folder: Path | None = None) -> int | None:
    """Claim ``domain``: the open file descriptor that holds it (close it to release), or
    None if another process holds it."""
    path = lock_path(domain, folder)
    path.parent.mkdir(mode=0o700, parents=True, exist_ok=True)
    fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_APPEND | os.O_CLOEXEC, 0o600)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        os.close(fd)
        return None
    return fd


@contextlib.contextmanager
def domain_slot(base: int, folder: Path | None = None, pool: int = DOMAIN_POOL):
    """The first domain of ``base`` .. ``base + pool - 1`` (within 232) that nobody holds,
    claimed for the block; waits while every one is held. Yields (domain, fd): a caller that
    passes fd to its graph's process (``pass_fds``) lets that graph keep the domain if the
    caller is killed."""
    domains = range(base, min(base + pool, MAX_DOMAIN + 1))
    while True:
        for domain in domains:
            fd = claim(domain, folder)
            if fd is None:
                continue
            try:
                yield domain, fd
            finally:
                os.close(fd)
            return
        time.sleep(0.5)     # every domain held (other callers with the same base): wait


def main(argv: list[str] | None = None) -> int:
    """``path DOMAIN``: print the lock file of DOMAIN (made ready for ``flock``)."""
    args = sys.argv[1:] if argv is None else argv
    if len(args) != 2 or args[0] != 'path' or not args[1].isdigit():
        print('usage: python -m replan_ros.launch.domain path DOMAIN', file=sys.stderr)
        return 2
    try:
        path = lock_path(int(args[1]))
    except ValueError as err:
        print(f'config error: {err}', file=sys.stderr)
        return 2
    path.parent.mkdir(mode=0o700, parents=True, exist_ok=True)
    print(path)
    return 0


if __name__ == '__main__':
    sys.exit(main())
