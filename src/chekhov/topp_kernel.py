"""TOPP-RA (Pham & Pham 2018) for joint velocity and acceleration limits, compiled (numba).

The problem toppra solves for :mod:`chekhov.timing`, without its generic machinery: along a
path q(s) sampled at grid points s_0 < … < s_N (rad of path length), with q'(s_i) = dq[i] and
q''(s_i) = ddq[i], find squared path speeds x_i = ṡ_i² (constant path acceleration u_i on
stage i, x_{i+1} = x_i + 2 Δ_i u_i) that reach the end fastest, from rest to rest, subject to

* velocity: |dq[i, j]| √x_i ≤ v_j, i.e. x_i ≤ min_j (v_j / |dq[i, j]|)²;
* acceleration, with toppra's *interpolation* scheme (its default for joint acceleration):
  |dq[i, j] u_i + ddq[i, j] x_i| ≤ a_j at s_i, and the same at s_{i+1} with x_{i+1} — so
  |(dq[i+1, j] + 2 Δ_i ddq[i+1, j]) u_i + ddq[i+1, j] x_i| ≤ a_j.

Backward pass: the controllable sets K_i = [lo_i, hi_i] (the x_i from which the end can
still be reached at rest), K_N = {0}. Every constraint of stage i is linear in (x_i, u_i);
eliminating u (Fourier–Motzkin: every upper bound on u must be ≥ every lower bound) leaves
linear bounds on x alone, so K_i is exact — where toppra solves two LPs per stage. Forward
pass: from x_0 = 0, the largest u_i that keeps x_{i+1} in K_{i+1} (toppra's greedy pass).

Same answers as toppra's to its solver's tolerance (``tests/test_trajectory.py`` compares
them); about 20 times faster than the package's solver on 190 random polylines (grid and
path derivatives included).
"""

from __future__ import annotations

import numpy as np
from numba import njit

X_CAP = 1e12
"""(rad/s)²: the bound on x where no joint moves along the path (a degenerate stage)."""
SLACK = 1e-9
"""Relative tolerance when a controllable set closes to a point (the last stages, at rest)."""


@njit(cache=True, nogil=True, inline="always")
def _add(alpha, beta, gamma, up, lo, nu, nl, x_lo, x_hi):  # pragma: no cover - compiled
    """File the constraint alpha·x + beta·u ≤ gamma: as an upper (beta > 0) or lower
    (beta < 0) bound on u, u ≤ (gamma − alpha x) / beta, stored as (intercept, slope) in row
    nu of up or nl of lo; with beta = 0, as a bound on x. Returns (nu, nl, x_lo, x_hi)."""
    if beta > 0.0:
        up[nu, 0] = gamma / beta
        up[nu, 1] = -alpha / beta
        return nu + 1, nl, x_lo, x_hi
    if beta < 0.0:
        lo[nl, 0] = gamma / beta
        lo[nl, 1] = -alpha / beta
        return nu, nl + 1, x_lo, x_hi
    if alpha > 0.0:
        return nu, nl, x_lo, min(x_hi, gamma / alpha)
    if alpha < 0.0:
        return nu, nl, max(x_lo, gamma / alpha), x_hi
    if gamma < 0.0:
        return nu, nl, 1.0, -1.0   # 0 ≤ gamma < 0: infeasible
    return nu, nl, x_lo, x_hi


