"""The results page's exploratory findings, one bullet per experiment, and its tables of the
pre-registered verdicts (``preregistration_section``, ``readme_table``, README.md's block
``fill_readme``): every number computed from the runs; a cause the runs do not isolate is
labelled a hypothesis."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from replan_experiments.page_push import impulse_label
from replan_experiments.stats import (
    P_VALUE,
    PAPER_QP_MS,
    POWER,
    against_paper,
    compare_paired,
    cycles_to_within,
    forward_speed_rows,
    is_variant,
    p_text,
    pilot_sizes,
    primary_verdicts,
    prompt_by_cycles,
    push_resolution,
    push_sign_test,
    steady_cycles_text,
    steady_velocity,
    values,
)


def findings(page, name: str, data, results: dict) -> None:
    """The bullets of experiment ``name`` (its ``data``) on ``page`` (page.Page)."""
    settings = results.get('settings') or {}
    if name == 'velocity_changes':
        for scenario in dict.fromkeys(r['scenario'] for r in data):
            sel = [r for r in data if r['scenario'] == scenario and r['world'] == 'realistic']
            if not sel:
                continue
            rise, settle = values(sel, 'rise_steps'), values(sel, 'settle_steps')
            # The steady state over the last whole crawl cycles (the sway averaged out, the
            # trunk at its speed) where a run has them, else after the settling.
            ratio = [np.hypot(*steady_velocity(r)[:2]) / np.hypot(*r['commanded'][:2])
                     for r in sel if r.get('achieved') and any(r['commanded'][:2])]
            label = scenario.removeprefix('exp_').replace('_', ' ')
            page.finding(
                f'Velocity change, {label}: the change itself is made in '
                f'{np.mean(rise):.1f} touchdowns on average (90 % of the way, {len(rise)} of '
                f'{len(sel)} runs)' if rise else f'Velocity change, {label}: no rise measured')
            if ratio:
                page.findings[-1] += (
                    f'; {len(settle)} of {len(sel)} runs get within 10 % of the set-point '
                    f'(1 s average), after {np.mean(settle):.1f} touchdowns on average'
                    if settle else '; no run gets within 10 % of the set-point (1 s average)')
                page.findings[-1] += (
                    f', {prompt_by_cycles(sel)[1]} of {len(sel)} by whole-cycle means from the '
                    'second whole cycle on')
                page.findings[-1] += (
                    f'; the realistic robot walks at {np.mean(ratio) * 100:.1f} % of its '
                    'set-point speed after the change (mean over the runs, over the last whole '
                    'crawl cycles)')
                tolerance = sel[0].get('steady_tolerance')
                counts = [cycles_to_within(r, tolerance) for r in sel] if tolerance else []
                known = [c for c in counts if c is not None]
                if counts:
                    page.findings[-1] += (
                        f'; its velocity is within {tolerance * 100:.0f} % of the set-point '
                        f'from whole cycle {np.mean(known) + 1:.1f} after the change on '
                        f'(mean, {len(known)} of {len(counts)} runs)' if known else
                        f'; no run is within {tolerance * 100:.0f} % of the set-point by its '
                        'last whole cycle')
                page.findings[-1] += '.'

    elif name == 'lateral_push':
        cfg, table = data['config'], data['settings']
        suffix = ' (ideal)' if data.get('world') == 'ideal' else ''
        mass = data.get('robot_mass_kg')
        first = float(cfg['first_impulse'])
        dv = [p['first']['velocity_change_mps'] for ph in table.values() for p in ph
              if p.get('first') and p['first'].get('velocity_change_mps') is not None]
        off = [p['survived_ns'] for p in table.get('correction_off', [])]
        text = (f'Lateral pushes{suffix}: every setting survived at least '
                f'{min(min(p["survived_ns"] for p in ph) for ph in table.values()):.0f} N s at '
                f'every phase and seed, {min(off):.0f} N s without foothold correction.'
                if off else f'Lateral pushes{suffix}:')
        if dv and mass:
            text += (f' A {first:.0f} N s push leaves the base {np.mean(dv):.3f} m/s along it '
                     f'(mean over phases, seeds and settings) where a free body of {mass:.0f} '
                     f'kg would gain {first / mass:.3f} m/s. A hypothesis these runs do not '
                     'isolate: the stance legs take most of the impulse at once, so the hips '
                     'move little and the footholds about them differ little from the ones '
                     'about the feet (the sway-free rule moves the footholds with the hips '
                     'as a whole only beyond '
                     + (f'{settings["correction_threshold_m"] * 100:.0f} cm'
                        if settings.get('correction_threshold_m') is not None
                        else 'its threshold') + '); the '
                     'sustained and the large push move them further (their sections).')
        res = push_resolution(cfg)
        shown = False
        for setting in ('correction_sway_free', 'correction_literal'):
            if setting in table and off and len(table[setting]) == len(off):
                _, verdict = push_sign_test(table, setting, res)
                text += f' {setting.replace("_", " ").capitalize()} vs off: {verdict}.'
                shown = shown or verdict.startswith('holds')
                doubles = [(a['second'], b['second']) for a, b in
                           zip(table[setting], table['correction_off'], strict=True)
                           if a.get('second') and b.get('second')]
                if doubles:
                    text += (f' Two pushes of {cfg["second_push"]["impulse"]:g} N s, '
                             f'{cfg["second_push"]["after_steps"]:g} steps apart: survived '
                             f'{sum(not a["fell"] for a, _ in doubles)} of {len(doubles)} '
                             f'times with it, {sum(not b["fell"] for _, b in doubles)} of '
                             f'{len(doubles)} without.')
        if off and not shown:
            text += (' So these runs do not show the paper\'s benefit of the correction on '
                     'survival; what a push that moves the trunk 10-20 cm over its feet does to '
                     'the support is the large push\'s.' if 'large_push' in results else
                     ' So these runs do not show the paper\'s benefit of the correction; a '
                     'hypothesis they do not test: it needs pushes that move the hips further '
                     'than this stiff controller lets them.')
        page.finding(text)
    elif name == 'large_push':
        off = [r for r in data if r['setting'] == 'correction_off']
        if not data or not off:
            return
        text = f'Large push ({impulse_label(data)}, {len(off)} runs per setting):'
        for setting in dict.fromkeys(r['setting'] for r in data):
            rows = [r for r in data if r['setting'] == setting]
            shift = values(rows, 'trunk_shift_max_m')
            text += (f' {setting.replace("_", " ")} moved the trunk '
                     + (f'{min(shift) * 100:.1f}-{max(shift) * 100:.1f} cm over its feet'
                        if shift else 'by no measured amount')
                     + f' ({sum(r["fell"] for r in rows)} falls);')
        for setting in [n for n in dict.fromkeys(r['setting'] for r in data)
                        if n != 'correction_off']:
            on = [r for r in data if r['setting'] == setting]
            capture, p_capture = compare_paired(on, off, 'capture_margin_p5_m',
                                                ('phase', 'seed'), 'higher')
            feet, p_feet = compare_paired(on, off, 'foot_offset_change_m', ('phase', 'seed'),
                                          'lower')
            text += (f' {setting.replace("_", " ")} vs off: the capture point\'s margin '
                     f'{capture}{p_text(p_capture)}, the feet kept about the hips '
                     f'{feet}{p_text(p_feet)};')
        page.finding(text.rstrip(';') + '.')
    elif name == 'replan_window':
        sel = [r for r in data if r.get('world', 'realistic') == 'realistic']
        windows = sorted({r['window'] for r in sel})

        def window(w: int) -> list[dict]:
            return [r for r in sel if r['window'] == w]

        text = 'Replan window:'
        steady_holds = False
        for key, label in (('steady_error_mps', 'steady velocity error (last '
                            f'{steady_cycles_text(sel)} whole cycles)'),
                           ('linear_error_mps', 'velocity error from 2 s to the end')):
            err = {w: values(window(w), key) for w in windows}
            parts = ', '.join(f'{np.mean(v) * 1000:.1f} mm/s at window {w}'
                              for w, v in err.items() if v)
            verdict, p = compare_paired(window(1), window(2), key, ('seed', 'setpoint'),
                                        'lower')
            if text.endswith('.'):
                label = label[0].upper() + label[1:]
            text += f' {label} {parts}; 1 vs 2: {verdict}{p_text(p)}.'
            steady_holds = steady_holds or (key == 'steady_error_mps'
                                            and verdict.startswith('holds'))
        dev = {w: values(window(w), 'cop_zmp_deviation_rms_m') for w in windows}
        if steady_holds:
            text += (' The paper\'s explanation, which these runs do not isolate (a hypothesis '
                     'here): between re-plans the robot follows a plan made from an older state, '
                     'and the model\'s errors act for 2 or 3 steps instead of 1.')
        margin = {w: values(window(w), 'cop_margin_p5_m') for w in windows}
        for w in [w for w in margin if w != 1]:
            verdict, p = compare_paired(window(1), window(w), 'cop_margin_p5_m',
                                        ('seed', 'setpoint'), 'higher')
            if margin.get(1) and margin[w]:
                text += (f' CoP margin p5 at window 1 vs {w}: {np.mean(margin[1]) * 100:.2f} vs '
                         f'{np.mean(margin[w]) * 100:.2f} cm, {verdict}{p_text(p)}.')
        if all(dev.values()):
            text += (' The measured centre of pressure strays from the planned ZMP by '
                     + ', '.join(f'{np.mean(v) * 100:.2f} cm' for v in dev.values())
                     + ' RMS per window.')
        page.finding(text)
    elif name == 'haptic':
        sel = [r for r in data if r.get('world', 'realistic') == 'realistic']
        flat_on = values([r for r in sel if r['terrain'] == 'flat' and r['haptic']],
                         'pitch_peak_mean_deg')
        flat_off = values([r for r in sel if r['terrain'] == 'flat' and not r['haptic']],
                          'pitch_peak_mean_deg')
        text = 'Haptic touchdown:'
        if flat_on and flat_off:
            verdict, p = compare_paired(
                [r for r in sel if r['terrain'] == 'flat' and not r['haptic']],
                [r for r in sel if r['terrain'] == 'flat' and r['haptic']],
                'pitch_peak_mean_deg', ('seed',), 'higher')
            text += (f' on flat ground the touchdown pitch peaks are {np.mean(flat_on):.2f} deg '
                     f'(on) and {np.mean(flat_off):.2f} deg (off); "off disturbs the pitch": '
                     f'{verdict}{p_text(p)}.')
        for terrain in ('step_down_10cm', 'step_down_5cm', 'rough_4cm'):
            on = values([r for r in sel if r['terrain'] == terrain and r['haptic']],
                        'pitch_peak_max_deg')
            off = values([r for r in sel if r['terrain'] == terrain and not r['haptic']],
                         'pitch_peak_max_deg')
            if on and off:
                text += (f' {terrain.replace("_", " ").capitalize()}: the largest touchdown '
                         f'pitch peak is {np.mean(off):.2f} deg with haptic off and '
                         f'{np.mean(on):.2f} deg with it on.')
        ideal = [r for r in (results.get('ideal_world') or {}).get('haptic', [])
                 if r['terrain'] == 'step_down_10cm' and r['haptic'] and r['fell']]
        if ideal and settings.get('haptic_search_m'):
            text += (f' In the ideal world the haptic robot fell at the 10 cm step: a haptic '
                     f'swing looks for the ground down to {settings["haptic_search_m"] * 100:.0f}'
                     f' cm below its foothold (touchdown_depth '
                     f'{settings["touchdown_depth_m"] * 100:.1f} cm plus haptic_velocity '
                     f'{settings["haptic_velocity_mps"]:.2f} m/s for max_extension '
                     f'{settings["max_extension_s"]:.1f} s) and is then forced into stance in '
                     'the air.')
            crossed = [r.get('crossed') for r in sel
                       if r['terrain'] == 'step_down_10cm' and r['haptic']]
            if crossed and all(crossed):
                text += (' That the realistic robot crossed the same step is then not a margin '
                         'to rely on.')
        page.finding(text)
    elif name == 'velocity_term':
        steady = [r for r in data if r.get('setpoint') != 'step']
        measured = {on: [r for r in forward_speed_rows(steady) if r['velocity_term'] == on]
                    for on in (True, False)}
        on, off = (values(measured[key], 'speed_ratio') for key in (True, False))
        if on and off:
            verdict, p = compare_paired(measured[True], measured[False], 'speed_error',
                                        ('seed', 'setpoint'), 'lower')
            effect = ('the term brings the speed closer to the set-point'
                      if verdict.startswith('holds') else
                      'the term takes the speed further from the set-point'
                      if verdict.startswith('does not hold') else
                      'no difference beyond the spread of the runs')
            page.finding(
                f'Velocity term: with it the robot walks at {np.mean(on) * 100:.1f} % of the '
                f'set-point, without it at {np.mean(off) * 100:.1f} % (the steady state): '
                f'{effect} ({verdict}{p_text(p)}). Both settings take their speed from the '
                f'same footholds, so this '
                f'steady-state figure does not test the paper\'s "faster motion"; the rise '
                f'time after a set-point step (table) does.')
        _trunk_travel_finding(page, steady)
    elif name == 'qp_timing':
        bench = data.get('working_set') or {}
        graph = []
        for key in ('replan_window', 'velocity_term', 'haptic', 'velocity_changes'):
            graph += [r for r in results.get(key) or []
                      if r.get('world', 'realistic') == 'realistic']
        med = values(graph, 'mpc_solve_ms_median')
        if bench.get('mean_ms') and med:
            page.finding(
                f'QP timing: at the paper\'s size the re-planner solves in '
                f'{bench["mean_ms"]:.1f} ms on average alone, '
                f'{against_paper(bench["mean_ms"])}, whose QP took {PAPER_QP_MS:.0f} ms '
                f'(a working-set dual QP that warm-starts '
                f'from the last plan instead of the full QP; the dense QP as the paper posed it '
                f'takes {(data.get("dense") or {}).get("mean_ms", float("nan")):.0f} ms here). '
                f'Inside the graph the per-run median is {np.median(med):.1f} ms: the other '
                'nodes (and here, other work on the machine) share the 2 cores. The realistic '
                'profile applies the paper\'s 58 ms as planning latency regardless.')


def _trunk_travel_finding(page, steady: list[dict]) -> None:
    """The velocity term's effect on how the trunk travels through the swings, from the
    straight walks' ``motion_effects``: computed, or nothing."""
    def mean(on: bool, key: str) -> float | None:
        xs = [r[key] for r in steady if r['velocity_term'] == on and r.get(key) is not None]
        return float(np.mean(xs)) if xs else None
    share_on, share_off = mean(True, 'swing_travel_share'), mean(False, 'swing_travel_share')
    time_on, time_off = mean(True, 'swing_time_share'), mean(False, 'swing_time_share')
    back_on, back_off = mean(True, 'backward_travel_m'), mean(False, 'backward_travel_m')
    stride_on, stride_off = mean(True, 'stride_length_m'), mean(False, 'stride_length_m')
    if None in (share_on, share_off, time_on, time_off, back_on, back_off):
        return
    page.finding(
        f'Velocity term, how the trunk travels (straight walks): a foot swings '
        f'{time_on * 100:.0f} % of the time with the term and {time_off * 100:.0f} % without; '
        f'the trunk makes {share_on * 100:.0f} % of its travel then with the term and '
        f'{share_off * 100:.0f} % without, and moves back {back_on * 1000:.1f} mm against '
        f'{back_off * 1000:.1f} mm over a run'
        + (f'; the strides are {stride_on:.3f} and {stride_off:.3f} m'
           if stride_on is not None and stride_off is not None else '')
        + '. The table\'s paired test says whether the share differs beyond the runs\' spread.')


