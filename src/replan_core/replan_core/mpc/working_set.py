"""The working-set formulation of the jerk QP eq. (6)-(7), the re-planner's default.

:class:`WorkingSetDual` is the part of :class:`replan_core.mpc.lip_mpc.LipMpc` that solves it: the
dual of the QP restricted to a working set of polygon rows (``_solve_working_set``), each
restricted dual solved exactly by the small active-set method ``_nnqp`` (or, with
``exact_dual`` off, by proxsuite followed by a KKT polish). Why it is exact and fast: docs/mpc.md.
"""

from __future__ import annotations

import numpy as np
from scipy.linalg.lapack import dposv as _dposv

from replan_core.common.proxqp import aligned, proxqp
from replan_core.mpc.support import MAX_ROWS, SupportSchedule

_INF = 1e20                     # proxsuite's "no bound"


class WorkingSetDual:
    """Mixin of :class:`~replan_core.mpc.lip_mpc.LipMpc` for ``formulation='working_set'``.

    The host sets ``settings``, ``n``, ``n_in``, ``n_terminal``, ``lifted``, ``_omega``,
    ``_prev`` (the last solution's start time), ``_ws_t0`` and ``_ws_prev`` and provides
    ``_settings(qp)`` (the proxsuite settings); the rest of the state is set here.
    """

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
        if s.position_weight > 0.0:
            H = H + s.position_weight * L.Pu.T @ L.Pu
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
        if s.velocity_weight > 0.0 or s.position_weight > 0.0:
            L = self.lifted
            x03 = x0.reshape(2, 3).T                                      # (3, 2)
            g = np.zeros((n, 2))
            if s.velocity_weight > 0.0:
                g += s.velocity_weight * L.Vu.T @ (L.V0 @ x03 - v_ref[None, :])
            if s.position_weight > 0.0:
                g += s.position_weight * L.Pu.T @ (L.P0 @ x03 - s.position_reference(sched))
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
