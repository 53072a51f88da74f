"""Statistics of the results page: spreads and the verdicts of comparisons, computed from
the runs, never typed (docs: ``page.py``)."""

from __future__ import annotations

import math
import re
import warnings
from collections import Counter

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
    (``achieved_steady``, replan_core.evaluation.metrics.tracking_errors: the trunk has got to
    the speed and the sway is averaged out); else over the whole cycles after the settling
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


# Share of the set-point: the band of "followed promptly"
# (replan_core.evaluation.metrics.settle_time's default tolerance), judged here on whole-cycle
# means.
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


def pairs_to_resolve(diff, effect: float | None = None, alpha: float = P_VALUE) -> int | None:
    """The fewest pairs whose paired t-test (two-sided, p < ``alpha``) resolves a true mean
    difference ``effect`` (default: the mean of ``diff``) at the spread of ``diff`` with
    probability ``POWER``; None above ``MAX_PAIRS`` or for no difference. The pilot's
    differences with the pre-registered smallest effect and Holm's strictest level (alpha over
    the number of claims) give a plan's n; an estimate from the runs otherwise. A tail of the
    noncentral t that scipy cannot compute (NaN, far out) counts as 0."""
    from scipy.stats import nct, t
    d = np.asarray(diff, dtype=float)
    mean = float(d.mean()) if effect is None else float(effect)
    sd = float(d.std(ddof=1)) if len(d) > 1 else 0.0
    if mean == 0.0 or not sd > 0.0:
        return None
    standardized = abs(mean) / sd
    for n in range(2, MAX_PAIRS + 1):
        crit = t.ppf(1.0 - alpha / 2.0, n - 1)
        shift = standardized * math.sqrt(n)
        tails = (float(nct.sf(crit, n - 1, shift)), float(nct.cdf(-crit, n - 1, shift)))
        if sum(x for x in tails if not math.isnan(x)) >= POWER:
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
    verdict = 'holds' if better > worse else 'does not hold (the opposite)'
    return verdict + f' ({counts}, p = {p:.2g})'


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


# -- pre-registered verdicts -----------------------------------------------------------------
#
# One family: every claim's primary test (config/experiments.yaml, ``primary``), Holm's
# step-down correction over them. Outcomes, in this order of precedence:
#   opposite     Holm-significant with the other sign than the claim's
#   holds        Holm-significant with the claim's sign and the whole 95 % interval beyond
#                the smallest effect that matters (its nearer end at least that effect)
#   negligible   the 95 % interval inside +- the smallest effect (this implies the two one-sided
#                tests of TOST, each at 0.025, so TOST at 0.05)
#   not resolved otherwise

ALPHA = 0.05
CONFIDENCE = 0.95
TESTS = ('paired_t', 'wilcoxon', 'mcnemar', 'fisher')
BINARY_TESTS = ('mcnemar', 'fisher')     # of a yes/no outcome (fell, crossed)
OUTCOMES = ('holds', 'opposite', 'negligible', 'not resolved')


def holm(p_values: list[float], alpha: float = ALPHA) -> tuple[list[float], list[bool]]:
    """Holm's step-down correction: the adjusted p-values (in the given order) and which
    hypotheses are rejected at ``alpha`` (family-wise error at most ``alpha``)."""
    m = len(p_values)
    order = sorted(range(m), key=lambda i: p_values[i])
    adjusted = [0.0] * m
    running = 0.0
    for rank, i in enumerate(order):
        # Monotone: an adjusted p is never below the one of a smaller raw p.
        running = max(running, min(1.0, (m - rank) * p_values[i]))
        adjusted[i] = running
    return adjusted, [a < alpha for a in adjusted]


def paired_t(diff) -> tuple[float, tuple[float, float], float]:
    """Mean of the paired differences, its t interval (``CONFIDENCE``) and the two-sided
    paired t-test's p-value. Differences without spread: the interval is the point and p is
    0 (or 1 when all are zero); one difference: no interval, (-inf, inf), and p = 1."""
    from scipy.stats import t, ttest_1samp
    d = np.asarray(diff, dtype=float)
    mean = float(d.mean())
    if len(d) < 2:
        return mean, (-math.inf, math.inf), 1.0
    if not d.std(ddof=1) > 0.0:
        return mean, (mean, mean), (1.0 if mean == 0.0 else 0.0)
    half = float(t.ppf(0.5 + CONFIDENCE / 2.0, len(d) - 1) * d.std(ddof=1) / math.sqrt(len(d)))
    return mean, (mean - half, mean + half), float(ttest_1samp(d, 0.0).pvalue)


