"""The robots page's plan (config/robots_page.yaml) and the scenario documents it gives each
robot: forces from the mass, push times from the derived crawl cycle, steps from the leg
length. No graph runs."""

from __future__ import annotations

import itertools
import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import yaml

from replan_experiments.plan import ExperimentError
from replan_experiments.robot_info import RobotInfo, robot_info
from replan_experiments.robots_plan import (
    GRAVITY,
    froude_number,
    gait_plan,
    gait_turn_doc,
    gait_walk_doc,
    listed_parameters,
    load_robots_plan,
    push_doc,
    push_force,
    push_times,
    quiet_window,
    response_doc,
    stand_doc,
    step_doc,
    step_geometry,
    walk_doc,
)

CONFIG = Path(__file__).resolve().parents[3] / 'config'
PLAN = CONFIG / 'robots_page.yaml'
WALK = {'name': 'exp_walk', 'duration': 14.0, 'events': [{'t': 0.5, 'cmd_vel': [0.1, 0, 0]}]}


def synthetic(name: str = 'go1', mass: float = 10.0, leg: float = 0.5, swing: float = 0.4,
              four_feet: float = 0.1) -> RobotInfo:
    return RobotInfo(name, mass, leg, 0.3, 0.28, 0.005,
                     {'gait': {'swing_duration': swing, 'four_feet_duration': four_feet,
                               'group_size': 1,
                               'max_linear_x': 0.2}})


def test_the_committed_plan_loads_with_the_six_robots():
    full = load_robots_plan(PLAN)
    assert list(full.robots) == ['hyq', 'anymal_c', 'go1', 'b1', 'anymal_b', 'a1', 'go2']
    assert full.robots['go1'] == {'forward': 0.05, 'lateral': 0.033, 'yaw': 0.067}
    assert full.profile == 'realistic'
    quick = load_robots_plan(PLAN, quick=True, only=['go1'])
    assert list(quick.robots) == ['go1']
    assert quick.tests['push']['phases'] < full.tests['push']['phases']


def _mutated(tmp_path: Path, change) -> Path:
    doc = yaml.safe_load(PLAN.read_text())
    change(doc)
    path = tmp_path / 'plan.yaml'
    path.write_text(yaml.safe_dump(doc))
    return path


@pytest.mark.parametrize('change, key', [
    (lambda d: d['full']['push'].update(level=[0.2]), 'full.push.level: unknown key'),
    (lambda d: d['full']['push'].pop('phases'), 'full.push.phases: missing'),
    (lambda d: d['full']['push'].update(levels=[0.3, 0.2]), 'full.push.levels: must rise'),
    (lambda d: d['full']['push'].update(phases=0), 'full.push.phases: expected a whole'),
    (lambda d: d['full']['step_down'].update(shares=[0.05, 'x']), 'full.step_down.shares[1]'),
    (lambda d: d['full']['stand'].update(drift_from=20.0), 'full.stand.drift_from'),
    (lambda d: d['full'].pop('walk'), 'full.walk: missing'),
    (lambda d: d['full']['response'].update(seeds=[0, 0]), 'full.response.seeds: each seed'),
    (lambda d: d['full']['response'].update(seeds=[]), 'full.response.seeds: expected'),
    (lambda d: d['full']['response'].update(seeds=[1, -2]),
     'full.response.seeds[1]: expected a whole number >= 0'),
    (lambda d: d['full']['response'].update(phases=0),
     'full.response.phases: expected a whole number >= 1'),
    (lambda d: d['full']['response'].pop('phases'), 'full.response.phases: missing'),
    (lambda d: d.update(seed=True), 'seed: expected a whole number >= 0'),
    (lambda d: d['robots']['go1'].pop('yaw'), 'robots.go1.yaw: missing'),
    (lambda d: d['robots']['go1'].update(forward=-0.1), 'robots.go1.forward: expected a pos'),
    (lambda d: d.update(robot={}), 'robot: unknown key'),
    (lambda d: d.update(parameters=['swing_duration']), 'parameters[0]: expected node.key'),
    (lambda d: d['gaits']['trot']['full']['walk'].update(cycles=3),
     'gaits.trot.full.walk.cycles: unknown key'),
    (lambda d: d['gaits']['trot']['quick'].pop('push'), 'gaits.trot.quick.push'),
    (lambda d: d['gaits']['trot']['full']['push'].pop('phases'),
     'gaits.trot.full.push.phases: missing'),
    (lambda d: d['gaits']['trot']['full']['walk'].update(steady_cycles=8),
     'gaits.trot.full.walk.steady_cycles: must be fewer'),
    (lambda d: d['gaits']['trot']['full']['step_down'].update(shares=[0.1, 0.05]),
     'gaits.trot.full.step_down.shares: must rise'),
    (lambda d: d['gaits']['trot']['setpoints'].update(crawl_times=2.0),
     'gaits.trot.setpoints: expected one of froude, crawl_times'),
    (lambda d: d['gaits']['trot']['setpoints'].pop('yaw_legs'),
     'gaits.trot.setpoints.yaw_legs: missing'),
    (lambda d: d['gaits']['trot']['setpoints'].update(froude=-0.02),
     'gaits.trot.setpoints.froude: expected a pos'),
    (lambda d: d['gaits']['trot'].update(ful={}), 'gaits.trot.ful: unknown key'),
    (lambda d: d['gaits'].update(crawl=d['gaits']['trot']), 'gaits.crawl: the crawl'),
    (lambda d: d['gaits']['walking_trot']['full'].update(jump={}),
     'gaits.walking_trot.full.jump: unknown test'),
    (lambda d: d['gaits']['trot']['full']['fast'].pop('froude'),
     'gaits.trot.full.fast.froude: missing'),
    (lambda d: d['gaits']['trot']['full']['fast'].update(steady_cycles=10),
     'gaits.trot.full.fast.steady_cycles: must be fewer'),
])
def test_a_bad_plan_is_one_line_naming_the_file_and_the_key(tmp_path, change, key):
    path = _mutated(tmp_path, change)
    with pytest.raises(ExperimentError) as err:
        load_robots_plan(path)
    message = str(err.value)
    assert '\n' not in message
    assert message.startswith(f'{path}: ') and key in message, message


