"""launch.domain: one graph per ROS domain on a machine (a lock file per network namespace and
domain). Real flock and processes, no ROS."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import threading
import time

import pytest

from replan_ros.launch.domain import (
    DOMAIN_POOL,
    claim,
    domain_slot,
    lock_path,
    loopback_dds,
    main,
)


def test_a_claimed_domain_is_refused_until_released(tmp_path):
    fd = claim(7, tmp_path)
    assert fd is not None
    assert claim(7, tmp_path) is None           # another open file: refused, even in-process
    other = claim(8, tmp_path)
    assert other is not None                    # the next domain is free
    os.close(fd)
    again = claim(7, tmp_path)
    assert again is not None
    os.close(again)
    os.close(other)


def test_a_claim_ends_with_its_process(tmp_path):
    """A crashed holder frees its domain: the lock goes with its last open file."""
    holder = subprocess.Popen(
        [sys.executable, '-c', 'import sys, time; from pathlib import Path; '
         'from replan_ros.launch.domain import claim; '
         f'fd = claim(9, Path({str(tmp_path)!r})); print(fd is not None, flush=True); '
         'time.sleep(60)'], stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout.readline().strip() == 'True'
        assert claim(9, tmp_path) is None
    finally:
        holder.kill()
        holder.wait()
    fd = claim(9, tmp_path)
    assert fd is not None
    os.close(fd)


def test_the_domain_range_is_checked(tmp_path):
    with pytest.raises(ValueError, match=r'0\.\.232'):
        lock_path(233, tmp_path)
    assert main(['path', '233']) == 2
    assert main(['path']) == 2


def test_the_lock_file_is_per_network_namespace(tmp_path, capsys):
    """DDS discovery does not cross a network namespace: a graph in another one (a Ray test
    under ``unshare -n``) does not hold this namespace's domain."""
    assert main(['path', '5']) == 0
    here = capsys.readouterr().out.strip()
    assert here == str(lock_path(5))
    if shutil.which('unshare') is None:
        pytest.skip('no unshare here')
    there = subprocess.run(['unshare', '-n', sys.executable, '-m', 'replan_ros.launch.domain',
                            'path', '5'], capture_output=True, text=True)
    if there.returncode != 0 and 'Operation not permitted' in there.stderr:
        pytest.skip('unshare -n not permitted here')
    assert there.returncode == 0, there.stderr
    assert there.stdout.strip() != here
    assert there.stdout.strip().endswith('-domain5.lock')


def test_two_holders_on_one_machine_never_share_a_domain(tmp_path):
    with domain_slot(150, tmp_path) as (first, _), domain_slot(150, tmp_path) as (second, _):
        assert first == 150 and second == 151
    with domain_slot(150, tmp_path) as (again, _):
        assert again == 150                  # released on leaving


def test_a_domain_claimed_by_a_script_is_skipped(tmp_path):
    fd = claim(150, tmp_path)
    try:
        with domain_slot(150, tmp_path) as (domain, _):
            assert domain == 151
    finally:
        os.close(fd)


def test_the_pool_stops_at_domain_232(tmp_path):
    with domain_slot(232, tmp_path) as (domain, _):
        assert domain == 232
    assert DOMAIN_POOL >= 8


def test_a_full_pool_waits_for_a_domain(tmp_path):
    got = []

    def second():
        with domain_slot(232, tmp_path) as (domain, _):
            got.append((domain, time.monotonic()))

    with domain_slot(232, tmp_path):
        thread = threading.Thread(target=second)
        thread.start()
        time.sleep(0.3)
        released = time.monotonic()
    thread.join(timeout=5)
    assert got and got[0][0] == 232 and got[0][1] >= released


def test_a_child_that_inherits_the_lock_keeps_the_domain(tmp_path):
    """A graph orphaned by a killed runner holds its domain until it is gone."""
    with domain_slot(150, tmp_path) as (domain, fd):
        child = subprocess.Popen([sys.executable, '-c', 'import time; time.sleep(3)'],
                                 pass_fds=(fd,))
    try:
        with domain_slot(150, tmp_path) as (other, _):
            assert other != domain
    finally:
        child.kill()
        child.wait()
    with domain_slot(150, tmp_path) as (after, _):
        assert after == domain


def test_loopback_dds_names_the_range_and_the_profile_together(tmp_path):
    """SYSTEM_DEFAULT without the loopback profile would be Fast DDS's own defaults (the
    network): the two come as a pair; a user's setting stays unless told otherwise."""
    profile = str(tmp_path / 'dds' / 'fastdds.xml')
    assert loopback_dds({'X': '1'}, tmp_path) == {
        'X': '1', 'ROS_AUTOMATIC_DISCOVERY_RANGE': 'SYSTEM_DEFAULT',
        'FASTRTPS_DEFAULT_PROFILES_FILE': profile}
    users = {'ROS_AUTOMATIC_DISCOVERY_RANGE': 'SUBNET', 'FASTRTPS_DEFAULT_PROFILES_FILE': 'mine'}
    assert loopback_dds(users, tmp_path) == users
    assert loopback_dds(users, tmp_path, keep_set=False) == {
        'ROS_AUTOMATIC_DISCOVERY_RANGE': 'SYSTEM_DEFAULT',
        'FASTRTPS_DEFAULT_PROFILES_FILE': profile}
