"""Each realism element switched on alone: its effect on the measured balance and tracking.

    scripts/realism_table.sh [--scenario FILE] [--runs N] [--out DIR] [--write-doc FILE]

Runs the scenario (default config/scenarios/realism.yaml) in the ideal world, in the ideal world
plus each element of config/profiles/elements.yaml with its values from
config/profiles/realistic.yaml, and on the whole realistic profile; prints a markdown table of
the measured CoP margin, the velocity error, pitch and touchdown figures (mean over the runs,
each with its own noise seed), and with --write-doc replaces the table in that file between the
markers ``<!-- realism-table -->`` and ``<!-- /realism-table -->``.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import sys
import time
from pathlib import Path

import yaml

from replan_experiments.scenario import ScenarioError, load_scenario, run_scenario

COLUMNS = (
    ('fell', lambda m: m.get('fell'), '{}'),
    ('CoP margin min cm', lambda m: m.get('cop_margin_min_m'), 'cm'),
    ('CoP margin 5th pct cm', lambda m: m.get('cop_margin_p5_m'), 'cm'),
    ('speed error m/s', lambda m: m.get('mean_linear_tracking_error_mps'), '{:.3f}'),
    ('max pitch deg', lambda m: m.get('max_pitch_rad'), 'deg'),
    ('max roll deg', lambda m: m.get('max_roll_rad'), 'deg'),
    ('pitch around touchdowns deg', lambda m: (m.get('touchdown_pitch_peak_deg') or {}).get(
        'mean'), '{:.2f}'),
    ('touchdown timing |err| median ms', lambda m: (m.get('touchdown_timing_error_s') or {}).get(
        'median_abs'), 'ms'),
    ('estimator xy error end cm', lambda m: (m.get('estimator') or {}).get('xy_error_end_m'),
     'cm'),
)
BEGIN, END = '<!-- realism-table -->', '<!-- /realism-table -->'


def element_profiles(config_dir: Path) -> dict[str, tuple[str, dict]]:
    """element name -> (description, parameter document with its realistic values only)."""
    realistic = yaml.safe_load((config_dir / 'profiles' / 'realistic.yaml').read_text())
    elements = yaml.safe_load((config_dir / 'profiles' / 'elements.yaml').read_text())
    covered: set[tuple[str, str]] = set()
    out = {}
    for name, spec in elements.items():
        doc: dict = {}
        for node, keys in spec.items():
            if node == 'description':
                continue
            values = realistic[node]['ros__parameters']
            for key in keys:
                if key not in values:
                    raise ValueError(f'elements.yaml: {name}: {node}.{key} is not in '
                                     'realistic.yaml')
                doc.setdefault(node, {'ros__parameters': {}})['ros__parameters'][key] = (
                    values[key])
                covered.add((node, key))
        out[name] = (spec.get('description', ''), doc)
    missing = [f'{node}.{key}' for node, section in realistic.items()
               for key in section['ros__parameters'] if (node, key) not in covered]
    if missing:
        raise ValueError(f'realistic.yaml keys in no element of elements.yaml: {missing}')
    return out


def cell(values: list, fmt: str) -> str:
    values = [v for v in values if v is not None]
    if not values:
        return '-'
    if fmt == '{}':
        return ', '.join(str(v) for v in values) if len(set(values)) > 1 else str(values[0])
    scale = {'cm': 100.0, 'ms': 1000.0, 'deg': 57.29578}.get(fmt, 1.0)
    numbers = [float(v) * scale for v in values]
    text_fmt = '{:.2f}' if fmt in ('cm', 'ms', 'deg') else fmt
    mean = text_fmt.format(statistics.mean(numbers))
    if len(numbers) > 1:
        spread = (max(numbers) - min(numbers)) / 2
        return f'{mean} ± {text_fmt.format(spread)}'
    return mean


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog='realism_table.sh', description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    config_dir = Path(os.environ.get('REPLAN_CONFIG', 'config'))
    parser.add_argument('--scenario', type=Path, default=config_dir / 'scenarios' / 'realism.yaml')
    parser.add_argument('--runs', type=int, default=1, help='runs per row (noise seeds 0..N-1)')
    parser.add_argument('--out', type=Path, help='output folder (default runs/realism-<time>)')
    parser.add_argument('--write-doc', type=Path, metavar='FILE',
                        help='replace the table between the realism-table markers of FILE')
    args = parser.parse_args(argv)
    try:
        scenario = load_scenario(args.scenario)
        elements = element_profiles(config_dir)
    except (ScenarioError, ValueError, OSError) as err:
        print(f'realism_table: {err}', file=sys.stderr)
        return 2
    root = Path(os.environ.get('REPLAN_ROOT', '.'))
    out = args.out or root / 'runs' / f'realism-{time.strftime("%Y%m%d-%H%M%S")}'
    out.mkdir(parents=True, exist_ok=True)
    rows = [('ideal', 'none: the ideal profile', 'ideal', None)]
    for name, (description, doc) in elements.items():
        rows.append((name, description, 'ideal', doc))
    rows.append(('realistic', 'all of them: the realistic profile', 'realistic', None))
    results: dict[str, list[dict]] = {}
    started = time.monotonic()
    total = len(rows) * args.runs
    for index, (name, _, profile, doc) in enumerate(rows):
        for seed in range(args.runs):
            run_dir = out / f'{name}_{seed}'
            overlay: dict = {}
            for node, section in (doc or {}).items():
                overlay.setdefault(node, {'ros__parameters': {}})['ros__parameters'].update(
                    section['ros__parameters'])
            # The run's seed, whatever the element's own noise_seed says.
            overlay.setdefault('sim', {'ros__parameters': {}})['ros__parameters'][
                'noise_seed'] = seed
            overlay_file = out / f'{name}_{seed}.yaml'
            overlay_file.write_text(yaml.safe_dump(overlay, sort_keys=False))
            scenario.profile = profile
            done = index * args.runs + seed
            elapsed = time.monotonic() - started
            left = f', about {elapsed / done * (total - done) / 60:.0f} min left' if done else ''
            print(f'[realism] run {done + 1}/{total}: {name} (seed {seed}){left}', flush=True)
            metrics = run_scenario(scenario, run_dir, extra_param_files=[overlay_file],
                                   log=lambda *_: None)
            results.setdefault(name, []).append(metrics)
    lines = ['| element on (alone) | what | runs | '
             + ' | '.join(c[0] for c in COLUMNS) + ' |',
             '| --- | --- | --- |' + ' --- |' * len(COLUMNS)]
    for name, description, _, _ in rows:
        runs = results[name]
        lines.append(f'| {name} | {description} | {len(runs)} | '
                     + ' | '.join(cell([get(m) for m in runs], fmt) for _, get, fmt in COLUMNS)
                     + ' |')
    table = '\n'.join(lines)
    shown = args.scenario.resolve()
    if shown.is_relative_to(root.resolve()):
        shown = shown.relative_to(root.resolve())
    command = f'scripts/realism_table.sh --scenario {shown} --runs {args.runs}'
    footer = (f'\n\nGenerated by `{command}` on {time.strftime("%Y-%m-%d")} '
              f'({platform.machine()}, {os.cpu_count()} cores); scenario '
              f'`{args.scenario.name}`; mean ± half the range over the runs.')
    print(table + footer)
    (out / 'table.md').write_text(table + footer + '\n')
    (out / 'results.json').write_text(json.dumps(results, indent=1, default=str))
    if args.write_doc:
        text = args.write_doc.read_text()
        if BEGIN not in text or END not in text:
            print(f'realism_table: {args.write_doc} has no {BEGIN} ... {END} markers',
                  file=sys.stderr)
            return 2
        head, rest = text.split(BEGIN, 1)
        _, tail = rest.split(END, 1)
        args.write_doc.write_text(f'{head}{BEGIN}\n{table}{footer}\n{END}{tail}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
