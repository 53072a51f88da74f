"""The text of the robots page (docs/robots.md) from the data ``robots_page.main`` collects
(``robots.json``: meta, facts, robots): a table of each robot's facts and derived parameters, a
table of what its runs measured, and how each figure is defined. Falls are reported as falls;
a run that failed to produce metrics is reported as such, never as a figure."""

from __future__ import annotations

_AXES = {'forward': ('forward', 'm/s'), 'lateral': ('lateral', 'm/s'), 'yaw': ('yaw', 'rad/s')}


def _num(value, digits: int = 3) -> str:
    """A number to ``digits`` significant figures; a list value by value; '-' for None."""
    if value is None:
        return '-'
    if isinstance(value, (list, tuple)):
        return '[' + ', '.join(_num(v, digits) for v in value) + ']'
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return str(value)
    return f'{value:.{digits}g}'


def _unit(key: str) -> str:
    """The unit of parameter ``node.name`` from its declaration (``params.tables``), the one
    source of its unit; '' for one it does not know."""
    from replan_ros.params.tables import TABLES, table
    node, _, name = key.partition('.')
    spec = table(node).get(name) if node in TABLES else None
    return spec.unit if spec is not None else ''


def _fall(row: dict) -> str:
    at = row.get('fall_time_s')
    return '**fell**' + (f' at {at:.1f} s' if at is not None else '')


def _not_measured(row: dict | None) -> str | None:
    """What a cell says of a run that measured nothing: none, failed, or fell; else None."""
    if not row:
        return '-'
    if not row.get('ok'):
        return 'run failed'
    if row.get('fell'):
        return _fall(row)
    return None


def walk_cell(row: dict | None, unit: str) -> str:
    """Achieved of commanded (and the difference), or the fall, or the failure."""
    if (said := _not_measured(row)) is not None:
        return said
    if row.get('achieved') is None:
        return 'no figure'
    achieved, commanded = row['achieved'], row['commanded']
    partial = ' (no whole crawl cycle: after the settling)' if row.get('cycles') == 0 else ''
    return (f'{_num(achieved)} of {commanded:g} {unit} '
            f'({100.0 * (achieved - commanded) / commanded:+.1f} %){partial}')


def stand_cell(row: dict | None) -> str:
    if (said := _not_measured(row)) is not None:
        return said
    if row.get('travel_m') is None:
        return 'no truth in the bag'
    start, end = row['drift_window_s']
    last = row.get('last_touchdown_s')
    return (f'{100.0 * row["travel_m"]:.2f} cm ({start:g}-{end:g} s); '
            f'{row["touchdowns"]} touchdowns' + (f' (last at {last:.2f} s)' if last is not None
                                                else ''))


def response_misses(cell: dict | None) -> list[str]:
    """What a response axis misses: 'first' (a leg's first cycle off by more than 10 %),
    'later' (a later one off by more than 5 %), 'overshoot' (a cycle more than 5 % above the
    set-point); ['no whole cycle'] without cycles."""
    if not cell or not cell['legs']:
        return ['no whole cycle']
    misses = []
    if cell['first_error'] > 0.10:
        misses.append('first')
    if cell['later_error'] is not None and cell['later_error'] > 0.05:
        misses.append('later')
    if cell.get('overshoot') is not None and cell['overshoot'] > 0.05:
        misses.append('overshoot')
    return misses


def cycle_ranges(cell: dict) -> str:
    """A response axis's cycles in per cent of the set-point: for the first cycle of every
    leg, then the second, and so on, the lowest and highest over the legs ('82-99'), or one
    figure where they round alike."""
    count = max(len(leg['shares']) for leg in cell['legs'])
    out = []
    for k in range(count):
        shares = [leg['shares'][k] for leg in cell['legs'] if len(leg['shares']) > k]
        low, high = f'{100.0 * min(shares):.0f}', f'{100.0 * max(shares):.0f}'
        out.append(low if low == high else f'{low}-{high}')
    return ' '.join(out)