def test_an_unknown_robot_or_parameter_is_refused_by_name(tmp_path):
    with pytest.raises(ExperimentError, match=r'--robot solo12: not in .*robots_page.yaml'):
        load_robots_plan(PLAN, only=['solo12'])
    plan = load_robots_plan(_mutated(tmp_path, lambda d: d.update(
        parameters=['gait.swing_duration', 'gait.swing_durationn'])))
    with pytest.raises(ExperimentError, match=r'parameters\[1\]: no node parameter '
                                              r'gait.swing_durationn'):
        listed_parameters(synthetic(), plan)


def test_push_force_follows_the_mass_and_times_the_crawl_cycle():
    plan = load_robots_plan(PLAN)
    cfg = plan.tests['push']
    light, heavy = synthetic(mass=10.0), synthetic(mass=80.0, swing=0.5, four_feet=0.25)
    assert light.cycle_s == pytest.approx(2.0) and heavy.cycle_s == pytest.approx(3.0)
    fx, fy, fz = push_force(light, plan, 0.3)
    assert (fx, fz) == (0.0, 0.0) and fy == pytest.approx(10.0 * 0.3 / cfg['push_duration'])
    assert push_force(heavy, plan, 0.3)[1] == pytest.approx(8.0 * fy)
    for info in (light, heavy):
        times = push_times(WALK, info, plan)
        assert len(times) == cfg['phases']
        assert times[0] == pytest.approx(0.5 + cfg['first_push_cycles'] * info.cycle_s)
        gaps = {round(b - a, 3) for a, b in itertools.pairwise(times)}
        assert gaps == {round(info.cycle_s / cfg['phases'], 3)}
    doc = push_doc(WALK, light, plan, 0.3, push_times(WALK, light, plan)[1])
    push = doc['events'][-1]
    assert push['push']['force'][1] == pytest.approx(fy, abs=1e-4)
    assert doc['events'][0]['cmd_vel'] == [0.05, 0.0, 0.0]            # go1's forward
    assert doc['duration'] == pytest.approx(push['t'] + cfg['push_duration']
                                            + cfg['after_push_cycles'] * 2.0, abs=1e-3)
    assert doc['robot'] == 'go1' and doc['profile'] == 'realistic'
    assert doc['params']['sim']['noise_seed'] == plan.seed


