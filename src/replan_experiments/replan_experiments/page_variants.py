"""The results page's sections on the claims tested again elsewhere (variant sections of the
plan: another robot, gait or set-point scale): where, and per setting the runs, falls and
primary measure; their verdicts are in the pre-registered table (``findings``)."""

from __future__ import annotations

from replan_experiments.findings import claim_label, setting_text
from replan_experiments.stats import spread, values


def variant_section(page, name: str, info: dict, rows: list[dict], block: dict | None) -> None:
    """A claim tested again elsewhere (a variant section of the plan): where, and per setting
    its runs, falls and primary measure; the verdict is the pre-registered table's."""
    label = claim_label(name, info)
    rows = [r for r in rows or [] if isinstance(r, dict)]
    by = ((block or {}).get('compare') or {}).get('by')
    measure = (block or {}).get('measure')
    lines = [f'## {label}', '',
             f'The plan\'s `{name}` runs the experiment `{info["experiment"]}` again '
             + ', '.join(f'with {k} {v}' for k, v in info.items() if k != 'experiment')
             + ' (the set-points of its scenarios times `setpoint_scale`; the set-points, '
             'forces and terrains the section gives are its own). Its verdict is the '
             'pre-registered table\'s; its runs are the rows under its name in "Every '
             'measure (exploratory)".', '']
    groups = sorted({r.get(by) for r in rows}, key=str) if by else [None]
    for value in groups:
        runs = [r for r in rows if by is None or r.get(by) == value]
        setting = setting_text(by, value) if by else 'all runs'
        falls = sum(bool(r.get('fell')) for r in runs)
        if measure and measure not in ('fell', 'crossed'):
            page.row(label, setting, f'`{measure}` ({block["unit"]})',
                     spread(values(runs, measure), 4), len(runs), '', f'{falls} falls')
        else:
            page.row(label, setting, 'falls', f'{falls} of {len(runs)}', len(runs), '', '')
    page.section('\n'.join(lines))


def variant_sections(page, results: dict, meta: dict) -> None:
    """The section of each variant of the call (``results['variants']``, claims.run_all)."""
    claims = (meta.get('preregistration') or {}).get('claims') or {}
    for name, info in (results.get('variants') or {}).items():
        if name in results:
            variant_section(page, name, info, results[name], claims.get(name))