def run_labels(runs: list[dict], rows: list[dict]) -> str:
    """The response ``runs`` (some of a robot's ``rows``) by what tells them apart: 'phases
    1, 3' where every run has one seed, 'seeds 0, 2' where every run has one phase of the
    changes, else 'seed 0 phase 1, seed 2 phase 0'."""
    one_seed = len({row['seed'] for row in rows}) == 1
    one_phase = len({row['phase'] for row in rows}) == 1
    if one_seed or one_phase:
        kind = 'phase' if one_seed and not one_phase else 'seed'
        values = [str(run[kind]) for run in runs]
        return f'{kind}{"s" if len(values) > 1 else ""} {", ".join(values)}'
    return ', '.join(f'seed {run["seed"]} phase {run["phase"]}' for run in runs)


def response_cell(rows: list[dict] | None, axis: str) -> str:
    """Each whole crawl cycle after the change to ``axis``'s set-point, in per cent of it, the
    range over the legs that open them (``cycle_ranges``), one run per noise seed and phase
    of the changes (``response.seeds`` and ``phases``, in order, separated by /); met: in every
    run every leg's first within 10 %, every later one within 5 %, none more than 5 % above;
    else the cell says what is not, and in which runs (``run_labels``)."""
    if not rows:
        return '-'
    parts, missed = [], {}
    for row in rows:
        if (said := _not_measured(row)) is not None:
            parts.append(said)
            continue
        cell = row['axes'].get(axis)
        misses = response_misses(cell)
        if misses == ['no whole cycle']:
            parts.append('no whole cycle')
            continue
        parts.append(cycle_ranges(cell) + ' %')
        for miss in misses:
            missed.setdefault(miss, []).append(row)
    text = ' / '.join(parts)
    if not missed:
        return text
    if len(rows) == 1:
        return f'{text} (**{" and ".join(missed)} off**)'
    said = '; '.join(f'{miss} off on {run_labels(runs, rows)}' for miss, runs in missed.items())
    return f'{text} (**{said}**)'


def push_cell(push: dict | None, skipped: str | None) -> str:
    """The largest dv survived at every phase, its impulse, and the level that felled it."""
    if push is None:
        return f'not run: {skipped}' if skipped else '-'
    levels = push['levels']
    by_dv = {level['dv_mps']: level for level in levels}
    parts = []
    if push['survived_dv'] is None:
        parts.append(f'none of the levels tried (< {levels[0]["dv_mps"]:g} m/s)'
                     if levels else 'no level tried')
    else:
        level = by_dv[push['survived_dv']]
        parts.append(f'**{push["survived_dv"]:g} m/s** ({level["impulse_ns"]:.1f} N s) at all '
                     f'{push["phases"]} phases')
    if push['fell_dv'] is not None:
        fell = [p['phase'] for p in by_dv[push['fell_dv']]['phases'] if p['fell']]
        parts.append(f'{push["fell_dv"]:g} m/s fell at phase {", ".join(map(str, fell))} '
                     f'of {push["phases"]}')
    elif push['failed']:
        parts.append(f'a run at {levels[-1]["dv_mps"]:g} m/s failed')
    elif levels:
        parts.append(f'the largest level tried ({levels[-1]["dv_mps"]:g} m/s) survived')
    return '; '.join(parts)


def step_cell(steps: list[dict], skipped: str | None) -> str:
    """The largest share crossed with every smaller one crossed, and what happened above."""
    if not steps:
        return f'not run: {skipped}' if skipped else '-'
    crossed = 0        # the leading run of crossed shares (they rise)
    while crossed < len(steps) and steps[crossed]['crossed']:
        crossed += 1
    best = steps[crossed - 1] if crossed else None
    rest = []
    for step in steps[crossed:]:
        what = ('run failed' if not step['ok'] else _fall(step) if step['fell']
                else f'stopped at x {step["final_x_m"]:.2f} m of {step["cross_x_m"]:.2f}'
                if not step['crossed'] else 'crossed')
        rest.append(f'{step["share"]:g}: {what}')
    head = (f'**{best["share"]:g}** of the leg ({100.0 * best["height_m"]:.1f} cm)'
            if best else f'none (< {steps[0]["share"]:g})')
    return '; '.join([head, *rest])


