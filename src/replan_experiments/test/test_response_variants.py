"""response_variants: the settings it refuses, the documents it runs, the lines it keeps."""

from __future__ import annotations

import pytest
from test_gait_report import _write_run
from test_robots_plan import PLAN, WALK, synthetic

from replan_experiments.gait_report import report
from replan_experiments.plan import ExperimentError
from replan_experiments.response_variants import judged_lines, settings, variant_doc
from replan_experiments.robots_plan import load_robots_plan, response_doc


def test_the_noise_seed_is_not_a_setting():
    assert settings(['gait.correction_threshold=0.3']) == {'gait': {'correction_threshold': 0.3}}
    with pytest.raises(ExperimentError, match='give the seeds with --seed'):
        settings(['sim.noise_seed=3'])


def test_the_variant_is_the_pages_response_run_with_the_settings_on_top():
    plan = load_robots_plan(PLAN)
    info = synthetic()
    page = response_doc(WALK, info, plan, 1)
    doc = variant_doc(WALK, info, plan, 1, {'gait': {'correction_threshold': 0.3}})
    assert doc['params'] == {'sim': {'noise_seed': 1}, 'gait': {'correction_threshold': 0.3}}
    assert {k: v for k, v in doc.items() if k != 'params'} == {
        k: v for k, v in page.items() if k != 'params'}
    assert variant_doc(WALK, info, plan, 1, {}) == page       # no setting: the page's run
    # A later phase: the page's run of that phase.
    assert variant_doc(WALK, info, plan, 1, {}, 2) == response_doc(WALK, info, plan, 1, 2)


def test_it_keeps_the_report_lines_that_judge_each_set_point(tmp_path):
    _write_run(tmp_path)
    kept = judged_lines(report(tmp_path, after=0.0, late=0.04))
    assert kept == ['  lateral: each whole cycle opened by each leg, % of the set-point, as '
                    'docs/robots.md judges them: lh at 0.50 s 107 100; lf at 1.25 s 100 '
                    '(overshoot off)']

