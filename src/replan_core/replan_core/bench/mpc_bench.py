"""Benchmark of the LIP-ZMP re-planner on a realistic crawl (ROS-free).

200 consecutive re-plans (default) at the paper's size: 8 s horizon, 40 ms samples, 8 planned
footholds. Each re-plan starts at a haptic touchdown (planned time +- jitter, so the horizon
shift is not a whole number of samples), from the previous plan sampled there plus a tracking
error, with footholds recomputed about the actual CoM (foothold correction) for a velocity
set-point that changes over the run. The crawl is built here on purpose (no dependency on
``replan_core.gait.crawl``). The last printed line is one JSON object.

    python -m replan_core.bench.mpc_bench [--formulation sparse|dense] [--replans 200] ...
                                          [--robot NAME|FILE --root DIR]

The crawl is a robot's (``--robot``, a robot file; HyQ's by default): its feet in the standing
pose, the bench's swing and four-feet times scaled by its pendulum time sqrt(l / g), the
set-points by sqrt(g l) and the LIP height its CoM height (``config/robots/scaling.yaml``).

``median_iter``/``max_iter`` count the QP iterations of a re-plan: active-set iterations of the
working-set dual by default, proxsuite's with ``--proxsuite-dual`` or a full formulation.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from replan_core.bench import bench_robots, is_reference
from replan_core.common.types import FootholdPlan, Step
from replan_core.mpc.lip_mpc import LipMpc
from replan_core.mpc.settings import MpcSettings
from replan_core.robot.robot_file import robot_facts
from replan_core.robot.scaling import SCALES

CRAWL_ORDER = (2, 0, 3, 1)                 # lh, lf, rh, rf
SWING, FOUR_FEET = 0.6, 0.4                # s, the reference robot's bench crawl


@dataclass(frozen=True)
class BenchCrawl:
    """The robot the bench plans for: its standing feet (4, 2) (m, base frame xy), one swing
    and the four-feet phase before it (s), the factor of the set-points and the LIP height
    (m)."""

    feet_xy: np.ndarray
    swing: float = SWING
    four_feet: float = FOUR_FEET
    speed_scale: float = 1.0
    com_height: float | None = None     # None: the MPC settings' (the reference robot's)

    def settings(self, base: MpcSettings | None = None) -> MpcSettings:
        """``base`` (default: the defaults) with this robot's CoM height as the LIP height;
        the reference robot keeps the tuned one, as the launcher does."""
        base = base or MpcSettings()
        return base if self.com_height is None else replace(base, com_height=self.com_height)


def bench_crawl(robot: str, root: Path) -> BenchCrawl:
    """The crawl of robot file ``robot`` (a name of ``root``/config/robots/ or a path):
    timing and set-points scaled from the reference robot's by sqrt(l / g) and sqrt(g l).
    ValueError (RobotFileError) names the file and key of a bad robot file."""
    spec, reference, _ = bench_robots(robot, root)
    facts, ref = robot_facts(spec), robot_facts(reference)
    time_scale = SCALES['time'](facts) / SCALES['time'](ref)
    # The reference keeps its tuned LIP height (config/mpc.yaml), as the launcher does.
    same = is_reference(spec, reference)
    return BenchCrawl(feet_xy=np.asarray(facts.feet_xy, dtype=float), swing=SWING * time_scale,
                      four_feet=FOUR_FEET * time_scale,
                      speed_scale=SCALES['speed'](facts) / SCALES['speed'](ref),
                      com_height=None if same else float(facts.com_height))


def crawl_plan(t0: float, com: np.ndarray, yaw: float, feet: np.ndarray, first_leg: int,
               v_ref: np.ndarray, rng: np.random.Generator, *, layout: np.ndarray,
               n_steps: int = 8, swing: float = SWING, four_feet: float = FOUR_FEET,
               noise: float = 0.01) -> FootholdPlan:
    """A crawl FootholdPlan from ``t0``: four-feet phase, then ``n_steps`` swings in crawl order.

    Footholds are placed about the CoM reference ``com + v_ref (t - t0)`` at touchdown, a half
    cycle ahead (foothold correction about the actual CoM), at the standing ``layout`` (4, 2)
    (m, base frame), plus seeded noise (m).
    """
    k0 = CRAWL_ORDER.index(first_leg)
    cycle = len(CRAWL_ORDER) * (swing + four_feet)
    c, s = np.cos(yaw), np.sin(yaw)
    rot = np.array([[c, -s], [s, c]])
    steps = []
    t = t0 + four_feet
    for j in range(n_steps):
        leg = CRAWL_ORDER[(k0 + j) % 4]
        td = t + swing
        ref = com[:2] + v_ref * (td - t0) + v_ref * cycle / 2.0
        xy = ref + rot @ layout[leg] + rng.normal(0.0, noise, 2)
        steps.append(Step(leg=leg, liftoff_time=t, touchdown_time=td,
                          target=np.array([xy[0], xy[1], 0.0]), step_height=0.1,
                          haptic=True, replan=(j == 0), yaw=yaw))
        t = td + four_feet
    return FootholdPlan(start_time=t0, initial_feet=feet.copy(), initial_yaw=yaw, steps=steps)


def velocity_profile(i: int) -> np.ndarray:
    """Set-point (m/s) of re-plan i: start, speed up, side-step, slow down, ..."""
    phase = (i // 25) % 4
    return np.array([[0.05, 0.0], [0.12, 0.0], [0.08, 0.04], [0.10, -0.03]][phase])


IDLE_MODES = ('sleep', 'spin', 'evict')


def _idle(seconds: float, mode: str, sweep: np.ndarray | None) -> None:
    if mode == 'sleep':
        time.sleep(seconds)
        return
    end = time.perf_counter() + seconds
    while time.perf_counter() < end:
        if sweep is not None:
            sweep += 1.0


def run(settings: MpcSettings, crawl: BenchCrawl, replans: int = 200, seed: int = 0,
        jitter: float = 0.03, pos_noise: float = 0.003, vel_noise: float = 0.01,
        idle: float = 0.0, idle_mode: str = 'sleep') -> dict:
    """Run ``crawl``'s robot and return the figures (times in ms). ``idle`` (wall s) before each
    re-plan (not timed), as the mpc node idles between touchdowns in the graph; ``idle_mode``
    says how: ``sleep`` (the core is free: as in the graph), ``spin`` (a busy loop that
    touches little memory: the core never idles, the caches keep the solver's data) or
    ``evict`` (busy writing a 64 MB buffer: the core never idles, the caches lose the
    solver's data). ``cpu_median_ms`` tells a slower solve from waiting for a core."""
    if idle_mode not in IDLE_MODES:
        raise ValueError(f'idle_mode must be one of {IDLE_MODES}: {idle_mode!r}')
    sweep = np.zeros(8 << 20) if idle_mode == 'evict' else None      # 64 MB of float64
    rng = np.random.default_rng(seed)
    t_build = time.perf_counter()
    mpc = LipMpc(settings)
    build_ms = (time.perf_counter() - t_build) * 1e3
    feet = np.column_stack([crawl.feet_xy, np.zeros(4)])
    com = np.zeros(3)
    vel = np.zeros(3)
    acc = np.zeros(3)
    t = 0.0
    leg = CRAWL_ORDER[0]
    times, iters, viols, margins, statuses, n_tri, n_quad = [], [], [], [], {}, 0, 0
    cpu_times = []
    end_speed = []
    for i in range(replans):
        v_ref = velocity_profile(i) * crawl.speed_scale
        plan = crawl_plan(t, com, 0.0, feet, leg, v_ref, rng, layout=crawl.feet_xy,
                          swing=crawl.swing, four_feet=crawl.four_feet)
        if idle > 0.0:
            _idle(idle, idle_mode, sweep)
        t0 = time.perf_counter()
        res = mpc.solve(t, com, vel, acc, plan, v_ref=v_ref)
        times.append((time.perf_counter() - t0) * 1e3)
        cpu_times.append(res.solve_cpu_ms)
        iters.append(res.iterations)
        statuses[res.status] = statuses.get(res.status, 0) + 1
        viols.append(res.max_zmp_violation_m)
        margins.append(res.min_zmp_margin_m)
        if i == 0:
            sched_feet = [len(p.offsets) for p in mpc.last_schedule.polygons]
            n_tri = sum(1 for m in sched_feet if m == 3)
            n_quad = sum(1 for m in sched_feet if m == 4)
        end_speed.append(float(np.linalg.norm(res.plan.velocity[-1, :2])))
        # The robot executes the plan until the first step's (haptic) touchdown.
        first = plan.steps[0]
        t_next = first.touchdown_time + rng.uniform(-jitter, jitter)
        p, v, a = res.plan.sample(t_next)
        com = p + np.r_[rng.normal(0.0, pos_noise, 2), 0.0]
        vel = v + np.r_[rng.normal(0.0, vel_noise, 2), 0.0]
        acc = a
        feet = feet.copy()
        feet[first.leg] = first.target
        leg = CRAWL_ORDER[(CRAWL_ORDER.index(first.leg) + 1) % 4]
        t = t_next
    arr = np.array(times)
    return {
        'formulation': settings.formulation,
        'n_per_axis': mpc.n,
        'n_variables': mpc.nv,
        'n_constraints': mpc.n_in + mpc.n_eq,
        'n_inequalities': mpc.n_in,
        'n_equalities': mpc.n_eq,
        'replans': replans,
        'triangle_samples_first_plan': n_tri,
        'quad_samples_first_plan': n_quad,
        'build_ms': round(build_ms, 3),
        'cold_ms': round(float(arr[0]), 3),
        'median_ms': round(float(np.median(arr[1:])), 3),
        'cpu_median_ms': round(float(np.median(cpu_times[1:])), 3),
        'idle_s': idle,
        'idle_mode': idle_mode,
        'mean_ms': round(float(np.mean(arr[1:])), 3),
        'std_ms': round(float(np.std(arr[1:], ddof=1)) if len(arr) > 2 else 0.0, 3),
        'p99_ms': round(float(np.percentile(arr[1:], 99)), 3),
        'max_ms': round(float(np.max(arr[1:])), 3),
        'median_iter': float(np.median(iters[1:])),
        'max_iter': int(np.max(iters)),
        'max_zmp_violation_m': float(np.nanmax(viols)),
        'min_zmp_margin_m': round(float(np.nanmin(margins)), 5),
        'max_end_speed_mps': round(float(np.max(end_speed)), 4),
        'statuses': statuses,
        'eps_abs': settings.eps_abs,
        'warm_start': settings.warm_start,
        'terminal_capture_point': settings.terminal_capture_point,
        'drop_inactive': settings.drop_inactive,
        'add_peaks_only': settings.add_peaks_only,
        'exact_dual': settings.exact_dual,
    }


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('--formulation', default=MpcSettings.formulation,
                    choices=('working_set', 'sparse', 'dense'))
    ap.add_argument('--replans', type=int, default=200)
    ap.add_argument('--idle', type=float, default=0.0,
                    help='wall s of sleep before each re-plan (not timed): cold solves as in '
                         'the graph, where the mpc idles between touchdowns')
    ap.add_argument('--idle-mode', default='sleep', choices=IDLE_MODES,
                    help='sleep (default; the core is free), spin (busy, caches kept) or evict '
                         '(busy writing 64 MB: caches lost)')
    ap.add_argument('--seed', type=int, default=0)
    ap.add_argument('--eps-abs', type=float, default=MpcSettings.eps_abs)
    ap.add_argument('--max-iter', type=int, default=MpcSettings.max_iter)
    ap.add_argument('--jerk-weight', type=float, default=MpcSettings.jerk_weight)
    ap.add_argument('--velocity-weight', type=float, default=0.0)
    ap.add_argument('--zmp-margin', type=float, default=0.02)
    ap.add_argument('--no-warm', action='store_true', help='cold start every re-plan')
    ap.add_argument('--no-terminal', action='store_true', help='no terminal capture point')
    ap.add_argument('--keep-inactive', action='store_true',
                    help='working set: keep rows whose multiplier is 0')
    ap.add_argument('--add-all-violated', action='store_true',
                    help='working set: add the worst row of every violated sample')
    ap.add_argument('--proxsuite-dual', action='store_true',
                    help='working set: solve the dual with proxsuite (+ KKT polish) instead of '
                         'the exact active-set method')
    ap.add_argument('--robot', default='',
                    help='a robot file: a name of config/robots/ (go1) or a path (default: '
                         'the reference robot of config/robots/scaling.yaml, HyQ)')
    ap.add_argument('--root', default='.', help='the project (its config/ and urdf/)')
    args = ap.parse_args(argv)
    try:
        crawl = bench_crawl(args.robot, Path(args.root))
    except ValueError as err:            # RobotFileError: one line naming file and key
        print(f'config error: {err}', file=sys.stderr)
        raise SystemExit(2) from None
    settings = MpcSettings(formulation=args.formulation, eps_abs=args.eps_abs,
                           max_iter=args.max_iter, jerk_weight=args.jerk_weight,
                           velocity_weight=args.velocity_weight, zmp_margin=args.zmp_margin,
                           warm_start=not args.no_warm,
                           terminal_capture_point=not args.no_terminal,
                           drop_inactive=not args.keep_inactive,
                           add_peaks_only=not args.add_all_violated,
                           exact_dual=not args.proxsuite_dual)
    settings = crawl.settings(settings)
    print(json.dumps({'robot': args.robot, **run(settings, crawl, args.replans, args.seed,
                                                  idle=args.idle, idle_mode=args.idle_mode)}))


if __name__ == '__main__':
    main()
