"""The harness itself: isolated domains, real processes, clean teardown."""

import os
import signal
import subprocess
import sys

from harness import (
    DomainReservation,
    Launcher,
    Probe,
    descends_from,
    domain_processes,
    graph_env,
    parent_pid,
    reap_leftovers,
)

from replan_ros.launch.domain import claim, domain_slot


def test_reserved_domains_are_unique_while_held():
    first, second = DomainReservation(), DomainReservation()
    try:
        assert first.domain_id != second.domain_id
    finally:
        first.release()
        second.release()


def test_a_reserved_domain_is_claimed_and_a_runner_pool_skips_it():
    """A test session's domain is claimed like a user's graph: an experiment runner started
    by another session with its domain pool over it (``--domain-base``) takes the next one."""
    reservation = DomainReservation()
    try:
        assert claim(reservation.domain_id) is None
        with domain_slot(reservation.domain_id) as (domain, _):
            assert domain != reservation.domain_id
    finally:
        reservation.release()
    freed = claim(reservation.domain_id)
    assert freed is not None, 'the claim outlived its release'
    os.close(freed)


def test_two_graphs_on_two_domains_do_not_see_each_other(tmp_path, reserve_domain):
    domain_a, domain_b = reserve_domain(), reserve_domain()
    graph_a, graph_b = Launcher(domain_a, tmp_path), Launcher(domain_b, tmp_path)
    probe_a, probe_b = Probe(domain_a, 'probe_a'), Probe(domain_b, 'probe_b')
    try:
        graph_a.start('topic_probe', args=['talk', 'only_in_a'], name='talker_a')
        graph_b.start('topic_probe', args=['talk', 'only_in_b'], name='talker_b')
        assert probe_a.wait_for_topics(['only_in_a'], timeout=20), graph_a.logs()
        assert probe_b.wait_for_topics(['only_in_b'], timeout=20), graph_b.logs()
        # Both graphs are fully up; give discovery time to leak if it were going to.
        probe_a.spin_for(2.0)
        probe_b.spin_for(0.5)
        assert '/only_in_b' not in probe_a.topics()
        assert '/only_in_a' not in probe_b.topics()
    finally:
        probe_a.close()
        probe_b.close()
        graph_a.stop_all()
        graph_b.stop_all()


def test_node_processes_stop_on_sigint(launcher, probe):
    talker = launcher.start('topic_probe', args=['talk', 'chatter'], name='talker')
    assert probe.wait_for_topics(['chatter'], timeout=20), launcher.logs()
    talker.signal(signal.SIGINT)
    talker.process.wait(10)
    assert talker.process.returncode == 0, talker.log()


def test_a_process_left_on_a_domain_is_found_and_killed(reserve_domain):
    """What the conftest's leftover check relies on: a process started with the domain in its
    environment (as a script's graph inherits it) is found by it, and killed."""
    domain = reserve_domain()
    before = set(domain_processes(domain))
    # It says when it runs: until then it may be between exec calls (the venv's python
    # re-executes itself once), when /proc shows no command line and no environment.
    stray = subprocess.Popen([sys.executable, '-c',
                              'import time; print("up", flush=True); time.sleep(60)'],
                             env=graph_env(domain), start_new_session=True,
                             stdout=subprocess.PIPE, text=True)
    try:
        assert stray.stdout.readline() == 'up\n'
        assert stray.pid in domain_processes(domain)
        assert parent_pid(stray.pid) == os.getpid()
        # What the per-test check keeps: this process's own children (a module's graph).
        assert descends_from(stray.pid, os.getpid()) and not descends_from(stray.pid, stray.pid)
        assert reap_leftovers(domain, before, grace=0.2,
                              keep=lambda pid: descends_from(pid, os.getpid())) == {}
        assert stray.poll() is None
        left = reap_leftovers(domain, before, grace=0.5)
        assert list(left) == [stray.pid] and 'time.sleep(60)' in left[stray.pid]
        assert stray.wait(5) == -signal.SIGKILL
        assert stray.pid not in domain_processes(domain)
    finally:
        if stray.poll() is None:
            stray.kill()
        stray.stdout.close()
