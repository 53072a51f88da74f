"""The robots page's text from synthetic data (as robots_page.main collects it): the header
names revision, code fingerprint and command; falls read as falls, failures as failures."""

from __future__ import annotations

import json

from test_robots_plan import PLAN

from replan_experiments.robots_page import README_BEGIN, README_END, render_saved
from replan_experiments.robots_plan import load_robots_plan
from replan_experiments.robots_render import (
    push_cell,
    readme_block,
    render_page,
    response_cell,
    run_labels,
    share_cell,
    standing_cell,
    step_cell,
)

META = {'command': 'scripts/robots_page.sh --robot go1 --robot anymal_c', 'machine': '2 cores',
        'revision': 'abc1234', 'code': 'feedc0ffee12', 'date': '2026-11-26 02:00 UTC',
        'wall_time_min': 12.5, 'runs': 30, 'reused': 2, 'quick': False, 'jobs': 2,
        'failures': ['go1_yaw-123: exit 1: boom'], 'plan_file': 'config/robots_page.yaml',
        'profile': 'realistic', 'seed': 0, 'tests': load_robots_plan(PLAN).tests}


def _facts(mass: float) -> dict:
    return {'mass_kg': mass, 'leg_length_m': 0.426, 'standing_height_m': 0.274,
            'com_height_m': 0.255, 'min_joint_inertia': 0.0057, 'cycle_s': 2.347,
            'parameters': {'gait.swing_duration': 0.3912, 'wbc.swing_kp': [370.1, 370.1, 370.1],
                           'mpc.com_height': 0.2548}}


def _walk(commanded: float, achieved: float | None, fell: bool = False, ok: bool = True
          ) -> dict:
    return {'run': 'r', 'ok': ok, 'fell': fell, 'commanded': commanded, 'achieved': achieved,
            'fall_time_s': 2.9 if fell else None}


def _legs(*per_leg: list[float]) -> list[dict]:
    """A response axis's ``legs``: each leg's cycle shares, lh first."""
    names = ('lh', 'lf', 'rh', 'rf')[:len(per_leg)]
    return [{'leg': name, 'start_s': 0.5 + k, 'shares': shares}
            for k, (name, shares) in enumerate(zip(names, per_leg, strict=True))]


def _phases(fell_at: list[int], n: int = 4) -> list[dict]:
    return [{'t': 4.0 + k, 'phase': k, 'ok': True, 'fell': k in fell_at, 'run': 'r'}
            for k in range(n)]


GO1 = {'robot': 'go1', 'skipped': None, 'cycle_s': 2.347,
       'walks': {'forward': _walk(0.05, 0.0505), 'lateral': _walk(0.033, 0.030),
                 'yaw': _walk(0.067, None, ok=False)},
       'stand': {'run': 'r', 'ok': True, 'fell': False, 'drift_m': 0.0035,
                 'travel_m': 0.0061, 'drift_window_s': [0.0, 12.0], 'touchdowns': 0,
                 'last_touchdown_s': None},
       'response': [{'seed': 0, 'phase': 0, 'run': 'r', 'ok': True, 'fell': False, 'axes': {
           'forward': {'legs': _legs([0.93, 0.98, 1.01]), 'first_error': 0.07,
                       'later_error': 0.02, 'overshoot': 0.01},
           'lateral': {'legs': _legs([0.85, 0.93, 0.99]), 'first_error': 0.15,
                       'later_error': 0.07, 'overshoot': -0.01}}}],
       'push': {'levels': [{'dv_mps': 0.2, 'force_n': 10.48, 'impulse_ns': 2.62,
                            'phases': _phases([])},
                           {'dv_mps': 0.3, 'force_n': 15.72, 'impulse_ns': 3.93,
                            'phases': _phases([])},
                           {'dv_mps': 0.4, 'force_n': 20.96, 'impulse_ns': 5.24,
                            'phases': _phases([1, 3])}],
                'survived_dv': 0.3, 'fell_dv': 0.4, 'failed': False, 'phases': 4},
       'step_down': [{'share': 0.05, 'height_m': 0.0213, 'cross_x_m': 0.68, 'ok': True,
                      'fell': False, 'final_x_m': 0.9, 'crossed': True},
                     {'share': 0.10, 'height_m': 0.0426, 'cross_x_m': 0.68, 'ok': True,
                      'fell': False, 'final_x_m': 0.9, 'crossed': True},
                     {'share': 0.15, 'height_m': 0.0639, 'cross_x_m': 0.68, 'ok': True,
                      'fell': True, 'fall_time_s': 11.2, 'final_x_m': 0.5, 'crossed': False}],
       'timing': {'runs': 14, 'rtf_median': 1.61, 'rtf_min': 0.82, 'mpc_median_ms': 1.43,
                  'mpc_p99_max_ms': 9.1}}
