"""The convex subproblem of each SQP step, with a sparsity pattern fixed for the whole solve.

Variables z = [x, s]: x the waypoints Q (T, K) flattened (fixed waypoints get equal bounds),
s ≥ 0 the l1 slacks. The QP is

    minimise   ½ xᵀ P x + μ Σ c_i s_i
    subject to l ≤ A z ≤ u

with P the smoothness Hessian, the identity rows of A holding the trust region ∩ joint limits,
and one or two rows per penalised term (its linearisation plus its slack). Every row has a
fixed set of columns, so between steps only the values of A, l, u and q change: OSQP is set up
once per solve and updated in place (its KKT pattern and symbolic factorisation are reused).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
import scipy.sparse as sp
from numpy.typing import NDArray

from chekhov.trajopt._osqp import QPSolver
from chekhov.trajopt.kernels import fill_collision_rows, residual_slacks
from chekhov.trajopt.problem import Evaluation, TrajOptProblem

Array = NDArray[np.float64]
IntArray = NDArray[np.int64]
INF = np.inf


class _Rows:
    """A block of rows with ``width`` variable columns each and one slack column each."""

    def __init__(self, cols: IntArray, slack: IntArray, sense: IntArray, start: int,
                 value_offset: int) -> None:
        self.cols, self.slack, self.sense = cols, slack, sense  # sense +1: ≥ row, -1: ≤ row
        self.start, self.value_offset = start, value_offset

    @property
    def n(self) -> int:
        return int(self.cols.shape[0])

    @property
    def width(self) -> int:
        return int(self.cols.shape[1])


class _BlockRows(NamedTuple):
    """The blocks' rows as :func:`kernels.residual_slacks` reads them: per block (B,) its
    first global row, rows, width and first value's index; per row, one block after another,
    its columns (``width`` each), sense (+1: ≥ row, -1: ≤ row) and slack (counted from the
    first). All int64."""

    start: IntArray
    n_rows: IntArray
    width: IntArray
    value_at: IntArray
    cols: IntArray
    sense: IntArray
    slack: IntArray


class TrajOptQP:
    """The SQP subproblem of a :class:`TrajOptProblem`: pattern, values and the OSQP solver."""

    def __init__(self, problem: TrajOptProblem, waypoint_capacity: IntArray | None = None,
                 segment_capacity: IntArray | None = None) -> None:
        """``waypoint_capacity`` (T,) / ``segment_capacity`` (T-1,): collision rows kept per
        waypoint / segment (at most terms_per_waypoint / terms_per_segment; all by default).
        Far from obstacles most are 0, which keeps the QP small."""
        self.problem = problem
        cfg = problem.config
        T, K = problem.n_waypoints, problem.dof
        self.n_x = T * K
        xi = np.arange(T * K, dtype=np.int64).reshape(T, K)
        self._blocks: dict[str, _Rows] = {}
        self._slack_coeff: list[Array] = []
        self._n_slack = 0
        self._rows = self.n_x  # identity rows for x first; slack identity rows at the end
        self._values = 0
        self._pattern: list[tuple[IntArray, IntArray]] = []
        Cd = cfg.terms_per_waypoint
        Cc = cfg.terms_per_segment if cfg.continuous else 0
        cap_w = np.full(T, Cd) if waypoint_capacity is None else np.minimum(waypoint_capacity, Cd)
        cap_s = np.full(T - 1, Cc) if segment_capacity is None else \
            np.minimum(segment_capacity, Cc)
        self.waypoint_capacity = cap_w.astype(np.int64)
        self.segment_capacity = cap_s.astype(np.int64)
        self._wp_t, self._wp_k = _term_index(self.waypoint_capacity)
        self._seg_t, self._seg_k = _term_index(self.segment_capacity)
        self._add_blocks(problem, xi)
        n_z = self.n_x + self._n_slack
        self.n_z = n_z
        self.slack_coeff = np.concatenate(self._slack_coeff) if self._slack_coeff else \
            np.zeros(0)
        self._assemble_pattern()
        self.P = _smoothness_hessian(problem, n_z)
        self._solver: QPSolver | None = None
        self._last_ev: Evaluation | None = None
        self.admm_iterations = 0
        self._l = np.zeros(self.n_rows)
        self._u = np.zeros(self.n_rows)
        self._lower_x, self._upper_x = np.tile(problem.lower, T), np.tile(problem.upper, T)
        self._constant_bounds()
        self._block_rows = self._row_layout()

    def _constant_bounds(self) -> None:
        """The bounds that no step changes: the slacks' identity rows (s ≥ 0), the collision
        rows' upper ones (none) and the velocity and acceleration rows (|finite difference|
        ≤ limit)."""
        self._l[self._rows:], self._u[self._rows:] = 0.0, INF
        for name in ("waypoint", "segment"):
            b = self._blocks.get(name)
            if b is not None:
                self._u[b.start:b.start + b.n] = INF
        p = self.problem
        for name, limit in (("velocity", p.velocity_limit),
                            ("acceleration", p.acceleration_limit)):
            b = self._blocks.get(name)
            if b is None:
                continue
            self._band(b, np.zeros(b.n // 2), limit)

    def _row_layout(self) -> _BlockRows:
        """The blocks' rows as :func:`kernels.residual_slacks` reads them."""
        blocks = list(self._blocks.values())

        def per_block(values: list[int]) -> IntArray:
            return np.array(values, dtype=np.int64).reshape(-1)

        def per_row(values: list[IntArray]) -> IntArray:
            return np.concatenate(values).astype(np.int64) if values else \
                np.zeros(0, dtype=np.int64)

        return _BlockRows(per_block([b.start for b in blocks]), per_block([b.n for b in blocks]),
                          per_block([b.width for b in blocks]),
                          per_block([self.n_z + b.value_offset for b in blocks]),
                          per_row([b.cols.ravel() for b in blocks]),
                          per_row([b.sense for b in blocks]),
                          per_row([b.slack - self.n_x for b in blocks]))

    def _add_blocks(self, problem: TrajOptProblem, xi: IntArray) -> None:
        """The row blocks of every penalised term: collision (one ≥ row and one slack per
        term, within the capacities), goal pose, velocity / acceleration and torque limits.
        ``xi`` (T, K): the column of each waypoint's joint."""
        cfg = problem.config
        T, K = xi.shape
        if len(self._wp_t):
            self._add("waypoint", xi[self._wp_t], 1, cfg.collision_coeff)
        if len(self._seg_t):
            seg = np.concatenate([xi[:-1], xi[1:]], axis=1)
            self._add("segment", seg[self._seg_t], 1, cfg.collision_coeff)
        if problem.goal.is_pose:
            self._add("goal", np.repeat(xi[-1:], 6, axis=0), 2, cfg.goal_coeff)
        if problem.has_dynamics and T > 1:
            pair = np.stack([xi[:-1].ravel(), xi[1:].ravel()], axis=1)
            self._add("velocity", pair, 2, cfg.limit_coeff)
            if T > 2:
                trip = np.stack([xi[:-2].ravel(), xi[1:-1].ravel(), xi[2:].ravel()], axis=1)
                self._add("acceleration", trip, 2, cfg.limit_coeff)
        if problem.has_torque and T > 2:
            win = np.concatenate([xi[:-2], xi[1:-1], xi[2:]], axis=1)  # (T-2, 3K)
            self._add("torque", np.repeat(win, K, axis=0), 2, cfg.torque_coeff)

    def _assemble_pattern(self) -> None:
        """A's pattern: identity rows (x, then slacks), then each block's rows; the constant
        values (identity, slack senses, finite-difference rows) filled in."""
        n_z = self.n_z
        ident_rows = np.concatenate([np.arange(self.n_x), self._rows + np.arange(self._n_slack)])
        self.n_rows = self._rows + self._n_slack
        rows = [ident_rows]
        cols = [np.arange(n_z, dtype=np.int64)]
        for r, c in self._pattern:
            rows.append(r)
            cols.append(c)
        R = np.concatenate(rows)
        Cn = np.concatenate(cols)
        self._order = np.lexsort((R, Cn))
        self._A_rows, self._A_cols = R, Cn
        vals = np.zeros(len(R))
        vals[:n_z] = 1.0
        for name, b in self._blocks.items():
            v = np.zeros((b.n, b.width + 1))
            v[:, -1] = b.sense
            if name == "velocity":
                v[:, :2] = [-1.0, 1.0]
            elif name == "acceleration":
                v[:, :3] = [1.0, -2.0, 1.0]
            vals[n_z + b.value_offset:n_z + b.value_offset + v.size] = v.ravel()
        self._vals = vals

    def _add(self, name: str, var_cols: IntArray, rows_per_term: int, coeff: float) -> None:
        """Add a block of terms; each term gets one slack and ``rows_per_term`` rows (1: a ≥
        row; 2: a ≤ row then a ≥ row sharing the slack, for |a·x - c| ≤ tol)."""
        n_terms, width = var_cols.shape
        slack = self.n_x + self._n_slack + np.arange(n_terms, dtype=np.int64)
        self._n_slack += n_terms
        self._slack_coeff.append(np.full(n_terms, coeff))
        cols = np.repeat(var_cols, rows_per_term, axis=0)
        slk = np.repeat(slack, rows_per_term)
        sense = np.tile([1] if rows_per_term == 1 else [-1, 1], n_terms).astype(np.int64)
        n = len(cols)
        start = self._rows
        self._rows += n
        full_cols = np.concatenate([cols, slk[:, None]], axis=1)
        self._pattern.append((np.repeat(start + np.arange(n), width + 1), full_cols.ravel()))
        offset = self._values  # after the identity values, which come first
        self._blocks[name] = _Rows(cols, slk, sense, start, offset)
        self._values += full_cols.size

    # --- per-step values ----------------------------------------------------------------
    def _fill(self, ev: Evaluation, x_bar: Array, trust: float, mu: float
              ) -> tuple[Array, Array, Array, Array]:
        p = self.problem
        T, K = p.n_waypoints, p.dof
        vals = self._vals
        lo_, u = self._l, self._u
        off0 = self.n_z  # identity values come first
        Qb = x_bar.reshape(T, K)
        # identity rows: trust region ∩ joint limits; fixed waypoints pinned
        lo = np.maximum(self._lower_x, x_bar - trust)
        hi = np.minimum(self._upper_x, x_bar + trust)
        lo[:K] = hi[:K] = p.q_start
        if p.fixed_goal:
            lo[-K:] = hi[-K:] = Qb[-1]
        lo_[:self.n_x], u[:self.n_x] = lo, hi
        safe_w, safe_s = p.safety_margins()
        for name, b in self._blocks.items():
            if name == "waypoint":
                fill_collision_rows(vals, lo_, off0 + b.value_offset, b.start, self._wp_t,
                                    self._wp_k, ev.grad_waypoint, ev.dist_waypoint, safe_w,
                                    Qb, False)
            elif name == "segment":
                fill_collision_rows(vals, lo_, off0 + b.value_offset, b.start, self._seg_t,
                                    self._seg_k, ev.grad_segment, ev.dist_segment, safe_s,
                                    Qb, True)
            elif name in ("goal", "torque"):   # velocity and acceleration rows are constant
                self._fill_linear(name, b, ev, Qb)
        q = np.concatenate([-p.config.proximal_weight * x_bar, mu * self.slack_coeff])
        return vals[self._order], lo_, u, q

    def _fill_linear(self, name: str, b: _Rows, ev: Evaluation, Qb: Array) -> None:
        """The goal's or the torques' rows (``name`` "goal" / "torque"), |A x - c| ≤ tol,
        linearised at Qb (T, K)."""
        p = self.problem
        K = p.dof
        w = b.width
        vb = self._vals[self.n_z + b.value_offset:self.n_z + b.value_offset
                        + b.n * (w + 1)].reshape(b.n, w + 1)
        if name == "goal":
            A = ev.goal_jacobian
            c = A @ Qb[-1] - ev.goal_error
            tol = p.goal_tolerance
        else:
            A = ev.torque_jacobian.reshape(-1, 3 * K)
            win = np.concatenate([Qb[:-2], Qb[1:-1], Qb[2:]], axis=1)
            c = np.einsum("tkj,tj->tk", ev.torque_jacobian, win).ravel() - ev.torque.ravel()
            tol = p.torque_limit
        vb[0::2, :w] = A
        vb[1::2, :w] = A
        self._band(b, c, tol)

    def _band(self, b: _Rows, c: Array, tol: Array | float) -> None:
        """Block b's bounds for |a x - c| ≤ tol, c (n / 2,): each term's ≤ row (a x - s ≤
        c + tol) then its ≥ row (a x + s ≥ c - tol); ``tol`` repeated over the terms."""
        tol = np.resize(tol, len(c))
        rows = slice(b.start, b.start + b.n, 2)
        after = slice(b.start + 1, b.start + b.n, 2)
        self._l[rows], self._u[rows] = -INF, c + tol
        self._l[after], self._u[after] = c - tol, INF

    def solve(self, ev: Evaluation, x_bar: Array, trust: float, mu: float,
              time_limit_s: float = 0.0) -> tuple[Array, float, str]:
        """Solve the QP linearised at ev (x_bar = ev.Q flattened): (x, model objective, status).

        The model objective is ½ xᵀPx + μ Σ c s, i.e. the merit of the linearised problem.
        ``time_limit_s`` > 0 bounds OSQP's ADMM iterations (s; 0: no bound)."""
        Ax, lo_, u, q = self._fill(ev, x_bar, trust, mu)
        relinearised = ev is not self._last_ev
        self._last_ev = ev
        if self._solver is None:
            col_counts = np.bincount(self._A_cols, minlength=self.n_z)
            A = sp.csc_matrix((Ax, self._A_rows[self._order],
                               np.concatenate([[0], np.cumsum(col_counts)])),
                              shape=(self.n_rows, self.n_z))
            eps = self.problem.config.osqp_eps
            self._solver = QPSolver(self.P, q, A, lo_, u, {
                "verbose": False, "eps_abs": eps, "eps_rel": eps, "polishing": False,
                "max_iter": 4000, "warm_starting": True, "check_termination": 5,
                "scaling": 0, "rho": self.problem.config.osqp_rho})
        elif relinearised:
            self._solver.update(Ax=Ax, lower=lo_, upper=u, q=q)
        else:  # trust-region shrink: same matrix, no refactorisation
            self._solver.update(lower=lo_, upper=u, q=q)
        if relinearised:  # start ADMM at the linearisation point and its violations
            z0 = np.concatenate([x_bar, np.maximum(self._residual_slacks(x_bar, lo_, u), 0.0)])
            self._solver.warm_start(z0)
        x, iterations, status = self._solver.solve(time_limit_s if time_limit_s > 0 else 1e10)
        self.admm_iterations += iterations
        if x is None or not np.all(np.isfinite(x)):
            return x_bar.copy(), np.inf, status
        xs = np.clip(x[:self.n_x], lo_[:self.n_x], u[:self.n_x])
        s_model = np.maximum(self._residual_slacks(xs, lo_, u), 0.0)
        obj = self.problem.smoothness(xs.reshape(-1, self.problem.dof)) \
            + mu * float(self.slack_coeff @ s_model)
        return xs, obj, status

    def fits(self, ev: Evaluation) -> bool:
        """Whether every term with a gradient at ev has a row (else rebuild with
        :func:`term_counts`)."""
        w, s = term_counts(ev)
        return bool(np.all(w <= self.waypoint_capacity) and np.all(s <= self.segment_capacity))

    def _residual_slacks(self, x: Array, lo_: Array, u: Array) -> Array:
        """The smallest slacks that make every block row hold at x: the linearised model's
        violations (so the model objective is evaluated exactly at the clipped x)."""
        r = self._block_rows
        return residual_slacks(self._vals, x, lo_, u, r.start, r.n_rows, r.width, r.value_at,
                               r.cols, r.sense, r.slack, self._n_slack)


