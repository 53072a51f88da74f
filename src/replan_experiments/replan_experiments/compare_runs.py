"""Print a markdown table comparing the metrics.json of several runs.

    python -m replan_experiments.compare_runs RUN_DIR [RUN_DIR ...]
"""

import json
import sys
from pathlib import Path

COLUMNS = (
    ('fell', 'fell', '{}'),
    ('mean speed error m/s', 'mean_linear_tracking_error_mps', '{:.3f}'),
    ('max roll deg', 'max_roll_rad', 'deg'),
    ('max pitch deg', 'max_pitch_rad', 'deg'),
    ('trunk z min m', 'trunk_height_min_m', '{:.3f}'),
    ('min ZMP margin m', 'min_zmp_margin_m', '{}'),
    ('re-plans', 'replans', '{}'),
    ('QP median ms', 'mpc_solve_ms_median', '{}'),
    ('QP p99 ms', 'mpc_solve_ms_p99', '{}'),
    ('RTF', 'real_time_factor', '{:.2f}'),
)


def cell(metrics: dict, key: str, fmt: str) -> str:
    value = metrics.get(key)
    if value is None:
        return '-'
    if fmt == 'deg':
        return f'{value * 57.29578:.2f}'
    return fmt.format(value)


def table(runs: list[Path]) -> str:
    lines = ['| run | ' + ' | '.join(c[0] for c in COLUMNS) + ' |',
             '| --- |' + ' --- |' * len(COLUMNS)]
    for run in runs:
        metrics = json.loads((run / 'metrics.json').read_text())
        lines.append(f'| {metrics.get("scenario", run.name)} | '
                     + ' | '.join(cell(metrics, key, fmt) for _, key, fmt in COLUMNS) + ' |')
    return '\n'.join(lines)


def main(argv=None) -> int:
    runs = [Path(a) for a in (argv if argv is not None else sys.argv[1:])]
    missing = [str(r) for r in runs if not (r / 'metrics.json').exists()]
    if not runs or missing:
        print(f'usage: compare_runs RUN_DIR ...; no metrics.json in {missing}', file=sys.stderr)
        return 2
    print(table(runs))
    return 0


if __name__ == '__main__':
    sys.exit(main())
