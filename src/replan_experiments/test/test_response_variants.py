"""response_variants: the settings it takes, the documents it runs, the lines it keeps."""

from __future__ import annotations

import re

import pytest
from test_gait_report import _write_run
from test_robots_plan import PLAN, WALK, synthetic

from replan_experiments.gait_report import report
from replan_experiments.plan import ExperimentError
from replan_experiments.response_variants import judged_lines, parse_settings, variant_doc
from replan_experiments.robots_plan import load_robots_plan, response_doc


def test_settings_are_node_key_values_read_as_yaml():
    assert parse_settings(['gait.correction_threshold=0.3', 'mpc.position_sway=0',
                           'gait.haptic=false', 'mpc.com_offset=[0.01, 0]']) == {
        'gait': {'correction_threshold': 0.3, 'haptic': False},
        'mpc': {'position_sway': 0, 'com_offset': [0.01, 0]}}
    assert parse_settings([]) == {}


@pytest.mark.parametrize('item, said', [
    ('correction_threshold=0.3', 'expected NODE.KEY=VALUE'),
    ('gait.correction_threshold', 'expected NODE.KEY=VALUE'),
    ('gait.correction_threshold=', 'expected NODE.KEY=VALUE'),
    ('sim.noise_seed=3', 'give the seeds with --seed'),
    ('gait.step_height=[0.1', 'gait.step_height=[0.1'),
])
def test_a_wrong_setting_is_one_message(item, said):
    with pytest.raises(ExperimentError, match=re.escape(said)):
        parse_settings([item])


def test_a_setting_given_twice_is_refused():
    with pytest.raises(ExperimentError, match=r'gait\.step_height: given twice'):
        parse_settings(['gait.step_height=0.1', 'gait.step_height=0.2'])


def test_the_variant_is_the_pages_response_run_with_the_settings_on_top():
    plan = load_robots_plan(PLAN)
    info = synthetic()
    page = response_doc(WALK, info, plan, 1)
    doc = variant_doc(WALK, info, plan, 1, {'gait': {'correction_threshold': 0.3}})
    assert doc['params'] == {'sim': {'noise_seed': 1}, 'gait': {'correction_threshold': 0.3}}
    assert {k: v for k, v in doc.items() if k != 'params'} == {
        k: v for k, v in page.items() if k != 'params'}
    assert variant_doc(WALK, info, plan, 1, {}) == page       # no setting: the page's run


def test_it_keeps_the_report_lines_that_judge_each_set_point(tmp_path):
    _write_run(tmp_path)
    kept = judged_lines(report(tmp_path, after=0.0, late=0.04))
    assert kept == ['  lateral: each whole cycle as docs/robots.md measures it, % of the '
                    'set-point: 107 100 (overshoot off)']

