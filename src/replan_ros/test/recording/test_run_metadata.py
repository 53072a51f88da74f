"""The recorder's log times: a message's arrival placed between two takes' clock readings."""

from __future__ import annotations

from itertools import pairwise

from replan_ros.recording.run_metadata import arrival_time

SIM = 1_000_000_000          # ns


def test_arrival_is_placed_linearly_between_the_takes():
    previous, take = (10_000, 4 * SIM), (10_400, 5 * SIM)       # 400 ns wall, 1 s sim
    assert arrival_time(10_100, previous, take) == 4 * SIM + SIM // 4
    assert arrival_time(10_400, previous, take) == 5 * SIM
    # Arrived before the previous take (taken late) or stamped after this one: clamped.
    assert arrival_time(9_000, previous, take) == 4 * SIM
    assert arrival_time(11_000, previous, take) == 5 * SIM


def test_first_take_no_reception_time_or_no_wall_progress_give_the_take_time():
    take = (10_400, 5 * SIM)
    assert arrival_time(10_100, None, take) == 5 * SIM
    assert arrival_time(0, (10_000, 4 * SIM), take) == 5 * SIM
    assert arrival_time(10_100, (10_400, 4 * SIM), take) == 5 * SIM


def test_log_times_never_decrease_over_takes_in_reception_order():
    takes = [(1_000 * k, 20_000_000 * (k // 3)) for k in range(1, 12)]   # sim clock steps
    times = []
    for previous, take in pairwise(takes):
        for received in range(previous[0] - 200, take[0] + 1, 50):
            times.append(arrival_time(received, previous, take))
    assert times == sorted(times)
    assert times[0] == takes[0][1] and times[-1] == takes[-1][1]


def _params(tmp_path, **changes):
    p = {'log_time_clock': 'sim', 'config_files': [], 'scenario_file': '', 'metadata_json': ''}
    p.update(changes)
    return p


def test_the_run_records_hold_the_configuration_and_say_what_could_not_be_stored(tmp_path):
    from replan_ros.recording.run_metadata import run_records

    config = tmp_path / 'gait.yaml'
    config.write_text('gait:\n  ros__parameters: {}\n')
    scenario = tmp_path / 'walk.yaml'
    scenario.write_text('duration: 4.0\n')
    records, errors = run_records(_params(
        tmp_path, config_files=[str(config), str(tmp_path / 'missing.yaml')],
        scenario_file=str(scenario), metadata_json='{"seed": 3, "note": "x"}'), True)
    named = dict(records)
    assert list(named) == ['replan_run', 'replan_config', 'replan_scenario', 'replan_user']
    assert named['replan_run']['use_sim_time'] == 'true'
    assert named['replan_run']['git_revision']
    assert named['replan_config'] == {str(config): 'gait:\n  ros__parameters: {}\n'}
    assert named['replan_scenario']['content'] == 'duration: 4.0\n'
    assert named['replan_user'] == {'seed': '3', 'note': 'x'}
    assert len(errors) == 1 and 'missing.yaml not stored' in errors[0]
    records, errors = run_records(_params(tmp_path, metadata_json='[1, 2]'), False)
    assert [name for name, _ in records] == ['replan_run']
    assert errors == ['metadata_json not stored: not a JSON object']


def test_without_git_the_revision_is_the_one_baked_in(tmp_path, monkeypatch):
    from replan_ros.recording.run_metadata import run_records

    monkeypatch.setenv('REPLAN_ROOT', str(tmp_path))          # no repository there
    monkeypatch.setenv('REPLAN_GIT_REVISION', 'abc1234')
    records, _ = run_records(_params(tmp_path), False)
    run = dict(records)['replan_run']
    assert run['git_revision'] == 'abc1234' and run['git_dirty'] == 'false'