# -- the pre-registered verdicts -------------------------------------------------------------

# The paper's claim each pre-registered experiment tests, as the verdict tables name it.
CLAIMS = {
    'velocity_changes': 'a velocity change is followed promptly (VI-1)',
    'lateral_push': 'foothold correction helps against pushes (V.B, VI-2)',
    'replan_window': 'replan window 2 tracks worse than 1 (VI)',
    'haptic': 'without haptic touchdown the pitch is disturbed (V.A, VI)',
    'velocity_term': 'the velocity term gives faster motion (eq. 6)',
    'sustained_push': 'foothold correction keeps the support, sustained push (V.B)',
    'large_push': 'foothold correction keeps the support, large push (V.B)',
}


def claim_label(name: str, block: dict | None = None) -> str:
    """How the verdict tables name claim ``name``: the paper's claim, and for a variant
    (``block`` with ``experiment``) where it is tested again: gait, robot, set-point scale."""
    experiment = (block or {}).get('experiment')
    if experiment is None:
        return CLAIMS.get(name, name)
    where = [f'{block["gait"]} gait' if block.get('gait') else '',
             str(block['robot']) if block.get('robot') else '',
             f'set-points x{float(block["setpoint_scale"]):g}'
             if block.get('setpoint_scale') is not None else '']
    return f'{CLAIMS.get(experiment, experiment)}: {", ".join(w for w in where if w)}'


