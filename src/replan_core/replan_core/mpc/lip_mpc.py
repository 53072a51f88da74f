"""LIP-ZMP MPC, the CoM plan of a re-plan: the jerk QP of eq. (6) with the coupled
support-polygon rows of eq. (7).

This module is the MPC's interface: :class:`MpcResult`, the status and fallback names, and
:class:`LipMpc`, which checks the input, builds the support schedule, solves, checks the plan
against every row and falls back (its settings, ``MpcSettings``, are in ``mpc/settings.py``,
numpy only). Three formulations of the same QP, all built once, solved by the two classes
:class:`LipMpc` mixes in:

- ``working_set`` (default, ``mpc/working_set.py``): the dual restricted to a working set of
  polygon rows, solved exactly by a small active-set method (docs/mpc.md);
- ``sparse`` and ``dense`` (``mpc/full_qp.py``): the full QP with proxsuite, states and jerks
  with the dynamics as equality rows, or the condensed form of the paper (jerks only).

A solve never raises: bad input or an infeasible problem gives a :class:`MpcResult` whose
``status`` and ``reason`` say what went wrong (which sample, which constraint block) and whose
plan is a safe fallback, flagged as such (slack-relaxed solution, else the previous plan shifted,
else holding the current position).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np

from replan_core.common.proxqp import aligned_empty, proxqp
from replan_core.common.types import ComPlan, FootholdPlan
from replan_core.gait.crawl import is_stand_plan
from replan_core.mpc.full_qp import FullQp
from replan_core.mpc.lip import lift, lip_matrices
from replan_core.mpc.settings import MpcSettings
from replan_core.mpc.support import MAX_ROWS, SupportSchedule, support_schedule
from replan_core.mpc.working_set import WorkingSetDual

_INF = 1e20                     # proxsuite's "no bound"

STATUS_SOLVED = 'solved'
STATUS_DEGENERATE = 'degenerate_polygon'
STATUS_INFEASIBLE = 'infeasible'
STATUS_REJECTED = 'rejected'
FALLBACK_NONE = ''
FALLBACK_RELAXED = 'relaxed'
FALLBACK_SHIFTED = 'previous_plan_shifted'
FALLBACK_HOLD = 'hold_position'


def replan_start_state(t: float, measured_com: np.ndarray, measured_vcom: np.ndarray,
                       footholds: FootholdPlan, last_plan: ComPlan | None,
                       last_stood: bool) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The CoM position (m), velocity (m/s) and acceleration (m/s^2) a re-plan at ``t`` starts
    from.

    Algorithm 1 re-plans from the measured CoM, with the acceleration of the plan in force
    (eq. 2). A stand plan that follows a stand plan (``last_stood``: the plan in force was made
    for one) continues the plan in force instead: the feet have not moved, and re-planning a
    standing robot from its measured CoM adds the controller's steady tracking offset to the
    reference at every idle re-plan (``gait.idle_replan_period``), a ratchet that carried the
    trunk 2-3 cm in 7 s of standing (docs/gait.md, "Idle stance").
    """
    acc = np.zeros(3)
    if last_plan is not None and last_plan.start_time <= t:
        position, velocity, acc = last_plan.sample(t)
        if last_stood and is_stand_plan(footholds):
            return position, velocity, acc
    return measured_com, measured_vcom, acc


@dataclass
class MpcResult:
    """Outcome of one re-plan. ``plan`` is None only if there was nothing safe to return."""

    status: str                       # STATUS_*
    fallback: str                     # FALLBACK_*: '' when the plan is the QP optimum
    reason: str                       # human-readable why (empty when solved)
    plan: ComPlan | None
    zmp: np.ndarray                   # (N+1, 2) m, predicted ZMP at the samples (row 0: now)
    solve_time_ms: float              # wall time of the whole re-plan call
    iterations: int                   # QP iterations (hard + relaxed solves): active-set
                                      # ones of the working-set dual, else proxsuite's
    min_zmp_margin_m: float           # smallest distance of the ZMP inside its polygon (k>=1)
    max_zmp_violation_m: float        # largest violation of a polygon row (margin included)
    jerk: np.ndarray | None = None    # (N, 2) m/s^3
    cost: float = math.nan            # jerk cost 1/2 R sum |u|^2 of the returned plan
    # CPU time of this thread in the call: below solve_time_ms when the process lost its core
    # meanwhile (other processes on a busy machine), so the two tell contention from work.
    solve_cpu_ms: float = math.nan

    @property
    def ok(self) -> bool:
        return self.status == STATUS_SOLVED

    @property
    def is_fallback(self) -> bool:
        return bool(self.fallback)


