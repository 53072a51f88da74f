"""Benchmark of the MPC's support constraint on two feet (a trot's diagonal; docs/mpc.md).

Closed-loop re-plans of a gait file's plan (``config/gaits/<gait>.yaml``, HyQ's standing feet
and mpc settings), each at the planned touchdown of the plan's first step (its last foot
down), from the previous CoM plan sampled there; the feet land on their targets. Two
formulations of the support constraint of two feet:

- ``strip`` (what ``LipMpc`` does): the line support of ``mpc/support.py``, the 4 half-space
  rows of a strip ``--width`` wide about the segment, solved by the working-set dual;
- ``vertex`` (Winkler et al. 2017): the ZMP of each sample a convex combination of its stance
  feet, z_k = sum_i w_ki p_i, w_ki >= 0, sum_i w_ki = 1; the weights are decision variables
  (one per stance foot and sample), the dynamics' ZMP enters as equalities, solved by
  proxsuite's dense backend (warm-started from the previous solution). No margin (a vertex
  form with a margin needs shrunk feet, which a segment does not have).

Same cost in both: the jerk plus the velocity term (``velocity_weight``, the node's 300); no
position term. One JSON line per run:

    python -m replan_core.bench.line_support_bench --gait trot --speed 0.1 --width 0.02
    python -m replan_core.bench.line_support_bench --gait trot --formulation vertex
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

from replan_core.common.proxqp import proxqp
from replan_core.gait.crawl import CrawlSchedule, GaitParams, compute_footholds
from replan_core.gait.gait_file import load_gait
from replan_core.mpc.lip import lift
from replan_core.mpc.lip_mpc import LipMpc
from replan_core.mpc.settings import MpcSettings
from replan_core.mpc.support import implied_velocity, support_schedule

ROOT = Path(__file__).resolve().parents[4]      # the repository (src/replan_core/replan_core/..)
HEIGHT = 0.55                                   # m, HyQ's LIP height (config/mpc.yaml)


def hyq_settings(width: float, margin: float = 0.02) -> MpcSettings:
    """config/mpc.yaml's QP without the position term, with a line support ``width`` m."""
    return MpcSettings(com_height=HEIGHT, velocity_weight=300.0, zmp_margin=margin,
                       line_support_width=width)


def standing_feet(params: GaitParams) -> np.ndarray:
    """(4, 3) HyQ's feet in its standing pose about the origin, yaw 0."""
    xy = np.asarray(params.hip_offsets) + np.asarray(params.stance_offsets)
    return np.column_stack([xy, np.zeros(4)])


class VertexQp:
    """The vertex form of the support constraint (Winkler 2017) as one dense QP per re-plan."""

    def __init__(self, settings: MpcSettings) -> None:
        self.s = settings
        self.n = settings.n
        self.lifted = lift(self.n, settings.dt, settings.com_height, settings.gravity)
        lf = self.lifted
        self.Hj = (settings.jerk_weight * np.eye(self.n)
                   + settings.velocity_weight * lf.Vu.T @ lf.Vu)
        self.qp = None
        self.shape = None
        self.last = None

    def solve(self, t0: float, pos, vel, acc, plan) -> dict:
        """One re-plan; wall time of the whole call (QP built and solved), ms."""
        start = time.perf_counter()
        n, lf = self.n, self.lifted
        # The contact set of each sample as LipMpc sees it (the trot's switch sample included):
        # the vertices of its polygon or the two ends of its segment.
        sched = support_schedule(plan, t0, self.s.dt, n, 0.0, line_width=1e-6)
        feet = [poly.vertices for poly in sched.polygons]
        nw = sum(len(f) for f in feet)
        nv = 2 * n + nw
        v_ref = implied_velocity(plan)
        H = np.zeros((nv, nv))
        g = np.zeros(nv)
        A = np.zeros((3 * n, nv))
        b = np.zeros(3 * n)
        col = 2 * n
        for ax in range(2):
            x0 = np.array([pos[ax], vel[ax], acc[ax]])
            sl = slice(ax * n, (ax + 1) * n)
            H[sl, sl] = self.Hj
            g[sl] = self.s.velocity_weight * lf.Vu.T @ (lf.V0 @ x0 - v_ref[ax])
            A[ax * n:(ax + 1) * n, sl] = lf.Zu
            b[ax * n:(ax + 1) * n] = -lf.Z0 @ x0
        for k, fk in enumerate(feet):
            m = len(fk)
            A[k, col:col + m] = -fk[:, 0]              # z_x,k - sum w p_x = 0
            A[n + k, col:col + m] = -fk[:, 1]
            A[2 * n + k, col:col + m] = 1.0            # sum w = 1
            b[2 * n + k] = 1.0
            col += m
        C = np.zeros((nw, nv))
        C[:, 2 * n:] = np.eye(nw)
        lo, hi = np.zeros(nw), np.full(nw, 1e20)
        if self.qp is None or self.shape != nv:
            self.qp = proxqp.dense.QP(nv, 3 * n, nw)
            self.qp.settings.eps_abs = self.s.eps_abs
            self.qp.settings.max_iter = 10000
            self.qp.init(H, g, A, b, C, lo, hi)
            self.shape = nv
        else:
            self.qp.update(H, g, A, b, C, lo, hi)
        self.qp.solve()
        ms = (time.perf_counter() - start) * 1e3
        res = self.qp.results
        x = res.x
        ok = res.info.status == proxqp.QPSolverOutput.PROXQP_SOLVED
        states = []
        for ax in range(2):
            x0 = np.array([pos[ax], vel[ax], acc[ax]])
            states.append((lf.S0 @ x0 + lf.Su @ x[ax * n:(ax + 1) * n]).reshape(n, 3))
        weights_min = float(x[2 * n:].min())
        return dict(ok=ok, ms=ms, iterations=int(res.info.iter), states=states,
                    weights_min=weights_min)


