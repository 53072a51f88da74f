"""The robots page's runs and measures without graphs: a stand-in runner answers each scenario
document with the metrics a run of it would give (as test_experiments.py's ThresholdRunner
does for the bisection); the stand's measures from synthetic truth."""

from __future__ import annotations

import threading
from dataclasses import replace
from pathlib import Path

import pytest
import yaml
from test_robots_plan import PLAN, WALK, synthetic

from replan_experiments.robots_page import (
    drift_and_touchdowns,
    gait_axes,
    measure_gait,
    measure_robot,
    planned_runs,
    push_ladder,
    response_axis,
    response_row,
    timing,
    walk_row,
)
from replan_experiments.robots_plan import gait_plan, load_robots_plan, push_times
from replan_experiments.runs import RunResult, code_fingerprint, run_key

CONFIG = PLAN.parent


class StandInRunner:
    """Answers a document with metrics: a push of ``dv`` >= ``push_limit`` at ``fall_phase``'s
    time falls; ``forward_falls`` fells every walk; step downs above ``step_limit`` fall."""

    def __init__(self, out: Path, *, push_limit: float = 9.0, fall_phase: int = 1,
                 forward_falls: bool = False, step_limit: float = 0.12) -> None:
        self.out, self.push_limit, self.fall_phase = out, push_limit, fall_phase
        self.forward_falls, self.step_limit = forward_falls, step_limit
        self.results: dict = {}
        self.docs: list[dict] = []
        self.lock = threading.Lock()
        self.times: list[float] = []

    def scenario(self, name: str) -> dict:
        return yaml.safe_load((CONFIG / 'scenarios' / f'{name}.yaml').read_text())

    def run(self, doc: dict, bag: bool = False) -> RunResult:
        with self.lock:
            self.docs.append(doc)
        setpoint = next(e['cmd_vel'] for e in doc['events'] if 'cmd_vel' in e)
        pushes = [e for e in doc['events'] if 'push' in e]
        fell = self.forward_falls and any(setpoint)
        if pushes:
            dv = float(doc['name'].rsplit('_', 1)[1])
            phase = self.times.index(pushes[0]['t']) if pushes[0]['t'] in self.times else -1
            fell |= dv >= self.push_limit and phase == self.fall_phase
        terrain = doc.get('terrain') or {}
        share = float(doc['name'].rsplit('_', 1)[1]) if 'step_down' in doc['name'] else 0.0
        fell |= share > self.step_limit
        metrics = {'sim_time_s': doc['duration'], 'fell': fell, 'completed': True,
                   'fall_time_s': 2.9 if fell else None, 'real_time_factor': 1.2,
                   'mpc_solve_ms_median': 1.5, 'mpc_solve_ms_p99': 4.0,
                   'final_position_m': [2.0 if terrain and not fell else 0.1, 0.0, 0.3],
                   'velocity_tracking': [{'commanded': setpoint,
                                          'achieved': [0.95 * v for v in setpoint]}]}
        key = run_key(doc)
        result = RunResult(key, doc, metrics, self.out / key)
        self.results[key] = result
        return result


def test_the_push_ladder_stops_at_the_first_level_that_fells_it_at_some_phase(tmp_path):
    plan = load_robots_plan(PLAN)
    info = synthetic()
    runner = StandInRunner(tmp_path, push_limit=0.4, fall_phase=2)
    runner.times = push_times(WALK, info, plan)
    ladder = push_ladder(runner, WALK, info, plan)
    assert ladder['survived_dv'] == 0.3 and ladder['fell_dv'] == 0.4
    assert [level['dv_mps'] for level in ladder['levels']] == [0.2, 0.3, 0.4]   # no 0.5
    fell = [p['phase'] for p in ladder['levels'][-1]['phases'] if p['fell']]
    assert fell == [2]
    assert ladder['levels'][0]['impulse_ns'] == pytest.approx(10.0 * 0.2)   # mass x dv
    assert len(runner.docs) == 3 * plan.tests['push']['phases']


def test_a_robot_that_falls_walking_is_reported_and_not_pushed(tmp_path):
    plan = load_robots_plan(PLAN)
    runner = StandInRunner(tmp_path, forward_falls=True)
    row = measure_robot(runner, plan, synthetic('anymal_c'))
    assert row['walks']['forward']['fell'] and row['walks']['forward']['fall_time_s'] == 2.9
    assert row['push'] is None and row['step_down'] == []
    assert row['skipped'] == 'falls walking forward on flat ground'
    seeds, phases = plan.tests['response']['seeds'], plan.tests['response']['phases']
    responses = len(seeds) * phases
    assert len(runner.docs) == 4 + responses      # three walks, the stand, the responses
    assert not row['stand']['fell'] and 'drift_m' not in row['stand']     # no bag here
    assert [(r['seed'], r['phase']) for r in row['response']] == [
        (seed, phase) for seed in seeds for phase in range(phases)]
    assert all(r['fell'] for r in row['response'])
    assert row['timing']['runs'] == 4 + responses