def test_walks_stand_and_step_downs_for_one_robot():
    plan = load_robots_plan(PLAN)
    info = synthetic(leg=0.5)
    lateral = walk_doc(WALK, info, plan, 'lateral')
    assert lateral['events'] == [{'t': 0.5, 'cmd_vel': [0.0, 0.033, 0.0]}]
    assert lateral['name'] == 'go1_lateral' and lateral['robot'] == 'go1'
    assert walk_doc(WALK, info, plan, 'yaw')['events'][0]['cmd_vel'] == [0.0, 0.0, 0.067]
    stand = stand_doc({'name': 'stand', 'duration': 12.0,
                       'events': [{'t': 0.0, 'cmd_vel': [0.0, 0.0, 0.0]}]}, info, plan)
    assert stand['duration'] == plan.tests['stand']['duration'] and stand['robot'] == 'go1'
    cfg = plan.tests['step_down']
    for share in cfg['shares']:
        doc = step_doc(WALK, info, plan, share)
        geometry = step_geometry(info, plan, share)
        assert doc['terrain'] == {'type': 'step_down', 'step_height': round(share * 0.5, 4),
                                  'step_x': round(cfg['step_x_legs'] * 0.5, 4)}
        assert geometry['cross_x_m'] == pytest.approx((cfg['step_x_legs']
                                                       + cfg['cross_legs']) * 0.5, abs=1e-4)
        assert doc['duration'] == pytest.approx(
            0.5 + cfg['time_margin'] * geometry['cross_x_m'] / 0.05, abs=0.01)


def test_robot_info_is_the_launchers_derivation():
    """Go1's crawl cycle is HyQ's scaled by sqrt(leg length ratio) (the time rule), its mass
    and leg length the model's (docs/robot_files.md)."""
    go1, hyq = robot_info(CONFIG, 'go1', 'realistic'), robot_info(CONFIG, 'hyq', 'realistic')
    assert go1.mass_kg == pytest.approx(13.10, abs=0.01)
    assert hyq.cycle_s == pytest.approx(3.0)
    assert go1.cycle_s == pytest.approx(3.0 * math.sqrt(go1.leg_length_m / hyq.leg_length_m),
                                        rel=1e-9)
    assert go1.value('sim.payload_mass') < hyq.value('sim.payload_mass') == 5.0
    parameters = listed_parameters(go1, load_robots_plan(PLAN))
    assert parameters['mpc.com_height'] == pytest.approx(go1.com_height_m)


def trot(name: str = 'go1', mass: float = 10.0, leg: float = 0.5) -> RobotInfo:
    """A robot in a trot: two steps of a 0.3 s swing, idle after 0.6 s."""
    info = synthetic(name, mass=mass, leg=leg, swing=0.3, four_feet=0.0)
    info.values['gait'].update(group_size=2, idle_after=0.6)
    return info


def test_the_committed_plan_has_the_trot_at_froude_002_and_the_walking_trot_at_twice_the_crawl():
    for quick in (False, True):
        plan = load_robots_plan(PLAN, quick=quick)
        assert list(plan.gaits) == ['trot', 'walking_trot']
        assert plan.gaits['trot']['setpoints']['froude'] == 0.02
        assert plan.gaits['walking_trot']['setpoints']['crawl_times'] == 2.0
        assert plan.gaits['trot']['tests']['step_down']['shares'] == (
            [0.05, 0.1, 0.15] if not quick else [0.05])




def test_a_gaits_set_points_come_from_the_leg_length_and_the_crawl():
    plan = load_robots_plan(PLAN)
    short, long_ = trot(leg=0.4), trot('hyq', leg=0.7)
    trots = gait_plan(plan, 'trot', {'go1': short, 'hyq': long_, **{
        n: trot(n) for n in plan.robots if n not in ('go1', 'hyq')}})
    for info in (short, long_):
        forward = math.sqrt(0.02 * GRAVITY * info.leg_length_m)
        setpoints = trots.robots[info.name]
        assert setpoints['forward'] == pytest.approx(forward, abs=5e-4)
        assert froude_number(setpoints['forward'], info.leg_length_m) == pytest.approx(
            0.02, rel=0.01)
        assert setpoints['lateral'] == pytest.approx(0.5 * forward, abs=5e-4)
        assert setpoints['yaw'] == pytest.approx(forward / (2.0 * info.leg_length_m), abs=5e-4)
    walking = gait_plan(plan, 'walking_trot', {n: trot(n) for n in plan.robots})
    assert walking.robots['go1']['forward'] == pytest.approx(2 * 0.05)
    assert walking.robots['hyq']['forward'] == pytest.approx(2 * 0.15)
    assert trots.gait == 'trot' and trots.tests == plan.gaits['trot']['tests']