def timing_cells(timing: dict) -> tuple[str, str]:
    if not timing.get('runs'):
        return '-', '-'
    rtf = f'{_num(timing["rtf_median"])} (min {_num(timing["rtf_min"])}; {timing["runs"]} runs)'
    mpc = (f'{_num(timing["mpc_median_ms"])} ms median, p99 up to '
           f'{_num(timing["mpc_p99_max_ms"])} ms')
    return rtf, mpc


def _table(header: list[str], rows: list[list[str]]) -> list[str]:
    return ['| ' + ' | '.join(header) + ' |', '|' + '---|' * len(header),
            *['| ' + ' | '.join(r) + ' |' for r in rows]]


def facts_table(facts: dict) -> list[str]:
    names = list(facts)
    rows = [['mass kg (model)', *[_num(facts[n]['mass_kg'], 4) for n in names]],
            ['leg length m', *[_num(facts[n]['leg_length_m']) for n in names]],
            ['standing height m', *[_num(facts[n]['standing_height_m']) for n in names]],
            ['CoM height m', *[_num(facts[n]['com_height_m']) for n in names]],
            ['smallest joint inertia kg m^2',
             *[_num(facts[n]['min_joint_inertia'], 2) for n in names]],
            ['crawl cycle s (4 x (swing + four feet))', *[_num(facts[n]['cycle_s']) for n in
                                                          names]]]
    parameters = list(facts[names[0]]['parameters']) if names else []
    for p in parameters:
        unit = _unit(p)
        rows.append([f'`{p}`' + (f' {unit}' if unit else ''),
                     *[_num(facts[n]['parameters'].get(p)) for n in names]])
    return _table(['', *names], rows)


def results_table(robots: dict) -> list[str]:
    names = list(robots)
    rows = []
    for axis, (label, unit) in _AXES.items():
        rows.append([f'{label}: achieved of commanded',
                     *[walk_cell(robots[n]['walks'].get(axis), unit) for n in names]])
    for axis, (label, _unit) in _AXES.items():
        rows.append([f'response, {label}: each whole cycle after the change, % of set-point',
                     *[response_cell(robots[n].get('response'), axis) for n in names]])
    rows.append(['standing from launch: trunk travel, touchdowns',
                 *[stand_cell(robots[n]['stand']) for n in names]])
    rows.append(['largest lateral push survived at every phase (dv = impulse / mass)',
                 *[push_cell(robots[n]['push'], robots[n]['skipped']) for n in names]])
    rows.append(['blind step down crossed (share of leg length)',
                 *[step_cell(robots[n]['step_down'], robots[n]['skipped']) for n in names]])
    cells = [timing_cells(robots[n]['timing']) for n in names]
    rows.append(['real-time factor, median over its runs', *[c[0] for c in cells]])
    rows.append(['MPC solve time', *[c[1] for c in cells]])
    return _table(['', *names], rows)


def _response_runs(response: dict) -> str:
    """How the response runs differ: the phases of the changes and the noise seeds."""
    seeds = ', '.join(str(seed) for seed in response['seeds'])
    phases = response['phases']
    seeds_text = (f'the sim\'s noise seed {seeds}' if len(response['seeds']) == 1
                  else f'each of the sim\'s noise seeds {seeds}')
    if phases == 1:
        return f'one run on {seeds_text}, separated by / in that order'
    return (f'one run per phase 0 to {phases - 1} on {seeds_text}, separated by / in that '
            f'order. Phase k delays the two changes by k / {phases} of a crawl cycle, so that '
            'each leg in turn is the first to land after a change and the first to re-plan for '
            'it (the response depends on which: docs/gait.md, "Response to a set-point '
            'change")')