ANYMAL = {'robot': 'anymal_c', 'skipped': 'falls walking forward on flat ground',
          'cycle_s': 2.9,
          'walks': {'forward': _walk(0.10, None, fell=True), 'lateral': _walk(0.067, None, True),
                    'yaw': _walk(0.133, None, fell=True)},
          'stand': {'run': 'r', 'ok': True, 'fell': True, 'fall_time_s': 3.4},
          'push': None, 'step_down': [],
          'timing': {'runs': 4, 'rtf_median': 1.4, 'rtf_min': 1.3, 'mpc_median_ms': 1.6,
                     'mpc_p99_max_ms': 5.0}}


def test_the_page_names_its_revision_code_and_command_and_reports_falls():
    text = render_page({'meta': META, 'facts': {'go1': _facts(13.1), 'anymal_c': _facts(52.13)},
                        'robots': {'go1': GO1, 'anymal_c': ANYMAL}})
    assert 'revision abc1234, code fingerprint feedc0ffee12' in text
    assert '`scripts/robots_page.sh --robot go1 --robot anymal_c`' in text
    assert '|  | go1 | anymal_c |' in text
    assert '| mass kg (model) | 13.1 | 52.13 |' in text
    assert '| `gait.swing_duration` s | 0.391 | 0.391 |' in text
    assert '| `wbc.swing_kp` N/m | [370, 370, 370] |' in text
    assert '0.0505 of 0.05 m/s (+1.0 %)' in text
    assert '| yaw: achieved of commanded | run failed | **fell** at 2.9 s |' in text
    assert '0.61 cm (0-12 s); 0 touchdowns |' in text
    assert '| 93 98 101 % |' in text and '85 93 99 % (**first and later off**)' in text
    assert '| response, yaw: each whole cycle after the change, % of set-point | no whole cycle' \
        in text
    assert '**0.3 m/s** (3.9 N s) at all 4 phases; 0.4 m/s fell at phase 1, 3 of 4' in text
    assert '**0.1** of the leg (4.3 cm); 0.15: **fell** at 11.2 s' in text
    assert text.count('not run: falls walking forward on flat ground') == 2
    assert '1.61 (min 0.82; 14 runs)' in text and '1.43 ms median, p99 up to 9.1 ms' in text
    assert '- `go1_yaw-123: exit 1: boom`' in text
    assert '**Quick run**' not in text
    assert render_page({'meta': {**META, 'quick': True}, 'facts': {'go1': _facts(13.1)},
                        'robots': {'go1': GO1}}).count('**Quick run**') == 1


def test_push_and_step_cells_at_the_edges():
    first_falls = {**GO1['push'], 'levels': GO1['push']['levels'][:1], 'survived_dv': None,
                   'fell_dv': 0.2}
    first_falls['levels'] = [{**first_falls['levels'][0], 'phases': _phases([0])}]
    # Two legs: the first cycles 93 and 107 %, the second 99 and 99.2 %, lh's third 100 %.
    overshoot = {'legs': _legs([0.93, 0.99, 1.0], [1.07, 0.992]), 'first_error': 0.07,
                 'later_error': 0.01, 'overshoot': 0.07}
    row = {'seed': 0, 'phase': 0, 'ok': True, 'fell': False, 'axes': {'forward': overshoot}}
    assert response_cell([row], 'forward') == '93-107 99 100 % (**overshoot off**)'
    met = {'legs': _legs([0.95, 1.02, 1.0]), 'first_error': 0.05, 'later_error': 0.02,
           'overshoot': 0.02}
    late = {'legs': _legs([0.85, 0.93, 1.0]), 'first_error': 0.15, 'later_error': 0.07,
            'overshoot': 0.0}
    seeds = [{**row, 'seed': 1, 'axes': {'forward': met}}, row,
             {**row, 'seed': 2, 'axes': {'forward': late}},
             {'seed': 3, 'phase': 0, 'ok': True, 'fell': True, 'fall_time_s': 9.5}]
    assert response_cell(seeds, 'forward') == (
        '95 102 100 % / 93-107 99 100 % / 85 93 100 % / **fell** at 9.5 s '
        '(**overshoot off on seed 0; first off on seed 2; later off on seed 2**)')
    assert response_cell(seeds[:1], 'forward') == '95 102 100 %'
    assert response_cell([], 'forward') == '-'
    assert push_cell(first_falls, None) == ('none of the levels tried (< 0.2 m/s); 0.2 m/s '
                                            'fell at phase 0 of 4')
    all_survived = {**GO1['push'], 'fell_dv': None}
    assert push_cell(all_survived, None).endswith('the largest level tried (0.4 m/s) survived')
    stopped = [{**GO1['step_down'][0], 'crossed': False, 'final_x_m': 0.4}]
    assert step_cell(stopped, None) == 'none (< 0.05); 0.05: stopped at x 0.40 m of 0.68'
    assert step_cell([], 'falls walking forward on flat ground').startswith('not run')


