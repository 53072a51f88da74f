"""The full formulations of the jerk QP eq. (6)-(7), solved with proxsuite.

:class:`FullQp` is the part of :class:`replan_core.mpc.lip_mpc.LipMpc` that builds them once, writes
each re-plan's rows into them, solves them warm-started from the previous solution shifted in
time, and solves their slack-relaxed version for the fallback (``_solve_relaxed``):

- ``sparse``: the decision vector holds the states and the jerks of every sample,
  time-major ``[s_0, u_0, s_1, u_1, ..., s_N]`` with ``s_k = (x, xd, xdd, y, yd, ydd)`` and
  ``u_k = (jerk_x, jerk_y)``; eq. (3) enters as equality rows, so the KKT matrix is banded and
  every polygon row touches only the 4 state entries of its own sample. Between re-plans only
  the initial-state right-hand side and the polygon row values change (the Hessian and the
  dynamics rows are constant, the sparsity pattern is fixed).
- ``dense``: the condensed form of the paper, eq. (4)-(7), jerks only (kept for comparison).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp

from replan_core.common.proxqp import aligned, aligned_empty, proxqp
from replan_core.mpc.support import MAX_ROWS, SupportSchedule

_INF = 1e20                     # proxsuite's "no bound"


class FullQp:
    """Mixin of :class:`~replan_core.mpc.lip_mpc.LipMpc` for ``formulation='sparse'`` and
    ``'dense'``.

    The host sets ``settings``, ``n``, ``n_in``, ``n_terminal``, ``lifted``, ``_A``, ``_B``,
    ``_hg``, ``_omega``, ``_prev`` (the last solution, for the warm start), the bounds ``_l`` and
    ``_u``, and provides ``_settings(qp)`` (the proxsuite settings) and ``_states``.
    """

    # ------------------------------------------------------------------ building

    def _build_sparse(self) -> None:
        s, n = self.settings, self.n
        nv = 8 * n + 6
        self.nv = nv
        xi = [8 * k for k in range(n + 1)]                    # first state entry of sample k

        # Cost eq. (6): 1/2 R |u|^2 (+ 1/2 w_v |v - v_ref|^2 + 1/2 w_p |p - c|^2 over samples
        # 1..N).
        diag = np.zeros(nv)
        for k in range(n):
            diag[xi[k] + 6:xi[k] + 8] = s.jerk_weight
        if s.velocity_weight > 0.0:
            for k in range(1, n + 1):
                diag[[xi[k] + 1, xi[k] + 4]] = s.velocity_weight
        if s.position_weight > 0.0:
            for k in range(1, n + 1):
                diag[[xi[k] + 0, xi[k] + 3]] = s.position_weight
        self._H = sp.diags(diag).tocsc()
        self._vel_idx = np.array([[xi[k] + 1, xi[k] + 4] for k in range(1, n + 1)])
        self._pos_idx = self._vel_idx - 1
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
        if s.position_weight > 0.0:
            Hax = Hax + s.position_weight * L.Pu.T @ L.Pu
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

    # ------------------------------------------------------------------ per re-plan data

    def _fill(self, sched: SupportSchedule, x0: np.ndarray, v_ref: np.ndarray) -> None:
        """Write the polygon rows, bounds and initial state of this re-plan into the QP data."""
        s, n, hg = self.settings, self.n, self._hg
        ref = s.position_reference(sched) if s.position_weight > 0.0 else None
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
            if s.position_weight > 0.0:
                self._g[self._pos_idx[:, 0]] = -s.position_weight * ref[:, 0]
                self._g[self._pos_idx[:, 1]] = -s.position_weight * ref[:, 1]
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
            if s.velocity_weight > 0.0 or s.position_weight > 0.0:
                for a in range(2):
                    xa, ga = x0[3 * a:3 * a + 3], np.zeros(n)
                    if s.velocity_weight > 0.0:
                        ga += s.velocity_weight * L.Vu.T @ (L.V0 @ xa - v_ref[a])
                    if s.position_weight > 0.0:
                        ga += s.position_weight * L.Pu.T @ (L.P0 @ xa - ref[:, a])
                    self._g[a * n:(a + 1) * n] = ga
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
