"""LIP-ZMP re-planner: the jerk QP of eq. (6) with the coupled support-polygon rows of eq. (7).

Three formulations of the same QP, all built once: ``working_set`` (default), the dual
restricted to a working set of polygon rows, solved exactly by a small active-set method (see
``_solve_working_set`` and ``_nnqp``; docs/mpc.md), and two full ones solved with proxsuite:

- ``sparse``: the decision vector holds the states and the jerks of every sample,
  time-major ``[s_0, u_0, s_1, u_1, ..., s_N]`` with ``s_k = (x, xd, xdd, y, yd, ydd)`` and
  ``u_k = (jerk_x, jerk_y)``; eq. (3) enters as equality rows, so the KKT matrix is banded and
  every polygon row touches only the 4 state entries of its own sample. Between re-plans only
  the initial-state right-hand side and the polygon row values change (the Hessian and the
  dynamics rows are constant, the sparsity pattern is fixed).
- ``dense``: the condensed form of the paper, eq. (4)-(7), jerks only (kept for comparison).

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
import scipy.sparse as sp
from scipy.linalg.lapack import dposv as _dposv

from replan_core.lip import lift, lip_matrices
from replan_core.proxqp import aligned, aligned_empty, proxqp
from replan_core.support import MAX_ROWS, SupportSchedule, support_schedule
from replan_core.types import ComPlan, FootholdPlan

_INF = 1e20                     # proxsuite's "no bound"

STATUS_SOLVED = 'solved'
STATUS_DEGENERATE = 'degenerate_polygon'
STATUS_INFEASIBLE = 'infeasible'
STATUS_REJECTED = 'rejected'
FALLBACK_NONE = ''
FALLBACK_RELAXED = 'relaxed'
FALLBACK_SHIFTED = 'previous_plan_shifted'
FALLBACK_HOLD = 'hold_position'


@dataclass
class MpcSettings:
    """Parameters of the re-planner (the node reads them from ``config/mpc.yaml``)."""

    dt: float = 0.04                  # s, sampling = constant-jerk interval
    horizon: float = 8.0              # s
    com_height: float = 0.55          # m, above the mean stance foot height (eq. 1)
    gravity: float = 9.81             # m/s^2
    jerk_weight: float = 1.0          # R of eq. (6)
    velocity_weight: float = 0.0      # weight of sum |v_k - v_ref|^2; 0 disables the term
    zmp_margin: float = 0.0           # m, inward safety margin of every polygon
    terminal_capture_point: bool = True   # capture point at N inside the last polygon
    formulation: str = 'working_set'  # 'working_set' (default), 'sparse' or 'dense', see above
    eps_abs: float = 1e-6             # proxsuite absolute tolerance
    max_iter: int = 200               # proxsuite iterations per solve
    warm_start: bool = True           # warm start from the previous solution shifted in time
    violation_tol: float = 1e-4       # m, a "solved" plan may violate a row by at most this
    slack_weight: float = 1e6         # cost per m (and m^2) of row violation in the fallback
    max_rounds: int = 30              # working set: row-adding rounds before giving up
    drop_inactive: bool = True        # working set: drop rows whose multiplier is 0
    add_peaks_only: bool = True       # working set: add rows only where the violation peaks
    working_set_tol: float = 1e-6     # m, working set: a row violated by more is added
    dual_mu_in: float = 1e-1          # proxsuite mu_in of the working-set dual
    # Working set: give up (and take the relaxed fallback) once the duals of one solve have
    # used this many iterations (active-set iterations of _nnqp, proxsuite's with
    # exact_dual=False). A feasible re-plan uses 5-65 active-set iterations (30-75 proxsuite
    # ones; bench_mpc.sh); the dual of an infeasible one is unbounded and each proxsuite solve
    # of it runs ~10000, so without the budget an infeasible re-plan took 4-11 s
    # (test_bad_input.py) while the robot waited.
    iteration_budget: int = 2000
    # Working set: solve each restricted dual exactly by an active-set method (a few small
    # LAPACK Cholesky solves, see _nnqp) instead of proxsuite; False: proxsuite + KKT polish
    # (the previous default, kept for comparison: bench_mpc.sh --proxsuite-dual).
    exact_dual: bool = True

    @property
    def n(self) -> int:
        return round(self.horizon / self.dt)


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


class LipMpc:
    """The re-planner: QP built once in the constructor, updated and warm-started per call."""

    def __init__(self, settings: MpcSettings | None = None):
        self.settings = s = settings or MpcSettings()
        if s.formulation not in ('working_set', 'sparse', 'dense'):
            raise ValueError(f'unknown formulation {s.formulation!r}')
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

    # ------------------------------------------------------------------ building

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

    def _build_sparse(self) -> None:
        s, n = self.settings, self.n
        nv = 8 * n + 6
        self.nv = nv
        xi = [8 * k for k in range(n + 1)]                    # first state entry of sample k

        # Cost eq. (6): 1/2 R |u|^2 (+ 1/2 w_v |v - v_ref|^2 over samples 1..N).
        diag = np.zeros(nv)
        for k in range(n):
            diag[xi[k] + 6:xi[k] + 8] = s.jerk_weight
        if s.velocity_weight > 0.0:
            for k in range(1, n + 1):
                diag[[xi[k] + 1, xi[k] + 4]] = s.velocity_weight
        self._H = sp.diags(diag).tocsc()
        self._vel_idx = np.array([[xi[k] + 1, xi[k] + 4] for k in range(1, n + 1)])
        self._jerk_idx = np.array([[xi[k] + 6, xi[k] + 7] for k in range(n)])
        self._state_idx = np.array([xi[k] + np.arange(6) for k in range(n + 1)])

        # Equalities: s_0 = x0, then eq. (3) for both axes.
        rows, cols, vals = list(range(6)), list(range(6)), [1.0] * 6
        for k in range(n):
            for ax in range(2):
                for i in range(3):
                    r = 6 + 6 * k + 3 * ax + i
                    rows.append(r)
                    cols.append(xi[k + 1] + 3 * ax + i)
                    vals.append(1.0)
                    for j in range(3):
                        if self._A[i, j] != 0.0:
                            rows.append(r)
                            cols.append(xi[k] + 3 * ax + j)
                            vals.append(-self._A[i, j])
                    rows.append(r)
                    cols.append(xi[k] + 6 + ax)
                    vals.append(-self._B[i])
        self.n_eq = 6 + 6 * n
        self._Aeq = sp.csc_matrix((vals, (rows, cols)), shape=(self.n_eq, nv))
        self._beq = np.zeros(self.n_eq)

        # Inequalities eq. (7): row (k, r) has a fixed 4-entry pattern on s_k (positions and
        # accelerations: z = x - h/g xdd); values are written into C.data through _cmap.
        rows, cols = [], []
        for k in range(1, n + 1):
            for r in range(MAX_ROWS):
                row = MAX_ROWS * (k - 1) + r
                rows += [row] * 4
                cols += [xi[k] + 0, xi[k] + 2, xi[k] + 3, xi[k] + 5]
        for r in range(self.n_terminal):              # capture point x + xd / omega
            row = MAX_ROWS * n + r
            rows += [row] * 4
            cols += [xi[n] + 0, xi[n] + 1, xi[n] + 3, xi[n] + 4]
        self._C, self._cmap = _pattern(rows, cols, (self.n_in, nv))
        self._g = np.zeros(nv)

        self.qp = proxqp.sparse.QP(self._H != 0, self._Aeq != 0, _bool_pattern(self._C))
        self._settings(self.qp)
        self._initialized = False

    def _build_dense(self) -> None:
        s, n, L = self.settings, self.n, self.lifted
        self.nv = 2 * n
        Hax = s.jerk_weight * np.eye(n)
        if s.velocity_weight > 0.0:
            Hax = Hax + s.velocity_weight * L.Vu.T @ L.Vu
        # Aligned and written in place by _fill: proxsuite reads them where they are
        # (proxqp.py).
        self._H = aligned_empty((2 * n, 2 * n))
        self._H.fill(0.0)
        self._H[:n, :n] = Hax
        self._H[n:, n:] = Hax
        self._C = aligned_empty((self.n_in, 2 * n))
        self._C.fill(0.0)
        self._g = aligned_empty(2 * n)
        self._g.fill(0.0)
        self.n_eq = 0
        self.qp = proxqp.dense.QP(2 * n, 0, self.n_in)
        self._settings(self.qp)
        self._initialized = False

    def _build_working_set(self) -> None:
        """Constant matrices of the working-set dual (see ``_solve_working_set``).

        With ``H`` the (constant) per-axis Hessian of eq. (6), the jerk is
        ``u = u_free + H^-1 Zext^T (lambda * a)``, so every quantity the solver needs is a slice
        of two constant matrices: ``W = H^-1 Zext^T`` and the Gram matrix ``G = Zext W``.
        ``Zext`` is ``Zu`` of eq. (5) plus one row for the terminal capture point.
        """
        s, n, L = self.settings, self.n, self.lifted
        H = s.jerk_weight * np.eye(n)
        if s.velocity_weight > 0.0:
            H = H + s.velocity_weight * L.Vu.T @ L.Vu
        self._Hinv = np.linalg.inv(H)
        w = 1.0 / self._omega
        self._Zext = np.vstack([L.Zu, L.Pu[-1] + w * L.Vu[-1]])          # (N+1, N)
        self._Z0ext = np.vstack([L.Z0, L.P0[-1] + w * L.V0[-1]])         # (N+1, 3)
        self._W = self._Hinv @ self._Zext.T                                 # (N, N+1)
        self._G = self._Zext @ self._W                                      # (N+1, N+1)
        self._row_sample = np.minimum(np.arange(MAX_ROWS * (n + 1)) // MAX_ROWS, n)
        self._row_sample = self._row_sample[:self.n_in]
        self.nv = 2 * n
        self.n_eq = 0
        self._ws_qps: dict[int, object] = {}          # capacity -> box-constrained dense QP
        self._ws_fresh: set[int] = set()              # capacities not initialised yet
        self._initialized = True
        self.rounds = 0
        self._dual_exact = False

    def _ws_qp(self, size: int):
        """Dual QP of at least ``size`` variables: one per power-of-two capacity, built once."""
        cap = 16
        while cap < size:
            cap *= 2
        qp = self._ws_qps.get(cap)
        if qp is None:
            qp = proxqp.dense.QP(cap, 0, 0, True)
            self._settings(qp)
            qp.settings.check_duality_gap = False
            self._ws_qps[cap] = qp
            self._ws_fresh.add(cap)
        return cap, qp

    def _solve_working_set(self, sched: SupportSchedule, x0: np.ndarray, v_ref: np.ndarray,
                           relaxed: bool) -> tuple[bool, np.ndarray, int, str]:
        """Exact solution of eq. (6)-(7) by its dual restricted to a working set of rows.

        The dual of the jerk QP is ``min 1/2 lam' M lam + lam' d_free, lam >= 0`` with
        ``M_ij = (a_i . a_j) G[k_i, k_j]`` and ``d_free`` the row values of the unconstrained
        plan. Only a few rows bind (the ZMP leaning on the edge of a triangle), so the dual is
        solved (exactly, ``_nnqp``; or proxsuite, dense, box constraints) on a working set: the
        rows active in the previous plan shifted in time, plus, each round, the most violated
        row of every violated sample, until no row of the full problem is violated. A solution
        of the restricted problem that satisfies every row is the optimum of the full QP.
        ``relaxed`` solves the soft version (rows violated at a cost ``slack_weight`` per m^2,
        i.e. ``M + I / slack_weight``), which is always feasible.
        """
        s, n = self.settings, self.n
        nk = n + 1 if self.n_terminal else n            # row blocks: samples 1..N (+ terminal)
        if self.n_terminal:
            Ab = np.concatenate([sched.A, sched.A[-1:]])                 # (nk, MAX_ROWS, 2)
            bb = np.concatenate([sched.b, sched.b[-1:]])
            actb = np.concatenate([sched.active, sched.active[-1:]])
        else:
            Ab, bb, actb = sched.A, sched.b, sched.active
        bb = np.where(actb, bb, np.inf)                  # padding rows: never violated
        Ab = np.where(actb[:, :, None], Ab, 0.0)
        ax, ay = Ab[:, :, 0], Ab[:, :, 1]
        arows = Ab.reshape(-1, 2)                        # (n_in, 2): a of every row
        ks = self._row_sample
        u_free = np.zeros((n, 2))
        if s.velocity_weight > 0.0:
            L = self.lifted
            x03 = x0.reshape(2, 3).T                                      # (3, 2)
            g = s.velocity_weight * L.Vu.T @ (L.V0 @ x03 - v_ref[None, :])
            u_free = -self._Hinv @ g
        zf = self._Z0ext @ x0.reshape(2, 3).T + self._Zext @ u_free        # (N+1, 2)

        def rows_at(z):                                  # row values (n_in,) of ZMP/CP z
            return (ax * z[:nk, 0:1] + ay * z[:nk, 1:2] + bb).reshape(-1)

        d_free = rows_at(zf)
        add_tol = s.working_set_tol

        if s.warm_start:
            work, lam = self._warm_rows(sched)
        else:
            work, lam = np.zeros(0, dtype=np.int64), np.zeros(0)
        d = d_free
        iters = 0
        info = ''
        in_work = np.zeros(self.n_in, dtype=bool)
        for rnd in range(s.max_rounds):
            if len(work):
                aw = arows[work]
                kw = ks[work]
                lam, it, info = self._dual(kw, aw, d_free[work], relaxed, lam)
                iters += it
                if lam is None:
                    self.rounds = rnd + 1
                    return False, np.zeros((n, 2)), iters, info
                if iters > s.iteration_budget:
                    self.rounds = rnd + 1
                    return (False, np.zeros((n, 2)), iters,
                            f'iteration budget {s.iteration_budget} spent in {rnd + 1} rounds')
                d = rows_at(zf + self._G[:, kw] @ (lam[:, None] * aw))
            if relaxed:
                new = np.flatnonzero(d < -add_tol)
            else:
                # The most violated row of each violated sample that is a local minimum of
                # the violation along the horizon: one multiplier moves a whole stretch of
                # the ZMP trajectory, so rows are added where the violation peaks.
                dm = d.reshape(-1, MAX_ROWS)
                worst = dm.argmin(axis=1)
                dw = dm.min(axis=1)
                peak = dw < -add_tol
                if s.add_peaks_only and peak.any():
                    dn = dw[:n]
                    pk = peak[:n]
                    pk[1:] &= dn[1:] <= dn[:-1]
                    pk[:-1] &= dn[:-1] <= dn[1:]
                bad = np.flatnonzero(peak)
                new = bad * MAX_ROWS + worst[bad]
            if len(new):
                in_work[:] = False
                in_work[work] = True
                new = new[~in_work[new]]
            if len(new) == 0:
                self.rounds = rnd + 1
                break
            if s.drop_inactive and rnd < s.max_rounds // 2 and len(lam):
                keep = lam > 0.0              # rows that do not bind leave the working set
                work, lam = work[keep], lam[keep]
            work = np.concatenate([work, new])
            lam = np.concatenate([lam, np.zeros(len(new))])
        else:
            self.rounds = s.max_rounds
            return False, np.zeros((n, 2)), iters, f'working set not converged in {rnd + 1} rounds'
        if len(work) and not relaxed and not self._dual_exact:
            work, lam = self._polish(work, lam, arows, rows_at, d_free, zf, d)
        jerk = u_free.copy()
        if len(work):
            jerk += self._W[:, ks[work]] @ (lam[:, None] * arows[work])
        keep = lam > 0.0
        order = np.argsort(work[keep])
        self._ws_prev = (work[keep][order], lam[keep][order], arows[work[keep]][order])
        return True, jerk, iters, info

    def _polish(self, work, lam, arows, rows_at, d_free, zf, d):
        """Solve the KKT system of the binding rows exactly (a small dense solve).

        Only after a proxsuite dual (``_nnqp`` is exact already): proxsuite stops at
        ``eps_abs`` on the scaled dual, which for rows late in the horizon is a few micrometres
        of ZMP; with the binding rows known, the exact multipliers follow from one linear solve.
        Kept only if they stay >= 0 and violate no row more than before.
        """
        ks = self._row_sample
        bind = lam > 1e-9 * max(float(lam.max()), 1e-300)
        if not np.any(bind):
            return work, lam          # no row binds (e.g. standing deep inside the polygon)
        wa = work[bind]
        A = arows[wa]
        M = (A @ A.T) * self._G[np.ix_(ks[wa], ks[wa])]
        try:
            la = np.linalg.solve(M, -d_free[wa])
        except np.linalg.LinAlgError:
            return work, lam
        if not np.all(np.isfinite(la)) or la.min() < 0.0:
            return work, lam
        dp = rows_at(zf + self._G[:, ks[wa]] @ (la[:, None] * A))
        if dp.min() >= min(d.min(), 0.0):
            return wa, la
        return work, lam

    def _warm_rows(self, sched: SupportSchedule) -> tuple[np.ndarray, np.ndarray]:
        """Rows active in the previous plan and their multipliers, shifted by the samples
        elapsed since it (the terminal rows stay terminal). Edges are matched by direction, not
        by index: the hull's first vertex changes when the feet move."""
        p = self._prev
        empty = np.zeros(0, dtype=np.int64), np.zeros(0)
        if p is None or self._ws_prev is None or self._ws_t0 is None:
            return empty
        rows, lam, normals = self._ws_prev
        n = self.n
        m = round((self._ws_t0 - p['t0']) / self.settings.dt)
        k = rows // MAX_ROWS
        k = np.where(k >= n, k, k - m)
        ok = k >= 0
        k, lam, normals = k[ok], lam[ok], normals[ok]
        if len(k) == 0:
            return empty
        kk = np.minimum(k, n - 1)                         # terminal rows use the last polygon
        dots = np.einsum('ij,irj->ir', normals, sched.A[kk])
        dots = np.where(sched.active[kk], dots, -np.inf)
        r = np.argmax(dots, axis=1)
        new, idx = np.unique(k * MAX_ROWS + r, return_index=True)
        return new, lam[idx]

    def _dual(self, ks: np.ndarray, aw: np.ndarray, d0: np.ndarray, relaxed: bool,
              lam0: np.ndarray):
        """Solve the dual restricted to the rows of samples ``ks`` with normals ``aw`` (m, 2)
        and unconstrained values ``d0``; returns (lambda, iterations, status).

        By the exact active-set method ``_nnqp`` (a few small Cholesky solves, the working
        set has 7-15 rows) unless ``exact_dual`` is off. If it fails on the hard dual (dual
        unbounded: the problem is infeasible; or dependent rows it could not resolve within
        its iterations) the failure is returned (relaxed fallback); on the relaxed dual
        (positive definite, so this should not happen) and with ``exact_dual`` off, proxsuite
        solves it.
        """
        s = self.settings
        M = (aw @ aw.T) * self._G.take(ks, 0).take(ks, 1)
        if relaxed:
            M[np.diag_indices_from(M)] += 1.0 / s.slack_weight
        # Jacobi scaling: rows far in the horizon move by metres per unit jerk, the first ones
        # by millimetres; unit diagonal keeps the dual well scaled (mu = sqrt(M_ii) lambda).
        dsc = 1.0 / np.sqrt(np.maximum(M.diagonal(), 1e-300))
        Ms = M * dsc[:, None] * dsc[None, :]
        gs = d0 * dsc
        mu0 = lam0 / dsc
        m = len(ks)
        it = 0
        if s.exact_dual:
            mu, it, why = _nnqp(Ms, gs, mu0, 3 * m + 10)
            if mu is not None:
                self._dual_exact = True
                return mu * dsc, it, ''
            if not relaxed:
                # Dependent rows the active-set steps could not resolve, or a direction along
                # which the dual decreases without bound (no jerk keeps every row: the problem
                # is infeasible). proxsuite would iterate for seconds on such a dual (it did
                # before the iteration budget): report it, the relaxed fallback follows.
                self._dual_exact = True
                return None, it, f'working-set dual {why} with {m} rows (infeasible?)'
        self._dual_exact = False
        cap, qp = self._ws_qp(m)
        Hd = np.eye(cap)
        Hd[:m, :m] = Ms
        gd = np.ones(cap)                 # padding variables: cost +mu, mu >= 0 -> mu = 0
        gd[:m] = gs
        lb = np.zeros(cap)
        ub = np.full(cap, _INF)
        Hd, gd, lb, ub = aligned(Hd), aligned(gd), aligned(lb), aligned(ub)
        if cap in self._ws_fresh:
            qp.init(Hd, gd, None, None, None, None, None, lb, ub)
            self._ws_fresh.discard(cap)
        else:
            qp.update(H=Hd, g=gd, l_box=lb, u_box=ub)
        x0 = np.zeros(cap)
        x0[:m] = mu0
        qp.settings.initial_guess = proxqp.InitialGuess.WARM_START
        qp.solve(aligned(x0), None, None)
        st = qp.results.info.status
        it += int(qp.results.info.iter)
        if st != proxqp.QPSolverOutput.PROXQP_SOLVED:
            return None, it, str(st).split('.')[-1]
        lam = np.maximum(qp.results.x[:m], 0.0) * dsc
        return lam, it, ''

    # ------------------------------------------------------------------ per re-plan data

    def _fill(self, sched: SupportSchedule, x0: np.ndarray, v_ref: np.ndarray) -> None:
        """Write the polygon rows, bounds and initial state of this re-plan into the QP data."""
        s, n, hg = self.settings, self.n, self._hg
        act = sched.active
        ax = np.where(act, sched.A[:, :, 0], 0.0)           # (N, 4)
        ay = np.where(act, sched.A[:, :, 1], 0.0)
        bb = sched.b
        l_rows = np.where(act, -bb, -_INF)
        if self.n_terminal:
            axt, ayt, bt = ax[-1], ay[-1], bb[-1]
            lt = np.where(act[-1], -bt, -_INF)
        if s.formulation == 'sparse':
            d = self._C.data
            vals = np.stack([ax, -hg * ax, ay, -hg * ay], axis=-1)   # (N, 4, 4)
            d[self._cmap[:MAX_ROWS * n].ravel()] = vals.reshape(-1)
            if self.n_terminal:
                w = 1.0 / self._omega
                tv = np.stack([axt, w * axt, ayt, w * ayt], axis=-1)
                d[self._cmap[MAX_ROWS * n:].ravel()] = tv.reshape(-1)
            self._beq[:6] = x0
            if s.velocity_weight > 0.0:
                self._g[:] = 0.0
                self._g[self._vel_idx[:, 0]] = -s.velocity_weight * v_ref[0]
                self._g[self._vel_idx[:, 1]] = -s.velocity_weight * v_ref[1]
        else:
            L = self.lifted
            C = self._C
            Zu = L.Zu
            # A_p blockdiag(Zu, Zu) of eq. (7): row (k, r) = [ax Zu_k, ay Zu_k].
            C[:MAX_ROWS * n, :n] = (ax[:, :, None] * Zu[:, None, :]).reshape(-1, n)
            C[:MAX_ROWS * n, n:] = (ay[:, :, None] * Zu[:, None, :]).reshape(-1, n)
            z0x = L.Z0 @ x0[:3]
            z0y = L.Z0 @ x0[3:]
            l_rows = np.where(act, l_rows - ax * z0x[:, None] - ay * z0y[:, None], -_INF)
            if self.n_terminal:
                w = 1.0 / self._omega
                cp_u = L.Pu[-1] + w * L.Vu[-1]
                cp_0 = (L.P0[-1] + w * L.V0[-1])
                C[MAX_ROWS * n:, :n] = axt[:, None] * cp_u[None, :]
                C[MAX_ROWS * n:, n:] = ayt[:, None] * cp_u[None, :]
                lt = np.where(act[-1], lt - axt * (cp_0 @ x0[:3]) - ayt * (cp_0 @ x0[3:]), -_INF)
            if s.velocity_weight > 0.0:
                for a in range(2):
                    self._g[a * n:(a + 1) * n] = s.velocity_weight * L.Vu.T @ (
                        L.V0 @ x0[3 * a:3 * a + 3] - v_ref[a])
        self._l[:MAX_ROWS * n] = l_rows.reshape(-1)
        if self.n_terminal:
            self._l[MAX_ROWS * n:] = lt

    def _warm(self, t0: float, x0: np.ndarray):
        """Previous solution shifted by the elapsed samples: primal (x) and multipliers (y, z)."""
        p = self._prev
        if p is None or not self.settings.warm_start:
            return None
        n = self.n
        m = round((t0 - p['t0']) / self.settings.dt)
        if m < 0 or m >= n:
            return None
        jerk = np.zeros((n, 2))
        jerk[:n - m] = p['jerk'][m:]
        zin = np.zeros(self.n_in)
        zin[:MAX_ROWS * (n - m)] = p['z'][MAX_ROWS * m:MAX_ROWS * n]
        zin[MAX_ROWS * n:] = p['z'][MAX_ROWS * n:]
        if self.settings.formulation == 'dense':
            return np.concatenate([jerk[:, 0], jerk[:, 1]]), None, zin
        states = self._states(x0, jerk)                      # consistent with the new x0
        x = np.zeros(self.nv)
        x[self._state_idx.ravel()] = states.reshape(-1)
        x[self._jerk_idx.ravel()] = jerk.reshape(-1)
        y = np.zeros(self.n_eq)
        y[6:6 + 6 * (n - m)] = p['y'][6 + 6 * m:]
        return x, y, zin

    def _states(self, x0: np.ndarray, jerk: np.ndarray) -> np.ndarray:
        """States s_0..s_N (N+1, 6) of eq. (4) for the initial state x0 (6,) and jerks (N, 2)."""
        L = self.lifted
        out = np.empty((self.n + 1, 6))
        out[0] = x0
        xs = L.S0 @ x0.reshape(2, 3).T + L.Su @ jerk                 # (3N, 2): both axes
        out[1:] = xs.reshape(self.n, 3, 2).transpose(0, 2, 1).reshape(self.n, 6)
        return out

    # ------------------------------------------------------------------ solving

    def _solve_hard(self, warm) -> tuple[bool, np.ndarray, int, str]:
        qp = self.qp
        s = self.settings
        # Dense arrays at a fixed alignment (proxqp.py); the sparse matrices are copied by
        # proxsuite's binding, their vectors are not.
        g = aligned(self._g)
        if s.formulation == 'sparse':
            beq = aligned(self._beq)
            args = (self._H, g, self._Aeq, beq, self._C, self._l, self._u)
        else:
            args = (self._H, g, None, None, self._C, self._l, self._u)
        if not self._initialized:
            qp.init(*args)
            self._initialized = True
        elif s.formulation == 'sparse':
            qp.update(g=g, b=beq, C=self._C, l=self._l, u=self._u)
        else:
            qp.update(g=g, C=self._C, l=self._l, u=self._u)
        if warm is None:
            self.cold = True
            qp.settings.initial_guess = proxqp.InitialGuess.EQUALITY_CONSTRAINED_INITIAL_GUESS
            qp.solve()
        else:
            self.cold = False
            qp.settings.initial_guess = proxqp.InitialGuess.WARM_START
            qp.solve(*(aligned(a) for a in warm))
        res = qp.results
        ok = res.info.status == proxqp.QPSolverOutput.PROXQP_SOLVED
        return ok, self._jerk_of(res.x), int(res.info.iter), str(res.info.status).split('.')[-1]

    def _jerk_of(self, x: np.ndarray) -> np.ndarray:
        if self.settings.formulation == 'sparse':
            return x[self._jerk_idx]
        return np.column_stack([x[:self.n], x[self.n:]])

    def _solve_relaxed(self) -> tuple[bool, np.ndarray, int]:
        """Soft version of the same QP: rows C w + e >= l, e >= 0, cost += W/2 |e|^2 + W |e|.

        Built with proxsuite's sparse backend when needed: this is the rare failure path.
        """
        s = self.settings
        n_in, nv = self.n_in, self.nv
        W = s.slack_weight
        H = sp.block_diag([sp.csc_matrix(self._H), W * sp.eye(n_in)], format='csc')
        g = np.concatenate([self._g, W * np.ones(n_in)])     # the L1 part makes it exact
        C = sp.bmat([[sp.csc_matrix(self._C), sp.eye(n_in)],
                     [None, sp.eye(n_in)]], format='csc')
        l_ = np.concatenate([self._l, np.zeros(n_in)])
        u_ = np.full(2 * n_in, _INF)
        if self.n_eq:
            Aeq = sp.hstack([self._Aeq, sp.csc_matrix((self.n_eq, n_in))], format='csc')
            b = self._beq
        else:
            Aeq, b = None, None
        qp = proxqp.sparse.QP(nv + n_in, self.n_eq, 2 * n_in)
        self._settings(qp)
        qp.settings.max_iter = max(s.max_iter, 1000)
        qp.settings.initial_guess = proxqp.InitialGuess.EQUALITY_CONSTRAINED_INITIAL_GUESS
        qp.init(H, aligned(g), Aeq, aligned(b), C, aligned(l_), aligned(u_))
        qp.solve()
        ok = qp.results.info.status == proxqp.QPSolverOutput.PROXQP_SOLVED
        x = qp.results.x[:nv]
        return ok, self._jerk_of(x), int(qp.results.info.iter)

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
                                     self._poly_cache)
            if com_z is None:
                com_z = float(np.mean(np.asarray(support.initial_feet)[:, 2])) + s.com_height
        else:
            sched = support
            if sched.n != n:
                return self._fallback(start_time, None, None, STATUS_REJECTED,
                                      f'input rejected: schedule has {sched.n} samples, '
                                      f'the QP {n}', t_start, 0, None)
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


