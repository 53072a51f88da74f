"""Statistics of the results page: spreads and the verdicts of comparisons, computed from
the runs, never typed (docs: ``page.py``)."""

from __future__ import annotations

import math
import warnings

import numpy as np

P_VALUE = 0.05


# -- statistics ------------------------------------------------------------------------------


def values(rows: list[dict], key: str, **where) -> list[float]:
    """``key`` of the rows matching ``where`` (runs that completed), None left out."""
    out = []
    for row in rows:
        if not row.get('ok', True) or any(row.get(k) != v for k, v in where.items()):
            continue
        value = row.get(key)
        if value is not None and not (isinstance(value, float) and math.isnan(value)):
            out.append(float(value))
    return out


def steady_velocity(row: dict) -> list | None:
    """A velocity-tracking row's steady state (vx, vy, wz): over its last whole crawl cycles
    (``achieved_steady``, replan_core.metrics.tracking_errors: the trunk has got to the speed
    and the sway is averaged out); else over the whole cycles after the settling
    (``achieved_cycles``, runs of older code), else after the settling (``achieved``); None
    without any."""
    if row.get('achieved_steady'):
        return row['achieved_steady']
    whole = row.get('achieved_cycles') if row.get('cycles') else None
    return whole or row.get('achieved')


def steady_error(row: dict) -> float | None:
    """m/s, |achieved - commanded| of the planar velocity in the steady state (the mean of the
    last whole crawl cycles, ``achieved_steady``: speed and direction); None without it."""
    steady, commanded = row.get('achieved_steady'), row.get('commanded')
    if not steady or not commanded:
        return None
    return float(math.hypot(steady[0] - commanded[0], steady[1] - commanded[1]))


def steady_cycles_text(rows: list[dict]) -> str:
    """How many whole cycles the runs' steady state is the mean of (``steady_cycles``)."""
    counts = sorted({r['steady_cycles'] for r in rows if r.get('steady_cycles')})
    return ' or '.join(str(n) for n in counts) if counts else 'few'


def forward_speed_rows(rows: list[dict]) -> list[dict]:
    """The straight walks that completed with a steady state and a forward set-point, each
    with ``speed_ratio`` (steady forward speed / set-point) and ``speed_error`` (|1 - ratio|)."""
    out = []
    for r in rows:
        steady = steady_velocity(r)
        if r.get('ok') and steady and r['commanded'][0]:
            ratio = steady[0] / r['commanded'][0]
            out.append(dict(r, speed_ratio=ratio, speed_error=abs(1 - ratio)))
    return out


def cycles_to_within(row: dict, tolerance: float) -> int | None:
    """Whole crawl cycles from the start of a row's segment before every later cycle's mean
    velocity (``cycle_velocities``) is within ``tolerance`` (a share) of the set-point: planar
    speed error against the planar set-point (if any), yaw-rate error against a commanded yaw
    rate (if any).
    0: from the first cycle on; None: the last cycle is not within, or no cycles, or no
    set-point."""
    cycles = row.get('cycle_velocities') or []
    vx, vy, wz = row['commanded']
    speed = math.hypot(vx, vy)
    if not cycles or (speed == 0.0 and wz == 0.0):
        return None

    def within(v) -> bool:
        linear = speed == 0.0 or math.hypot(v[0] - vx, v[1] - vy) <= tolerance * speed
        return linear and (wz == 0.0 or abs(v[2] - wz) <= tolerance * abs(wz))

    outside = [k for k, c in enumerate(cycles) if not within(c['velocity'])]
    if outside and outside[-1] == len(cycles) - 1:
        return None
    return outside[-1] + 1 if outside else 0


# Share of the set-point: the band of "followed promptly" (replan_core.metrics.settle_time's
# default tolerance), judged here on whole-cycle means.
PROMPT_BAND = 0.10


def prompt_by_cycles(rows: list[dict]) -> tuple[list[int], int]:
    """Per run, the whole cycles until every later cycle's mean velocity is within
    ``PROMPT_BAND`` of the set-point (``cycles_to_within``; runs where it never is are left
    out), and how many runs are prompt: within from the second whole cycle after the change
    on (one cycle for the change itself)."""
    known = [c for c in (cycles_to_within(r, PROMPT_BAND) for r in rows) if c is not None]
    return known, sum(1 for c in known if c <= 1)