def test_a_robot_that_walks_is_measured_on_every_test(tmp_path):
    plan = load_robots_plan(PLAN, quick=True, only=['go1'])
    runner = StandInRunner(tmp_path, step_limit=0.12)
    runner.times = []                                   # no phase falls
    row = measure_robot(runner, plan, synthetic('go1'))
    assert row['walks']['lateral']['achieved'] == pytest.approx(0.95 * 0.033)
    assert row['push']['survived_dv'] == 0.3 and row['push']['fell_dv'] is None
    assert [s['crossed'] for s in row['step_down']] == [True]
    # 5 + 1 share + 1 level x 1 phase; the other gaits' runs are measure_gait's
    assert len(runner.docs) == planned_runs(replace(plan, gaits={}))
    assert [r['axes']['forward']['legs'] for r in row['response']] == [[]]   # no cycles
    assert row['timing'] == {'runs': 7, 'rtf_median': 1.2, 'rtf_min': 1.2,
                             'mpc_median_ms': 1.5, 'mpc_p99_max_ms': 4.0}


def test_standing_travel_is_the_trunks_largest_distance_and_every_touchdown_counts():
    # The trunk goes 2 cm away and comes back to 0.5 cm; one foot lifts and lands at 8 s.
    positions = [(0.004 * k, (0.02 * min(k, 1000) / 1000 - 0.015 * max(k - 1000, 0) / 2000,
                              0.0, 0.3)) for k in range(3001)]
    contacts = [(0.004 * k, [True] * 4) for k in range(3001)]
    contacts[2000] = (contacts[2000][0], [True, False, True, True])
    measures = drift_and_touchdowns(positions, contacts, drift_from=0.0)
    assert measures['travel_m'] == pytest.approx(0.02, abs=1e-9)
    assert measures['drift_m'] == pytest.approx(0.005, abs=1e-9)
    assert measures['drift_window_s'] == [0.0, 12.0]
    assert measures['touchdowns'] == 1 and measures['last_touchdown_s'] == 8.004
    # From 9 s on: no touchdown, and the travel from where the trunk was then.
    later = drift_and_touchdowns(positions, contacts, drift_from=9.0)
    assert later['touchdowns'] == 0 and later['last_touchdown_s'] is None
    assert later['travel_m'] == pytest.approx(0.015 * 750 / 2000, abs=1e-5)   # rounded
    assert drift_and_touchdowns(positions[:1], contacts, 0.0) is None


def test_a_response_gives_each_legs_whole_cycles_as_shares_of_its_set_point():
    def segment(start, commanded, per_leg):
        return {'start_s': start, 'commanded': commanded, 'leg_cycle_velocities': [
            {'leg': leg, 'cycles': [{'start_s': start + 0.1 * (k + 1) + j, 'end_s': 0.0,
                                     'velocity': v} for j, v in enumerate(per_cycle)]}
            for k, (leg, per_cycle) in enumerate(per_leg)]}
    metrics = {'fell': False, 'completed': True, 'sim_time_s': 30.0, 'velocity_tracking': [
        segment(0.0, [0.0, 0.0, 0.0], []),
        # lh's cycles read 92, 100, 104 %; rf's first one 106 %.
        segment(0.5, [0.1, 0.0, 0.0], [(2, [[0.092, 0.0, 0.0], [0.1, 0.0, 0.0],
                                            [0.104, 0, 0]]),
                                       (1, [[0.106, 0.0, 0.0], [0.1, 0.0, 0.0]])]),
        segment(10.5, [0.0, 0.05, 0.0], [(0, [[0.0, 0.04, 0.0], [0.0, 0.0475, 0.0]])]),
        segment(20.5, [0.0, 0.0, 0.2], [(3, [[0.0, 0.0, 0.2]])])]}
    row = response_row(RunResult('r', {}, metrics, Path('r')))
    forward, lateral, yaw = (row['axes'][a] for a in ('forward', 'lateral', 'yaw'))
    assert forward['legs'] == [{'leg': 'lh', 'start_s': 0.6, 'shares': [0.92, 1.0, 1.04]},
                               {'leg': 'rf', 'start_s': 0.7, 'shares': [1.06, 1.0]}]
    assert forward['first_error'] == pytest.approx(0.08)        # the worst leg's first cycle
    assert forward['later_error'] == pytest.approx(0.04)
    assert forward['overshoot'] == pytest.approx(0.06)          # rf's first cycle
    assert lateral['first_error'] == pytest.approx(0.2) and lateral['later_error'] == 0.05
    assert yaw['later_error'] is None and yaw['overshoot'] == 0.0
    assert response_axis({'commanded': [0.1, 0.0, 0.0]})[1]['legs'] == []   # no contacts