def how_section(meta: dict) -> list[str]:
    tests = meta['tests']
    stand, push, step = tests['stand'], tests['push'], tests['step_down']
    response = tests['response']
    return [
        '## How each figure is made', '',
        f'- **Set-points**: per robot in the plan. Each walk is its own run from standing '
        f'(`{tests["walk"]["scenario"]}`, {tests["walk"]["duration"]:g} s), achieved = the '
        'mean body-frame velocity of the simulator\'s truth over the last whole crawl cycles '
        '(each from a true touchdown of a leg to its next: the crawl\'s sway and surge '
        'average out; the trunk takes a few cycles from standing to get to the speed, which '
        'the steady state leaves out; the run\'s `velocity_tracking`, `achieved_steady`, '
        '`cycle_velocities`; yaw: the turn rate).',
        f'- **Response**: a run of `{response["scenario"]}` from standing: the robot\'s '
        f'forward set-point, then its lateral one, then its yaw one, each for '
        f'{response["segment_cycles"]} of its crawl cycles; {_response_runs(response)}. '
        'Each cell gives the commanded component\'s mean over each whole crawl cycle after '
        'the change, in per cent of the set-point. Each leg opens its own cycles: from each '
        'of its true touchdowns to its next (the run\'s '
        '`leg_cycle_velocities`). The legs land a step apart, so their first cycles start at '
        'different points of the way to the new speed: one leg\'s can hold a lag and its '
        'catch-up and read the set-point, another\'s only the catch-up (docs/gait.md, '
        '"Response to a set-point change"). A cell gives, for the first cycle of every leg, '
        'then the second, and so on, the lowest and the highest over the legs. Met: in every '
        'run, every leg\'s first cycle within 10 %, every later one within 5 %, and no cycle '
        'more than 5 % above the set-point; a cell says what is not, and in which runs. '
        '`scripts/gait_report.sh RUN_DIR` prints each leg\'s cycles.',
        f'- **Standing**: `{stand["scenario"]}` at zero set-point for {stand["duration"]:g} s '
        f'from launch; travel = the largest horizontal distance of the trunk on the truth from '
        f'its place at {stand["drift_from"]:g} s; touchdowns = true contact flags that rise '
        'after it.',
        f'- **Pushes**: walking forward at the set-point, one push of {push["push_duration"]:g} s '
        f'to {push["direction"]} (world frame, the robot heading along x) of force = mass x dv / '
        f'{push["push_duration"]:g} s, mass the model\'s (the table above; the realistic '
        'profile\'s payload, `sim.payload_mass`, comes on top, so the simulated body gains a '
        f'little less than dv); at {push["phases"]} phases over the robot\'s crawl cycle, the '
        f'first {push["first_push_cycles"]:g} cycles after the walk starts, then '
        f'{push["after_push_cycles"]:g} cycles of walking; levels {push["levels"]} m/s one '
        'after the other, all phases at once, up to the first level that fells it at some '
        'phase.',
        f'- **Step down**: `{step["scenario"]}` with a step down of each share '
        f'{step["shares"]} of the leg length, its edge {step["step_x_legs"]:g} leg lengths '
        'ahead of the spawn, walking forward at the set-point; crossed = no fall and the base '
        f'{step["cross_legs"]:g} leg lengths past the edge at the end (a run of '
        f'{step["time_margin"]:g} times the time the set-point takes to get there). The planner '
        'plans on flat ground: only the haptic touchdown finds the lower ground. The table '
        'gives the largest share with every smaller one crossed too.',
        '- **Real-time factor and MPC solve time**: from every completed run of the robot '
        '(`real_time_factor`: sim time over wall time of the graph; the MPC\'s solve time from '
        'its diagnostics: the median of the runs\' medians, and the largest p99). They depend '
        f'on the machine\'s load: {meta.get("jobs", 1)} runs at a time here.',
        '- A robot that falls walking forward on flat ground is not pushed or sent down a step '
        '(its row says why).',
    ]


def _short_walk(row: dict | None) -> str:
    """Achieved minus commanded in per cent of it, or what the run says instead."""
    if (said := _not_measured(row)) is not None:
        return said
    if row.get('achieved') is None:
        return 'no figure'
    return f'{100.0 * (row["achieved"] - row["commanded"]) / row["commanded"]:+.1f}'