def spread(xs: list[float], digits: int = 3, scale: float = 1.0) -> str:
    """'mean +- std (min to max)' of ``xs`` times ``scale``; '-' if empty."""
    if not xs:
        return '-'
    a = np.asarray(xs, dtype=float) * scale
    fmt = f'{{:.{digits}f}}'
    if len(a) == 1:
        return fmt.format(a[0])
    return (f'{fmt.format(a.mean())} ± {fmt.format(a.std(ddof=1))} '
            f'({fmt.format(a.min())} to {fmt.format(a.max())})')


def compare(a: list[float], b: list[float], a_better: str) -> tuple[str, float | None]:
    """Is ``a`` better than ``b`` beyond the spread? ``a_better``: 'lower' or 'higher'.
    Returns the verdict and Welch's p-value."""
    if len(a) < 2 or len(b) < 2:
        return 'not resolved (too few runs)', None
    from scipy.stats import ttest_ind
    if np.std(a) == 0 and np.std(b) == 0:
        if np.mean(a) == np.mean(b):
            return 'not resolved (equal)', 1.0
        p = 0.0
    else:
        with warnings.catch_warnings():      # nearly equal samples: the p-value says so
            warnings.simplefilter('ignore', RuntimeWarning)
            p = float(ttest_ind(a, b, equal_var=False).pvalue)
    better = np.mean(a) < np.mean(b) if a_better == 'lower' else np.mean(a) > np.mean(b)
    if p >= P_VALUE:
        return 'not resolved (within the spread)', p
    return ('holds' if better else 'does not hold (the opposite)'), p


def compare_paired(a_rows: list[dict], b_rows: list[dict], key: str, by: tuple[str, ...],
                   a_better: str) -> tuple[str, float | None]:
    """``compare`` of metric ``key`` where the runs pair (the same seed and set-point, ``by``):
    the paired t-test over the differences of the pairs where both runs have the metric (a
    run without it, e.g. one that fell, is left out and the verdict says how many were);
    Welch's test, said so, when fewer than two pairs remain."""
    def index(rows):
        out: dict[tuple, float] = {}
        for r in rows:
            if r.get(key) is not None:
                out[tuple(r.get(k) for k in by)] = float(r[key])
        return out

    a, b = index(a_rows), index(b_rows)
    pairs = sorted(set(a) & set(b))
    if len(pairs) < 2:
        verdict, p = compare(values(a_rows, key), values(b_rows, key), a_better)
        return verdict + (' (unpaired)' if p is not None else ''), p
    left_out = len(a_rows) + len(b_rows) - 2 * len(pairs)
    note = f'{len(pairs)} pairs' + (f'; {left_out} runs without the measure left out'
                                    if left_out else '')
    diff = np.array([a[k] - b[k] for k in pairs])
    if np.all(diff == 0):
        return f'not resolved (equal in every pair, {note})', 1.0
    from scipy.stats import ttest_rel
    with warnings.catch_warnings():
        warnings.simplefilter('ignore', RuntimeWarning)
        p = float(ttest_rel([a[k] for k in pairs], [b[k] for k in pairs]).pvalue)
    if not np.isfinite(p):                    # every difference the same, not zero
        p = 0.0
    better = diff.mean() < 0 if a_better == 'lower' else diff.mean() > 0
    if p >= P_VALUE:
        return f'not resolved (within the spread, {note}; {_would_resolve(diff)})', p
    return ('holds' if better else 'does not hold (the opposite)') + f' ({note})', p


POWER = 0.8          # the chance a test of that many pairs resolves a difference that is real
MAX_PAIRS = 10000