def _nnqp(M: np.ndarray, g: np.ndarray, x0: np.ndarray, max_iter: int, tol: float = 1e-10,
          min_pivot: float = 1e-6) -> tuple[np.ndarray | None, int, str]:
    """``min 1/2 x' M x + g' x, x >= 0`` (``M`` PSD, unit diagonal) by a primal active-set
    method (Lawson-Hanson style), exact to rounding.

    Warm start: every variable free from ``x0`` (>= 0); if that first free-set matrix is
    singular, the positive entries of ``x0`` only, then none. Each iteration solves the
    problem on the free set exactly (LAPACK ``dposv``, Cholesky) and either steps to it (then
    frees the variable of most negative gradient, if any) or stops where the first free
    variables reach 0 and fixes those at 0. If freeing a variable makes the free-set matrix
    singular (its row depends on the free ones: rows of one sample, an infeasible problem),
    the objective decreases linearly along the null direction: a step to the first blocking
    variable, or, if none blocks, the dual is unbounded below (the primal is infeasible).

    Returns ``(x, iterations, '')`` at the optimum (free variables > 0 with zero gradient to
    rounding, fixed ones with gradient >= -tol: the KKT conditions), else ``(None, iterations,
    why)`` with why ``'unbounded'``, ``'singular'`` or ``'max_iter'``.
    """
    m = len(g)
    if m == 0:
        return np.zeros(0), 1, ''
    x0 = np.maximum(x0, 0.0)
    it = 0
    for free in (np.ones(m, dtype=bool), x0 > 0.0, np.zeros(m, dtype=bool)):
        x, k, why = _nnqp_from(M, g, np.where(free, x0, 0.0), free, max_iter - it, tol,
                               min_pivot)
        it += k
        if why != 'singular_start':
            return x, it, why
    return None, it, 'singular'