def test_a_parameters_unit_is_its_declarations():
    """The facts table names each parameter's unit from params.tables, the one source of it
    (a hand-kept table there had left sim.actuator_time_constant without one)."""
    from replan_experiments.robots_render import _unit
    assert _unit('sim.actuator_time_constant') == 's'
    assert _unit('wbc.fz_max') == 'N' and _unit('mpc.zmp_margin') == 'm'
    assert _unit('wbc.estimator.contact_force_threshold') == 'N'
    assert _unit('nosuch.node') == '' and _unit('wbc.nosuch') == ''


def test_the_readme_table_and_a_render_from_saved_data(tmp_path):
    data = {'meta': META, 'facts': {'go1': _facts(13.1), 'anymal_c': _facts(52.13)},
            'robots': {'go1': GO1, 'anymal_c': ANYMAL}}
    block = readme_block(data)
    assert block.startswith('From [docs/robots.md](docs/robots.md) (2026-11-26 02:00 UTC, '
                            'realistic profile; generated')
    assert 'abc1234' not in block          # the README names no commit: the page does
    assert '| go1 | +1.0 / -9.1 / run failed | 0.61 cm, 0 steps | 0.3 m/s | 0.1 of the leg | ' \
        'off: lateral, yaw |' in block
    assert '| anymal_c | **fell** at 2.9 s / **fell** at 2.9 s / **fell** at 2.9 s | ' \
        '**fell** at 3.4 s | not run: falls walking forward on flat ground |' in block
    # --render: the page and the README's table from robots.json, nothing run; the README's
    # hand-written text around the markers is kept.
    out, docs = tmp_path / 'runs', tmp_path / 'docs'
    out.mkdir()
    docs.mkdir()
    (out / 'robots.json').write_text(json.dumps(data))
    readme = tmp_path / 'README.md'
    readme.write_text(f'# X\n\nbefore\n{README_BEGIN}\nOLD\n{README_END}\nafter\n')
    assert render_saved(tmp_path, out, docs / 'robots.md') == 0
    assert (docs / 'robots.md').read_text() == render_page(data)
    assert readme.read_text() == f'# X\n\nbefore\n{README_BEGIN}\n{block}{README_END}\nafter\n'
    assert render_saved(tmp_path, tmp_path / 'none', docs / 'robots.md') == 2


def _gait_run(**axes) -> dict:
    return {'run': 'r', 'ok': True, 'fell': False, 'fall_time_s': None,
            'axes': {a: {'commanded': c, 'achieved': share * c, 'share': share, 'cycles': 8}
                     for a, (c, share) in axes.items()}}


GO1_TROT = {'gait': 'trot', 'setpoints': {'forward': 0.289, 'lateral': 0.145, 'yaw': 0.339},
            'cycle_s': 0.469, 'froude': 0.02, 'walk': _gait_run(forward=(0.289, 0.987)),
            'turn': _gait_run(lateral=(0.145, 0.93), yaw=(0.339, 1.02)),
            'push': {**GO1['push'], 'levels': GO1['push']['levels'][1:2], 'survived_dv': 0.3,
                     'fell_dv': None, 'phases': 2},
            'step_down': GO1['step_down'][:2],
            'standing': {'window_s': [5.7, 7.7], 'drift_m': 0.0042, 'travel_m': 0.005,
                         'touchdowns': 0, 'last_touchdown_s': None},
            'falls': ['go1_trot_step_down_0.15-abc'], 'runs': 7, 'skipped': None,
            'timing': {'runs': 7, 'rtf_median': 1.1, 'rtf_min': 0.9, 'mpc_median_ms': 2.0,
                       'mpc_p99_max_ms': 8.0}}
GAIT_META = {**META, 'gaits': {
    'trot': {'setpoints': {'froude': 0.02, 'lateral_share': 0.5, 'yaw_legs': 2.0},
             'tests': load_robots_plan(PLAN).gaits['trot']['tests']}}}