_TEST_NAMES = {'paired_t': 'paired t (mean difference, t interval)',
               'wilcoxon': 'Wilcoxon signed-rank (Hodges-Lehmann estimate and interval)',
               'mcnemar': 'McNemar exact (difference in proportions, Newcombe interval)',
               'fisher': 'Fisher exact (difference in proportions, Newcombe interval)'}


def _num(x: float) -> str:
    return f'{x:.3g}'


def setting_text(by: str, value) -> str:
    """A setting as the tables name it: 'haptic off', 'window 2', 'correction literal'."""
    if isinstance(value, bool):
        return f'{by.replace("_", " ")} {"on" if value else "off"}'
    return (f'{by} {value}' if by == 'window' else str(value)).replace('_', ' ')


def comparison(block: dict) -> str:
    """'window 2 minus window 1, where ...': what a primary block's effect is the sign of."""
    if 'against' in block:
        text = f'runs minus {_num(float(block["against"]))} {block["unit"]}'
    else:
        c = block['compare']
        text = (f'{setting_text(c["by"], c["treatment"])} minus '
                f'{setting_text(c["by"], c["control"])}')
    where = block.get('where') or {}
    if where:
        text += ', ' + ', '.join(f'{k} {v}' for k, v in where.items())
    baseline = block.get('baseline') or {}
    if baseline:
        text += (', each run minus its setting\'s run at '
                 + ', '.join(f'{k} {v}' for k, v in baseline.items())
                 + ' (a difference in differences)')
    shared = block.get('params') or {}
    if shared:
        text += ', both settings with ' + ', '.join(
            f'{node}.{key} {value}' for node, values in shared.items()
            for key, value in values.items())
    return text + (f', paired by {", ".join(block["pair_by"])}' if block.get('pair_by') else '')