def _short_response(rows: list[dict] | None) -> str:
    """'met' or the axes whose cycles after a change miss the bounds of ``response_cell`` on
    some seed."""
    if not rows:
        return '-'
    for row in rows:
        if (said := _not_measured(row)) is not None:
            return said
    missed = [label for axis, (label, _) in _AXES.items()
              if any(response_misses(row['axes'].get(axis)) for row in rows)]
    return 'met' if not missed else 'off: ' + ', '.join(missed)


def _gait_heading(gait: str, rule: dict) -> str:
    at = (f'Froude {rule["froude"]:g}' if 'froude' in rule
          else f'{rule["crawl_times"]:g} x the crawl')
    return f'{gait.replace("_", " ")} at {at}: forward achieved, % of set-point'


def _short_gait(gait: dict | None) -> str:
    """A gait's forward achieved in per cent of its set-point, or what the run says."""
    if gait is None:
        return '-'
    walk = gait.get('walk')
    if (said := _not_measured(walk)) is not None:
        return said
    cell = (walk.get('axes') or {}).get('forward') or {}
    return f'{100.0 * cell["share"]:.1f}' if cell.get('share') is not None else 'no figure'


def readme_block(data: dict) -> str:
    """A short table of docs/robots.md for the README (between its robots markers): per robot
    the steady walks, standing, the largest push and step down, and whether the response to
    set-point changes meets its bounds."""
    meta, robots = data['meta'], data['robots']
    rows = []
    for name, robot in robots.items():
        walks = ' / '.join(_short_walk(robot['walks'].get(axis)) for axis in _AXES)
        stand = robot['stand']
        standing = (stand_cell(stand) if _not_measured(stand) is not None
                    or stand.get('travel_m') is None
                    else f'{100.0 * stand["travel_m"]:.2f} cm, {stand["touchdowns"]} steps')
        push = robot['push']
        pushed = (f'{push["survived_dv"]:g} m/s' if push and push['survived_dv'] is not None
                  else push_cell(push, robot['skipped']))
        steps = robot['step_down']
        crossed = 0                      # the leading run of crossed shares, as step_cell
        while crossed < len(steps) and steps[crossed]['crossed']:
            crossed += 1
        stepped = (f'{steps[crossed - 1]["share"]:g} of the leg' if crossed
                   else step_cell(steps, robot['skipped']))
        gaits = [_short_gait((robot.get('gaits') or {}).get(gait))
                 for gait in meta.get('gaits') or {}]
        rows.append([name, walks, standing, pushed, stepped,
                     _short_response(robot.get('response')), *gaits])
    header = ['robot', 'walk: forward / lateral / yaw, % off the set-point',
              f'standing {meta["tests"]["stand"]["duration"]:g} s from launch',
              'lateral push survived at every phase (dv)', 'blind step down crossed',
              'response to set-point changes',
              *[_gait_heading(gait, cfg['setpoints'])
                for gait, cfg in (meta.get('gaits') or {}).items()]]
    return '\n'.join([f'From [docs/robots.md](docs/robots.md) ({meta["date"]}, '
                      f'{meta["profile"]} profile; generated, the page names the revision of '
                      'its runs):', '', *_table(header, rows)]) + '\n'


# -- the other gaits ---------------------------------------------------------------------------


def share_cell(run: dict | None, axis: str, unit: str) -> str:
    """A gait's achieved ``axis`` over its last whole cycles, in per cent of the set-point,
    then each whole cycle's (when the run gave them), or the fall, the failure or the missing
    cycles."""
    if (said := _not_measured(run)) is not None:
        return said
    cell = (run.get('axes') or {}).get(axis)
    if not cell:
        return 'no segment'
    if cell.get('share') is None:
        return f'too few whole cycles ({cell.get("cycles", 0)})'
    shares = cell.get('cycle_shares')
    each = (f'; cycles {" ".join(f"{100.0 * x:.0f}" for x in shares)} %' if shares else '')
    return (f'{100.0 * cell["share"]:.1f} % ({_num(cell["achieved"])} of '
            f'{cell["commanded"]:g} {unit}){each}')


