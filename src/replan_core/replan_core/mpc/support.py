"""Support polygons per sample as half-spaces, the rows of eq. (7).

A polygon is the convex hull of the horizontal positions of the feet in stance. Each edge gives
one half-space ``a_x * z_x + a_y * z_y + b >= 0`` (``a`` the unit inward normal, so the left side
is the signed distance in metres from the edge, minus the safety margin). X and Y are coupled
by these rows (paper, footnote 1).

In a crawl a sample has 3 (one leg swinging) or 4 (all feet down) stance feet, so every sample
gets ``MAX_ROWS = 4`` rows; unused rows are flagged inactive (the QP keeps its sparsity pattern
and only relaxes them).

Two feet (a trot's diagonal pair) support the ZMP only on the segment between them. With a
``line_width`` > 0 such a sample gets a *line support*: a strip of that width centred on the
segment, two rows across it (no margin: a segment has no interior to shrink) and two along it
(shrunk by the margin at each end), the same 4 rows as a polygon (docs/mpc.md, "Two feet: the
line support"). With ``line_width`` 0 two feet are degenerate, as the crawl expects.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from itertools import combinations, pairwise

import numpy as np

from replan_core.common.types import LEGS, FootholdPlan

MAX_ROWS = 4
MIN_AREA = 1e-4           # m^2: below this a hull is treated as degenerate (collinear feet)


@dataclass
class SupportPolygon:
    """One convex polygon as half-spaces ``normals @ z + offsets >= 0`` (margin included)."""

    normals: np.ndarray                    # (m, 2) unit inward normals
    offsets: np.ndarray                    # (m,) m
    vertices: np.ndarray                   # (v, 2) hull vertices, counter-clockwise
    area: float                            # m^2, without margin
    chebyshev_radius: float                # m, radius of the largest inscribed disc, with margin
    degenerate: bool
    reason: str = ''

    def margin_of(self, z: np.ndarray) -> float:
        """Smallest signed distance (m, margin included) of ``z`` (2,) to the edges."""
        if len(self.offsets) == 0:
            return -np.inf
        return float(np.min(self.normals @ z + self.offsets))


def convex_hull(points: np.ndarray) -> np.ndarray:
    """Counter-clockwise hull of 2-D points (Andrew's monotone chain), collinear points dropped.

    Plain Python on purpose: the hulls here have at most 4 points, where numpy's per-call
    overhead would dominate (this runs for every stance of every re-plan).
    """
    return np.array(_hull_list(_xy_list(points)), dtype=float).reshape(-1, 2)


def _xy_list(points) -> list:
    """(x, y) float pairs of points (k, 2 or 3)."""
    arr = np.asarray(points, dtype=float)
    if arr.size == 0:
        return []
    return [(p[0], p[1]) for p in arr.reshape(len(arr), -1).tolist()]


def _hull_list(points: list) -> list:
    """``convex_hull`` on a list of (x, y) float pairs, returning a list of pairs."""
    pts = sorted(set(points))
    if len(pts) <= 2:
        return pts

    def cross(o, a, b):
        return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])

    lower: list = []
    for p in pts:
        while len(lower) >= 2 and cross(lower[-2], lower[-1], p) <= 1e-12:
            lower.pop()
        lower.append(p)
    upper: list = []
    for p in reversed(pts):
        while len(upper) >= 2 and cross(upper[-2], upper[-1], p) <= 1e-12:
            upper.pop()
        upper.append(p)
    return lower[:-1] + upper[:-1]


def _chebyshev_radius(normals: np.ndarray, offsets: np.ndarray) -> float:
    """Largest r with a disc of radius r inside ``normals @ z + offsets >= 0``.

    A 2-D LP in (z, r): its optimum sits where three edges are equidistant, so enumerating the
    triples of edges is exact (1 triple for a triangle, 4 for a quadrilateral). Equidistance
    from edges i, j, k is 2 linear equations in z, ``(n_j - n_i) z = o_i - o_j`` (same for k),
    solved by Cramer's rule in plain Python.
    """
    nl = normals.tolist() if isinstance(normals, np.ndarray) else list(normals)
    ol = offsets.tolist() if isinstance(offsets, np.ndarray) else list(offsets)
    m = len(ol)
    best = -math.inf
    for i, j, k in combinations(range(m), 3):
        (nix, niy), oi = nl[i], ol[i]
        d1x, d1y, e1 = nl[j][0] - nix, nl[j][1] - niy, oi - ol[j]
        d2x, d2y, e2 = nl[k][0] - nix, nl[k][1] - niy, oi - ol[k]
        det = d1x * d2y - d1y * d2x
        if abs(det) < 1e-12:
            continue
        zx = (e1 * d2y - d1y * e2) / det
        zy = (d1x * e2 - e1 * d2x) / det
        r = min(n[0] * zx + n[1] * zy + o for n, o in zip(nl, ol, strict=True))
        best = max(best, r)
    return best


def _segment_rows(p0: np.ndarray, p1: np.ndarray, margin: float
                  ) -> tuple[np.ndarray, np.ndarray]:
    """4 rows of a zero-width rectangle around the segment p0-p1 (a point: a zero box).

    Infeasible with a positive margin, but they give the slack-relaxed fallback something to
    pull the ZMP towards.
    """
    e = p1 - p0
    length = float(np.linalg.norm(e))
    e = e / length if length > 1e-9 else np.array([1.0, 0.0])
    nrm = np.array([-e[1], e[0]])
    normals = np.array([nrm, -nrm, e, -e])
    offsets = np.array([-nrm @ p0, nrm @ p0, -e @ p0, e @ p1]) - margin
    return normals, offsets


def _line_support(p0: np.ndarray, p1: np.ndarray, margin: float,
                  line_width: float) -> SupportPolygon:
    """The line support of two feet p0, p1 (2,): a strip ``line_width`` wide about the segment,
    rows ``|n . (z - p0)| <= line_width / 2`` across (n the segment's unit normal) and
    ``margin <= e . (z - p0) <= |p1 - p0| - margin`` along (e its unit direction).

    Degenerate when the margin leaves nothing along it (feet closer than twice the margin).
    """
    e = p1 - p0
    length = float(np.linalg.norm(e))
    e = e / length
    nrm = np.array([-e[1], e[0]])
    half = 0.5 * line_width
    normals = np.array([nrm, -nrm, e, -e])
    offsets = np.array([half - nrm @ p0, half + nrm @ p0, -e @ p0 - margin, e @ p1 - margin])
    hull = np.array([p0, p1])
    if length <= 2.0 * margin:
        return SupportPolygon(normals, offsets, hull, 0.0, -np.inf, True,
                              f'2 feet {length:.3f} m apart, empty after the {margin:.3f} m '
                              'margin')
    return SupportPolygon(normals, offsets, hull, 0.0, min(half, 0.5 * length - margin), False)


def polygon(points: np.ndarray, margin: float = 0.0, line_width: float = 0.0) -> SupportPolygon:
    """Half-spaces of the convex hull of ``points`` (k, 2 or 3), shrunk inwards by ``margin``.

    Degenerate (flagged, never raised): fewer than 3 distinct feet (2 feet are a line support
    if ``line_width`` > 0, m), collinear feet (area below ``MIN_AREA``), or nothing left inside
    once the margin is applied.
    """
    return _polygon(_xy_list(points), margin, line_width)


def _polygon(pl: list, margin: float, line_width: float = 0.0) -> SupportPolygon:
    """``polygon`` of a list of (x, y) float pairs."""
    hl = _hull_list(pl)
    hull = np.array(hl, dtype=float).reshape(-1, 2)
    if len(hull) == 0:
        return SupportPolygon(np.zeros((0, 2)), np.zeros(0), hull, 0.0, -np.inf, True,
                              'no stance foot')
    if len(hull) == 2 and line_width > 0.0 and len(set(pl)) == 2:
        return _line_support(hull[0], hull[1], margin, line_width)
    if len(hull) < 3:
        normals, offsets = _segment_rows(hull[0], hull[-1], margin)
        n_pts = len(set(pl))
        why = ('collinear stance feet' if n_pts >= 3
               else f'{n_pts} distinct stance feet (need 3)')
        return SupportPolygon(normals, offsets, hull, 0.0, -np.inf, True, why)
    nv = len(hl)
    area = 0.5 * sum(hl[i][0] * hl[(i + 1) % nv][1] - hl[(i + 1) % nv][0] * hl[i][1]
                     for i in range(nv))
    if area < MIN_AREA:
        i, j = np.unravel_index(np.argmax(np.linalg.norm(hull[:, None] - hull[None], axis=2)),
                                (len(hull), len(hull)))
        normals, offsets = _segment_rows(hull[i], hull[j], margin)
        return SupportPolygon(normals, offsets, hull, area, -np.inf, True,
                              f'collinear stance feet (area {area:.2e} m^2)')
    nrm, off = [], []
    for i in range(nv):                  # inward unit normal of a CCW edge: left of it
        ex = hl[(i + 1) % nv][0] - hl[i][0]
        ey = hl[(i + 1) % nv][1] - hl[i][1]
        ln = math.hypot(ex, ey)
        nx, ny = -ey / ln, ex / ln
        nrm.append((nx, ny))
        off.append(-(nx * hl[i][0] + ny * hl[i][1]) - margin)
    normals = np.array(nrm)
    offsets = np.array(off)
    if nv == 3:        # incircle: r = 2 area / perimeter, minus the margin (every edge shifts)
        perimeter = sum(math.dist(hl[i], hl[(i + 1) % 3]) for i in range(3))
        radius = 2.0 * area / perimeter - margin
    else:
        radius = _chebyshev_radius(nrm, off)
    if radius <= 0.0:
        return SupportPolygon(normals, offsets, hull, area, radius, True,
                              f'empty after the {margin:.3f} m margin')
    return SupportPolygon(normals, offsets, hull, area, radius, False)


def stance_at(plan: FootholdPlan, t: float) -> tuple[np.ndarray, np.ndarray]:
    """Feet positions (4, 3) and stance flags (4,) at sim time ``t`` under ``plan``.

    A leg is in swing on the closed interval [liftoff, touchdown]: at the boundary samples the
    smaller polygon is used, which is the conservative choice.
    """
    feet = np.array(plan.initial_feet, dtype=float).copy()
    stance = np.ones(len(LEGS), dtype=bool)
    for s in plan.steps:
        if t < s.liftoff_time:
            continue
        if t <= s.touchdown_time:
            stance[s.leg] = False
        else:
            feet[s.leg] = s.target
            stance[s.leg] = True
    # A leg swinging at t may have landed earlier steps: the loop keeps the latest state.
    return feet, stance


@dataclass
class SupportSchedule:
    """The eq. (7) rows for samples k = 1..N: ``A[k-1, r] @ z_k + b[k-1, r] >= 0``."""

    times: np.ndarray                      # (N,) s, sim time of each sample
    A: np.ndarray                          # (N, MAX_ROWS, 2)
    b: np.ndarray                          # (N, MAX_ROWS)
    active: np.ndarray                     # (N, MAX_ROWS) bool: False = padding row
    n_feet: np.ndarray                     # (N,) stance feet per sample
    degenerate: np.ndarray                 # (N,) bool
    reasons: list[str] = field(default_factory=list)   # per degenerate sample: why
    polygons: list[SupportPolygon] = field(default_factory=list)
    # (N, 2) m: centre of the four feet at each sample, a swinging foot halfway between its
    # lift-off point and its target, and centroid of the stance feet (the position term's
    # references, MpcSettings.position_weight and position_sway)
    centres: np.ndarray | None = None
    stance_centres: np.ndarray | None = None
    # (N,) rad: the trunk yaw reference at each sample (that of the last step touched down, the
    # plan's initial yaw before the first), which turns the position term's CoM offset
    yaws: np.ndarray | None = None

    @property
    def n(self) -> int:
        return len(self.times)

    def first_degenerate(self) -> int:
        """Index (0-based, sample k = index + 1) of the first degenerate sample, or -1."""
        idx = np.flatnonzero(self.degenerate)
        return int(idx[0]) if len(idx) else -1

    def margins(self, zmp: np.ndarray) -> np.ndarray:
        """Per sample, the smallest signed distance (m) of ``zmp`` (N, 2) inside its polygon."""
        d = np.einsum('nrj,nj->nr', self.A, zmp) + self.b
        d = np.where(self.active, d, np.inf)
        out = d.min(axis=1)
        out[self.degenerate] = -np.inf
        return out


def support_schedule(plan: FootholdPlan, start_time: float, dt: float, n: int,
                     margin: float = 0.0, cache: dict | None = None,
                     centres: bool = False, line_width: float = 0.0) -> SupportSchedule:
    """Support polygons at the samples ``start_time + k dt``, k = 1..N, from a foothold plan.

    After the last planned step the final stance is kept to the end of the horizon. The stance
    of every sample is computed with array operations (one pass per step); the samples then
    fall into runs of one stance (a crawl horizon has ~17), whose rows are written as slices.
    Polygons are built once per distinct stance and kept in ``cache`` (a dict owned by the
    caller) across calls, since consecutive re-plans share all but one foothold. A swinging leg
    is out of the stance on the closed interval [liftoff, touchdown] (see ``stance_at``).
    ``centres``: also the position term's references (``SupportSchedule.centres``,
    ``stance_centres`` and ``yaws``; left None otherwise, so a re-plan without the term does not
    pay for them).
    ``line_width``: m, > 0 makes two stance feet a line support (``polygon``). Then a sample
    that the closed swing intervals leave with fewer than two feet (a trot's switch, where one
    pair touches down as the other lifts off) counts the legs touching down at it (within
    1e-9 s) as down: the ZMP, continuous, passes there through the crossing of the two
    diagonals, which lies on the landing pair's segment.
    """
    times = start_time + dt * np.arange(1, n + 1)
    nleg = len(LEGS)
    feet0 = np.asarray(plan.initial_feet, dtype=float)
    # src[k, leg]: -1 = initial foot, j = target of step j; swing[k, leg]: in the air.
    src = np.full((n, nleg), -1, dtype=np.int64)
    swing = np.zeros((n, nleg), dtype=bool)
    if plan.steps:                      # times ascend: the comparisons become index ranges
        i_lo = np.searchsorted(times, [st.liftoff_time for st in plan.steps], 'left').tolist()
        i_td = np.searchsorted(times, [st.touchdown_time for st in plan.steps], 'right').tolist()
        for j, st in enumerate(plan.steps):
            swing[i_lo[j]:i_td[j], st.leg] = True      # liftoff <= t <= touchdown
            src[i_td[j]:, st.leg] = j                    # t > touchdown
        if line_width > 0.0:
            _land_at_switches(plan, times, i_td, swing, src)
    code = np.where(swing, -2, src)                      # what defines each leg's contribution
    # Runs of samples with the same stance: [bounds[i], bounds[i + 1]).
    bounds = np.flatnonzero((code[1:] != code[:-1]).any(axis=1)) + 1
    bounds = [0, *bounds.tolist(), n]
    feet_xy = feet0[:, :2].tolist()
    targets_xy = [(float(st.target[0]), float(st.target[1])) for st in plan.steps]
    A = np.zeros((n, MAX_ROWS, 2))
    b = np.zeros((n, MAX_ROWS))
    active = np.zeros((n, MAX_ROWS), dtype=bool)
    n_feet = np.zeros(n, dtype=int)
    degenerate = np.zeros(n, dtype=bool)
    polys: list[SupportPolygon] = []
    reasons: list[str] = []
    if cache is None:
        cache = {}
    for (k0, k1), row in zip(pairwise(bounds), code[bounds[:-1]].tolist(), strict=True):
        pts = tuple((feet_xy[leg][0], feet_xy[leg][1]) if c == -1 else targets_xy[c]
                    for leg, c in enumerate(row) if c != -2)
        key = (pts, margin, line_width)
        poly = cache.get(key)
        if poly is None:
            poly = _polygon(list(pts), margin, line_width)
            cache[key] = poly
        polys.extend([poly] * (k1 - k0))
        m = min(len(poly.offsets), MAX_ROWS)
        A[k0:k1, :m] = poly.normals[:m]
        b[k0:k1, :m] = poly.offsets[:m]
        active[k0:k1, :m] = True
        n_feet[k0:k1] = len(pts)
        if poly.degenerate:
            degenerate[k0:k1] = True
            reasons += [f'sample {k + 1} (t={times[k]:.3f} s): {poly.reason}'
                        for k in range(k0, k1)]
    sched = SupportSchedule(times, A, b, active, n_feet, degenerate, reasons, polys)
    if centres:
        sched.centres, sched.stance_centres = _feet_centres(plan, feet0, src, swing)
        # Steps touch down in their order, so the last one down is the largest index stood on.
        last = src.max(axis=1)
        yaws = np.array([plan.initial_yaw, *(st.yaw for st in plan.steps)], dtype=float)
        sched.yaws = yaws[last + 1]
    return sched


def _land_at_switches(plan: FootholdPlan, times: np.ndarray, i_td: list[int],
                      swing: np.ndarray, src: np.ndarray) -> None:
    """In place: at samples with fewer than two feet down under the closed swing intervals,
    the legs whose touchdown is at the sample (within 1e-9 s) stand on their targets."""
    few = (~swing).sum(axis=1) < 2
    if not few.any():
        return
    i_land = np.searchsorted(times, [st.touchdown_time - 1e-9 for st in plan.steps],
                             'left').tolist()
    for j, st in enumerate(plan.steps):
        rows = np.arange(i_land[j], i_td[j])
        rows = rows[few[rows]]
        swing[rows, st.leg] = False
        src[rows, st.leg] = j


def _feet_centres(plan: FootholdPlan, feet0: np.ndarray, src: np.ndarray,
                  swing: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per sample (N, 2) m: the centre of the four feet, a swinging foot halfway between its
    lift-off point and its target, and the centroid of the feet in stance. ``src`` and
    ``swing`` are ``support_schedule``'s: the step whose target a leg stands on (-1: its
    initial foot; while it swings, the step before), and whether it is in the air."""
    nleg = len(feet0)
    targets = np.array([st.target[:2] for st in plan.steps], dtype=float).reshape(-1, 2)
    # Each leg's position per sample: row `leg` of `where` for an initial foot, nleg + j for
    # the target of step j.
    where = np.vstack([feet0[:, :2], targets])
    legs = np.broadcast_to(np.arange(nleg), src.shape)
    stand = where[np.where(src < 0, legs, nleg + src)]            # (N, legs, 2)
    # A swinging leg's target: the first step of that leg after the one it stands on.
    nxt = np.full(src.shape, -1, dtype=np.int64)
    for j in range(len(plan.steps) - 1, -1, -1):     # later steps first: the earliest wins
        leg = plan.steps[j].leg
        nxt[:, leg] = np.where(src[:, leg] < j, j, nxt[:, leg])
    legs_xy = stand
    if plan.steps:
        air = where[nleg + np.maximum(nxt, 0)]
        legs_xy = np.where(swing[:, :, None], 0.5 * (stand + air), stand)
    down = ~swing
    stance = (stand * down[:, :, None]).sum(axis=1) / np.maximum(down.sum(axis=1), 1)[:, None]
    return legs_xy.mean(axis=1), stance


def implied_velocity(plan: FootholdPlan) -> np.ndarray:
    """Horizontal velocity (m/s, world) the footholds imply: the reference of the velocity
    term of the cost.

    With at least two steps per leg it is the advance of the stance centre over the last full
    cycle (each leg moved once more) divided by its duration: the first step of each leg also
    makes up for where the feet happen to be (foothold correction, lag), which would bias a
    start-to-end average. With fewer steps it falls back to that average; with fewer than one
    per leg (a plan that stops: a stand plan, or the last swing before one) it is zero, as the
    few steps only bring feet back under the trunk.
    """
    steps = plan.steps
    if len(steps) < len(plan.initial_feet):
        return np.zeros(2)
    feet = np.array(plan.initial_feet, dtype=float)
    centres = [(plan.start_time, feet[:, :2].mean(axis=0))]
    for s in steps:
        feet[s.leg] = s.target
        centres.append((s.touchdown_time, feet[:, :2].mean(axis=0)))
    n_legs = len(plan.initial_feet)
    first = len(centres) - 1 - n_legs if len(steps) >= 2 * n_legs else 0
    (t0, c0), (t1, c1) = centres[first], centres[-1]
    if not t1 - t0 > 0.0:
        return np.zeros(2)
    v = (c1 - c0) / (t1 - t0)
    return v if np.all(np.isfinite(v)) else np.zeros(2)