def effect_text(verdict: dict) -> str:
    """'0.8 mm/s [0.4, 1.2]': the estimate and its 95 % interval, or '-'."""
    if verdict.get('estimate') is None:
        return '-'
    low, high = verdict['interval']
    return (f'{_num(verdict["estimate"])} [{_num(low)}, {_num(high)}] '
            f'{"share" if verdict["test"] in ("mcnemar", "fisher") else verdict["unit"]}')


def preregistration_section(prereg: dict | None, verdicts: list[dict],
                            pilot_results: dict | None = None) -> list[str]:
    """The page's pre-registration (hash, per claim the primary test and where its n comes
    from) and its verdict table; the quick plan's page says it has none. With a pilot call's
    ``pilot_results``, also what they make of each claim's n (``pilot_section``)."""
    if not prereg or not prereg.get('claims'):
        return ['## Pre-registered verdicts', '',
                'This plan pre-registers no primary tests (only the full plan does): no '
                'verdicts; every comparison below is exploratory.', '']
    lines = ['## Pre-registration', '',
             f'Plan hash **{prereg["hash"]}** (`{prereg["file"]}`, the `primary` blocks: '
             'measure, selection, direction, smallest effect, test, n and seeds; the hash of '
             'the claims\' hashes). Each confirmatory run\'s key holds its claim\'s hash, so a '
             'claim pre-registered again gets runs of its own, and a verdict is refused on '
             'runs of another pre-registration of its claim. One primary test per claim, fixed '
             'before its confirmatory runs; n is the number of confirmatory seeds, set from '
             'the pilot runs of the pilot seeds, which never enter a verdict.', '',
             '| Claim | Primary measure (effect: the sign of) | Direction | Smallest effect '
             '(reason) | Test | n (seeds) | Pilot seeds | Claim hash |',
             '|---|---|---|---|---|---|---|---|']
    hashes = prereg.get('claim_hashes') or {}
    for name, block in prereg['claims'].items():
        lines.append(
            f'| {claim_label(name, block)} | `{block["measure"]}` ({comparison(block)}) | '
            f'{block["direction"]} | {_num(float(block["smallest_effect"]))} {block["unit"]} '
            f'({" ".join(str(block["reason"]).split())}) | {_TEST_NAMES[block["test"]]} | '
            f'{block["n"]} ({", ".join(str(s) for s in block["seeds"])}) | '
            f'{", ".join(str(s) for s in block["pilot_seeds"])} | {hashes.get(name, "-")} |')
    lines += ['', '## Verdicts', '',
              _families(verdicts) + ' **holds**: Holm-significant with the claim\'s sign '
              'and the whole 95 % interval beyond the smallest effect; **opposite**: '
              'Holm-significant with the other sign; **negligible**: the 95 % interval inside '
              '± the smallest effect (an equivalence test: both one-sided tests of TOST at '
              '0.025, so TOST at 0.05); **not resolved**: otherwise. Every other comparison '
              'on this page is '
              'exploratory: unadjusted p, no verdict.', '',
              '| Claim | Measure | Effect (95 % CI) | Units | Holm-adjusted p | Outcome |',
              '|---|---|---|---|---|---|']
    for v in verdicts:
        lines.append(f'| {claim_label(v["claim"], v)} | `{v["measure"]}` | '
                     f'{effect_text(v)} | {v.get("units", "-")} | '
                     + (f'{v["p_holm"]:.2g}' if v.get('p_holm') is not None else '-')
                     + f' | {v["outcome"]} |')
    if pilot_results is not None:
        lines += ['', *pilot_section(pilot_sizes(prereg, pilot_results))]
    return [*lines, '']