def test_timing_leaves_out_runs_that_failed():
    good = RunResult('a', {}, {'sim_time_s': 5.0, 'fell': False, 'completed': True,
                               'real_time_factor': 2.0,
                               'mpc_solve_ms_median': 1.0, 'mpc_solve_ms_p99': 3.0}, Path('a'))
    failed = RunResult('b', {}, {}, Path('b'))
    assert timing([good, failed]) == {'runs': 1, 'rtf_median': 2.0, 'rtf_min': 2.0,
                                      'mpc_median_ms': 1.0, 'mpc_p99_max_ms': 3.0}
    assert timing([failed])['rtf_median'] is None


def test_a_walk_reads_its_speed_over_whole_crawl_cycles():
    """The achieved speed is the one over whole crawl cycles where the run has one (the crawl's
    sway averaged out), else the one after the settling, marked by ``cycles`` 0."""
    segment = {'commanded': [0.0, 0.033, 0.0], 'achieved': [0.0, 0.0289, 0.0],
               'achieved_cycles': [0.0, 0.0327, 0.0], 'cycles': 3}
    metrics = {'sim_time_s': 14.0, 'fell': False, 'completed': True,
               'velocity_tracking': [{'commanded': [0.0, 0.0, 0.0], 'achieved': [0.0] * 3},
                                     segment]}
    row = walk_row(RunResult('w', {}, metrics, Path('w')), 'lateral', 0.033)
    assert row['achieved'] == 0.0327 and row['cycles'] == 3
    segment.update(achieved_cycles=None, cycles=0)
    row = walk_row(RunResult('w', {}, metrics, Path('w')), 'lateral', 0.033)
    assert row['achieved'] == 0.0289 and row['cycles'] == 0


def test_the_robots_page_and_its_plan_do_not_shape_a_run(tmp_path):
    """Editing the page's code or plan does not make every run again (runs.py _NOT_SHAPING)."""
    files = ['src/replan_experiments/replan_experiments/robots_page.py',
             'src/replan_experiments/replan_experiments/robots_plan.py',
             'src/replan_experiments/replan_experiments/robots_render.py',
             'config/robots_page.yaml']
    for rel in [*files, 'config/robots/go1.yaml']:
        (tmp_path / rel).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / rel).write_text('a = 1\n')
    first = code_fingerprint(tmp_path)
    for rel in files:
        (tmp_path / rel).write_text('a = 2\n')
        assert code_fingerprint(tmp_path) == first, rel
    (tmp_path / 'config/robots/go1.yaml').write_text('a = 2\n')
    assert code_fingerprint(tmp_path) != first


def test_the_page_names_its_plan_relative_to_the_repository(tmp_path):
    """A page made in one checkout names no folder of that machine (it named
    /work/regen/config/robots_page.yaml); a plan outside the repository keeps its path."""
    from replan_experiments.robots_page import _shown
    root = tmp_path / 'repo'
    assert _shown(root / 'config' / 'robots_page.yaml', root) == 'config/robots_page.yaml'
    assert _shown(tmp_path / 'mine.yaml', root) == str(tmp_path / 'mine.yaml')


class GaitRunner(StandInRunner):
    """As StandInRunner, with a segment per set-point of the document, each with three whole
    cycles of the gait at 97 % of its set-point."""

    def run(self, doc: dict, bag: bool = False) -> RunResult:
        result = super().run(doc, bag)
        commands = [e['cmd_vel'] for e in doc['events'] if 'cmd_vel' in e]
        result.metrics['velocity_tracking'] = [
            {'commanded': c, 'cycle_velocities': [
                {'start_s': float(k), 'end_s': k + 1.0, 'velocity': [0.97 * v for v in c]}
                for k in range(3)]} for c in commands]
        return result


def trot_info(name: str = 'go1') -> object:
    info = synthetic(name, swing=0.3, four_feet=0.0)
    info.values['gait'].update(group_size=2, idle_after=0.6)
    return info


