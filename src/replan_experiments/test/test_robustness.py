"""The soak's scenario and the robustness page, without DDS. The faults themselves in a
walking graph: test/test_faults.py."""

import json

from replan_experiments import robustness_page, soak


def test_the_soak_scenario_cycles_set_points_and_alternates_pushes():
    plan = soak.scenario(600.0, 20.0, 45.0, 80.0)
    setpoints = [e for e in plan['events'] if 'cmd_vel' in e]
    pushes = [e for e in plan['events'] if 'push' in e]
    assert plan['duration'] == 600.0 and len(setpoints) == 30 and len(pushes) == 13
    assert len({tuple(e['cmd_vel']) for e in setpoints}) == len(soak.CYCLE)
    assert [p['push']['force'][1] for p in pushes[:2]] == [80.0, -80.0]
    times = [e['t'] for e in plan['events']]
    assert times == sorted(times) and times[-1] < 600.0


def test_the_robustness_page_has_one_row_per_result_in_order(tmp_path):
    for name in ('urdf_sim', 'kill_mpc', 'something_new'):
        (tmp_path / f'{name}.json').write_text(json.dumps(
            {'fault': name, 'time_to_safe_s': 0.5, 'diagnostics': 'a | b'}))
    out = tmp_path / 'robustness.md'
    assert robustness_page.main(['--results', str(tmp_path), '--out', str(out),
                                 '--soak', str(tmp_path / 'none.json')]) == 0
    rows = [line for line in out.read_text().splitlines() if line.startswith('| ')][2:]
    assert [row.split(' | ')[0] for row in rows] == ['| kill_mpc', '| urdf_sim',
                                                      '| something_new']
    assert 'a \\| b' in rows[0] and '0.50' in rows[0]
    assert robustness_page.main(['--results', str(tmp_path / 'empty'),
                                 '--out', str(out)]) == 2
