"""The results page's sections on what a push does to the support over the steps that follow
(paper V.B, foothold correction): the sustained push (a force held over several
steps) and the large push (one short push that moves the trunk 10-20 cm over its feet). The
measures are ``push_effects``'s, from the truth; a setting is compared with correction off in
paired runs."""

from __future__ import annotations

import numpy as np

from replan_experiments.stats import compare_paired, exploratory, p_text, spread, values

# (row key, metric on the page, scale to its unit, which side is better in a comparison with
# correction off: None = not compared)
_METRICS = (
    ('trunk_shift_max_m', 'largest trunk shift over its feet (cm)', 100.0, None),
    ('capture_margin_p5_m', 'capture point in the support, 5th percentile (cm)', 100.0,
     'higher'),
    ('capture_margin_min_m', 'capture point in the support, least (cm)', 100.0, None),
    ('foot_offset_change_m', 'feet off their places about the hips, mean (cm)', 100.0, None))
_CLAIM = 'foothold correction keeps the support from degenerating'
_MEASURES = ('From the truth over the push and the steps after it '
             '(`replan_experiments/push_effects.py`): the trunk\'s shift over its feet; the '
             'capture point\'s distance to the edges of the polygon of the feet in contact '
             '(positive inside; the base stands for the CoM); how far the feet left their '
             'places about the hips.')


def _label(name: str) -> str:
    return name.replace('_', ' ')


def _setting_rows(page, experiment: str, label: str, runs: list[dict]) -> None:
    falls = sum(r['fell'] for r in runs)
    for key, metric, scale, _ in _METRICS:
        first = key == 'trunk_shift_max_m'
        page.row(experiment, label, metric, spread(values(runs, key), 1, scale), len(runs),
                 'no fall' if first else '', f'{falls} falls' if first else '')


def _compare_rows(page, experiment: str, label: str, on: list[dict], off: list[dict],
                  by: tuple[str, ...], metrics: tuple[tuple[str, str, str], ...]) -> list[str]:
    """Rows of ``on`` against ``off`` (paired ``by``) on each (key, metric, better side);
    the exploratory comparisons, for the prose."""
    verdicts = []
    for key, metric, better in metrics:
        verdict, p = compare_paired(on, off, key, by, better)
        a, b = values(on, key), values(off, key)
        page.row(experiment, label, metric,
                 f'{np.mean(a) * 100:.1f} vs {np.mean(b) * 100:.1f}' if a and b else '-',
                 len(on) + len(off), _CLAIM, verdict + p_text(p))
        verdicts.append(f'{metric}: {exploratory(verdict)}{p_text(p)}')
    return verdicts


def _falls(name: str, on: list[dict], off: list[dict], where: str) -> list[str]:
    falls_on, falls_off = sum(r['fell'] for r in on), sum(r['fell'] for r in off)
    if not (falls_on or falls_off):
        return []
    return [f'- {where}: falls {falls_on} of {len(on)} with {_label(name)}, {falls_off} of '
            f'{len(off)} with correction off (a fallen run has no support measures).']


def sustained_push_section(page, rows: list[dict], results) -> None:
    settings = list(dict.fromkeys(r['setting'] for r in rows))
    lines = ['## Sustained lateral push: the support over the following steps', '',
             'Walking at 0.1 m/s, a lateral force to the robot\'s left held for a few seconds '
             '(table: the force; the page\'s plan file: start and duration), so the trunk moves '
             'over its feet for several steps, the situation the paper\'s foothold correction '
             '(V.B) is for. ' + _MEASURES + ' Paired by seed and force: a setting is compared '
             'with correction off on the capture point\'s 5th percentile (higher: a support '
             'that did not degenerate). The one short push that moves the trunk further is the '
             'next section.', '']
    capture = (('capture_margin_p5_m', 'capture point in the support, 5th percentile (cm)',
                'higher'),)
    for force in sorted({r['force_n'] for r in rows}):
        for name in settings:
            _setting_rows(page, 'sustained push', f'{_label(name)}, {force:.0f} N',
                          [r for r in rows if r['setting'] == name and r['force_n'] == force])
        off = [r for r in rows if r['setting'] == 'correction_off' and r['force_n'] == force]
        for name in [n for n in settings if n != 'correction_off']:
            on = [r for r in rows if r['setting'] == name and r['force_n'] == force]
            _compare_rows(page, 'sustained push', f'{_label(name)} vs off, {force:.0f} N', on,
                          off, ('seed',), capture)
            lines += _falls(name, on, off, f'{force:.0f} N')
    page.section('\n'.join(lines))


def impulse_label(rows: list[dict]) -> str:
    """The large push's impulse as the page names it: '75 N s', or '75-120 N s' where it
    differs between phases."""
    impulses = sorted({r['impulse_ns'] for r in rows}) or [0.0]
    if len(impulses) == 1:
        return f'{impulses[0]:.0f} N s'
    return f'{impulses[0]:.0f}-{impulses[-1]:.0f} N s'


def large_push_section(page, rows: list[dict], results) -> None:
    settings = list(dict.fromkeys(r['setting'] for r in rows))
    phases = sorted({r['phase'] for r in rows})
    by_phase_impulse = {r['phase']: r['impulse_ns'] for r in rows}
    impulse = impulse_label(rows)
    seeds = sorted({r['seed'] for r in rows})
    off_rows = [r for r in rows if r['setting'] == 'correction_off']
    shifts = values(off_rows, 'trunk_shift_max_m')
    by_phase = [(k, values([r for r in off_rows if r['phase'] == k], 'trunk_shift_max_m'))
                for k in phases]
    lines = ['## Large lateral push: the support over the following steps', '',
             'Walking at 0.1 m/s, one push to the robot\'s left over 0.25 s at '
             f'{len(phases)} phases of the crawl cycle, each with the sim noise seeds '
             f'{seeds} (the same in every setting: the runs pair by phase and seed), of '
             + ', '.join(f'{by_phase_impulse[k]:.0f}' for k in phases) + ' N s at phases '
             + ', '.join(str(k) for k in phases) + ' (the plan file gives how each was chosen), to '
             'move the trunk 10-20 cm over its feet without a fall'
             + (f'; without correction the largest shift was {np.min(shifts) * 100:.1f} to '
                f'{np.max(shifts) * 100:.1f} cm (mean by phase: '
                + ', '.join(f'{k}: {np.mean(v) * 100:.1f} cm' for k, v in by_phase if v) + ')'
                if shifts else '') + '. '
             + _MEASURES + ' Each run ends the plan\'s horizon after its push. A setting is '
             'compared with correction off on the capture point\'s 5th percentile (higher: a '
             'support that did not degenerate) and on how far the feet left their places about '
             'the hips (lower: the foot pattern kept about the body).', '']
    compared = (('capture_margin_p5_m', 'capture point in the support, 5th percentile (cm)',
                 'higher'),
                ('foot_offset_change_m', 'feet off their places about the hips, mean (cm)',
                 'lower'))
    for name in settings:
        _setting_rows(page, 'large push', f'{_label(name)}, {impulse}',
                      [r for r in rows if r['setting'] == name])
    off = [r for r in rows if r['setting'] == 'correction_off']
    for name in [n for n in settings if n != 'correction_off']:
        on = [r for r in rows if r['setting'] == name]
        verdicts = _compare_rows(page, 'large push', f'{_label(name)} vs off, {impulse}',
                                 on, off, ('phase', 'seed'), compared)
        lines.append(f'- {_label(name)} vs off: ' + '; '.join(verdicts) + '.')
        lines += _falls(name, on, off, impulse)
    page.section('\n'.join(lines))