def test_a_gait_is_measured_walking_turning_pushed_and_down_a_ladder_of_steps(tmp_path):
    plan = load_robots_plan(PLAN, only=['go1'])
    info = trot_info()
    trot = gait_plan(plan, 'trot', {'go1': info})
    runner = GaitRunner(tmp_path, step_limit=0.08)
    runner.times = []
    row = measure_gait(runner, trot, info)
    assert row['gait'] == 'trot' and row['froude'] == pytest.approx(0.02, abs=2e-4)
    assert row['walk']['axes']['forward']['share'] == pytest.approx(0.97)
    assert set(row['turn']['axes']) == {'lateral', 'yaw'}
    assert row['turn']['axes']['yaw']['share'] == pytest.approx(0.97)
    # The ladder stops at the first share not crossed: 0.05 crossed, 0.10 fell, 0.15 not run.
    assert [s['share'] for s in row['step_down']] == [0.05, 0.10]
    assert [s['crossed'] for s in row['step_down']] == [True, False]
    assert row['push']['survived_dv'] == 0.3 and row['push']['phases'] == 4
    assert len(row['falls']) == 1 and '_trot_step_down_0.1-' in row['falls'][0]
    assert all(d['gait'] == 'trot' and d['name'].startswith('go1_trot_') for d in runner.docs)
    assert len(runner.docs) == row['runs'] == 2 + 1 + 2 + 4
    walk = next(d for d in runner.docs if d['name'] == 'go1_trot_walk')
    assert row['standing']['window_s'][1] == walk['duration']          # the run's end
    # The fast walk: forward at Froude 0.05 from standing, its whole cycles measured.
    fast = next(d for d in runner.docs if d['name'] == 'go1_trot_fast')
    speed = fast['events'][0]['cmd_vel'][0]
    assert speed ** 2 / (9.81 * info.leg_length_m) == pytest.approx(0.05, rel=0.01)
    assert fast['duration'] == pytest.approx(
        fast['events'][0]['t'] + trot.tests['fast']['forward_cycles'] * info.cycle_s, abs=1e-4)
    assert row['fast']['froude'] == 0.05
    assert row['fast']['axes']['forward']['share'] == pytest.approx(0.97)


def test_a_gait_whose_walk_falls_is_not_pushed_or_stepped_down(tmp_path):
    plan = load_robots_plan(PLAN, quick=True, only=['go1'])
    info = trot_info()
    runner = GaitRunner(tmp_path, forward_falls=True)
    row = measure_gait(runner, gait_plan(plan, 'walking_trot', {'go1': info}), info)
    assert row['push'] is None and row['step_down'] == []
    assert row['skipped'] == 'falls walking forward on flat ground'
    assert len(runner.docs) == 2 and len(row['falls']) == 2


def test_planned_runs_count_every_gait():
    plan = load_robots_plan(PLAN, quick=True, only=['go1'])
    # crawl: 3 walks + stand + response + 1 share + 1 push; each gait: walk, turn, 1 share,
    # 1 push; the trot's fast walk
    assert planned_runs(plan) == 7 + 5 + 4
    full = load_robots_plan(PLAN)
    assert planned_runs(full) == planned_runs(replace(full, gaits={})) + 7 * (
        2 + 1 + 3 + 4 + 2 + 1 + 4)


def test_a_gaits_achieved_is_the_mean_of_its_last_whole_cycles():
    cycles = [{'start_s': 0.0, 'end_s': 1.0, 'velocity': [0.1, 0.0, 0.0]},
              {'start_s': 1.0, 'end_s': 2.0, 'velocity': [0.28, 0.01, 0.0]},
              {'start_s': 2.0, 'end_s': 3.0, 'velocity': [0.30, -0.01, 0.0]}]
    metrics = {'velocity_tracking': [{'commanded': [0.29, 0.0, 0.0], 'cycle_velocities': cycles},
                                     {'commanded': [0.0, 0.0, 0.0], 'cycle_velocities': []}]}
    axes = gait_axes(RunResult('w', {}, metrics, Path('w')), 2)
    assert list(axes) == ['forward']
    assert axes['forward']['share'] == pytest.approx(0.29 / 0.29) and axes['forward'][
        'cycles'] == 3
    assert axes['forward']['cycle_shares'] == pytest.approx([0.1 / 0.29, 0.28 / 0.29,
                                                             0.30 / 0.29], abs=1e-4)
    assert gait_axes(RunResult('w', {}, metrics, Path('w')), 4)['forward']['share'] is None