def standing_cell(gait: dict) -> str:
    """Standing after the stop: the trunk's drift over the quiet window and the touchdowns
    in it."""
    walk = gait.get('walk')
    if (said := _not_measured(walk)) is not None:
        return said
    standing = gait.get('standing') or {}
    if standing.get('drift_m') is None:
        return 'no truth in the bag'
    start, end = standing['window_s']
    steps = standing['touchdowns']
    return (f'{100.0 * standing["drift_m"]:.2f} cm, {steps} touchdown'
            f'{"" if steps == 1 else "s"} ({start:.2f}-{end:.2f} s)')


def falls_cell(gait: dict) -> str:
    falls = gait.get('falls') or []
    if not falls:
        return f'none ({gait.get("runs", 0)} runs)'
    return f'**{len(falls)} of {gait.get("runs", 0)} runs**: ' + ', '.join(
        f'`{key.rsplit("-", 1)[0]}`' for key in falls)


def gait_table(robots: dict, gait: str) -> list[str]:
    names = [n for n in robots if gait in (robots[n].get('gaits') or {})]
    rows_of = {n: robots[n]['gaits'][gait] for n in names}
    rows = [['set-point forward (Froude number v^2 / (g l))',
             *[f'{rows_of[n]["setpoints"]["forward"]:g} m/s ({rows_of[n]["froude"]:.4f})'
               for n in names]],
            ['set-points lateral, yaw',
             *[f'{rows_of[n]["setpoints"]["lateral"]:g} m/s, '
               f'{rows_of[n]["setpoints"]["yaw"]:g} rad/s' for n in names]],
            ['cycle s', *[_num(rows_of[n]['cycle_s']) for n in names]],
            ['forward achieved, % of set-point',
             *[share_cell(rows_of[n].get('walk'), 'forward', 'm/s') for n in names]],
            ['lateral achieved, % of set-point',
             *[share_cell(rows_of[n].get('turn'), 'lateral', 'm/s') for n in names]],
            ['yaw achieved, % of set-point',
             *[share_cell(rows_of[n].get('turn'), 'yaw', 'rad/s') for n in names]],
            *([[f'forward at Froude number {fast[0]["froude"]:g}, % of set-point',
                *[share_cell(rows_of[n].get('fast'), 'forward', 'm/s') for n in names]]]
              if (fast := [r['fast'] for r in rows_of.values() if r.get('fast')]) else []),
            ['largest lateral push survived at every phase (dv = impulse / mass)',
             *[push_cell(rows_of[n]['push'], rows_of[n]['skipped']) for n in names]],
            ['blind step down crossed (share of leg length)',
             *[step_cell(rows_of[n]['step_down'], rows_of[n]['skipped']) for n in names]],
            ['standing after the stop: trunk drift, touchdowns',
             *[standing_cell(rows_of[n]) for n in names]],
            ['falls', *[falls_cell(rows_of[n]) for n in names]]]
    cells = [timing_cells(rows_of[n].get('timing') or {}) for n in names]
    rows.append(['real-time factor, median over its runs', *[c[0] for c in cells]])
    rows.append(['MPC solve time', *[c[1] for c in cells]])
    return _table(['', *names], rows)


def _setpoint_rule(rule: dict) -> str:
    forward = (f'the speed of Froude number v^2 / (g l) = {rule["froude"]:g} for its leg '
               f'length l, sqrt({rule["froude"]:g} g l)' if 'froude' in rule else
               f'{rule["crawl_times"]:g} x its crawl forward set-point')
    return (f'forward {forward}; lateral {rule["lateral_share"]:g} x forward; yaw forward / '
            f'({rule["yaw_legs"]:g} x l)')