def pairs_to_resolve(diff) -> int | None:
    """The fewest pairs whose paired t-test (two-sided, p < P_VALUE) resolves a true mean
    difference and spread equal to those of ``diff`` with probability ``POWER``; None above
    ``MAX_PAIRS`` or for no difference. An estimate from the runs: their own mean and spread
    stand for the true ones."""
    from scipy.stats import nct, t
    d = np.asarray(diff, dtype=float)
    mean, sd = float(d.mean()), float(d.std(ddof=1)) if len(d) > 1 else 0.0
    if mean == 0.0 or not sd > 0.0:
        return None
    effect = abs(mean) / sd
    for n in range(2, MAX_PAIRS + 1):
        crit = t.ppf(1.0 - P_VALUE / 2.0, n - 1)
        shift = effect * math.sqrt(n)
        if nct.sf(crit, n - 1, shift) + nct.cdf(-crit, n - 1, shift) >= POWER:
            return n
    return None


def _would_resolve(diff) -> str:
    """What more runs would do for an unresolved paired comparison, computed."""
    n = pairs_to_resolve(diff)
    if n is None:
        return f'more than {MAX_PAIRS} pairs would be needed at this difference and spread'
    return (f'at this mean difference and spread about {n} pairs would resolve it '
            f'({POWER:.0%} power)')


def p_text(p: float | None) -> str:
    return '' if p is None else f', p = {p:.2g}'


def sign_test(diff, resolution: float | None, unit: str = 'phases') -> str:
    """Paired comparison: a pair counts as better or worse only if the two settings differ;
    the verdict needs the sign test (two-sided, p < P_VALUE) over those. ``resolution``: N s,
    the smallest difference a bisection sees (None: a yes/no outcome); ``unit``: what a pair
    is, for the text."""
    from scipy.stats import binomtest
    better, worse = int(np.sum(np.asarray(diff) > 0)), int(np.sum(np.asarray(diff) < 0))
    counts = (f'better at {better}, worse at {worse}, equal at {len(diff) - better - worse} '
              f'{unit}')
    if better + worse == 0:
        return f'not resolved ({counts})'
    p = float(binomtest(better, better + worse).pvalue)
    if p >= P_VALUE:
        step = (f'; a difference is one bisection step, {resolution:.0f} N s, or more'
                if resolution is not None else '')
        return f'not resolved ({counts}{step}, p = {p:.2g})'
    return ('holds' if better > worse else 'does not hold') + f' ({counts}, p = {p:.2g})'


def push_resolution(cfg: dict) -> float:
    """N s, the bisection's last step: after a first probe that survived, the interval from
    ``first_impulse`` to ``max_impulse`` halved at each of the other probes."""
    return (float(cfg['max_impulse']) - float(cfg['first_impulse'])) / 2 ** max(
        int(cfg['probes']) - 1, 0)


def push_sign_test(table: dict, name: str, resolution: float) -> tuple[list[float], str]:
    """Setting ``name`` against ``correction_off`` over the impulse-push table's pairs (phase
    and seed, index k in both): the differences of the impulse survived and the sign test's
    verdict. A pair where no probe fell in either setting is censored (both figures are lower
    bounds, their difference unknown, not zero): left out, and the verdict says how many
    were."""
    on, off = table[name], table['correction_off']
    censored = [k for k in range(len(on))
                if on[k]['fallen_ns'] is None and off[k]['fallen_ns'] is None]
    diff = [on[k]['survived_ns'] - off[k]['survived_ns'] for k in range(len(on))
            if k not in censored]
    verdict = sign_test(diff, resolution, unit='pairs (phase, seed)') + (
        f'; {len(censored)} pairs censored (no probe fell in either setting: left out)'
        if censored else '')
    return diff, verdict


PAPER_QP_MS = 58.0       # ms per QP in the paper (VI), on 2016 hardware
PAPER_QP_STD_MS = 6.0    # ms, its spread


def against_paper(mean_ms: float, paper_ms: float = PAPER_QP_MS,
                  paper_std_ms: float = PAPER_QP_STD_MS) -> str:
    """A solve time against the paper's 58 +- 6 ms: faster or slower beyond its spread (by how
    much), else as fast."""
    def times(ratio: float) -> str:
        return f'{ratio:.0f}x' if ratio >= 10 else f'{ratio:.1f}x'
    if mean_ms < paper_ms - paper_std_ms:
        return f'faster than the paper ({times(paper_ms / mean_ms)})'
    if mean_ms > paper_ms + paper_std_ms:
        return f'slower than the paper ({times(mean_ms / paper_ms)})'
    return f'as fast as the paper (within its ± {paper_std_ms:.0f} ms)'