def _sampler(states: list[np.ndarray], t0: float, dt: float):
    """The vertex form's plan at a sample time after ``t0``: (pos, vel, acc) (3,) each."""
    sx, sy = states

    def sample(t: float):
        k = round((t - t0) / dt)
        return (np.array([sx[k - 1, 0], sy[k - 1, 0], HEIGHT]),
                np.array([sx[k - 1, 1], sy[k - 1, 1], 0.0]),
                np.array([sx[k - 1, 2], sy[k - 1, 2], 0.0]))
    return sample


def run(gait: str, speed: float, width: float, formulation: str, replans: int,
        margin: float) -> dict:
    """Closed-loop re-plans; the figures of the run."""
    spec = load_gait(gait, ROOT / 'config')
    params = spec.params()
    settings = hyq_settings(width, margin if formulation == 'strip' else 0.0)
    solver = LipMpc(settings) if formulation == 'strip' else VertexQp(settings)
    schedule = CrawlSchedule(params.sequence, groups=params.groups)
    feet = standing_feet(params)
    pos = np.array([feet[:, 0].mean(), feet[:, 1].mean(), HEIGHT])
    vel, acc = np.zeros(3), np.zeros(3)
    t = 0.0
    times, iters, statuses, margins, violations = [], [], {}, [], []
    for i in range(replans):
        plan = compute_footholds((speed, 0.0, 0.0), feet, pos, 0.0, None, schedule.next_leg,
                                 t, params, delay=0.0 if i else params.swing_duration)
        if formulation == 'strip':
            res = solver.solve(t, pos, vel, acc, plan, v_ref=implied_velocity(plan))
            statuses[res.status] = statuses.get(res.status, 0) + 1
            if i:
                times.append(res.solve_time_ms)
            iters.append(res.iterations)
            margins.append(res.min_zmp_margin_m)
            violations.append(res.max_zmp_violation_m)
            sample = res.plan.sample
        else:
            out = solver.solve(t, pos, vel, acc, plan)
            key = 'solved' if out['ok'] else 'not_solved'
            statuses[key] = statuses.get(key, 0) + 1
            if i:
                times.append(out['ms'])
            iters.append(out['iterations'])
            violations.append(max(0.0, -out['weights_min']))
            sample = _sampler(out['states'], t, settings.dt)
        group = [st for st in plan.steps if st.liftoff_time == plan.steps[0].liftoff_time]
        t_next = group[0].touchdown_time
        # Re-plan on the sample grid (the vertex form's states are at samples only).
        t_next = t + settings.dt * round((t_next - t) / settings.dt)
        p, v, a = sample(t_next)
        pos, vel, acc = np.asarray(p, float).copy(), np.asarray(v, float).copy(), \
            np.asarray(a, float).copy()
        for st in group:
            feet[st.leg] = st.target
            schedule.touched_down(st.leg)
        t = t_next
    times_arr = np.asarray(times)
    return dict(gait=gait, formulation=formulation, speed=speed,
                width=width if formulation == 'strip' else None,
                margin=settings.zmp_margin, replans=replans, statuses=statuses,
                median_ms=round(float(np.median(times_arr)), 3),
                p99_ms=round(float(np.percentile(times_arr, 99)), 3),
                median_iter=float(np.median(iters)), max_iter=int(max(iters)),
                min_zmp_margin_m=(round(float(np.min(margins)), 5) if margins else None),
                max_violation_m=float(np.max(violations)),
                distance_m=round(float(pos[0] - standing_feet(params)[:, 0].mean()), 3),
                end_time_s=round(t, 3))


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    parser.add_argument('--gait', default='trot')
    parser.add_argument('--speed', type=float, default=0.1, help='m/s forward')
    parser.add_argument('--width', type=float, default=0.02, help='m, strip width')
    parser.add_argument('--margin', type=float, default=0.02, help='m, zmp_margin (strip)')
    parser.add_argument('--formulation', choices=('strip', 'vertex'), default='strip')
    parser.add_argument('--replans', type=int, default=40)
    args = parser.parse_args(argv)
    print(json.dumps(run(args.gait, args.speed, args.width, args.formulation, args.replans,
                         args.margin)))


if __name__ == '__main__':
    main()