def test_a_gait_section_gives_set_point_froude_number_shares_push_step_and_standing():
    anymal_trot = {**GO1_TROT, 'walk': {'run': 'r', 'ok': True, 'fell': True,
                                        'fall_time_s': 3.1, 'axes': {}},
                   'push': None, 'step_down': [], 'standing': {'window_s': [5.0, 7.0]},
                   'falls': ['anymal_c_trot_walk-abc'], 'runs': 2,
                   'skipped': 'falls walking forward on flat ground'}
    data = {'meta': GAIT_META, 'facts': {'go1': _facts(13.1), 'anymal_c': _facts(52.13)},
            'robots': {'go1': {**GO1, 'gaits': {'trot': GO1_TROT}},
                       'anymal_c': {**ANYMAL, 'gaits': {'trot': anymal_trot}}}}
    text = render_page(data)
    section = text[text.index('## Trot'):]
    assert 'Froude number v^2 / (g l) = 0.02' in section
    assert '| set-point forward (Froude number v^2 / (g l)) | 0.289 m/s (0.0200) |' in section
    assert '| forward achieved, % of set-point | 98.7 % (0.285 of 0.289 m/s) | ' \
        '**fell** at 3.1 s |' in section
    assert '| yaw achieved, % of set-point | 102.0 % (0.346 of 0.339 rad/s) |' in section
    assert '**0.3 m/s** (3.9 N s) at all 2 phases' in section
    assert '**0.1** of the leg (4.3 cm)' in section
    assert '| standing after the stop: trunk drift, touchdowns | 0.42 cm, 0 touchdowns ' \
        '(5.70-7.70 s) | **fell** at 3.1 s |' in section
    assert '**1 of 7 runs**: `go1_trot_step_down_0.15`' in section
    assert section.count('not run: falls walking forward on flat ground') == 2
    block = readme_block(data)
    assert 'trot at Froude 0.02: forward achieved, % of set-point |' in block
    assert '| off: lateral, yaw | 98.7 |' in block and '| **fell** at 3.1 s |' in block
    # A page without gaits (older robots.json) renders as before.
    assert '## Trot' not in render_page({'meta': META, 'facts': {'go1': _facts(13.1)},
                                         'robots': {'go1': GO1}})


def test_gait_cells_at_the_edges():
    assert share_cell(None, 'forward', 'm/s') == '-'
    few = {'run': 'r', 'ok': True, 'fell': False,
           'axes': {'forward': {'commanded': 0.3, 'achieved': None, 'share': None,
                                'cycles': 1}}}
    assert share_cell(few, 'forward', 'm/s') == 'too few whole cycles (1)'
    scattered = {'run': 'r', 'ok': True, 'fell': False,
                 'axes': {'lateral': {'commanded': 0.05, 'achieved': 0.0308, 'share': 0.616,
                                      'cycles': 4, 'cycle_shares': [1.13, 1.58, 0.64, 0.59]}}}
    assert share_cell(scattered, 'lateral', 'm/s') == \
        '61.6 % (0.0308 of 0.05 m/s); cycles 113 158 64 59 %'
    assert share_cell(few, 'yaw', 'rad/s') == 'no segment'
    assert share_cell({'run': 'r', 'ok': False}, 'forward', 'm/s') == 'run failed'
    assert standing_cell({'walk': few, 'standing': {'window_s': [1.0, 2.0]}}) == \
        'no truth in the bag'


def test_response_runs_are_named_by_what_tells_them_apart():
    met = {'legs': _legs([0.95, 1.02, 1.0]), 'first_error': 0.05, 'later_error': 0.02,
           'overshoot': 0.02}
    lag = {'legs': _legs([0.85, 1.0], [1.08, 1.0]), 'first_error': 0.15, 'later_error': 0.0,
           'overshoot': 0.08}
    phases = [{'seed': 0, 'phase': k, 'ok': True, 'fell': False,
               'axes': {'lateral': lag if k % 2 else met}} for k in range(4)]
    assert response_cell(phases, 'lateral') == (
        '95 102 100 % / 85-108 100 % / 95 102 100 % / 85-108 100 % '
        '(**first off on phases 1, 3; overshoot off on phases 1, 3**)')
    both = [{'seed': s, 'phase': k} for s in (0, 1) for k in (0, 1)]
    assert run_labels(both[1:3], both) == 'seed 0 phase 1, seed 1 phase 0'
    assert run_labels(both[2:], both[2:]) == 'phases 0, 1'
    assert run_labels(both[:1], [both[0], both[2]]) == 'seed 0'