def _nnqp_from(M, g, x, free, max_iter, tol, min_pivot):
    """The iterations of ``_nnqp`` from ``x`` with the free set ``free`` (modified)."""
    m = len(g)
    P = np.flatnonzero(free)
    added = -1                     # variable freed last; the free set without it is PD
    for it in range(1, max_iter + 1):
        y = np.zeros(m)
        if len(P):
            c, yP, info = _dposv(M.take(P, 0).take(P, 1), -g.take(P), lower=1)
            if info != 0 or c.diagonal().min() < min_pivot:
                if added < 0:
                    return None, it, 'singular_start'
                # Null direction v: v[added] = 1, M_QQ v_Q = -M_Q,added on Q = P - {added}.
                Q = P[added != P]
                v = np.zeros(m)
                v[added] = 1.0
                if len(Q):
                    _, vQ, info = _dposv(M.take(Q, 0).take(Q, 1), -M[Q, added], lower=1)
                    if info != 0:
                        return None, it, 'singular'
                    v[Q] = vQ
                dec = Q[v[Q] < -1e-9]
                if len(dec) == 0:
                    return None, it, 'unbounded'
                ratio = x[dec] / -v[dec]
                b = int(dec[ratio.argmin()])
                x = np.maximum(x + ratio.min() * v, 0.0)
                x[b] = 0.0
                free[b] = False
                x[~free] = 0.0
                P = np.flatnonzero(free)
                continue
            y[P] = yP
            ymin = yP.min()
        else:
            ymin = np.inf
        if ymin > 0.0:
            x = y
            w = M @ x + g
            w[P] = np.inf
            j = int(w.argmin())
            if w[j] >= -tol:
                return x, it, ''
            free[j] = True
            added = j
            P = np.flatnonzero(free)
            continue
        # Step from x towards y until the first free variable reaches 0; plain Python on the
        # few free variables (numpy's per-call overhead dominates at this size).
        pl = P.tolist()
        xl = x.take(P).tolist()
        yl = yP.tolist()
        alpha = 1.0
        for xi, yi in zip(xl, yl, strict=True):
            if yi <= 0.0:
                alpha = min(alpha, xi / (xi - yi) if xi - yi > 0.0 else 0.0)
        x = np.zeros(m)
        keep = []
        for p, xi, yi in zip(pl, xl, yl, strict=True):
            v_ = xi + alpha * (yi - xi)
            if v_ > 0.0 and not (yi <= 0.0 and (xi / (xi - yi) if xi - yi > 0.0 else 0.0)
                                 <= alpha):
                x[p] = v_
                keep.append(p)
            else:
                free[p] = False
        P = np.array(keep, dtype=np.int64)
        added = -1
    return None, max_iter, 'max_iter'


def _pattern(rows: list[int], cols: list[int], shape: tuple[int, int]
             ) -> tuple[sp.csc_matrix, np.ndarray]:
    """CSC matrix with a fixed pattern (explicit zeros kept) and the map entry -> data index."""
    nnz = len(rows)
    M = sp.csc_matrix((np.arange(1, nnz + 1, dtype=float), (rows, cols)), shape=shape)
    if M.nnz != nnz:
        raise ValueError('duplicate entries in the constraint pattern')
    cmap = np.empty(nnz, dtype=np.int64)
    cmap[M.data.astype(np.int64) - 1] = np.arange(nnz)
    M.data[:] = 0.0
    return M, cmap.reshape(shape[0], -1)


def _bool_pattern(M: sp.csc_matrix) -> sp.csc_matrix:
    P = M.copy()
    P.data = np.ones_like(P.data, dtype=bool)
    return P