def _signed_rank_cdf(n: int) -> np.ndarray:
    """P(T+ <= t) for t = 0..n(n+1)/2 of the Wilcoxon signed-rank statistic of ``n``
    differences without ties (the exact null distribution, by counting subsets of ranks)."""
    counts = np.zeros(n * (n + 1) // 2 + 1)
    counts[0] = 1.0
    for rank in range(1, n + 1):
        counts[rank:] = counts[rank:] + counts[:-rank].copy()
    return np.cumsum(counts) / 2.0 ** n


def hodges_lehmann(diff) -> tuple[float, tuple[float, float]]:
    """The Hodges-Lehmann estimate of the paired differences (the median of the Walsh
    averages) and its distribution-free interval (``CONFIDENCE``): the Walsh averages of rank
    c+1 and M-c (of M), c the largest count with P(T+ <= c) <= (1 - CONFIDENCE) / 2; below 6
    differences no interval reaches that confidence: (-inf, inf)."""
    d = np.sort(np.asarray(diff, dtype=float))
    n = len(d)
    walsh = np.sort([(d[i] + d[j]) / 2.0 for i in range(n) for j in range(i, n)])
    estimate = float(np.median(walsh))
    cdf = _signed_rank_cdf(n)
    below = np.nonzero(cdf <= (1.0 - CONFIDENCE) / 2.0)[0]
    if not len(below):
        return estimate, (-math.inf, math.inf)
    c = int(below[-1]) + 1              # Walsh averages left out on each side
    return estimate, (float(walsh[c - 1]), float(walsh[len(walsh) - c]))


def wilcoxon_p(diff) -> float:
    """Two-sided p-value of the Wilcoxon signed-rank test of the differences (zeros dropped,
    scipy's default; 1 when every difference is zero)."""
    from scipy.stats import wilcoxon
    d = np.asarray(diff, dtype=float)
    if not np.any(d != 0.0):
        return 1.0
    with warnings.catch_warnings():       # few non-zero differences: the p-value says so
        warnings.simplefilter('ignore')
        return float(wilcoxon(d).pvalue)


def binomial_two_sided(k: int, n: int) -> float:
    """Exact two-sided p-value of ``k`` successes in ``n`` trials at probability 1/2 (twice
    the smaller tail, at most 1): McNemar's exact test on ``k`` of ``n`` discordant pairs."""
    if n == 0:
        return 1.0
    tail = sum(math.comb(n, i) for i in range(min(k, n - k) + 1)) / 2.0 ** n
    return min(1.0, 2.0 * tail)


def wilson(successes: int, n: int) -> tuple[float, float]:
    """Wilson's score interval (``CONFIDENCE``) of a proportion."""
    from scipy.stats import norm
    if n == 0:
        return 0.0, 1.0
    z = float(norm.ppf(0.5 + CONFIDENCE / 2.0))
    p = successes / n
    centre = (p + z * z / (2 * n)) / (1 + z * z / n)
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / (1 + z * z / n)
    return max(0.0, centre - half), min(1.0, centre + half)


def mcnemar(pairs: list[tuple[bool, bool]]) -> tuple[float, tuple[float, float], float]:
    """Paired binary outcomes (treatment, control) per pair: the difference in proportions
    (treatment minus control), Newcombe's interval for paired proportions (his method 10,
    Wilson intervals with the pairs' correlation) and McNemar's exact p-value (the binomial
    test on the discordant pairs)."""
    n = len(pairs)
    a = sum(1 for t, c in pairs if t and c)
    b = sum(1 for t, c in pairs if t and not c)
    c_ = sum(1 for t, c in pairs if c and not t)
    d = n - a - b - c_
    p1, p2 = (a + b) / n, (a + c_) / n
    (l1, u1), (l2, u2) = wilson(a + b, n), wilson(a + c_, n)
    denominator = (a + b) * (c_ + d) * (a + c_) * (b + d)
    phi = (a * d - b * c_) / math.sqrt(denominator) if denominator else 0.0
    diff = p1 - p2
    low = diff - math.sqrt(max(0.0, (p1 - l1) ** 2 - 2 * phi * (p1 - l1) * (u2 - p2)
                               + (u2 - p2) ** 2))
    high = diff + math.sqrt(max(0.0, (u1 - p1) ** 2 - 2 * phi * (u1 - p1) * (p2 - l2)
                                + (p2 - l2) ** 2))
    return diff, (max(-1.0, low), min(1.0, high)), binomial_two_sided(b, b + c_)


def fisher(treatment: list[bool], control: list[bool]) -> tuple[float, tuple[float, float],
                                                                 float]:
    """Unpaired binary outcomes: the difference in proportions (treatment minus control),
    Newcombe's hybrid score interval (Wilson intervals of each) and Fisher's exact p-value."""
    from scipy.stats import fisher_exact
    n1, n2 = len(treatment), len(control)
    k1, k2 = sum(map(bool, treatment)), sum(map(bool, control))
    p1, p2 = k1 / n1, k2 / n2
    (l1, u1), (l2, u2) = wilson(k1, n1), wilson(k2, n2)
    diff = p1 - p2
    low = diff - math.sqrt((p1 - l1) ** 2 + (u2 - p2) ** 2)
    high = diff + math.sqrt((u1 - p1) ** 2 + (p2 - l2) ** 2)
    p = float(fisher_exact([[k1, n1 - k1], [k2, n2 - k2]]).pvalue)
    return diff, (low, high), p


def effect(test: str, sample) -> tuple[float, tuple[float, float], float]:
    """Estimate, 95 % interval and raw two-sided p of one primary test on its ``sample``:
    the paired differences (``paired_t``: mean and t interval; ``wilcoxon``: Hodges-Lehmann
    and its interval), the (treatment, control) outcome pairs (``mcnemar``) or the two
    groups' outcomes (``fisher``)."""
    if test == 'paired_t':
        return paired_t(sample)
    if test == 'wilcoxon':
        estimate, interval = hodges_lehmann(sample)
        return estimate, interval, wilcoxon_p(sample)
    if test == 'mcnemar':
        return mcnemar(sample)
    if test == 'fisher':
        return fisher(*sample)
    raise ValueError(f'unknown test {test!r} (known: {", ".join(TESTS)})')


def outcome(estimate: float, interval: tuple[float, float], significant: bool,
            direction: str, smallest: float) -> str:
    """The outcome of one primary test (the rules at the top of this section). ``direction``:
    'higher' or 'lower', the sign of the effect that supports the claim; ``smallest``: the
    smallest effect that matters (positive, in the measure's unit)."""
    sign = 1.0 if direction == 'higher' else -1.0
    if significant and sign * estimate < 0:
        return 'opposite'
    if significant and min(sign * interval[0], sign * interval[1]) >= smallest:
        return 'holds'
    if -smallest < interval[0] and interval[1] < smallest:
        return 'negligible'
    return 'not resolved'


def verdicts(tests: list[dict]) -> list[dict]:
    """Each primary test (``test``, ``sample``, ``direction``, ``smallest_effect``; ``sample``
    None when it cannot be judged, and ``reason`` then says why) with its ``estimate``,
    ``interval``, raw ``p``, Holm-adjusted ``p_holm`` and ``outcome``. The family is every
    test given, judged or not: one that cannot be judged counts with p = 1, so a claim left
    out never makes the correction of the others milder."""
    judged = [i for i, t in enumerate(tests) if t.get('sample') is not None]
    computed = [effect(tests[i]['test'], tests[i]['sample']) for i in judged]
    adjusted, rejected = holm([c[2] for c in computed] + [1.0] * (len(tests) - len(judged)))
    out = []
    for i, test in enumerate(tests):
        if i not in judged:
            out.append({**test, 'estimate': None, 'interval': None, 'p': None,
                        'p_holm': None, 'outcome': f'no verdict: {test.get("reason", "")}'})
            continue
        k = judged.index(i)
        estimate, interval, p = computed[k]
        out.append({**test, 'estimate': estimate, 'interval': interval, 'p': p,
                    'p_holm': adjusted[k], 'outcome': outcome(
                        estimate, interval, rejected[k], test['direction'],
                        float(test['smallest_effect']))})
    return out


def claim_rows(name: str, data) -> list[dict]:
    """The rows of claim ``name``'s results a primary test reads: the realistic runs' rows;
    the impulse push's table as rows (setting, phase, seed, ``survived_ns``, ``censored``: no
    probe fell, ``plan``)."""
    if name == 'lateral_push':
        if not isinstance(data, dict) or data.get('world', 'realistic') != 'realistic':
            return []
        return [{'setting': setting, 'phase': e['phase'], 'seed': e['seed'], 'ok': True,
                 'survived_ns': e['survived_ns'], 'censored': e['fallen_ns'] is None,
                 'plan': e.get('plan')}
                for setting, entries in data['settings'].items() for e in entries]
    return [r for r in data or [] if isinstance(r, dict)
            and r.get('world', 'realistic') == 'realistic']


def _matches(row: dict, where: dict | None) -> bool:
    return all(row.get(key) in (want if isinstance(want, list) else [want])
               for key, want in (where or {}).items())


def primary_sample(rows: list[dict], block: dict) -> tuple[object, list[dict]]:
    """The sample of primary ``block``'s test from a claim's ``rows`` (completed runs of the
    block's confirmatory ``seeds`` that match its ``where``) and the rows it uses: the
    differences of the pairs (``pair_by``) treatment minus control, or of each run minus
    ``against``; (treatment, control) outcome pairs for ``mcnemar``; the two groups'
    outcomes for ``fisher``. With ``baseline`` each run's measure is first taken minus that of
    its baseline run (a difference in differences; a run without one is left out, the
    baseline runs are among those used). A pair censored in both settings is left out (two
    lower bounds); so is a run without the measure."""
    measure, test = block['measure'], block['test']
    binary = test in BINARY_TESTS
    seeds = set(block['seeds'])
    sel = [r for r in rows if r.get('ok', True) and r.get('seed') in seeds
           and _matches(r, block.get('where')) and r.get(measure) is not None]

    def value(row: dict):
        return bool(row[measure]) if binary else float(row[measure])

    if 'against' in block:
        return [value(r) - float(block['against']) for r in sel], sel
    by, treatment, control = (block['compare'][k] for k in ('by', 'treatment', 'control'))
    pair_by = block.get('pair_by') or ['seed']
    baselines: dict[int, dict | None] = {}
    if block.get('baseline'):
        # A difference in differences: each run's measure minus that of its setting's run that
        # matches the baseline and the run's other pairing keys (the same seed, unpushed).
        baseline = block['baseline']
        match = [by] + [k for k in pair_by if k not in baseline]
        base_rows = {tuple(r.get(k) for k in match): r for r in rows
                     if r.get('ok', True) and r.get('seed') in seeds
                     and _matches(r, baseline) and r.get(measure) is not None}
        baselines = {id(r): base_rows.get(tuple(r.get(k) for k in match)) for r in sel}
        sel = [r for r in sel if baselines[id(r)] is not None]

    def measured(row: dict) -> float:
        base = baselines.get(id(row))
        return value(row) if base is None else value(row) - value(base)

    a = [r for r in sel if r.get(by) == treatment]
    b = [r for r in sel if r.get(by) == control]
    if test == 'fisher':
        return ([value(r) for r in a], [value(r) for r in b]), a + b

    def key(row: dict) -> tuple:
        return tuple(row.get(k) for k in pair_by)

    ia, ib = {key(r): r for r in a}, {key(r): r for r in b}
    pairs = [k for k in sorted(set(ia) & set(ib), key=str)
             if not (ia[k].get('censored') and ib[k].get('censored'))]
    used = [ia[k] for k in pairs] + [ib[k] for k in pairs]
    used += {id(b): b for r in used if (b := baselines.get(id(r))) is not None}.values()
    if test == 'mcnemar':
        return [(value(ia[k]), value(ib[k])) for k in pairs], used
    return [measured(ia[k]) - measured(ib[k]) for k in pairs], used


def primary_verdicts(prereg: dict, results: dict) -> list[dict]:
    """The verdict of every pre-registered claim (``prereg``: plan.preregistration) from the
    call's ``results``: none for a pilot call, for a claim not run, or for runs of another
    pre-registration of the claim (their hash is not the claim's in
    ``prereg['claim_hashes']``), which still count in Holm's family."""
    hashes = prereg.get('claim_hashes') or {}
    tests = []
    for name, block in (prereg.get('claims') or {}).items():
        current = hashes.get(name)
        test = {'claim': name, **block, 'sample': None}
        if prereg.get('role') != 'confirmatory':
            test['reason'] = (f'{prereg.get("role")} runs (seeds {block["seeds"]}) never enter '
                              'a verdict')
        elif name not in results:
            test['reason'] = 'not run in this call'
        else:
            sample, used = primary_sample(claim_rows(name, results[name]), block)
            plans = {r.get('plan') for r in used}
            units = len(sample[0]) + len(sample[1]) if block['test'] == 'fisher' else len(sample)
            if plans - {current}:
                other = ', '.join(sorted(str(p or 'none') for p in plans - {current}))
                test['reason'] = (f'runs of another pre-registration (hash {other}, this '
                                  f'claim\'s {current})')
            elif units < 2:
                test['reason'] = f'{units} usable runs or pairs of the plan\'s seeds'
            else:
                test['sample'], test['units'] = sample, units
        tests.append(test)
    # Two families, each Holm-corrected on its own: the paper's claims, and the claims tested
    # again elsewhere (variants: another robot or gait), so a replication never makes the
    # correction of the paper's claims stricter.
    return (verdicts([t for t in tests if not is_variant(t)])
            + verdicts([t for t in tests if is_variant(t)]))


# Where a variant of a claim is tested (plan.VARIANT_KEYS besides ``experiment``).
VARIANT_WHERE = ('robot', 'gait', 'setpoint_scale')


def is_variant(block: dict) -> bool:
    """Whether a primary block (or its verdict) is a claim tested again elsewhere."""
    return 'experiment' in block


def pilot_sizes(prereg: dict, results: dict) -> list[dict]:
    """Per pre-registered claim, what its pilot runs (``results`` of a ``--pilot`` call) say
    of its n: the primary sample on the pilot seeds, its mean and spread, and the confirmatory
    seeds a paired t-test needs to resolve the smallest effect that matters with ``POWER`` at
    Holm's strictest level (alpha over the number of claims of its family):
    ``pairs_to_resolve`` of the pilot's differences (each run minus the bound with
    ``against``), over the pilot's pairs per seed. A binary outcome gets no figure (its n:
    the plan's reason)."""
    blocks = prereg.get('claims') or {}
    family = Counter(is_variant(block) for block in blocks.values())
    rows = []
    for name, block in blocks.items():
        alpha = P_VALUE / family[is_variant(block)]
        row = {'claim': name, 'measure': block['measure'], 'unit': block['unit'],
               'smallest_effect': float(block['smallest_effect']), 'n': block['n'],
               'alpha': alpha, 'pairs': None,
               **{k: block[k] for k in ('experiment', *VARIANT_WHERE)
                  if k in block}}
        if name not in results:
            row['reason'] = 'not run in this call'
        elif block['test'] in BINARY_TESTS:
            row['reason'] = 'a binary outcome: n from the plan\'s reason'
        else:
            pilot = {**block, 'seeds': list(block['pilot_seeds'])}
            diff, used = primary_sample(claim_rows(name, results[name]), pilot)
            seeds = {r.get('seed') for r in used}
            if len(diff) < 2:
                row['reason'] = f'{len(diff)} usable pilot pairs'
            else:
                d = np.asarray(diff, dtype=float)
                per_seed = len(d) / max(len(seeds), 1)
                pairs = pairs_to_resolve(d, effect=row['smallest_effect'], alpha=alpha)
                row.update(pairs=len(d), pilot_seeds=len(seeds), mean=float(d.mean()),
                           sd=float(d.std(ddof=1)), pairs_needed=pairs,
                           seeds_needed=(None if pairs is None
                                         else max(2, math.ceil(pairs / per_seed))))
        rows.append(row)
    return rows


_EXPLORATORY = ((re.compile(r'\bdoes not hold \(the opposite\)'), 'the other direction'),
                (re.compile(r'\bdoes not hold\b'), 'not met'),
                (re.compile(r'\bholds\b'), 'the claimed direction'),
                (re.compile(r'\bnot resolved\b'), 'undecided'))


def exploratory(text: str) -> str:
    """A comparison's text as an exploratory one: the words of a verdict ('holds', 'does not
    hold', 'not resolved') replaced by what they describe; only the pre-registered primary
    tests have verdicts."""
    for pattern, words in _EXPLORATORY:
        text = pattern.sub(words, text)
    return text
