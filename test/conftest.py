"""Fixtures for node-graph tests (see harness.py).

- ``ros_domain``: the ROS_DOMAIN_ID reserved (claimed) for this test session (also set in
  os.environ, with ``REPLAN_DOMAIN_HELD``: a script the tests start passes the claim).
- ``launcher``: ``launcher.start('sim_node', params_file=CONFIG_DIR / 'sim.yaml', params={...})``
  starts a real node process; all are stopped (SIGINT, then SIGKILL) after the test, and their
  logs are printed when the test failed.
- ``probe``: a test-side rclpy node on the session domain (``probe.node``, ``spin_until``,
  ``collect``, ``subscribe``, ``wait_for_topics``).
- ``reserve_domain``: reserve one more domain inside a test (for isolation tests).
- ``ray_temp``: a short folder of its own for a Ray cluster's session files.
"""

from __future__ import annotations

import os
import shutil
import tempfile

import pytest
from harness import (
    CONFIG_DIR,
    HELD_ENV,
    DomainReservation,
    Launcher,
    Probe,
    descends_from,
    domain_processes,
    reap_leftovers,
)

from replan_ros.launch.domain import loopback_dds

__all__ = ['CONFIG_DIR']

_session_domain: DomainReservation | None = None


def pytest_configure(config):
    global _session_domain  # the reservation must outlive every fixture of the session
    if _session_domain is None:
        _session_domain = DomainReservation()
        os.environ['ROS_DOMAIN_ID'] = str(_session_domain.domain_id)
        os.environ[HELD_ENV] = str(_session_domain.domain_id)    # scripts pass our claim
        os.environ.update(loopback_dds(dict(os.environ), CONFIG_DIR, keep_set=False))


def pytest_unconfigure(config):
    if _session_domain is not None:
        _session_domain.release()


@pytest.hookimpl(wrapper=True, tryfirst=True)
def pytest_runtest_makereport(item, call):
    report = yield
    setattr(item, f'rep_{report.when}', report)
    return report


def _failed(request) -> bool:
    return any(getattr(request.node, f'rep_{when}', None) is not None
               and getattr(request.node, f'rep_{when}').failed for when in ('setup', 'call'))


@pytest.fixture(scope='session')
def ros_domain() -> int:
    return _session_domain.domain_id


def _no_leftovers(domain: int, before: set[int], what: str, keep=lambda pid: False) -> None:
    left = reap_leftovers(domain, before, keep=keep)
    if left:
        pytest.fail(f'{what} left {len(left)} process(es) running on the session domain '
                    f'{domain} (killed now): ' + '; '.join(
                        f'{pid}: {cmd[:160]}' for pid, cmd in sorted(left.items())),
                    pytrace=False)


@pytest.fixture(scope='module', autouse=True)
def no_leftover_processes_of_module(request):
    """Every process that a test module (or its module fixtures) started on the session
    domain is gone at its end: a node left running would publish into the next tests (a
    stray sim's /diagnostics once failed test_wbc_node in CI)."""
    domain = _session_domain.domain_id
    before = set(domain_processes(domain))
    yield
    _no_leftovers(domain, before, f'module {request.module.__name__}')


@pytest.fixture(autouse=True)
def no_leftover_processes(request, no_leftover_processes_of_module):
    """The same for each test, but for the descendants of this process: a module fixture's
    graph outlives its tests, its launcher may start nodes while the first test runs
    (test_live_view.py), and a test may restart one of them (test_faults.py); those are
    checked at the module's end. What was left behind orphaned (a killed launcher's nodes, no
    longer our descendants) is caught here."""
    domain = _session_domain.domain_id
    me = os.getpid()
    before = set(domain_processes(domain))
    yield
    _no_leftovers(domain, before, f'test {request.node.name}',
                  keep=lambda pid: descends_from(pid, me))


@pytest.fixture
def reserve_domain():
    held: list[DomainReservation] = []

    def reserve() -> int:
        held.append(DomainReservation())
        return held[-1].domain_id

    yield reserve
    for reservation in held:
        reservation.release()


@pytest.fixture
def launcher(request, ros_domain, tmp_path):
    launch = Launcher(ros_domain, tmp_path)
    yield launch
    launch.stop_all()
    if _failed(request):
        print(f'\n----- node logs (domain {ros_domain}) -----\n{launch.logs()}')


@pytest.fixture
def probe(ros_domain):
    test_probe = Probe(ros_domain)
    yield test_probe
    test_probe.close()


@pytest.fixture
def ray_temp():
    """Ray's session folder: short (its socket paths must stay under 108 characters) and the
    test's own."""
    folder = tempfile.mkdtemp(prefix='ray', dir='/tmp')
    yield folder
    shutil.rmtree(folder, ignore_errors=True)