def _families(verdicts: list[dict]) -> str:
    """The sentence that says which tests are corrected together (``stats.primary_verdicts``)."""
    again = sum(is_variant(v) for v in verdicts)
    paper = len(verdicts) - again
    if not again:
        return (f'One family: the {paper} claims\' primary tests, Holm\'s step-down '
                'correction over all of them at α = 0.05 (a claim that cannot be judged counts '
                'with p = 1).')
    return (f'Two families, each with Holm\'s step-down correction over all of its tests at '
            f'α = 0.05 (a claim that cannot be judged counts with p = 1): the paper\'s {paper} '
            f'claims on HyQ\'s crawl, and the {again} claims tested again on another robot or '
            'gait (named so in the tables), so that a replication never makes the correction '
            'of the paper\'s claims stricter.')


def pilot_section(sizes: list[dict]) -> list[str]:
    """A pilot call's section: per claim, what its pilot runs say of its n
    (``stats.pilot_sizes``)."""
    if not sizes:
        return []
    lines = ['## Sample sizes from the pilot', '',
             'Per pre-registered claim, its primary sample on the pilot seeds: the mean and '
             'spread of the differences, and the confirmatory seeds a paired t-test needs to '
             f'resolve the smallest effect that matters (not the pilot\'s own mean) with '
             f'{POWER:.0%} power at Holm\'s strictest level, α = {P_VALUE} / the number of '
             'claims of its family (`stats.pairs_to_resolve`; `α` below). The plan\'s n is '
             'set from this before its confirmatory runs.', '',
             '| Claim | Measure | Pilot pairs (seeds) | Mean difference | SD | Smallest effect '
             '| α | Seeds needed | n in the plan |', '|---|---|---|---|---|---|---|---|---|']
    for row in sizes:
        if row.get('pairs') is None:
            lines.append(f'| {claim_label(row["claim"], row)} | `{row["measure"]}` | '
                         f'- | - | - | {_num(row["smallest_effect"])} {row["unit"]} | '
                         f'{row["alpha"]:.3g} | {row.get("reason", "-")} | {row["n"]} |')
            continue
        needed = row['seeds_needed']
        lines.append(
            f'| {claim_label(row["claim"], row)} | `{row["measure"]}` | {row["pairs"]} '
            f'({row["pilot_seeds"]}) | {_num(row["mean"])} | {_num(row["sd"])} | '
            f'{_num(row["smallest_effect"])} {row["unit"]} | {row["alpha"]:.3g} | '
            f'{needed if needed is not None else "more than the largest n tried"} | '
            f'{row["n"]} |')
    return [*lines, '']


