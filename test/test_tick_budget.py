"""The per-tick budget of the lock-step loop (tick_budget.py) in the running sim and wbc: every
phase appears in their /diagnostics, finite and not negative, the work done every tick
positive, and the figures agree with what a tick is made of. No timing is asserted."""

from __future__ import annotations

import math

from conftest import CONFIG_DIR
from diagnostic_msgs.msg import DiagnosticArray
from nav_msgs.msg import Odometry

from replan_experiments.benchmarks.tick_table import OVERLAPPED
from replan_ros.messages.stamps import stamp_to_sec
from replan_ros.telemetry import diagnostics, tick_budget
from replan_ros.telemetry.tick_budget import parse_diagnostic_values
from replan_ros.transport.qos import COMMAND, SENSOR


def _latest(diags, name: str) -> dict | None:
    """The newest status ``name`` with budget figures, as phase -> {median_ms, mean_ms}."""
    for array in reversed(diags):
        for status in array.status:
            if status.name == name:
                phases = parse_diagnostic_values(diagnostics.values_of(status))
                if phases:
                    return phases
    return None


def _sim_and_wbc_running(launcher, probe, **wbc_params) -> list:
    """Sim and wbc (standing: no planners) started, 2 s of sim time run; the /diagnostics
    arrays received from then on."""
    launcher.start('sim_node', params_file=CONFIG_DIR / 'sim.yaml',
                   params={'diagnostics_period': 0.5})
    launcher.start('wbc_node', params_file=CONFIG_DIR / 'wbc.yaml',
                   params={'plan_timeout': 0.5, 'first_plan_timeout': 0.5,
                           'diagnostics_period': 0.5, **wbc_params})
    odoms = probe.subscribe(Odometry, 'ground_truth/odom', SENSOR)
    diags = probe.subscribe(DiagnosticArray, '/diagnostics', COMMAND)
    ok = probe.spin_until(lambda: odoms and stamp_to_sec(odoms[-1].header.stamp) >= 2.0,
                          timeout=90)
    assert ok, launcher.logs()
    diags.clear()
    return diags


def test_budget_figures_in_diagnostics_of_sim_and_wbc(launcher, probe):
    diags = _sim_and_wbc_running(launcher, probe)
    assert probe.spin_until(lambda: _latest(diags, 'sim') and _latest(diags, 'wbc'),
                            timeout=10), launcher.logs()
    sim, wbc = _latest(diags, 'sim'), _latest(diags, 'wbc')
    assert set(sim) == set(tick_budget.SIM_PHASES)
    assert set(wbc) == set(tick_budget.WBC_PHASES)
    for phases in (sim, wbc):
        for name, stats in phases.items():
            assert set(stats) == {'median_ms', 'mean_ms'}, name
            assert all(math.isfinite(v) and v >= 0.0 for v in stats.values()), (name, stats)
    # Work done in every tick costs something; DDS gives both processes the message info.
    for name in ('sim_physics', 'sim_sensing', 'sim_conversion', 'sim_publish_joint_states',
                 'sim_wait', 'sim_tick', 'sim_wake'):
        assert sim[name]['median_ms'] > 0.0, name
    for name in ('wbc_decode', 'wbc_take', 'wbc_controller', 'wbc_command', 'wbc_wake'):
        assert wbc[name]['median_ms'] > 0.0, name
    # The ideal world: no estimator, and this wbc holds no tick for plans (it stands).
    assert wbc['wbc_estimator']['mean_ms'] == 0.0
    assert wbc['wbc_estimator_next']['mean_ms'] == 0.0
    # A tick is the sim's own phases and its wait for the command, one after the other; the
    # work it does after joint_states are out (the truth, /clock, the lead physics steps) is
    # inside that wait.
    off_chain = {key for key, _ in OVERLAPPED}
    own = sum(stats['mean_ms'] for name, stats in sim.items()
              if name not in ('sim_tick', 'sim_wait', 'sim_transport_cmd', 'sim_wake')
              and name not in off_chain)
    inside_wait = sum(sim[name]['mean_ms'] for name in off_chain if name in sim)
    assert sim['sim_tick']['mean_ms'] >= 0.99 * (own + sim['sim_wait']['mean_ms'])
    assert sim['sim_wait']['mean_ms'] >= 0.99 * inside_wait


def _latest_values(diags, name: str) -> dict | None:
    for array in reversed(diags):
        for status in array.status:
            if status.name == name and 'estimator_prepared_steps' in diagnostics.values_of(
                    status):
                return diagnostics.values_of(status)
    return None


def test_estimator_covariance_step_is_prepared_off_the_chain(launcher, probe):
    """With the estimator on, its next covariance step is prepared after each command
    (StateEstimator.prepare_next) and the next update uses it: the estimator's on-chain phase
    and the off-chain one both cost something, and nearly every tick used a prepared step."""
    diags = _sim_and_wbc_running(launcher, probe, state_estimation=True,
                                 contact_estimation=True)
    assert probe.spin_until(lambda: _latest(diags, 'wbc') and _latest_values(diags, 'wbc'),
                            timeout=10), launcher.logs()
    phases, values = _latest(diags, 'wbc'), _latest_values(diags, 'wbc')
    assert phases['wbc_estimator']['median_ms'] > 0.0
    assert phases['wbc_estimator_next']['median_ms'] > 0.0
    ticks, prepared = int(values['ticks']), int(values['estimator_prepared_steps'])
    # Standing on four feet: only the first update and the stand's first ticks go without.
    assert ticks >= 400 and 0.9 * ticks <= prepared < ticks, (ticks, prepared)
