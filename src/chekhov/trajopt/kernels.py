"""Compiled per-step work of TrajOpt's SQP: the subproblem's (``qp.TrajOptQP``) collision rows'
values and bounds and the slacks that make its rows hold at a point, and the merit's sums
(``problem.TrajOptProblem.merit``: violations and smoothness).

The subproblem's rows come in blocks of fixed width (``qp._Rows``); their values sit in one
flat array in the order OSQP's pattern was assembled, row after row, each row's variable
coefficients followed by its slack's. In numpy each block cost a dozen array calls a step
(fancy indexing, einsum, ``np.maximum.at``): ~0.2 ms a fill and ~0.1 ms a residual on a
50-waypoint problem, more than the arithmetic; the merit, ~60 µs a call as a dict of
violation arrays. Here each is one loop.
"""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True, nogil=True)
def fill_collision_rows(vals, lo, value_start, row_start, t_index, k_index, grad, dist, safe,
                        Q, segment):  # pragma: no cover - compiled
    """Write one collision block's rows at the linearisation point Q (T, K) rad.

    Row i is term k_index[i] of waypoint (or, with ``segment``, segment) t_index[i]: its
    coefficients grad[t, k] (W,) m/rad go to vals[value_start + i (W + 1):][:W] (the slack's
    coefficient after them stays), and its lower bound lo[row_start + i] = safe[t] - dist[t, k]
    + grad[t, k] · x_t, with x_t = Q[t] (W = K) or (Q[t], Q[t + 1]) (W = 2 K): the hinge
    dist + grad · (x - x_t) ≥ safe."""
    K = Q.shape[1]
    W = grad.shape[2]
    for i in range(t_index.shape[0]):
        t, k = t_index[i], k_index[i]
        at = value_start + i * (W + 1)
        dot = 0.0
        for j in range(W):
            g = grad[t, k, j]
            vals[at + j] = g
            if segment and j >= K:
                dot += g * Q[t + 1, j - K]
            else:
                dot += g * Q[t, j]
        lo[row_start + i] = safe[t] - dist[t, k] + dot


@njit(cache=True, nogil=True)
def residual_slacks(vals, x, lo, hi, start, count, width, value_at, cols, sense, slack,
                    n_slack):  # pragma: no cover - compiled
    """(n_slack,): per slack, the largest violation at x of the rows it serves, at least 0.

    Block b holds ``count[b]`` rows from global row ``start[b]``, each with ``width[b]``
    coefficients (its row i's at vals[value_at[b] + i (width[b] + 1):], the slack's after
    them); the blocks' rows one after another: their columns ``cols`` (``width`` each),
    ``sense`` (> 0: a · x ≥ lo[row], else a · x ≤ hi[row]) and ``slack`` (counted from the
    first)."""
    s = np.zeros(n_slack)
    i = 0       # the row, over all blocks
    c = 0       # its first column in cols
    for b in range(start.shape[0]):
        w = width[b]
        for j in range(count[b]):
            at = value_at[b] + j * (w + 1)
            ax = 0.0
            for m in range(w):
                ax += vals[at + m] * x[cols[c + m]]
            r = start[b] + j
            v = lo[r] - ax if sense[i] > 0 else ax - hi[r]
            if v > s[slack[i]]:
                s[slack[i]] = v
            i += 1
            c += w
    return s


@njit(cache=True, nogil=True)
def hinge_sum(safe, dist):  # pragma: no cover - compiled
    """Σ_t Σ_c max(safe[t] - dist[t, c], 0): the collision terms' violations (m), safe (T,),
    dist (T, C) m."""
    total = 0.0
    for t in range(dist.shape[0]):
        for c in range(dist.shape[1]):
            v = safe[t] - dist[t, c]
            if v > 0.0:
                total += v
    return total


@njit(cache=True, nogil=True)
def excess_sum(values, limit):  # pragma: no cover - compiled
    """Σ max(|values[t, k]| - limit[k], 0) over values (N, K) and limit (K,): violations of
    symmetric limits (velocities, accelerations, torques, the goal's error)."""
    total = 0.0
    for t in range(values.shape[0]):
        for k in range(values.shape[1]):
            v = abs(values[t, k]) - limit[k]
            if v > 0.0:
                total += v
    return total


@njit(cache=True, nogil=True)
def weighted_squared_steps(Q, weights):  # pragma: no cover - compiled
    """Σ_t ||weights ∘ (Q[t + 1] - Q[t])||² (rad²) over Q (T, K): the smoothness cost."""
    total = 0.0
    for t in range(Q.shape[0] - 1):
        for k in range(Q.shape[1]):
            d = (Q[t + 1, k] - Q[t, k]) * weights[k]
            total += d * d
    return total