def term_counts(ev: Evaluation) -> tuple[IntArray, IntArray]:
    """Collision terms within the check distance per waypoint (T,) and per segment (T-1,)
    (the kernels sort them first; unused slots hold 1e3)."""
    return ((ev.dist_waypoint < 1e2).sum(axis=1).astype(np.int64),
            (ev.dist_segment < 1e2).sum(axis=1).astype(np.int64))


def _term_index(capacity: IntArray) -> tuple[IntArray, IntArray]:
    """(waypoint or segment, slot) of each row for the given capacities."""
    t = np.repeat(np.arange(len(capacity), dtype=np.int64), capacity)
    starts = np.repeat(np.cumsum(capacity) - capacity, capacity)
    return t, np.arange(len(t), dtype=np.int64) - starts


def _smoothness_hessian(problem: TrajOptProblem, n_z: int) -> sp.csc_matrix:
    """P (n_z, n_z), upper triangle, CSC: the smoothness Hessian, ½ xᵀ P x = Σ_t ||W (x_{t+1} -
    x_t)||², plus the proximal term ½ ρ ||x - x̄||² that regularises each step (ADMM converges
    far faster on a strongly convex QP; the merit model of the ratio test leaves it out).
    Built directly: column (t, j) holds (t-1, j) and its diagonal; slack columns are empty."""
    T, K = problem.n_waypoints, problem.dof
    w2 = np.tile(2.0 * problem.weights**2, T)
    deg = np.full(T * K, 2.0)
    deg[:K] = deg[-K:] = 1.0
    diag = deg * w2 + problem.config.proximal_weight
    if T == 1:
        diag = np.full(K, problem.config.proximal_weight)
    has_up = np.arange(T * K) >= K
    counts = np.concatenate([1 + has_up.astype(np.int64),
                             np.zeros(n_z - T * K, dtype=np.int64)])
    indptr = np.concatenate([[0], np.cumsum(counts)])
    indices = np.empty(indptr[-1], dtype=np.int64)
    data = np.empty(indptr[-1])
    first = indptr[:-1][:T * K]
    up = first[has_up]
    cols_up = np.flatnonzero(has_up)
    indices[up], data[up] = cols_up - K, -w2[cols_up]
    dpos = first + has_up
    indices[dpos], data[dpos] = np.arange(T * K), diag
    return sp.csc_matrix((data, indices, indptr), shape=(n_z, n_z))
