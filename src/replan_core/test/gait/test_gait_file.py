"""Gait files (gait/gait_file.py, config/gaits/)."""

from dataclasses import fields

import pytest
from gait_config import CONFIG, LF, LH, RF, RH

from replan_core.gait.crawl import GaitParams
from replan_core.gait.gait_file import (
    GaitFileError,
    gait_names,
    load_gait,
    load_gait_file,
    parse_gait,
)


def test_the_three_gaits_ship():
    assert {'crawl', 'walking_trot', 'trot'} <= set(gait_names(CONFIG))


def test_crawl_file_is_exactly_the_default_crawl():
    params = load_gait('crawl', CONFIG).params()
    default = GaitParams()
    for f in fields(GaitParams):
        assert getattr(params, f.name) == getattr(default, f.name), f.name
    assert params.swing_groups == ((LH,), (LF,), (RH,), (RF,))


@pytest.mark.parametrize('name, four_feet', [('walking_trot', True), ('trot', False)])
def test_trots_swing_the_diagonal_pairs(name, four_feet):
    spec = load_gait(name, CONFIG)
    params = spec.params()
    assert params.swing_groups == ((LF, RH), (RF, LH))
    assert params.steps_per_cycle == 2
    assert (params.four_feet_duration > 0) == four_feet
    assert params.cycle_duration == pytest.approx(2 * params.step_period)
    # At the speed limit a cycle's stride stays within the step limit.
    assert params.max_linear_x * params.cycle_duration <= params.max_step_length_x
    assert params.max_linear_y * params.cycle_duration <= params.max_step_length_y


def test_node_parameters_are_the_files_values():
    spec = load_gait('trot', CONFIG)
    params = spec.node_parameters()
    assert params['gait'] == 'trot'
    assert params['sequence'] == ['lf', 'rh', 'rf', 'lh']
    assert params['group_size'] == 2
    assert params['swing_duration'] == spec.values['swing_duration']
    assert load_gait('crawl', CONFIG).node_parameters()['group_size'] == 1


def test_groups_of_different_sizes_are_refused():
    with pytest.raises(GaitFileError, match='one size'):
        parse_gait(_doc(groups=[['lf', 'rh', 'rf'], ['lh']]), 'g.yaml')


def _doc(**changes):
    doc = {'name': 'g', 'groups': [['lf', 'rh'], ['rf', 'lh']], 'swing_duration': 0.3,
           'four_feet_duration': 0.0}
    doc.update(changes)
    return {k: v for k, v in doc.items() if v is not None}


@pytest.mark.parametrize('changes, message', [
    ({'groups': [['lf', 'xx'], ['rf', 'lh', 'rh']]}, "unknown leg 'xx'"),
    ({'groups': [['lf', 'rh'], ['rf']]}, 'each leg once'),
    ({'groups': [['lf', 'rh'], ['rf', 'lh', 'lf']]}, 'each leg once'),
    ({'groups': []}, 'non-empty list'),
    ({'swing_duration': None}, 'missing swing_duration'),
    ({'swing_duration': 0.0}, 'swing_duration must be > 0'),
    ({'four_feet_duration': -0.1}, 'four_feet_duration must be a finite number >= 0'),
    ({'max_linear_x': float('nan')}, 'max_linear_x must be a finite number'),
    ({'n_footholds': 0}, 'n_footholds must be an integer >= 1'),
    ({'sequence': ['lf']}, 'unknown key sequence'),
])
def test_bad_gait_files_name_the_key(changes, message):
    with pytest.raises(GaitFileError, match=message):
        parse_gait(_doc(**changes), 'x.yaml')


def test_unknown_gait_names_the_gaits_there():
    with pytest.raises(GaitFileError, match=r"unknown gait 'gallop'.*crawl.*trot"):
        load_gait('gallop', CONFIG)


def test_name_must_be_the_file_name(tmp_path):
    path = tmp_path / 'pace.yaml'
    path.write_text('name: trot\ngroups: [[lf, lh], [rf, rh]]\nswing_duration: 0.3\n'
                    'four_feet_duration: 0.0\n')
    with pytest.raises(GaitFileError, match='is not the file name'):
        load_gait_file(path)
    path.write_text(path.read_text().replace('name: trot', 'name: pace'))
    assert load_gait_file(path).params().swing_groups == ((LF, LH), (RF, RH))