def test_a_gaits_documents_run_the_gait_in_its_cycles():
    plan = load_robots_plan(PLAN, only=['go1'])
    info = trot(mass=12.0, leg=0.5)
    trots = gait_plan(plan, 'trot', {'go1': info})
    cfg, forward = trots.tests, trots.robots['go1']['forward']
    assert info.cycle_s == pytest.approx(0.6)
    walk = gait_walk_doc(WALK, info, trots)
    stop = 0.5 + cfg['walk']['forward_cycles'] * 0.6
    assert walk['gait'] == 'trot' and walk['name'] == 'go1_trot_walk'
    assert walk['events'] == [{'t': 0.5, 'cmd_vel': [forward, 0.0, 0.0]},
                              {'t': pytest.approx(stop), 'cmd_vel': [0.0, 0.0, 0.0]}]
    begin, end = quiet_window(info, trots)
    assert begin == pytest.approx(stop + 0.6 + cfg['walk']['settle_s'])
    assert end == pytest.approx(begin + cfg['walk']['quiet_s']) == walk['duration']
    turn = gait_turn_doc(WALK, info, trots)
    span = cfg['turn']['segment_cycles'] * 0.6
    assert [e['cmd_vel'] for e in turn['events']] == [
        [0.0, trots.robots['go1']['lateral'], 0.0], [0.0, 0.0, trots.robots['go1']['yaw']]]
    assert turn['duration'] == pytest.approx(0.5 + 2 * span) and turn['gait'] == 'trot'
    # The push: mass x 0.3 m/s over the push's duration, at phases of the trot's cycle.
    times = push_times(WALK, info, trots)
    assert len(times) == cfg['push']['phases'] == 4
    assert times[1] - times[0] == pytest.approx(0.6 / 4)          # the trot's cycle, 2 x 0.3 s
    push = push_doc(WALK, info, trots, 0.3, times[0])
    assert push['events'][-1]['push']['force'][1] == pytest.approx(
        12.0 * 0.3 / cfg['push']['push_duration'], abs=1e-4)
    assert push['gait'] == 'trot' and push['name'] == 'go1_trot_push_0.3'
    assert push['events'][0]['cmd_vel'] == [forward, 0.0, 0.0]
    step = step_doc(WALK, info, trots, 0.15)
    assert step['terrain']['step_height'] == pytest.approx(0.075)
    assert step['gait'] == 'trot' and step['name'] == 'go1_trot_step_down_0.15'


def test_the_crawls_documents_are_as_before_gaits_had_plans():
    """No gait key and the same names: the crawl's run keys, and so its cached runs, stay."""
    plan = load_robots_plan(PLAN)
    info = synthetic()
    docs = [walk_doc(WALK, info, plan, 'forward'), response_doc(WALK, info, plan, plan.seed),
            push_doc(WALK, info, plan, 0.3, 4.0), step_doc(WALK, info, plan, 0.05)]
    assert all('gait' not in d for d in docs)
    assert [d['name'] for d in docs] == ['go1_forward', 'go1_response', 'go1_push_0.3',
                                         'go1_step_down_0.05']


def test_the_response_runs_once_per_seed_and_the_page_seeds_run_is_as_before():
    plan = load_robots_plan(PLAN)
    plan = replace(plan, tests={**plan.tests, 'response': {**plan.tests['response'],
                                                           'seeds': [plan.seed, 1, 2]}})
    info = synthetic()
    docs = [response_doc(WALK, info, plan, seed) for seed in plan.tests['response']['seeds']]
    assert [d['params']['sim']['noise_seed'] for d in docs] == [plan.seed, 1, 2]
    assert docs[0]['name'] == 'go1_response'
    assert [d['name'] for d in docs[1:]] == ['go1_response_seed1', 'go1_response_seed2']
    assert all(d['events'] == docs[0]['events'] for d in docs)


def test_each_phase_delays_both_changes_by_its_share_of_a_crawl_cycle():
    plan = load_robots_plan(PLAN)
    phases = plan.tests['response']['phases']
    assert phases == 4                       # each leg in turn re-plans for a change first
    info = synthetic()
    docs = [response_doc(WALK, info, plan, plan.seed, k) for k in range(phases)]
    assert [d['name'] for d in docs] == ['go1_response'] + [f'go1_response_phase{k}'
                                                            for k in range(1, phases)]
    times = np.array([[e['t'] for e in d['events']] for d in docs])
    delays = times - times[0]
    assert delays[:, 0] == pytest.approx(0.0)                   # the walk-off: from standing
    for k in range(phases):
        assert delays[k, 1:] == pytest.approx(k * info.cycle_s / phases, abs=1e-4)
        assert docs[k]['duration'] - docs[0]['duration'] == pytest.approx(
            k * info.cycle_s / phases, abs=1e-4)
    with pytest.raises(ExperimentError, match='response phase 4 is not one of 0-3'):
        response_doc(WALK, info, plan, plan.seed, phases)