def gait_section(meta: dict, robots: dict, gait: str) -> list[str]:
    cfg = meta['gaits'][gait]
    tests = cfg['tests']
    walk, turn, push, step = tests['walk'], tests['turn'], tests['push'], tests['step_down']
    title = gait.replace('_', ' ')
    return [
        f'## {title[0].upper() + title[1:]}', '',
        f'`config/gaits/{gait}.yaml`, each robot\'s set-points from its leg length: '
        f'{_setpoint_rule(cfg["setpoints"])}. One run walks forward from standing for '
        f'{walk["forward_cycles"]} of the gait\'s cycles, then stops: achieved = the mean over '
        f'the last {walk["steady_cycles"]} whole cycles before the stop (a true touchdown of a '
        'leg to its next); standing after = the trunk\'s drift on the truth and the true '
        f'touchdowns from the gait\'s `idle_after` + {walk["settle_s"]:g} s after the stop to '
        f'{walk["quiet_s"]:g} s later (the run\'s end). One run goes sideways, then turns, '
        f'{turn["segment_cycles"]} cycles each (the last {turn["steady_cycles"]} whole cycles '
        f'of each). Pushes at {push["phases"]} phases of the cycle (the first '
        f'{push["first_push_cycles"]:g} cycles after the start, force = mass x dv / '
        f'{push["push_duration"]:g} s, levels {push["levels"]} m/s) and blind step downs '
        f'(shares {step["shares"]}, edge {step["step_x_legs"]:g} leg lengths ahead, one after '
        'the other up to the first not crossed) as the crawl\'s, walking forward at the '
        'gait\'s set-point; not run if the walk falls.'
        + (f' One run walks forward from standing at the speed of Froude number '
           f'{tests["fast"]["froude"]:g}, sqrt({tests["fast"]["froude"]:g} g l), for '
           f'{tests["fast"]["forward_cycles"]} cycles (the last {tests["fast"]["steady_cycles"]} '
           'whole cycles).' if 'fast' in tests else '')
        + ' After each achieved share: every whole cycle\'s of the set-point\'s segment, from '
        'the first (the start or the change) on, in per cent: how much one cycle of the gait '
        'scatters about its mean.', '',
        *gait_table(robots, gait), '']


def render_page(data: dict) -> str:
    """The page's markdown from ``robots.json``'s ``meta``, ``facts`` and ``robots``."""
    meta, facts, robots = data['meta'], data['facts'], data['robots']
    lines = [
        '# Robots: what each does on the realistic profile', '',
        f'Generated by `{meta["command"]}` on {meta["date"]} ({meta["machine"]}), revision '
        f'{meta["revision"]}, code fingerprint {meta["code"]}: {meta["runs"]} runs '
        f'({meta["reused"]} read from earlier calls), this call {meta["wall_time_min"]} min. '
        f'Profile `{meta["profile"]}`, sim noise seed {meta["seed"]}, plan '
        f'`{meta["plan_file"]}`. Do not edit by hand: every figure comes from the robots\' '
        'models, the launcher\'s derivation (`launch/param_files.py` `robot_parameters`) and '
        'the runs (`replan_experiments/robots_page.py`, `robots_plan.py`, '
        '`robots_render.py`; docs/robot_files.md for the files and the scaling rules).', '']
    if meta.get('quick'):
        lines += ['**Quick run** (`--quick`): one short run of each kind, to check that the '
                  'page is produced; its figures are not the robots\'.', '']
    lines += ['## Facts and derived parameters', '',
              'Facts measured on each model in its standing pose (`robot_facts`); parameters as '
              f'the nodes get them on the `{meta["profile"]}` profile.', '',
              *facts_table(facts), '',
              '## Measured', '', *results_table(robots), '', *how_section(meta)]
    for gait in meta.get('gaits') or {}:
        lines += ['', *gait_section(meta, robots, gait)]
    if meta.get('failures'):
        lines += ['', f'{len(meta["failures"])} runs failed to produce metrics:',
                  *[f'- `{f}`' for f in meta['failures']]]
    return '\n'.join(lines) + '\n'
