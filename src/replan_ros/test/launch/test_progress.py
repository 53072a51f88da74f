"""The launcher's progress line: its text, its real-time factors, terminal or plain lines."""

import io
import os
import subprocess

import pytest

from replan_ros.launch.graph import (
    MIN_MEASURED_SIM_S,
    closing_figures,
    cpu_per_sim_s,
    process_cpu_seconds,
)
from replan_ros.launch.progress import (
    EVENT_WORDS,
    PROGRESS_PLAIN_PERIOD,
    PROGRESS_TTY_PERIOD,
    ProgressLine,
    RunProgress,
    format_progress,
    is_terminal,
)


class _Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True


def test_format_progress_has_every_figure():
    text = format_progress(12.34, 30.0, 1.523, 1.48, 1.234, replans=17, events=(3, 7))
    assert text == ('[progress] sim  12.3 / 30.0 s ( 41 %) | RTF 1.52 now, 1.48 overall | '
                    'distance 1.23 m | re-plans 17 | events 3/7')


def test_format_progress_before_the_first_tick_and_without_duration():
    text = format_progress(0.0, None, None, None, None, replans=0)
    assert text == '[progress] sim   0.0 s | waiting for the first tick | re-plans 0'
    assert '(estimated)' in format_progress(5.0, None, None, 1.5, 0.5, estimated=True)


@pytest.mark.parametrize('args', [
    (0.0, None, None, None, None), (12.0, 12.0, 1.2, 1.3, 0.7), (3.0, 30.0, None, 1.0, None)])
def test_progress_never_looks_like_a_launcher_event(args):
    """Tests and users grep the launcher's output for 'started mpc (pid N)', 'node mpc died',
    'respawned mpc', 'real-time factor'...: a progress line must never match them."""
    text = format_progress(*args, estimated=True, replans=3, events=(1, 2)).lower()
    assert not [word for word in EVENT_WORDS if word in text], text


def test_real_time_factors_recent_and_since_the_first_tick():
    progress = RunProgress(20.0, event_times=[1.0, 5.0, 5.3], window=5.0)
    progress.sample(0.0, 0.0)                    # the sim has not moved yet
    assert progress.real_time_factors() == (None, None)
    for k in range(11):                          # 1 sim s per wall s for 10 s ...
        progress.sample(10.0 + k, 1.0 + k)
    for k in range(1, 11):                       # ... then 2 sim s per wall s
        progress.sample(20.0 + k, 11.0 + 2 * k)
    recent, total = progress.real_time_factors()
    assert recent == pytest.approx(2.0)
    assert total == pytest.approx(30.0 / 20.0)
    assert 'events 3/3' in progress.text(None)
    progress = RunProgress(20.0, event_times=[1.0, 5.0, 5.3])
    progress.sample(3.0, 4.0)
    assert 'events 1/3' in progress.text(2.0)


def test_plain_lines_when_not_a_terminal():
    stream = io.StringIO()
    line = ProgressLine(stream)
    assert not line.in_place and line.period == PROGRESS_PLAIN_PERIOD
    assert not line.due(100.0)                    # the first line one period after the start
    assert not line.due(100.0 + PROGRESS_PLAIN_PERIOD - 0.1)
    assert line.due(100.0 + PROGRESS_PLAIN_PERIOD)
    line.show('[progress] a', 105.0)
    line.clear()                                  # nothing to erase in a log
    line.show('[progress] b', 110.0)
    assert stream.getvalue() == '[progress] a\n[progress] b\n'


def test_refreshed_in_place_on_a_terminal(monkeypatch):
    monkeypatch.setenv('TERM', 'xterm')
    stream = _Terminal()
    assert is_terminal(stream)
    line = ProgressLine(stream)
    assert line.in_place and line.period == PROGRESS_TTY_PERIOD
    line.show('[progress] a', 1.0)
    line.show('[progress] b', 2.0)
    line.clear()
    assert stream.getvalue() == ('\r[progress] a\x1b[K\r[progress] b\x1b[K\r\x1b[K')
    monkeypatch.setenv('TERM', 'dumb')
    assert not is_terminal(stream)


def test_a_closed_or_odd_stream_is_no_terminal():
    stream = io.StringIO()
    stream.close()
    assert not is_terminal(stream)
    assert not is_terminal(object())


def test_cpu_per_sim_s_counts_each_node_once_and_a_respawn_from_its_start():
    before = {'sim:100': 1.0, 'wbc:101': 2.0, 'mpc:102': 0.5}
    after = {'sim:100': 3.0, 'wbc:101': 4.5, 'mpc:200': 0.4}      # mpc respawned as pid 200
    assert cpu_per_sim_s(before, after, 10.0) == pytest.approx(
        {'sim': 200.0, 'wbc': 250.0, 'mpc': 40.0})


def test_a_run_too_short_to_measure_gives_no_closing_figures():
    before, after = {'sim:1': 1.0, 'wbc:2': 2.0}, {'sim:1': 1.5, 'wbc:2': 2.2}
    assert closing_figures(0.5 * MIN_MEASURED_SIM_S, 1.0, before, after) == (None, {})
    rtf, cpu = closing_figures(2.0, 4.0, before, after)
    assert rtf == 0.5 and cpu == pytest.approx({'sim': 250.0, 'wbc': 100.0})


def test_a_process_cpu_time_is_read_while_it_runs():
    assert process_cpu_seconds(os.getpid()) >= 0.0
    child = subprocess.Popen(['true'])
    child.wait()
    assert process_cpu_seconds(child.pid) is None          # gone (reaped)