def page_verdicts(results: dict, meta: dict) -> list[dict]:
    """The pre-registered claims' verdicts of a call (``meta['preregistration']``, from
    plan.preregistration): none without one."""
    prereg = meta.get('preregistration')
    return primary_verdicts(prereg, results) if prereg and prereg.get('claims') else []


README_BEGIN, README_END = '<!-- results:begin -->', '<!-- results:end -->'


def replace_block(readme: Path, begin: str, end: str, block: str) -> bool:
    """Put ``block`` between the markers ``begin`` and ``end`` of ``readme`` (a generated part
    of a hand-written file); False (nothing written) without both markers."""
    text = readme.read_text() if readme.is_file() else ''
    if begin not in text or end not in text:
        return False
    head, rest = text.split(begin, 1)
    tail = rest.split(end, 1)[1]
    readme.write_text(head + begin + '\n' + block + end + tail)
    return True


def fill_readme(readme: Path, results: dict, meta: dict) -> bool:
    """The verdict table (``findings.readme_table``) between the results markers of ``readme``,
    linking the page; False (nothing written) without the markers or without verdicts."""
    verdicts = page_verdicts(results, meta)
    if not verdicts:
        return False
    block = ('The pre-registered verdicts of [docs/results.md](docs/results.md) (generated; '
             'the page names the revision, plan and runs they come from):\n\n'
             + readme_table(verdicts))
    return replace_block(readme, README_BEGIN, README_END, block)


def readme_table(verdicts: list[dict]) -> str:
    """The short table of the pre-registered verdicts (claim, verdict, effect with its 95 %
    interval) for README.md's results block."""
    lines = ['| Claim | Verdict | Effect (95 % CI) |', '|---|---|---|']
    lines += [f'| {claim_label(v["claim"], v)} | {v["outcome"]} | {effect_text(v)} |'
              for v in verdicts]
    return '\n'.join(lines) + '\n'