def _finite(name: str, value, shape: tuple[int, ...]) -> str:
    """'' if ``value`` is a finite array of ``shape``, else the rejection message."""
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        return f'{name} is not numeric'
    if arr.shape != shape:
        return f'{name} has shape {arr.shape}, expected {shape}'
    if not np.all(np.isfinite(arr)):
        return f'{name} contains NaN or inf: {arr.tolist()}'
    return ''


class LipMpc(WorkingSetDual, FullQp):
    """The re-planner: QP built once in the constructor, updated and warm-started per call."""

    def __init__(self, settings: MpcSettings | None = None):
        self.settings = s = settings or MpcSettings()
        if s.formulation not in ('working_set', 'sparse', 'dense'):
            raise ValueError(f'unknown formulation {s.formulation!r}')
        if not (math.isfinite(s.line_support_width) and s.line_support_width >= 0.0):
            raise ValueError(f'line_support_width must be finite, >= 0, got '
                             f'{s.line_support_width}')
        self.n = n = s.n
        self.lifted = lift(n, s.dt, s.com_height, s.gravity)
        self._A, self._B, _ = lip_matrices(s.dt, s.com_height, s.gravity)
        self._hg = s.com_height / s.gravity
        self._omega = math.sqrt(s.gravity / s.com_height)
        self.n_terminal = MAX_ROWS if s.terminal_capture_point else 0
        self.n_in = MAX_ROWS * n + self.n_terminal
        self._prev: dict | None = None            # last solution, for the warm start
        self._last_plan: ComPlan | None = None    # last plan returned, for the fallback
        self.last_schedule: SupportSchedule | None = None
        self._poly_cache: dict = {}               # polygons by stance, shared across re-plans
        self._ws_t0: float | None = None
        self._ws_prev: tuple[np.ndarray, ...] | None = None
        self.cold = True
        if s.formulation == 'sparse':
            self._build_sparse()
        elif s.formulation == 'dense':
            self._build_dense()
        else:
            self._build_working_set()
        self._l = aligned_empty(self.n_in)
        self._l.fill(-_INF)
        self._u = aligned_empty(self.n_in)
        self._u.fill(_INF)

    # ------------------------------------------------------------------ shared by the formulations

    def _settings(self, qp) -> None:
        s = self.settings
        qp.settings.eps_abs = s.eps_abs
        qp.settings.eps_rel = 0.0
        qp.settings.max_iter = s.max_iter
        qp.settings.verbose = False
        # Without the gap check the sparse backend may stop at a point that is primal and dual
        # feasible but not complementary (a row with a multiplier that is not tight).
        qp.settings.check_duality_gap = True
        qp.settings.eps_duality_gap_abs = s.eps_abs
        qp.settings.eps_duality_gap_rel = 0.0
        qp.settings.initial_guess = proxqp.InitialGuess.WARM_START

    def _states(self, x0: np.ndarray, jerk: np.ndarray) -> np.ndarray:
        """States s_0..s_N (N+1, 6) of eq. (4) for the initial state x0 (6,) and jerks (N, 2)."""
        L = self.lifted
        out = np.empty((self.n + 1, 6))
        out[0] = x0
        xs = L.S0 @ x0.reshape(2, 3).T + L.Su @ jerk                 # (3N, 2): both axes
        out[1:] = xs.reshape(self.n, 3, 2).transpose(0, 2, 1).reshape(self.n, 6)
        return out

    # ------------------------------------------------------------------ solving

    def reset(self) -> None:
        """Forget the previous solution (next solve is cold, no shifted fallback)."""
        self._prev = None
        self._last_plan = None
        self._ws_prev = None

    def solve(self, start_time: float, com_pos: np.ndarray, com_vel: np.ndarray,
              com_acc: np.ndarray, support: FootholdPlan | SupportSchedule,
              v_ref: np.ndarray | None = None, com_z: float | None = None) -> MpcResult:
        """Re-plan from the actual CoM state at ``start_time``.

        ``com_pos``, ``com_vel``, ``com_acc`` are (3,) (only x, y are planned); ``support`` is a
        foothold plan (polygons are built here) or a ready schedule of N samples; ``v_ref`` (2,)
        m/s is the velocity the tracking term pulls to; ``com_z`` (m) the planned CoM height
        (default: mean initial foot height + ``com_height``, else ``com_pos[2]``).
        """
        cpu_start = time.thread_time()
        result = self._solve(start_time, com_pos, com_vel, com_acc, support, v_ref, com_z)
        result.solve_cpu_ms = (time.thread_time() - cpu_start) * 1e3
        return result

    def _solve(self, start_time: float, com_pos: np.ndarray, com_vel: np.ndarray,
               com_acc: np.ndarray, support: FootholdPlan | SupportSchedule,
               v_ref: np.ndarray | None, com_z: float | None) -> MpcResult:
        t_start = time.perf_counter()
        s, n = self.settings, self.n
        msg = (_finite('com_pos', com_pos, (3,)) or _finite('com_vel', com_vel, (3,))
               or _finite('com_acc', com_acc, (3,))
               or _finite('start_time', start_time, ()))
        if not msg and v_ref is not None:
            msg = _finite('v_ref', v_ref, (2,))
        if not msg and isinstance(support, FootholdPlan):
            msg = _finite('initial_feet', support.initial_feet, (4, 3))
            steps = support.steps
            if not msg and steps:
                try:
                    table = np.array([[*st.target, st.liftoff_time, st.touchdown_time]
                                      for st in steps], dtype=float)
                except (TypeError, ValueError):
                    table = np.full((1, 5), np.nan)
                if table.shape != (len(steps), 5) or not np.all(np.isfinite(table)):
                    bad = [i for i, st in enumerate(steps)
                           if _finite('', [*np.ravel(st.target), st.liftoff_time,
                                           st.touchdown_time], (5,))]
                    msg = f'steps {bad} have a non-finite or malformed target or time'
        if msg:
            t0 = float(start_time) if not _finite('', start_time, ()) else 0.0
            return self._fallback(t0, None, None, STATUS_REJECTED, f'input rejected: {msg}',
                                  t_start, 0, None)
        com_pos = np.asarray(com_pos, dtype=float)
        com_vel = np.asarray(com_vel, dtype=float)
        com_acc = np.asarray(com_acc, dtype=float)
        if isinstance(support, FootholdPlan):
            if len(self._poly_cache) > 512:         # footholds keep moving: stay bounded
                self._poly_cache.clear()
            sched = support_schedule(support, start_time, s.dt, n, s.zmp_margin,
                                     self._poly_cache, centres=s.position_weight > 0.0,
                                     line_width=s.line_support_width)
            if com_z is None:
                com_z = float(np.mean(np.asarray(support.initial_feet)[:, 2])) + s.com_height
        else:
            sched = support
            if sched.n != n:
                return self._fallback(start_time, None, None, STATUS_REJECTED,
                                      f'input rejected: schedule has {sched.n} samples, '
                                      f'the QP {n}', t_start, 0, None)
            if s.position_weight > 0.0 and sched.centres is None:
                return self._fallback(start_time, None, None, STATUS_REJECTED,
                                      'input rejected: the position term needs the feet '
                                      'centres (support_schedule(..., centres=True))',
                                      t_start, 0, None)
        if com_z is None:
            com_z = float(com_pos[2])
        x0 = np.array([com_pos[0], com_vel[0], com_acc[0], com_pos[1], com_vel[1], com_acc[1]])
        v_ref = np.zeros(2) if v_ref is None else np.asarray(v_ref, dtype=float)

        self.last_schedule = sched
        self._ws_t0 = start_time
        self._ws_args = (sched, x0, v_ref)
        if s.formulation != 'working_set':
            self._fill(sched, x0, v_ref)
        iters = 0
        if not sched.degenerate.any():
            try:
                if s.formulation == 'working_set':
                    ok, jerk, iters, solver_status = self._solve_working_set(
                        sched, x0, v_ref, relaxed=False)
                else:
                    ok, jerk, iters, solver_status = self._solve_hard(
                        self._warm(start_time, x0))
            except (RuntimeError, ValueError) as exc:        # proxsuite's own errors
                ok, jerk, solver_status = False, None, f'proxsuite error: {exc}'
            if ok and np.all(np.isfinite(jerk)):
                states = self._states(x0, jerk)
                viol = self._violations(sched, states)
                if viol.max(initial=0.0) <= s.violation_tol:
                    if s.formulation == 'working_set':
                        self._prev = {'t0': start_time}
                    else:
                        qres = self.qp.results
                        self._prev = {'t0': start_time, 'jerk': jerk, 'z': qres.z.copy(),
                                      'y': qres.y.copy() if self.n_eq else None}
                    res = self._result(STATUS_SOLVED, FALLBACK_NONE, '', start_time, states,
                                       jerk, com_z, sched, t_start, iters, viol)
                    self._last_plan = res.plan
                    return res
                why = self._first_violation(sched, viol, solver_status='')
                status_reason = f'QP solved but {why}'
            else:
                status_reason = f'QP not solved ({solver_status})'
            status = STATUS_INFEASIBLE
        else:
            status = STATUS_DEGENERATE
            status_reason = 'degenerate support polygon at ' + '; '.join(sched.reasons[:3])
            if len(sched.reasons) > 3:
                status_reason += f' (+{len(sched.reasons) - 3} more samples)'
        return self._fallback(start_time, x0, sched, status, status_reason, t_start, iters,
                              com_z)

    # ------------------------------------------------------------------ results and fallbacks

    def _violations(self, sched: SupportSchedule, states: np.ndarray) -> np.ndarray:
        """Violation (m, >= 0) of every row: (N+terminal, MAX_ROWS)."""
        zmp = np.column_stack([states[1:, 0] - self._hg * states[1:, 2],
                               states[1:, 3] - self._hg * states[1:, 5]])
        d = np.einsum('nrj,nj->nr', sched.A, zmp) + sched.b
        d = np.where(sched.active, d, np.inf)
        out = [np.maximum(-d, 0.0)]
        if self.n_terminal:
            cp = np.array([states[-1, 0] + states[-1, 1] / self._omega,
                           states[-1, 3] + states[-1, 4] / self._omega])
            dt_ = np.where(sched.active[-1], sched.A[-1] @ cp + sched.b[-1], np.inf)
            out.append(np.maximum(-dt_, 0.0)[None, :])
        return np.vstack(out)

    def _first_violation(self, sched: SupportSchedule, viol: np.ndarray,
                         solver_status: str) -> str:
        bad = np.argwhere(viol > self.settings.violation_tol)
        if len(bad) == 0:
            return f'no row violated by more than {self.settings.violation_tol:g} m' + (
                f' ({solver_status})' if solver_status else '')
        k, r = (int(v) for v in bad[0])
        worst = float(viol.max())
        if k >= self.n:
            return (f'terminal capture-point block violated (edge {r}, worst row '
                    f'{worst:.4f} m)')
        return (f'support-polygon block eq. (7) violated first at sample {k + 1} '
                f'(t={sched.times[k]:.3f} s, {sched.n_feet[k]} feet, edge {r}), '
                f'{len(bad)} rows, worst {worst:.4f} m')

    def _result(self, status, fallback, reason, t0, states, jerk, com_z, sched, t_start,
                iters, viol=None) -> MpcResult:
        s = self.settings
        n = self.n
        pos = np.column_stack([states[:, 0], states[:, 3], np.full(n + 1, com_z)])
        vel = np.column_stack([states[:, 1], states[:, 4], np.zeros(n + 1)])
        acc = np.column_stack([states[:, 2], states[:, 5], np.zeros(n + 1)])
        plan = ComPlan(start_time=float(t0), dt=s.dt, position=pos, velocity=vel,
                       acceleration=acc)
        zmp = np.column_stack([states[:, 0] - self._hg * states[:, 2],
                               states[:, 3] - self._hg * states[:, 5]])
        if sched is not None:
            if viol is None:
                viol = self._violations(sched, states)
            margins = sched.margins(zmp[1:]) + s.zmp_margin     # distance to the real edges
            min_margin = float(np.min(margins))
            max_viol = float(viol.max(initial=0.0))
        else:
            min_margin, max_viol = math.nan, math.nan
        cost = 0.5 * s.jerk_weight * float(np.sum(jerk**2)) if jerk is not None else math.nan
        return MpcResult(status=status, fallback=fallback, reason=reason, plan=plan, zmp=zmp,
                         solve_time_ms=(time.perf_counter() - t_start) * 1e3,
                         iterations=iters, min_zmp_margin_m=min_margin,
                         max_zmp_violation_m=max_viol, jerk=jerk, cost=cost)

    def _fallback(self, t0, x0, sched, status, reason, t_start, iters, com_z) -> MpcResult:
        """Safe plan when the QP optimum is not available, flagged as such."""
        if sched is not None and x0 is not None:
            try:
                if self.settings.formulation == 'working_set':
                    ok, jerk, it, _ = self._solve_working_set(*self._ws_args, relaxed=True)
                else:
                    ok, jerk, it = self._solve_relaxed()
            except (RuntimeError, ValueError):
                ok, jerk, it = False, None, 0
            iters += it
            if ok and np.all(np.isfinite(jerk)):
                states = self._states(x0, jerk)
                viol = self._violations(sched, states)
                if status == STATUS_INFEASIBLE:
                    reason = f'{reason}; relaxed: {self._first_violation(sched, viol, "")}'
                res = self._result(status, FALLBACK_RELAXED, reason, t0, states, jerk, com_z,
                                   sched, t_start, iters)
                # The relaxed plan is what will be executed: warm-start from it next time.
                self._prev = {'t0': t0, 'jerk': jerk, 'z': np.zeros(self.n_in),
                              'y': np.zeros(self.n_eq) if self.n_eq else None}
                if self.settings.formulation == 'working_set':
                    self._prev = {'t0': t0}
                self._last_plan = res.plan
                return res
        n, dt = self.n, self.settings.dt
        if self._last_plan is not None:
            p = self._last_plan
            samples = [p.sample(t0 + k * dt) for k in range(n + 1)]
            pos = np.array([q[0] for q in samples])
            vel = np.array([q[1] for q in samples])
            acc = np.array([q[2] for q in samples])
            fb, plan = FALLBACK_SHIFTED, ComPlan(t0, dt, pos, vel, acc)
        elif x0 is not None:
            z = com_z if com_z is not None else 0.0
            pos = np.tile([x0[0], x0[3], z], (n + 1, 1))
            fb, plan = FALLBACK_HOLD, ComPlan(t0, dt, pos, np.zeros((n + 1, 3)),
                                              np.zeros((n + 1, 3)))
        else:
            fb, plan = FALLBACK_HOLD, None
        zmp = (np.column_stack([plan.position[:, 0] - self._hg * plan.acceleration[:, 0],
                                plan.position[:, 1] - self._hg * plan.acceleration[:, 1]])
               if plan is not None else np.zeros((n + 1, 2)))
        return MpcResult(status=status, fallback=fb, reason=reason, plan=plan, zmp=zmp,
                         solve_time_ms=(time.perf_counter() - t_start) * 1e3,
                         iterations=iters, min_zmp_margin_m=math.nan,
                         max_zmp_violation_m=math.nan)
