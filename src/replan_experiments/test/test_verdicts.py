"""The pre-registered verdicts (``stats``: Holm, effects and intervals, the four outcomes; the
plan's primary blocks and hash, ``plan``; the page's verdict table, ``page``) on numbers
worked out by hand."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
import yaml

from replan_experiments.findings import fill_readme, page_verdicts, readme_table
from replan_experiments.page import write_page
from replan_experiments.plan import (
    ExperimentError,
    claim_hashes,
    load_plan,
    pilot_plan,
    plan_hash,
    preregistration,
)
from replan_experiments.runs import run_key
from replan_experiments.stats import (
    _signed_rank_cdf,
    binomial_two_sided,
    exploratory,
    fisher,
    hodges_lehmann,
    holm,
    mcnemar,
    outcome,
    paired_t,
    pairs_to_resolve,
    pilot_sizes,
    primary_sample,
    primary_verdicts,
    verdicts,
)

CONFIG = Path(__file__).resolve().parents[3] / 'config'


def test_holm_step_down_on_a_textbook_example():
    # p = 0.01, 0.04, 0.03, 0.005 at alpha 0.05, m = 4. Sorted: 0.005 x 4 = 0.02 <= 0.05,
    # reject; 0.01 x 3 = 0.03 <= 0.05, reject; 0.03 x 2 = 0.06 > 0.05: stop, keep it and
    # 0.04. Adjusted (monotone): 0.02, 0.03, 0.06, max(0.04 x 1, 0.06) = 0.06.
    adjusted, rejected = holm([0.01, 0.04, 0.03, 0.005])
    assert adjusted == pytest.approx([0.03, 0.06, 0.06, 0.02])
    assert rejected == [True, False, False, True]
    # A single test is its own family.
    assert holm([0.049]) == ([0.049], [True])


def test_paired_t_mean_interval_and_p():
    # Differences 1, 2, 3, 4: mean 2.5, sd 1.291, se 0.6455; t(0.975, 3) = 3.1824:
    # 2.5 +- 2.054; t = 3.873 on 3 df: p = 0.0305.
    mean, (low, high), p = paired_t([1.0, 2.0, 3.0, 4.0])
    assert mean == 2.5
    assert (low, high) == pytest.approx((0.4457, 4.5543), abs=1e-4)
    assert p == pytest.approx(0.0305, abs=1e-4)
    assert paired_t([0.5, 0.5, 0.5]) == (0.5, (0.5, 0.5), 0.0)      # no spread
    assert paired_t([0.5]) == (0.5, (-math.inf, math.inf), 1.0)      # no interval at all


def test_hodges_lehmann_estimate_and_interval():
    # n = 10: P(T+ <= 8) = 25/1024 = 0.0244 <= 0.025 < P(T+ <= 9) = 33/1024, so the 95 %
    # interval runs from the 9th smallest to the 9th largest of the 55 Walsh averages.
    assert _signed_rank_cdf(10)[8] == pytest.approx(25 / 1024)
    assert _signed_rank_cdf(10)[9] == pytest.approx(33 / 1024)
    # Differences -2..7: the Walsh averages start -2, -1.5, -1, -1, -0.5, -0.5, 0, 0, 0 (the
    # 9th: 0) and, symmetric about 2.5, end ... 5 (the 9th largest); their median 2.5.
    estimate, interval = hodges_lehmann(np.arange(10) - 2.0)
    assert estimate == 2.5 and interval == (0.0, 5.0)
    # Five differences cannot give a 95 % interval (P(T+ = 0) = 1/32 > 0.025).
    assert hodges_lehmann([1.0, 2.0, 3.0, 4.0, 5.0])[1] == (-math.inf, math.inf)


def test_mcnemar_exact_on_known_tables():
    # 9 pairs better with the treatment, 2 worse, 5 alike: the binomial on 11 discordant
    # pairs, 2 x P(X <= 2) = 2 x (1 + 11 + 55) / 2048 = 134 / 2048 = 0.0654.
    pairs = [(True, False)] * 9 + [(False, True)] * 2 + [(True, True)] * 5
    diff, (low, high), p = mcnemar(pairs)
    assert p == pytest.approx(134 / 2048)
    assert diff == pytest.approx((9 - 2) / 16) and -1.0 <= low < diff < high <= 1.0
    # 10 of 10 discordant pairs one way: 2 / 2^10.
    assert mcnemar([(True, False)] * 10 + [(False, False)] * 10)[2] == pytest.approx(2 / 1024)
    assert binomial_two_sided(5, 10) == 1.0 and binomial_two_sided(0, 0) == 1.0


def test_fisher_exact_and_newcombes_interval():
    # 8 of 10 against 2 of 10: Fisher's two-sided p = 0.0230 (the textbook table).
    assert fisher([True] * 8 + [False] * 2, [True] * 2 + [False] * 8)[2] == pytest.approx(
        0.0230, abs=1e-4)
    # Newcombe (1998), unpaired, method 10: 56/70 against 48/80, difference 0.2,
    # interval 0.0524 to 0.3339.
    diff, interval, _ = fisher([True] * 56 + [False] * 14, [True] * 48 + [False] * 32)
    assert diff == pytest.approx(0.2) and interval == pytest.approx((0.0524, 0.3339), abs=1e-4)


@pytest.mark.parametrize('estimate, interval, significant, direction, expected', [
    (2.0, (1.2, 2.8), True, 'higher', 'holds'),            # beyond the smallest effect 1
    (0.6, (0.3, 0.9), True, 'higher', 'negligible'),       # significant, too small, CI in +-1
    (0.6, (0.3, 1.3), True, 'higher', 'not resolved'),     # significant, too small, CI out
    (-0.6, (-0.9, -0.3), True, 'higher', 'opposite'),      # significant with the other sign
    (-2.0, (-2.8, -1.2), True, 'lower', 'holds'),
    (1.5, (0.8, 2.2), True, 'higher', 'not resolved'),     # estimate beyond, interval not
    (-1.5, (-2.2, -0.8), True, 'lower', 'not resolved'),
    (0.1, (-0.5, 0.7), False, 'higher', 'negligible'),     # the equivalence: CI in +-1
    (0.1, (-1.5, 1.7), False, 'higher', 'not resolved'),   # the CI reaches beyond +-1
])
def test_the_four_outcomes(estimate, interval, significant, direction, expected):
    assert outcome(estimate, interval, significant, direction, 1.0) == expected


def test_verdicts_correct_over_the_whole_family():
    # Two tests with p = 0.0305 each: Holm makes the smaller 2 x 0.0305 = 0.061 (not
    # significant), the other max(0.0305, 0.061); alone each would hold.
    block = {'test': 'paired_t', 'direction': 'higher', 'smallest_effect': 1.0}
    out = verdicts([{**block, 'sample': [1.0, 2.0, 3.0, 4.0]},
                    {**block, 'sample': [1.0, 2.0, 3.0, 4.0]}])
    assert [v['p_holm'] for v in out] == pytest.approx([0.061, 0.061], abs=1e-3)
    assert [v['outcome'] for v in out] == ['not resolved', 'not resolved']
    # Alone it is significant, but its interval (0.45 to 4.55) reaches below the smallest
    # effect: not resolved; a tighter sample's interval (1.72 to 3.78) is beyond it: holds.
    assert verdicts([{**block, 'sample': [1.0, 2.0, 3.0, 4.0]}])[0]['outcome'] == 'not resolved'
    assert verdicts([{**block, 'sample': [2.0, 2.5, 3.0, 3.5]}])[0]['outcome'] == 'holds'
    # A claim that cannot be judged still counts in the family, with p = 1.
    out = verdicts([{**block, 'sample': [1.0, 2.0, 3.0, 4.0]},
                    {**block, 'sample': None, 'reason': 'not run'}])
    assert out[0]['p_holm'] == pytest.approx(0.061, abs=1e-3)
    assert out[1]['outcome'] == 'no verdict: not run'


def _plan_text() -> str:
    return (CONFIG / 'experiments.yaml').read_text()


def test_the_plan_hash_follows_the_primary_blocks_only(tmp_path):
    path = tmp_path / 'experiments.yaml'
    path.write_text(_plan_text())
    plan, _ = load_plan(path, False, [])
    first = plan_hash(plan)
    assert first and len(first) == 12
    # A comment, the reason's words, an exploratory setting: the same plan hash.
    path.write_text(_plan_text().replace('# paper VI: window 2 lets the model errors grow',
                                         '# paper VI: a comment changed'))
    assert plan_hash(load_plan(path, False, [])[0]) == first
    doc = yaml.safe_load(_plan_text())
    doc['full']['haptic']['primary']['reason'] = 'another reason'
    doc['full']['haptic']['duration'] = 19.0
    path.write_text(yaml.safe_dump(doc))
    assert plan_hash(load_plan(path, False, [])[0]) == first
    # The smallest effect, the test or the confirmatory seeds: another plan.
    for change in ({'smallest_effect': 0.4}, {'test': 'fisher'}):
        doc = yaml.safe_load(_plan_text())
        doc['full']['haptic']['primary'].update(change)
        path.write_text(yaml.safe_dump(doc))
        assert plan_hash(load_plan(path, False, [])[0]) != first, change
    doc = yaml.safe_load(_plan_text())
    doc['full']['haptic']['seeds'] = list(range(20, 30))
    path.write_text(yaml.safe_dump(doc))
    changed = load_plan(path, False, [])[0]
    assert plan_hash(changed) != first
    # Only the changed claim's own hash moves: the other claims keep their runs.
    before, after = claim_hashes(plan), claim_hashes(changed)
    assert set(before) == set(after) and before['haptic'] != after['haptic']
    assert all(before[name] == after[name] for name in before if name != 'haptic')
    # The velocity term's shared node params define its comparison: its hash moves with them.
    doc = yaml.safe_load(_plan_text())
    doc['full']['velocity_term']['params'] = {'gait': {'velocity_feedback_gain': 0.25}}
    path.write_text(yaml.safe_dump(doc))
    shared = claim_hashes(load_plan(path, False, [])[0])
    assert shared['velocity_term'] != before['velocity_term']
    assert all(before[name] == shared[name] for name in before if name != 'velocity_term')
    # The quick plan pre-registers nothing; the pilot plan runs the pilot seeds, unhashed.
    assert plan_hash(load_plan(CONFIG / 'experiments.yaml', True, [])[0]) is None
    pilot = pilot_plan(plan)
    assert plan_hash(pilot) is None
    assert pilot['haptic']['seeds'] == plan['haptic']['primary']['pilot_seeds']


@pytest.mark.parametrize('change, message', [
    ({'drop': 'smallest_effect'}, r"full.haptic.primary: missing keys \['smallest_effect'\]"),
    ({'add': {'smalest': 1}}, r"full.haptic.primary: unknown keys \['smalest'\]"),
    ({'add': {'n': 9}}, r'full.haptic.primary: n: 9, but the confirmatory seeds are 10'),
    ({'add': {'pilot_seeds': [0, 10]}}, r'full.haptic.primary: pilot_seeds: \[10\] are '
                                        r'confirmatory seeds too'),
    ({'add': {'test': 'paired_t'}}, r'full.haptic.primary: test: paired_t does not fit'),
    ({'add': {'measure': 'pitch'}}, r"full.haptic.primary: measure: 'pitch' is not one"),
    ({'add': {'direction': 'up'}}, r'full.haptic.primary: direction: higher or lower'),
    ({'add': {'against': 1.0}}, r'full.haptic.primary: needs one of compare'),
])
def test_the_plan_loader_checks_the_primary_block(tmp_path, change, message):
    doc = yaml.safe_load(_plan_text())
    block = doc['full']['haptic']['primary']
    block.pop(change.get('drop'), None)
    block.update(change.get('add', {}))
    path = tmp_path / 'experiments.yaml'
    path.write_text(yaml.safe_dump(doc))
    with pytest.raises(ExperimentError, match=f'^{path}: ' + message):
        load_plan(path, False, [])


def test_a_confirmatory_runs_key_holds_the_plan_hash():
    doc = {'name': 'walk', 'duration': 9.0}
    assert run_key(doc, 'c') == run_key(doc, 'c', None)          # as before plans had hashes
    key = run_key(doc, 'c', 'abc123abc123')
    assert key.startswith('walk-planabc123abc123-') and key != run_key(doc, 'c')
    assert key != run_key(doc, 'c', 'def456def456')


# -- the page --------------------------------------------------------------------------------

def _haptic_rows(plan: str | None, seeds, off_more: float = 0.5) -> list[dict]:
    """Haptic rows on the 10 cm step: off peaks ``off_more`` deg above on in every pair, and
    the setting that peaks higher falls (off with ``off_more`` > 0), except at every fifth
    seed."""
    def fell(on: bool, s: int) -> bool:
        return s % 5 != 0 and (on if off_more < 0 else not on)
    return [{'ok': True, 'fell': fell(on, s), 'world': 'realistic', 'terrain': 'step_down_10cm',
             'haptic': on, 'seed': s, 'plan': plan, 'pitch_peak_mean_deg': 0.4,
             'pitch_peak_max_deg': 1.0 + 0.01 * s + (0.0 if on else off_more + 0.01 * (s % 3)),
             'touchdown_timing_median_abs_s': 0.02, 'crossed': not fell(on, s)}
            for on in (True, False) for s in seeds]


def _meta(prereg: dict) -> dict:
    return {'command': 'scripts/experiments.sh', 'machine': 'test', 'revision': 'abc',
            'date': 'today', 'wall_time_min': 1.0, 'runs': 20, 'failures': [],
            'preregistration': prereg}


def _haptic_prereg(role: str = 'confirmatory') -> dict:
    plan, _ = load_plan(CONFIG / 'experiments.yaml', False, [])
    return preregistration({'haptic': plan['haptic']}, 'config/experiments.yaml', role)


def test_the_page_judges_the_runs_of_this_plan(tmp_path):
    prereg = _haptic_prereg()
    seeds = prereg['claims']['haptic']['seeds']
    results = {'haptic': _haptic_rows(prereg['claim_hashes']['haptic'], seeds)
               + _haptic_rows(None, prereg['claims']['haptic']['pilot_seeds'], -0.5)}
    page = tmp_path / 'results.md'
    write_page(page, results, _meta(prereg))
    text = page.read_text()
    assert f'Plan hash **{prereg["hash"]}**' in text
    assert ('| without haptic touchdown the pitch is disturbed (V.A, VI) | '
            '`fell` (haptic off minus haptic on, terrain step_down_10cm, paired by seed) | '
            'higher | 0.3 share of runs (three falls in ten walks') in text
    assert ('| 10 (10, 11, 12, 13, 14, 15, 16, 17, 18, 19) | 0, 1, 2, 3, 4, 5, 6, 7, 8, 9 | '
            f'{prereg["claim_hashes"]["haptic"]} |') in text
    # The pilot rows (the other sign) never enter: off fell at 8 of 10 seeds, on at none
    # (McNemar exact: 2 / 2^8).
    row = next(line for line in text.splitlines()
               if line.startswith('| without haptic') and '| 10 |' in line)
    assert row.endswith('| 0.0078 | holds |') and '`fell` | 0.8 [0.384, 0.943] share' in row
    assert 'One family: the 1 claims\' primary tests, Holm\'s step-down' in text
    assert '## Every measure (exploratory)' in text
    assert readme_table(page_verdicts(results, _meta(prereg))) == (
        '| Claim | Verdict | Effect (95 % CI) |\n|---|---|---|\n'
        '| without haptic touchdown the pitch is disturbed (V.A, VI) | holds | '
        '0.8 [0.384, 0.943] share |\n')


def test_the_page_refuses_verdicts_on_runs_of_another_plan(tmp_path):
    prereg = _haptic_prereg()
    seeds = prereg['claims']['haptic']['seeds']
    page = tmp_path / 'results.md'
    # Runs of another pre-registration of the claim, none, or keyed by the whole plan's hash.
    for plan in ('0123456789ab', None, prereg['hash']):
        write_page(page, {'haptic': _haptic_rows(plan, seeds)}, _meta(prereg))
        text = page.read_text()
        assert (f'| - | - | - | no verdict: runs of another pre-registration (hash '
                f'{plan or "none"}, this claim\'s {prereg["claim_hashes"]["haptic"]}) |') in text
        # The runs' figures are still on the page.
        assert '| haptic | step down 10cm, off | largest touchdown pitch peak (deg) |' in text
    # A pilot call never judges, even on runs that would hold.
    pilot = _haptic_prereg('pilot')
    write_page(page, {'haptic': _haptic_rows(None, seeds)}, _meta(pilot))
    assert 'no verdict: pilot runs (seeds [10, 11, 12, 13, 14, 15, 16, 17, 18, 19]) never ' \
        'enter a verdict' in page.read_text()


def test_the_sample_pairs_by_the_blocks_keys_and_leaves_out_censored_pairs():
    block = {'measure': 'survived_ns', 'test': 'wilcoxon', 'seeds': [5, 6],
             'compare': {'by': 'setting', 'treatment': 'on', 'control': 'off'},
             'pair_by': ['phase', 'seed']}
    rows = [{'setting': name, 'phase': k, 'seed': s, 'survived_ns': v, 'censored': c}
            for name, k, s, v, c in (('on', 0, 5, 90.0, False), ('off', 0, 5, 75.0, False),
                                     ('on', 1, 5, 135.0, True), ('off', 1, 5, 135.0, True),
                                     ('on', 0, 6, 120.0, True), ('off', 0, 6, 105.0, False),
                                     ('on', 0, 0, 150.0, False), ('off', 0, 0, 30.0, False))]
    sample, used = primary_sample(rows, block)
    assert sample == [15.0, 15.0] and len(used) == 4      # seed 0: a pilot seed, left out


def test_readme_block_is_filled_between_its_markers(tmp_path):
    prereg = _haptic_prereg()
    results = {'haptic': _haptic_rows(prereg['claim_hashes']['haptic'],
                                      prereg['claims']['haptic']['seeds'])}
    readme = tmp_path / 'README.md'
    readme.write_text('# X\n\nbefore\n<!-- results:begin -->\nOLD TABLE\n'
                      '<!-- results:end -->\nafter\n')
    assert fill_readme(readme, results, _meta(prereg))
    text = readme.read_text()
    assert text.startswith('# X\n\nbefore\n<!-- results:begin -->\nThe pre-registered')
    assert '| without haptic touchdown the pitch is disturbed (V.A, VI) | holds |' in text
    assert prereg['hash'] not in text     # the page names the plan, the README links it
    assert 'OLD TABLE' not in text and text.endswith('<!-- results:end -->\nafter\n')
    readme.write_text('no markers\n')
    assert not fill_readme(readme, results, _meta(prereg))
    assert readme.read_text() == 'no markers\n'


def test_exploratory_comparisons_carry_no_verdict_words():
    assert exploratory('holds (20 pairs), p = 0.001') == (
        'the claimed direction (20 pairs), p = 0.001')
    assert exploratory('does not hold (the opposite) (5 pairs)') == (
        'the other direction (5 pairs)')
    assert exploratory('not resolved (within the spread)') == 'undecided (within the spread)'


def _pushed_rows(plan: str | None, seeds) -> list[dict]:
    """Sustained-push rows: 'literal' keeps 3 cm more margin than 'off' without a push and
    only 1 mm more under 60 and 80 N, 'sway_free' 5 mm more under a push than without."""
    gain = {('literal', 0.0): 0.03, ('literal', 60.0): 0.001, ('literal', 80.0): 0.001,
            ('sway_free', 0.0): 0.0, ('sway_free', 60.0): 0.005, ('sway_free', 80.0): 0.005}
    return [{'ok': True, 'world': 'realistic', 'correction': setting, 'force_n': force,
             'seed': s, 'plan': plan,
             'capture_margin_p5_m': 0.05 - force * 1e-4 + 1e-4 * (s % 3)
             + gain.get((setting, force), 0.0) + (2e-4 * (s % 2) if setting != 'off' else 0)}
            for setting in ('off', 'literal', 'sway_free') for force in (0.0, 60.0, 80.0)
            for s in seeds]


def test_a_baseline_makes_the_effect_a_difference_in_differences():
    """A setting better already without a push is not better against the push for that."""
    block = {'measure': 'capture_margin_p5_m', 'test': 'paired_t', 'seeds': [5, 6, 7],
             'compare': {'by': 'correction', 'treatment': 'literal', 'control': 'off'},
             'where': {'force_n': [60.0, 80.0]}, 'pair_by': ['seed', 'force_n'],
             'baseline': {'force_n': 0.0}}
    rows = _pushed_rows('h', [0, 5, 6, 7])
    plain, _ = primary_sample(rows, {k: v for k, v in block.items() if k != 'baseline'})
    sample, used = primary_sample(rows, block)
    assert len(plain) == len(sample) == 6
    assert all(abs(d - (0.001 + 2e-4 * (s % 2))) < 1e-12 for d, s in zip(
        plain, (5, 5, 6, 6, 7, 7), strict=True))
    assert all(abs(d - (0.001 - 0.03)) < 1e-12 for d in sample)
    # The baseline runs are among those used (their plan is checked too); seed 0 is not.
    assert sum(r['force_n'] == 0.0 for r in used) == 6 and {r['seed'] for r in used} == {5, 6, 7}
    # A run without its baseline run is left out.
    missing = [r for r in rows if not (r['seed'] == 7 and r['force_n'] == 0.0
                                       and r['correction'] == 'off')]
    assert len(primary_sample(missing, block)[0]) == 4
    # The page says what the effect is.
    from replan_experiments.findings import comparison
    assert comparison(block) == ('literal minus off, force_n [60.0, 80.0], '
                                 'each run minus its setting\'s run at force_n 0.0 (a difference '
                                 'in differences), paired by seed, force_n')


def test_the_page_says_which_node_parameters_both_settings_share():
    """The velocity term's settings differ in the cost term only: the page's pre-registration
    names the parameters both get (they are part of the claim's hash)."""
    from replan_experiments.findings import comparison
    from replan_experiments.plan import claim_hash
    block = {'measure': 'rise_time_s', 'unit': 's', 'pair_by': ['seed'],
             'compare': {'by': 'velocity_term', 'treatment': True, 'control': False},
             'where': {'setpoint': 'step'}}
    shared = {**block, 'params': {'gait': {'velocity_feedback_gain': 0.0}}}
    assert comparison(shared) == comparison(block).replace(
        ', paired by', ', both settings with gait.velocity_feedback_gain 0.0, paired by')
    assert claim_hash(shared) != claim_hash(block)


@pytest.mark.parametrize('change, message', [
    ({'test': 'mcnemar', 'measure': 'fell'}, 'baseline: a mapping of run keys'),
    ({'baseline': 0.0}, 'baseline: a mapping of run keys'),
    ({'baseline': {'setting': 'correction_off'}}, r"baseline: 'setting' is what the settings"),
])
def test_the_plan_loader_checks_the_baseline(tmp_path, change, message):
    doc = yaml.safe_load(_plan_text())
    block = doc['full']['sustained_push']['primary']
    block.update(change)
    path = tmp_path / 'experiments.yaml'
    path.write_text(yaml.safe_dump(doc))
    with pytest.raises(ExperimentError, match=f'^{path}: full.sustained_push.primary: ' + message):
        load_plan(path, False, [])


def test_a_verdict_uses_its_claims_own_hash():
    plan, _ = load_plan(CONFIG / 'experiments.yaml', False, [])
    prereg = preregistration({'haptic': plan['haptic'], 'replan_window': plan['replan_window']},
                             'config/experiments.yaml', 'confirmatory')
    seeds = prereg['claims']['haptic']['seeds']
    own = {v['claim']: v for v in primary_verdicts(prereg, {'haptic': _haptic_rows(
        prereg['claim_hashes']['haptic'], seeds)})}
    assert own['haptic']['outcome'] == 'holds'
    assert own['replan_window']['outcome'] == 'no verdict: not run in this call'
    other = {v['claim']: v for v in primary_verdicts(prereg, {'haptic': _haptic_rows(
        prereg['claim_hashes']['replan_window'], seeds)})}
    assert other['haptic']['outcome'].startswith('no verdict: runs of another pre-registration')


def test_pairs_to_resolve_with_a_preregistered_effect_and_level():
    diff = [0.9, 1.1, 1.0, 1.2, 0.8]            # mean 1.0, sd 0.158
    assert pairs_to_resolve(diff) == 3
    # Half the effect needs more pairs; Holm's strictest level (0.05 / 7) more again.
    assert pairs_to_resolve(diff, effect=0.1) > pairs_to_resolve(diff, effect=0.5) > 3
    assert pairs_to_resolve(diff, effect=0.5, alpha=0.05 / 7) > pairs_to_resolve(diff, 0.5)
    # An effect of many spreads: scipy's far tail is NaN, which counts as 0, not as "never".
    assert pairs_to_resolve([10.0, 10.001, 9.999]) == 2
    assert pairs_to_resolve([1.0, 1.0]) is None               # no spread


def test_a_pilot_call_is_not_a_quick_one():
    from replan_experiments.runner import main
    with pytest.raises(SystemExit) as stop:
        main(['--quick', '--pilot'])
    assert stop.value.code == 2


def test_a_confirmatory_call_keys_its_runs_by_the_plan_and_judges_them(tmp_path, monkeypatch):
    """experiments.sh on the full plan's haptic claim with a stand-in for the graph (each run
    writes its metrics at once: without haptic it falls at 8 seeds of 10): the
    runs' keys hold the plan hash, the page judges them; --pilot makes the pilot seeds' runs,
    without a hash, and judges nothing."""
    from replan_experiments import runner as runner_module
    from replan_experiments.runs import Runner

    def execute(self, folder: Path, bag: bool) -> int:
        doc = yaml.safe_load((folder / 'input.yaml').read_text())
        off = (doc.get('params') or {}).get('gait', {}).get('haptic') is False
        seed = doc['params']['sim']['noise_seed']
        (folder / 'metrics.json').write_text(json.dumps({
            'sim_time_s': doc['duration'], 'fell': off and seed % 5 != 0, 'completed': True,
            'final_position_m': [3.0, 0.0, 0.5],
            'touchdown_pitch_peak_deg': {'mean': 0.4, 'max': 1.0 + 0.01 * seed
                                         + (0.5 + 0.01 * (seed % 3) if off else 0.0)}}))
        return 0

    monkeypatch.setattr(Runner, '_execute', execute)
    monkeypatch.setenv('REPLAN_ROOT', str(CONFIG.parent))
    monkeypatch.setenv('REPLAN_CONFIG', str(CONFIG))
    plan, _ = load_plan(CONFIG / 'experiments.yaml', False, [])
    hashed = claim_hashes(plan)['haptic']
    page = tmp_path / 'results.md'
    assert runner_module.main(['--only', 'haptic', '--out', str(tmp_path / 'out'), '--page',
                               str(page), '--quiet']) == 0
    keys = [p.name for p in (tmp_path / 'out' / 'runs').iterdir()]
    assert len(keys) == 80 and all(f'-plan{hashed}-' in k for k in keys)
    text = page.read_text()
    assert ('| without haptic touchdown the pitch is disturbed (V.A, VI) | '
            '`fell` | 0.8 [0.384, 0.943] share | 10 |') in text
    assert 'no verdict: not run in this call' in text      # the six other claims
    data = json.loads((tmp_path / 'out' / 'results.json').read_text())
    assert data['meta']['preregistration']['hash'] == plan_hash(plan)
    assert data['meta']['preregistration']['claim_hashes']['haptic'] == hashed
    assert runner_module.main(['--pilot', '--only', 'haptic', '--out', str(tmp_path / 'out'),
                               '--quiet']) == 0
    pilot = (tmp_path / 'out' / 'results-pilot.md').read_text()
    assert '**Pilot run**' in pilot and 'no verdict: pilot runs (seeds [10,' in pilot
    keys = [p.name for p in (tmp_path / 'out' / 'runs').iterdir()]
    assert len(keys) == 160 and sum('-plan' in k for k in keys) == 80


def test_a_pilot_page_says_what_its_runs_make_of_n(tmp_path):
    """The pilot's differences with the smallest effect and Holm's strictest level give the
    confirmatory seeds (stats.pairs_to_resolve); a binary outcome gets no figure."""
    plan, _ = load_plan(CONFIG / 'experiments.yaml', False, [])
    prereg = preregistration(plan, 'config/experiments.yaml', 'pilot')
    block = prereg['claims']['sustained_push']
    block['baseline'] = {'force_n': 0.0}
    rows = _pushed_rows(None, block['pilot_seeds'])
    for r in rows:
        if r['correction'] == 'literal' and r['force_n'] == 60.0:
            r['capture_margin_p5_m'] += 0.004 * (r['seed'] % 3)     # a spread of the DiD
        r['setting'] = {'off': 'correction_off', 'literal': 'correction_literal'}.get(
            r.pop('correction'), 'correction_sway_free')
    sizes = {s['claim']: s for s in pilot_sizes(prereg, {'sustained_push': rows,
                                                         'haptic': _haptic_rows(None, [0])})}
    push = sizes['sustained_push']
    assert push['pairs'] == 2 * len(block['pilot_seeds']) and push['alpha'] == 0.05 / 7
    assert abs(push['mean'] - (0.001 - 0.03)) < 0.005 and push['sd'] > 0.001
    expected = pairs_to_resolve(
        primary_sample(rows, {**block, 'seeds': block['pilot_seeds']})[0],
        effect=0.01, alpha=0.05 / 7)
    assert expected is not None and push['pairs_needed'] == expected
    assert push['seeds_needed'] == max(2, -(-expected // 2))    # two pairs (forces) a seed
    assert sizes['haptic']['pairs'] is None and 'binary' in sizes['haptic']['reason']
    assert sizes['replan_window']['reason'] == 'not run in this call'
    # The claims tested again elsewhere are a family of their own (stats.primary_verdicts).
    variants = [name for name, b in prereg['claims'].items() if 'experiment' in b]
    assert variants and all(sizes[v]['alpha'] == 0.05 / len(variants) for v in variants)
    page = tmp_path / 'results-pilot.md'
    meta = {**_meta(prereg), 'pilot': True}
    write_page(page, {'haptic': _haptic_rows(None, [0, 1])}, meta)
    text = page.read_text()
    assert '## Sample sizes from the pilot' in text and 'the number of claims of its family' in text
    assert f'| {0.05 / 7:.3g} | a binary outcome: n from the plan\'s reason | 10 |' in text


def test_a_claim_tested_again_elsewhere_is_a_family_of_its_own(tmp_path):
    """A variant's test (another robot or gait) is Holm-corrected with the other variants
    only: adding it leaves the paper's claims' adjusted p as they were; the page names where
    it was tested and gives its runs a section."""
    plan, _ = load_plan(CONFIG / 'experiments.yaml', False, [])
    alone = preregistration({'haptic': plan['haptic']}, 'config/experiments.yaml',
                            'confirmatory')
    both = preregistration({'haptic': plan['haptic'], 'haptic_trot': plan['haptic_trot']},
                           'config/experiments.yaml', 'confirmatory')
    assert both['claim_hashes']['haptic'] == alone['claim_hashes']['haptic']
    seeds = plan['haptic']['seeds']
    rows = _haptic_rows(alone['claim_hashes']['haptic'], seeds)
    trot = [{**r, 'plan': both['claim_hashes']['haptic_trot']}
            for r in _haptic_rows(None, plan['haptic_trot']['seeds'], off_more=-0.5)]
    first = primary_verdicts(alone, {'haptic': rows})
    second = {v['claim']: v for v in primary_verdicts(both, {'haptic': rows,
                                                             'haptic_trot': trot})}
    assert second['haptic']['p_holm'] == first[0]['p_holm'] == first[0]['p']
    assert second['haptic_trot']['outcome'] == 'opposite'     # there the trot falls with haptic
    page = tmp_path / 'results.md'
    results = {'haptic': rows, 'haptic_trot': trot,
               'variants': {'haptic_trot': {'experiment': 'haptic', 'gait': 'trot',
                                            'setpoint_scale': 2.0}}}
    write_page(page, results, _meta(both))
    text = page.read_text()
    label = 'without haptic touchdown the pitch is disturbed (V.A, VI): trot gait, set-points x2'
    assert 'Two families' in text and f'## {label}' in text
    assert f'| {label} | opposite |' in readme_table(list(second.values()))
    assert f'| {label} | haptic on | falls | 8 of 10 |' in text