@njit(cache=True, nogil=True, inline="always")
def _stage(i, grid, dq, ddq, vmax, amax, nxt_lo, nxt_hi, up, lo
           ):  # pragma: no cover - compiled
    """Stage i's constraints on (x_i, u_i), given K_{i+1} = [nxt_lo, nxt_hi], filed by
    :func:`_add`: (upper bounds on u, lower bounds on u, x_lo, x_hi)."""
    d = grid[i + 1] - grid[i]
    nu, nl, x_lo, x_hi = 0, 0, 0.0, X_CAP
    for j in range(dq.shape[1]):
        a0, b0, a1 = dq[i, j], ddq[i, j], ddq[i + 1, j]
        if a0 != 0.0:
            x_hi = min(x_hi, (vmax[j] / a0) * (vmax[j] / a0))
        b1 = dq[i + 1, j] + 2.0 * d * a1
        nu, nl, x_lo, x_hi = _add(b0, a0, amax[j], up, lo, nu, nl, x_lo, x_hi)
        nu, nl, x_lo, x_hi = _add(-b0, -a0, amax[j], up, lo, nu, nl, x_lo, x_hi)
        nu, nl, x_lo, x_hi = _add(a1, b1, amax[j], up, lo, nu, nl, x_lo, x_hi)
        nu, nl, x_lo, x_hi = _add(-a1, -b1, amax[j], up, lo, nu, nl, x_lo, x_hi)
    nu, nl, x_lo, x_hi = _add(1.0, 2.0 * d, nxt_hi, up, lo, nu, nl, x_lo, x_hi)
    nu, nl, x_lo, x_hi = _add(-1.0, -2.0 * d, -nxt_lo, up, lo, nu, nl, x_lo, x_hi)
    return nu, nl, x_lo, x_hi


@njit(cache=True, nogil=True)
def controllable_sets(grid, dq, ddq, vmax, amax):  # pragma: no cover - compiled
    """K (N+1, 2): [lo, hi] of x_i from which the path can still end at rest; NaN from the
    first stage (going back) where none is left."""
    N = grid.shape[0] - 1
    K = dq.shape[1]
    m = 4 * K + 2
    up = np.empty((m, 2))
    lo = np.empty((m, 2))
    out = np.full((N + 1, 2), np.nan)
    out[N, 0] = 0.0
    out[N, 1] = 0.0
    for i in range(N - 1, -1, -1):
        nu, nl, x_lo, x_hi = _stage(i, grid, dq, ddq, vmax, amax, out[i + 1, 0],
                                    out[i + 1, 1], up, lo)
        # every upper bound on u above every lower one: (c_p − c_q) + (s_p − s_q) x ≥ 0
        for p in range(nu):
            for q in range(nl):
                c = up[p, 0] - lo[q, 0]
                s = up[p, 1] - lo[q, 1]
                if s > 0.0:
                    x_lo = max(x_lo, -c / s)
                elif s < 0.0:
                    x_hi = min(x_hi, -c / s)
                elif c < 0.0:
                    x_hi = -1.0
        if x_lo > x_hi:
            if x_lo - x_hi > SLACK * max(1.0, abs(x_hi)):
                return out
            x_lo = x_hi
        out[i, 0] = max(x_lo, 0.0)
        out[i, 1] = max(x_hi, 0.0)
    return out


@njit(cache=True, nogil=True)
def greedy_speeds(grid, dq, ddq, vmax, amax, Kset):  # pragma: no cover - compiled
    """Squared path speeds x (N+1,) from rest: at each stage the largest path acceleration
    that keeps the next x in its controllable set Kset (N+1, 2)."""
    N = grid.shape[0] - 1
    K = dq.shape[1]
    m = 4 * K + 2
    up = np.empty((m, 2))
    lo = np.empty((m, 2))
    x = np.zeros(N + 1)
    for i in range(N):
        nu = _stage(i, grid, dq, ddq, vmax, amax, Kset[i + 1, 0], Kset[i + 1, 1], up, lo)[0]
        u = np.inf
        for p in range(nu):
            u = min(u, up[p, 0] + up[p, 1] * x[i])
        d = grid[i + 1] - grid[i]
        x[i + 1] = min(max(x[i] + 2.0 * d * u, Kset[i + 1, 0]), Kset[i + 1, 1])
    return x


def path_speeds(grid: np.ndarray, dq: np.ndarray, ddq: np.ndarray, vmax: np.ndarray,
                amax: np.ndarray) -> np.ndarray | None:
    """Time-optimal path speeds ṡ (N+1,) rad/s at the grid (N+1,) rad, from rest to rest,
    for q'(s) dq (N+1, K), q''(s) ddq (N+1, K) and limits vmax, amax (K,) (rad/s, rad/s²);
    None when the path cannot be followed within the limits (no controllable set)."""
    Kset = controllable_sets(grid, dq, ddq, vmax, amax)
    if np.isnan(Kset[0]).any() or Kset[0, 0] > 0.0:
        return None
    return np.sqrt(np.maximum(greedy_speeds(grid, dq, ddq, vmax, amax, Kset), 0.0))
