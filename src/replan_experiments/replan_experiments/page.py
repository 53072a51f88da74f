"""The results page of ``scripts/experiments.sh``: statistics, verdicts and plots from the runs.

Every figure on the page comes from the runs' metrics (``claims.py`` collects them). Verdicts
are given only to the pre-registered primary tests (``config/experiments.yaml``, ``primary``;
``stats.primary_verdicts``: Holm's correction over all of them, effects with 95 % intervals,
holds / opposite / negligible / not resolved), and only on runs of the plan with today's hash.
Every other comparison is exploratory: its test (paired t over the pairs where the runs pair,
``compare_paired``, else Welch's; a sign test for the impulse pushes) with an unadjusted p,
described by its direction (``stats.exploratory``), no verdict.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from replan_experiments.findings import findings, page_verdicts, preregistration_section
from replan_experiments.page_plots import plot_haptic, plot_push, plot_windows
from replan_experiments.page_push import large_push_section, sustained_push_section
from replan_experiments.page_variants import variant_sections
from replan_experiments.stats import (
    P_VALUE,
    PAPER_QP_MS,
    PAPER_QP_STD_MS,
    POWER,
    PROMPT_BAND,
    against_paper,
    compare_paired,
    cycles_to_within,
    exploratory,
    forward_speed_rows,
    p_text,
    prompt_by_cycles,
    push_resolution,
    push_sign_test,
    sign_test,
    spread,
    steady_cycles_text,
    steady_error,
    values,
)

_PAPER_QP = f'{PAPER_QP_MS:.0f} ± {PAPER_QP_STD_MS:.0f} ms'


# -- the page --------------------------------------------------------------------------------


def _bag_gaps(gaps: dict | None) -> list[str]:
    """The header's paragraph on how complete the runs' bags are (``runs.bag_gaps``)."""
    if not gaps or not gaps.get('runs'):
        return []
    if not gaps['short']:
        text = (f'Every measure is read from the run\'s bag; the bags of all {gaps["runs"]} '
                'completed runs that did not fall hold every tick of the estimate and the '
                'truth.')
    else:
        text = (f'Every measure is read from the run\'s bag, which holds what DDS delivered '
                f'to the recorder: the bags of {gaps["short"]} of {gaps["runs"]} completed runs '
                'that did not fall miss some ticks of the estimate (`/odom`) or the truth, at '
                f'most {gaps["most_missing"]} of a run\'s {gaps["ticks"]}; their measures come '
                'from the ticks recorded (a cause of small differences between two runs of one '
                'scenario that are otherwise the same to the bit).')
    if gaps.get('counted'):
        text += (f' By the recorder\'s own count (published against written, '
                 f'docs/recording.md), {gaps["counted"] - gaps["incomplete"]} of '
                 f'{gaps["counted"]} counted bags are complete.')
    return [text, '']


class Page:
    def __init__(self, path: Path) -> None:
        self.path = path
        self.plot_dir = path.parent / (path.stem + '_plots')
        self.rows: list[tuple] = []
        self.sections: list[str] = []
        self.findings: list[str] = []

    def row(self, experiment: str, setting: str, metric: str, value: str, runs: int,
            claim: str, verdict: str) -> None:
        self.rows.append((experiment, setting, metric, value, str(runs), claim,
                          exploratory(verdict)))

    def finding(self, text: str) -> None:
        """One bullet of the exploratory findings (numbers from the runs)."""
        self.findings.append('- ' + exploratory(' '.join(text.split())))

    def section(self, text: str) -> None:
        self.sections.append(text.strip() + '\n')

    def plot(self, name: str, draw) -> str:
        """Draw a figure with ``draw(plt)`` into the plot folder; its link for the page."""
        import matplotlib
        matplotlib.use('Agg')
        import matplotlib.pyplot as plt
        self.plot_dir.mkdir(parents=True, exist_ok=True)
        fig = draw(plt)
        fig.tight_layout()
        fig.savefig(self.plot_dir / name, dpi=90)
        plt.close(fig)
        return f'{self.plot_dir.name}/{name}'


def write_page(path: Path, results: dict, meta: dict) -> None:
    """Write the results page ``path`` (and its plots) from ``results`` (experiments.run_all)
    and ``meta`` (command, machine, revision, date, wall time, runs, failures, the plan's
    ``preregistration``)."""
    page = Page(path)
    for name, writer in (('velocity_changes', _velocity_changes),
                         ('lateral_push', _lateral_push), ('replan_window', _replan_window),
                         ('haptic', _haptic), ('velocity_term', _velocity_term),
                         ('sustained_push', sustained_push_section),
                         ('large_push', large_push_section),
                         ('qp_timing', _qp_timing), ('fastest_crawl', _fastest_crawl),
                         ('ideal_world', _ideal_world)):
        if name in results:
            writer(page, results[name], results)
            findings(page, name, results[name], results)
    variant_sections(page, results, meta)
    head = [
        '# Results: the paper\'s claims on the realistic robot',
        '',
        f'Generated by `{meta["command"]}` on {meta["date"]} ({meta["machine"]}, revision '
        f'{meta["revision"]}): {meta["runs"]} runs, {meta.get("run_time_min", "?")} min of '
        f'graph time in all (this call: {meta["wall_time_min"]} min; runs made by an earlier '
        'call with the same scenario and code, or shared between experiments, are read; '
        f'code fingerprint {meta.get("code", "?")}: a change to the core, the nodes or the '
        'configuration makes every run again). Do not edit '
        'by hand: every number, verdict and plot below comes from the runs '
        '(`replan_experiments/`: `claims.py` the experiments, `page.py` this page, '
        '`stats.py` its statistics, `findings.py` its findings; the plan is '
        '`config/experiments.yaml`).',
        '',
    ]
    if meta.get('robot'):
        head += [f'**Robot {meta["robot"]}** (`--robot`): every scenario runs it, the push '
                 'phases follow its crawl cycle and the impulses are read against its mass; '
                 'the plan\'s set-points, impulses and terrains are the plan file\'s (HyQ\'s in '
                 '`config/experiments.yaml`), not scaled to it.', '']
    if meta.get('pilot'):
        head += ['**Pilot run** (`--pilot`): each pre-registered claim on its pilot seeds, the '
                 'runs that set its n. Pilot runs never enter a verdict.', '']
    if meta.get('quick'):
        head += ['**Quick run** (`--quick`): one short run per kind, to check that the page is '
                 'produced. Its verdicts rest on too few runs to mean anything.', '']
    head += [
        'All runs are on the realistic profile (estimated state, sensor noise, actuator '
        'dynamics, 58 ms planning latency, a model that differs from the robot; '
        '`docs/realism.md`) unless the setting says *ideal*. Metrics come from the simulator\'s '
        'truth (`/ground_truth/*`), not from what the robot estimated. "Spread" is the standard '
        'deviation over the runs, with the smallest and largest value.',
        '',
        *_bag_gaps(meta.get('bag_gaps')),
        *preregistration_section(meta.get('preregistration'), page_verdicts(results, meta),
                                 results if meta.get('pilot') else None),
        '## Every measure (exploratory)',
        '',
        'The comparisons of this table and of the findings are exploratory: no verdict, an '
        'unadjusted p. "The claimed direction" when the difference has the paper\'s sign and '
        'a t-test puts it beyond the spread of the runs: the paired one where the runs pair '
        '(the same seed and set-point in both settings, "n pairs"), else Welch\'s '
        f'(p < {P_VALUE}); "the other direction" the same with the other sign; "undecided" '
        'when the runs cannot tell the settings apart, and then, for paired runs, how many '
        'pairs would resolve a difference as large as the runs\' mean one at their spread '
        f'({POWER:.0%} power of the paired t-test; an estimate: if the true difference is '
        'smaller, more); "met" and "not met" for a target every run must reach.',
        '',
        '| Experiment | Setting | Metric | Mean ± spread (min to max) | Runs | Paper\'s claim '
        '| Exploratory comparison |',
        '|---|---|---|---|---|---|---|',
    ]
    head += ['| ' + ' | '.join(r) + ' |' for r in page.rows]
    if page.findings:
        head += ['', '## What the runs show, and why (exploratory)', '',
                 'Generated from the same runs, without verdicts (those are the pre-registered '
                 'table\'s); where a cause is a hypothesis the runs do not isolate, it says so.',
                 '', *page.findings]
    if meta.get('failures'):
        head += ['', f'{len(meta["failures"])} runs failed to produce metrics (left out above):']
        head += [f'- `{f}`' for f in meta['failures']]
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text('\n'.join(head) + '\n\n' + '\n'.join(page.sections))


# -- one writer per experiment ---------------------------------------------------------------


def _velocity_changes(page: Page, rows: list[dict], _all) -> None:
    prompt = rows[0].get('prompt_steps', 4) if rows else 4
    claim = 'a velocity change is followed promptly'
    lines = ['## Velocity changes', '',
             'The set-point changes at 8 s; the figure is the time and the touchdowns until '
             'the velocity averaged over the last second is within 10 % of the new set-point '
             '(`settle_time_s`, `settle_steps` in each run\'s metrics). The paper gives no '
             f'figure for "promptly"; this page takes one crawl cycle ({prompt} steps). A '
             'steady offset of the achieved velocity from the set-point alone can keep a run '
             'out of the 10 % band; so the page also gives the time until the velocity has '
             'covered 90 % of the change it actually made (from the velocity achieved before '
             'the change to the steady state after it, `rise_time_s`, `rise_steps`). The '
             'steady state is the mean velocity over the last whole crawl cycles of the run '
             '(`achieved_steady`, `steady_cycles`): after a change the trunk takes a few '
             'cycles to get to the new speed, so an average from 2 s after the change on '
             '(`achieved`) keeps part of that. Each run\'s `cycle_velocities` give the mean '
             'velocity of every whole cycle after the change; the page counts the cycles '
             'before every later one is within the tolerance of the set-point.', '',
             'A crawl that sways by design (the MPC\'s position term with `mpc.position_sway`, '
             'docs/mpc.md) moves its trunk along and across within each cycle, and a 1 s '
             'average keeps part of that motion: so the page also judges "promptly" on '
             'whole-cycle means, '
             'the same 10 % band reached from the second whole cycle after the change on '
             f'(within one crawl cycle, {prompt} steps, of the first touchdown after it). That '
             'the sway is what keeps the 1 s averages out of the band is a hypothesis: this '
             'page does not measure the sway.', '']
    for scenario in sorted({r['scenario'] for r in rows}):
        for world in sorted({r['world'] for r in rows if r['scenario'] == scenario}):
            sel = [r for r in rows if r['scenario'] == scenario and r['world'] == world]
            steps = values(sel, 'settle_steps')
            settled = len(steps)
            falls = sum(r['fell'] for r in sel)
            prompt_runs = sum(1 for s in steps if s <= prompt)
            verdict = ('met' if prompt_runs == len(sel) and not falls else
                       f'not met ({len(sel) - prompt_runs} of {len(sel)} runs slower or '
                       'never within 10 %)')
            setting = scenario.removeprefix('exp_').replace('_', ' ') + (
                ' (ideal)' if world == 'ideal' else '')
            page.row('velocity change', setting, 'touchdowns until within 10 %',
                     spread(steps, 1), len(sel), claim, verdict)
            page.row('velocity change', setting, 'seconds until within 10 %',
                     spread(values(sel, 'settle_time_s'), 2), len(sel), '', '')
            _whole_cycle_row(page, setting, sel, claim, falls)
            rise = values(sel, 'rise_steps')
            prompt_rise = sum(1 for s in rise if s <= prompt)
            page.row('velocity change', setting,
                     'touchdowns until 90 % of the achieved change',
                     spread(rise, 1), len(sel), claim + ' (apart from the steady offset)',
                     'met' if prompt_rise == len(sel) and not falls else
                     f'not met ({len(sel) - prompt_rise} of {len(sel)} runs slower)')
            page.row('velocity change', setting, 'seconds until 90 % of the achieved change',
                     spread(values(sel, 'rise_time_s'), 2), len(sel), '', '')
            _steady_rows(page, setting, sel)
            achieved = [r['achieved'] for r in sel if r.get('achieved')]
            whole = [r for r in sel if r.get('achieved_cycles') and r.get('cycles')]
            if achieved:
                mean = np.mean(achieved, axis=0)
                lines.append(f'- {setting}: new set-point {tuple(sel[0]["commanded"])}, '
                             f'achieved (mean over the runs, after 2 s) '
                             f'({mean[0]:.3f}, {mean[1]:.3f}, {mean[2]:.3f})')
                if whole:
                    cycles = [r['cycles'] for r in whole]
                    mean = np.mean([r['achieved_cycles'] for r in whole], axis=0)
                    lines[-1] += (f', over the whole crawl cycles after 2 s ({min(cycles)} to '
                                  f'{max(cycles)} cycles, {len(whole)} runs) '
                                  f'({mean[0]:.3f}, {mean[1]:.3f}, {mean[2]:.3f})')
                lines[-1] += f'; {settled} of {len(sel)} runs within 10 %, {falls} falls.'
    page.section('\n'.join(lines))


def _whole_cycle_row(page: Page, setting: str, sel: list[dict], claim: str,
                     falls: int) -> None:
    """Whole cycles after the change until every later cycle's mean velocity is within 10 %
    of the set-point: prompt when that holds from the second whole cycle on (one cycle for the
    change), so the within-cycle motion of a crawl does not count."""
    known, prompt = prompt_by_cycles(sel)
    page.row('velocity change', setting,
             f'whole cycles until every later one is within {PROMPT_BAND * 100:.0f} %',
             spread(known, 1) + (f'; {len(sel) - len(known)} of {len(sel)} runs never'
                                 if len(known) < len(sel) else ''), len(sel),
             claim + ' (whole-cycle means)',
             'met' if prompt == len(sel) and not falls else
             f'not met ({len(sel) - prompt} of {len(sel)} runs later or never)')


def _steady_rows(page: Page, setting: str, sel: list[dict]) -> None:
    """The steady speed over the last whole cycles as a share of the set-point, and the whole
    cycles after the change until every later one is within the tolerance (3 %)."""
    steady = [r for r in sel if r.get('achieved_steady') and any(r['commanded'][:2])]
    if not steady:
        return
    tolerance = float(steady[0]['steady_tolerance'])
    last = steady[0].get('steady_cycles')
    # The planar velocity error (speed and direction) over the planar set-point.
    error = [steady_error(r) / math.hypot(*r['commanded'][:2]) for r in steady]
    within = sum(1 for e in error if e <= tolerance)
    page.row('velocity change', setting,
             f'steady velocity error / set-point speed (last {last} cycles), %',
             spread(error, 1, scale=100.0), len(steady),
             f'walks at the set-point, within {tolerance * 100:.0f} % (beyond the paper)',
             'met' if within == len(steady) else
             f'not met ({len(steady) - within} of {len(steady)} runs off by more)')
    counts = [cycles_to_within(r, tolerance) for r in steady]
    known = [c for c in counts if c is not None]
    page.row('velocity change', setting,
             f'whole cycles until every later one is within {tolerance * 100:.0f} %',
             spread(known, 1) + (f'; {len(counts) - len(known)} of {len(counts)} runs never'
                                 if len(known) < len(counts) else ''), len(steady), '', '')


def _lateral_push(page: Page, data: dict, _all) -> None:
    cfg = data['config']
    table = data['settings']
    ideal = data.get('world') == 'ideal'
    suffix = ' (ideal)' if ideal else ''
    target = 30.0
    res = push_resolution(cfg)
    seeds = cfg.get('seeds') or [cfg.get('seed')]
    second = cfg.get('second_push')
    lines = [f'## Lateral pushes and foothold correction{suffix}', '',
             f'Walking at 0.1 m/s, one push to the left of {cfg["push_duration"]} s at '
             f'{cfg["phases"]} phases of the crawl cycle ({cfg["cycle"]} s from '
             f'{cfg["first_push"]} s), each with the sim noise seeds {seeds} (the same seeds '
             'in every setting: the runs pair by phase and seed). Per phase and seed, the '
             f'largest impulse survived (no fall within {cfg["after_push"]} s of the push) by '
             f'bisection: first {cfg["first_impulse"]} N s, then halving towards '
             f'{cfg["max_impulse"]} N s, {cfg["probes"]} runs (resolution {res:.0f} N s; the '
             'figure is a lower bound, and where no probe fell it is censored: the robot '
             'survived the most that was tried). The degeneration of the support polygon: the '
             'least inradius of the three-foot support triangles over the 3 steps after the '
             f'{cfg["first_impulse"]} N s push, divided by the same over the 3 steps before '
             'it.' + (f' Second push: two pushes of {second["impulse"]:g} N s each, the '
                      f'second {second["after_steps"]:g} steps after the first, at the same '
                      'phases and seeds.' if second else ''), '']
    for name, entries in table.items():
        label = name.replace('_', ' ') + suffix
        survived = [p['survived_ns'] for p in entries]
        ratios = [p['first']['support_inradius_min_m'] / p['first']['support_inradius_before_m']
                  for p in entries if p.get('first') and not p['first']['fell']
                  and p['first'].get('support_inradius_min_m')
                  and p['first'].get('support_inradius_before_m')]
        on = name != 'correction_off'
        verdict = ''
        if on:
            verdict = ('target met' if survived and min(survived) >= target else
                       f'target not met (min {min(survived):.0f} < {target:.0f} N s)'
                       if survived else '-')
        page.row('lateral push', label, 'impulse survived, min over phases and seeds (N s)',
                 f'{min(survived):.1f}' if survived else '-', len(survived),
                 f'pushes absorbed; target ≥ {target:.0f} N s at every phase', verdict)
        censored = sum(1 for p in entries if p['fallen_ns'] is None)
        page.row('lateral push', label, 'impulse survived, over phases and seeds (N s)',
                 spread(survived, 1) + (f'; {censored} censored' if censored else ''),
                 len(survived), '', '')
        dv = [p['first']['velocity_change_mps'] for p in entries if p.get('first')
              and p['first'].get('velocity_change_mps') is not None]
        mass = data.get('robot_mass_kg')
        page.row('lateral push', label,
                 f'base velocity left by a {cfg["first_impulse"]:.0f} N s push (m/s)',
                 spread(dv, 3), len(dv),
                 f'a free body: {cfg["first_impulse"] / mass:.3f} m/s' if mass else '', '')
        page.row('lateral push', label,
                 f'support inradius after / before a {cfg["first_impulse"]:.0f} N s push',
                 spread(ratios, 2), len(ratios),
                 'correction prevents the degeneration' if on else '', '')
        doubles = [p['second'] for p in entries if p.get('second')]
        if doubles:
            page.row('lateral push', label,
                     f'two pushes of {second["impulse"]:g} N s survived',
                     f'{sum(not d["fell"] for d in doubles)} of {len(doubles)}', len(doubles),
                     'the support after a push still holds a second one', '')
        for k in sorted({p['phase'] for p in entries}):
            lines.append(f'- {label}, phase {k}: ' + ', '.join(
                f'{p["survived_ns"]:.1f}' + ('' if p['fallen_ns'] is not None else '+')
                for p in entries if p['phase'] == k) + ' N s over the seeds (+: censored).')
    if 'correction_off' in table:
        off = table['correction_off']
        for name, entries in table.items():
            if name == 'correction_off' or len(entries) != len(off):
                continue
            label = f'{name.replace("_", " ")} vs off{suffix}'
            diff, verdict = push_sign_test(table, name, res)
            page.row('lateral push', label,
                     'impulse survived, on minus off, per phase and seed (N s)', spread(diff, 1),
                     len(diff), 'foothold correction helps against pushes', verdict)
            pairs = [(a['second'], b['second']) for a, b in zip(entries, off, strict=True)
                     if a.get('second') and b.get('second')]
            if pairs:
                both = [float(b['fell']) - float(a['fell']) for a, b in pairs]   # +1: on only
                page.row('lateral push', label, 'two pushes: survived with on, not with off '
                         '(+1) or the reverse (-1), per phase and seed', spread(both, 2),
                         len(both), 'foothold correction helps against a second push',
                         sign_test(both, None, unit='pairs'))
        link = page.plot('push_impulse.png' if not ideal else 'push_impulse_ideal.png',
                         lambda plt: plot_push(plt, table))
        lines += ['', f'![largest impulse survived per phase]({link})']
    page.section('\n'.join(lines))


def _replan_window(page: Page, rows: list[dict], _all, world: str = 'realistic') -> None:
    sel = [r for r in rows if r.get('world', 'realistic') == world]
    windows = sorted({r['window'] for r in sel})
    suffix = ' (ideal)' if world == 'ideal' else ''
    claim = 'window 2 worse than 1 (model errors grow)'
    for w in windows:
        runs = [r for r in sel if r['window'] == w]
        falls = sum(r['fell'] for r in runs)
        page.row('replan window', f'{w} touchdown{"s" if w > 1 else ""}{suffix}',
                 'steady velocity error (m/s)', spread(values(runs, 'steady_error_mps'), 4),
                 len(runs), '', f'{falls} falls')
        page.row('replan window', f'{w} touchdown{"s" if w > 1 else ""}{suffix}',
                 'velocity error from 2 s (m/s)', spread(values(runs, 'linear_error_mps'), 4),
                 len(runs), '', '')
        page.row('replan window', f'{w} touchdown{"s" if w > 1 else ""}{suffix}',
                 'measured CoP margin, 5th percentile (cm)',
                 spread(values(runs, 'cop_margin_p5_m'), 2, 100.0), len(runs), '', '')
        page.row('replan window', f'{w} touchdown{"s" if w > 1 else ""}{suffix}',
                 'measured CoP minus planned ZMP, RMS (cm)',
                 spread(values(runs, 'cop_zmp_deviation_rms_m'), 2, 100.0), len(runs), '', '')
    lines = [f'## Replan window{suffix}', '',
             'Straight walks at ' + ', '.join(f'{v:.2f}' for v in sorted(
                 {r['setpoint'] for r in sel})) + ' m/s, seeds '
             + ', '.join(str(s) for s in sorted({r['seed'] for r in sel}))
             + '. Steady velocity error: |achieved - commanded| with the achieved velocity '
               f'the mean over the last {steady_cycles_text(sel)} whole crawl cycles (each from a '
               'true touchdown of a '
               'leg to its next, as every steady speed of this page). Velocity error from 2 s: '
               'the same with the mean velocity from 2 s after the set-point to the end of the '
               'run, the measure of earlier pages: it holds the end of the walk-off and lets a '
               'slow start cancel a fast end (the first whole cycle walked '
             + _first_cycle_shares(sel, windows) + '). CoP margin: the measured centre of '
               'pressure inside the polygon of the feet in contact (truth).', '']
    for w in windows[1:]:
        for key, label, digits, scale in (
                ('steady_error_mps', 'steady velocity error (m/s)', 4, 1.0),
                ('linear_error_mps', 'velocity error from 2 s (m/s)', 4, 1.0),
                ('cop_margin_p5_m', 'CoP margin p5 (cm)', 2, 100.0),
                ('cop_zmp_deviation_rms_m', 'CoP minus planned ZMP, RMS (cm)', 2, 100.0)):
            one_rows = [r for r in sel if r['window'] == 1]
            other_rows = [r for r in sel if r['window'] == w]
            one, other = values(one_rows, key), values(other_rows, key)
            verdict, p = compare_paired(one_rows, other_rows, key, ('seed', 'setpoint'),
                                        'higher' if key == 'cop_margin_p5_m' else 'lower')
            page.row('replan window', f'1 vs {w}{suffix}', label,
                     f'{np.mean(one) * scale:.{digits}f} vs {np.mean(other) * scale:.{digits}f}'
                     if one and other else '-', len(one) + len(other), claim, verdict + p_text(p))
    if world == 'realistic' and len(windows) > 1:
        link = page.plot('replan_window.png', lambda plt: plot_windows(plt, sel, windows))
        lines.append(f'![velocity error and CoP margin per replan window]({link})')
    page.section('\n'.join(lines))


def _first_cycle_shares(rows: list[dict], windows: list[int]) -> str:
    """'95 %, 82 % of the set-point at windows 1, 2': the mean speed of each run's first whole
    crawl cycle after the set-point over the set-point, per window."""
    shares = {}
    for w in windows:
        runs = [r for r in rows if r['window'] == w and r.get('cycle_velocities')
                and r.get('commanded') and any(r['commanded'][:2])]
        if runs:
            shares[w] = np.mean([math.hypot(*r['cycle_velocities'][0]['velocity'][:2])
                                 / math.hypot(*r['commanded'][:2]) for r in runs])
    if not shares:
        return 'unmeasured'
    return (', '.join(f'{v * 100:.0f} %' for v in shares.values()) + ' of the set-point at '
            'window' + ('s ' if len(shares) > 1 else ' ') + ', '.join(str(w) for w in shares))


def _haptic(page: Page, rows: list[dict], results, world: str = 'realistic') -> None:
    sel = [r for r in rows if r.get('world', 'realistic') == world]
    suffix = ' (ideal)' if world == 'ideal' else ''
    settings = results.get('settings') or {}
    depth = settings.get('touchdown_depth_m')
    search = settings.get('haptic_search_m')
    aims = (f'aims {depth * 100:.1f} cm below the foothold and, past the planned touchdown, '
            f'searches down to {search * 100:.0f} cm below it' if depth is not None
            and search is not None else 'aims below the foothold and searches')
    lines = [f'## Haptic touchdown on and off{suffix}', '',
             'Walking at 0.15 m/s onto ground the planner does not know. Haptic on: the swing '
             f'{aims}; it ends at the sensed contact. Haptic off: the swing aims at the '
             'foothold itself and ends at the planned time, touching the ground or not (the '
             'foot may load late, or early where the ground is higher). Pitch peak: the '
             'peak-to-peak pitch in [-0.1, +0.3] s around each touchdown; timing: the true '
             'contact minus the planned touchdown, the mean over a run\'s steps (negative: '
             'before the plan; a haptic swing meets the ground early by design, docs/gait.md, '
             '"When a haptic foot touches down"). Crossed: no fall and the base 0.5 m past the '
             'feature before the run ends.', '']
    for terrain in dict.fromkeys(r['terrain'] for r in sel):
        on = [r for r in sel if r['terrain'] == terrain and r['haptic']]
        off = [r for r in sel if r['terrain'] == terrain and not r['haptic']]
        for mode, runs in (('on', on), ('off', off)):
            falls = sum(r['fell'] for r in runs)
            crossed = [r['crossed'] for r in runs if r.get('crossed') is not None]
            note = f'{falls} falls' + (f', crossed {sum(crossed)} of {len(crossed)}'
                                       if crossed else '')
            target = ''
            if mode == 'on' and terrain in ('step_down_10cm', 'rough_4cm') and world == 'realistic':
                target = ('target met: ' if crossed and all(crossed) else 'target not met: ') + note
            page.row('haptic', f'{terrain.replace("_", " ")}, {mode}{suffix}',
                     'touchdown pitch peak (deg)', spread(values(runs, 'pitch_peak_mean_deg'), 2),
                     len(runs), 'crossed without a fall' if target else '', target or note)
            page.row('haptic', f'{terrain.replace("_", " ")}, {mode}{suffix}',
                     'largest touchdown pitch peak (deg)',
                     spread(values(runs, 'pitch_peak_max_deg'), 2), len(runs), '', '')
            page.row('haptic', f'{terrain.replace("_", " ")}, {mode}{suffix}',
                     'touchdown timing error, mean (ms; negative: early)', spread(values(
                         runs, 'touchdown_timing_mean_s'), 1, 1000.0), len(runs), '', '')
        verdict, p = compare_paired(off, on, 'pitch_peak_mean_deg', ('seed',), 'higher')
        big_off, big_on = values(off, 'pitch_peak_max_deg'), values(on, 'pitch_peak_max_deg')
        verdict_max, p_max = compare_paired(off, on, 'pitch_peak_max_deg', ('seed',), 'higher')
        page.row('haptic', f'{terrain.replace("_", " ")}: off vs on{suffix}',
                 'largest touchdown pitch peak (deg)',
                 f'{np.mean(big_off):.2f} vs {np.mean(big_on):.2f}' if big_off and big_on
                 else '-', len(on) + len(off), 'haptic off disturbs the pitch',
                 verdict_max + p_text(p_max))
        page.row('haptic', f'{terrain.replace("_", " ")}: off vs on{suffix}',
                 'touchdown pitch peak (deg)',
                 f'{np.mean(values(off, "pitch_peak_mean_deg")):.2f} vs '
                 f'{np.mean(values(on, "pitch_peak_mean_deg")):.2f}'
                 if values(off, 'pitch_peak_mean_deg') and values(on, 'pitch_peak_mean_deg')
                 else '-', len(on) + len(off), 'haptic off disturbs the pitch', verdict + p_text(p))
    if world == 'realistic' and sel:
        link = page.plot('haptic_pitch.png', lambda plt: plot_haptic(plt, sel))
        lines.append(f'![touchdown pitch peaks, haptic on and off]({link})')
    page.section('\n'.join(lines))


def _velocity_term(page: Page, rows: list[dict], _all) -> None:
    steady = [r for r in rows if r.get('setpoint') != 'step']
    steps = [r for r in rows if r.get('setpoint') == 'step']
    # The steady speed of each straight walk (its last whole crawl cycles) against its
    # set-point, once per run.
    measured = {on: [r for r in forward_speed_rows(steady) if r['velocity_term'] == on]
                for on in (True, False)}
    for on in (True, False):
        runs = [r for r in steady if r['velocity_term'] == on]
        page.row('velocity term', 'on (weight 300)' if on else 'off (weight 0)',
                 'achieved / commanded speed', spread(values(measured[on], 'speed_ratio'), 3),
                 len(runs), '', f'{sum(r["fell"] for r in runs)} falls')
    err_on, err_off = (values(measured[on], 'speed_error') for on in (True, False))
    verdict, p = compare_paired(measured[True], measured[False], 'speed_error',
                                ('seed', 'setpoint'), 'lower')
    page.row('velocity term', 'on vs off', '|1 - achieved / commanded|',
             f'{np.mean(err_on):.3f} vs {np.mean(err_off):.3f}' if err_on and err_off else '-',
             len(err_on) + len(err_off), 'the velocity term tracks the set-point',
             verdict + p_text(p))
    _trunk_travel(page, steady, ('seed', 'setpoint'), 'straight walks')
    text = ('## Velocity-tracking term\n\nThe same runs with the MPC\'s velocity weight at its '
            'default and at 0 (eq. 6 without the optional term): straight walks (the steady '
            f'speed: the mean over the last {steady_cycles_text(steady)} whole crawl cycles)')
    if steps:
        on = [r for r in steps if r['velocity_term']]
        off = [r for r in steps if not r['velocity_term']]
        for label, runs in (('on', on), ('off', off)):
            page.row('velocity term', f'set-point step, {label}',
                     'seconds until 90 % of the achieved change',
                     spread(values(runs, 'rise_time_s'), 2), len(runs), '',
                     f'{sum(r["fell"] for r in runs)} falls')
            page.row('velocity term', f'set-point step, {label}', 'step period, median (s)',
                     spread(values(runs, 'step_period_s'), 3), len(runs), '', '')
        verdict, p = compare_paired(on, off, 'rise_time_s', ('seed',), 'lower')
        rise_on, rise_off = values(on, 'rise_time_s'), values(off, 'rise_time_s')
        page.row('velocity term', 'set-point step: on vs off',
                 'seconds until 90 % of the achieved change',
                 f'{np.mean(rise_on):.2f} vs {np.mean(rise_off):.2f}' if rise_on and rise_off
                 else '-', len(on) + len(off), 'the velocity term gives faster motion',
                 verdict + p_text(p))
        _trunk_travel(page, steps, ('seed',), 'set-point step')
        text += (' and the set-point step of the velocity-change experiment (how promptly a '
                 'new set-point is reached, the paper\'s "faster motion"), paired by seed')
    page.section(text + '. How the trunk travels between the footholds is read from each '
                 'run\'s bag (`replan_experiments/motion_effects.py`), on the truth, along '
                 'the set-point: the share of the travel made while a foot is off the ground '
                 '(against the share of the time a foot is: a trunk that kept its speed through '
                 'the swings would make that share), the travel backwards, and the stride (the '
                 'distance between successive touchdowns of a foot); in a straight walk from '
                 'its `motion_after` s to its end, in a step from the change to the end.')


_TRAVEL_METRICS = (
    ('swing_travel_share', 'share of the travel made while a foot swings', 1.0, 3),
    ('swing_time_share', 'share of the time a foot swings', 1.0, 3),
    ('backward_travel_m', 'travel backwards (mm)', 1000.0, 1),
    ('stride_length_m', 'stride (m)', 1.0, 3))


def _trunk_travel(page: Page, rows: list[dict], by: tuple[str, ...], label: str) -> None:
    """The trunk-travel rows of the velocity term's runs (``motion_effects``), per setting,
    and the paired test of the share of travel made while a foot swings."""
    on = [r for r in rows if r['velocity_term']]
    off = [r for r in rows if not r['velocity_term']]
    if not values(on + off, 'swing_travel_share'):
        return
    for name, runs in (('on', on), ('off', off)):
        for key, metric, scale, digits in _TRAVEL_METRICS:
            page.row('velocity term', f'{label}, {name}', metric,
                     spread(values(runs, key), digits, scale), len(values(runs, key)), '', '')
    verdict, p = compare_paired(on, off, 'swing_travel_share', by, 'higher')
    share_on, share_off = values(on, 'swing_travel_share'), values(off, 'swing_travel_share')
    page.row('velocity term', f'{label}: on vs off',
             'share of the travel made while a foot swings',
             f'{np.mean(share_on):.3f} vs {np.mean(share_off):.3f}' if share_on and share_off
             else '-', len(share_on) + len(share_off),
             'the velocity term gives faster motion (the trunk moves through the swings)',
             verdict + p_text(p))


def _qp_timing(page: Page, data: dict, results: dict) -> None:
    lines = ['## QP timing', '',
             'The re-planner alone (`replan_core.bench.mpc_bench`: 8 s horizon, 40 ms samples, '
             '8 footholds, consecutive re-plans of a crawl), single-threaded, before any graph '
             'runs; and the solve times the MPC node reported inside the graph, over all '
             'realistic runs of this page. The paper: ' + _PAPER_QP + ' per QP (2016 hardware). '
             'The '
             'realistic profile\'s planning latency is fixed at the paper\'s 58 ms '
             '(`gait.plan_latency`), not at our solve time, so the experiments keep the paper\'s '
             'delay.', '']
    for name, bench in data.items():
        if 'error' in bench:
            page.row('QP timing', name, 'solve time (ms)', bench['error'], 0, _PAPER_QP, '-')
            continue
        med, p99 = bench.get('median_ms'), bench.get('p99_ms')
        mean, std = bench.get('mean_ms'), bench.get('std_ms')
        value = (f'median {med:.2f}, p99 {p99:.2f}' if med is not None else '-')
        if mean is not None and std is not None:
            value = f'{mean:.2f} ± {std:.2f}; ' + value
        verdict = against_paper(mean) if mean else '-'
        page.row('QP timing', f'{name} (bench)', 'solve time (ms)', value,
                 bench.get('replans', 0), _PAPER_QP + ' at 8 s / 40 ms', verdict)
    graph = []
    for key in ('replan_window', 'velocity_term', 'haptic', 'velocity_changes'):
        for r in results.get(key) or []:
            if r.get('world', 'realistic') == 'realistic' and r.get('mpc_solve_ms_median'):
                graph.append(r)
    if graph:
        page.row('QP timing', 'in the graph (realistic runs)', 'per-run median solve (ms)',
                 spread(values(graph, 'mpc_solve_ms_median'), 2), len(graph),
                 _PAPER_QP, '')
        page.row('QP timing', 'in the graph (realistic runs)', 'per-run p99 solve (ms)',
                 spread(values(graph, 'mpc_solve_ms_p99'), 2), len(graph), '', '')
    page.section('\n'.join(lines))


def _fastest_crawl(page: Page, data: dict, _all) -> None:
    rows, bound = (data['runs'], data.get('step_length_bound')) if isinstance(data, dict) else (
        data, None)
    held = [r for r in rows if r['ok'] and not r['fell'] and r.get('achieved')]
    best = max(held, key=lambda r: r['achieved'][0]) if held else None
    page.row('beyond the paper', 'fastest crawl, 30 s', 'speed achieved without a fall (m/s)',
             f'{best["achieved"][0]:.3f} (set-point {best["setpoint"]:.2f})' if best else '-',
             len(rows), 'the paper doubled its earlier planner\'s speed',
             'not tested: no static planner to compare with (below)')
    text = ('## Fastest crawl\n\nSet-points tried in turn (the gait\'s velocity clamp '
            'raised), stopping at the first fall: ' + ', '.join(
                f'{r["setpoint"]:.2f} m/s ' + ('fell' if r['fell'] else
                                              f'held (achieved {r["achieved"][0]:.3f})'
                                              if r.get('achieved') else 'failed')
                for r in rows) + '. The paper doubled the speed of its static planner ([4]: the '
            'trunk still while a leg swings), which is not built here: no baseline, no verdict.')
    if bound and best:
        text += (f' The speed stops growing near {bound["speed_mps"]:.3f} m/s: each leg steps '
                 f'once per crawl cycle ({bound["cycle_s"]:.2f} s) and the gait clamps a step '
                 f'to max_step_length_x = {bound["max_step_length_x_m"]:.2f} m (the leg\'s '
                 'reach), so a faster set-point only makes longer steps up to that clamp; going '
                 'faster needs a shorter cycle (swing_duration, four_feet_duration), which these '
                 'runs keep at the paper\'s crawl timing.')
    page.section(text)


def _ideal_world(page: Page, data: dict, results: dict) -> None:
    if 'replan_window' in data:
        _replan_window(page, data['replan_window'], results, world='ideal')
    if 'haptic' in data:
        _haptic(page, data['haptic'], results, world='ideal')
    if 'velocity_changes' in data:
        _velocity_changes(page, data['velocity_changes'], results)
    if 'lateral_push' in data:
        _lateral_push(page, data['lateral_push'], results)
