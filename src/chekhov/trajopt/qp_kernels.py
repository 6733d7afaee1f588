"""Compiled per-step work of the SQP subproblem (``qp.TrajOptQP``): its collision rows' values
and bounds, and the slacks that make its rows hold at a point.

The subproblem's rows come in blocks of fixed width (``qp._Rows``); their values sit in one
flat array in the order OSQP's pattern was assembled, row after row, each row's variable
coefficients followed by its slack's. In numpy each block cost a dozen array calls a step
(fancy indexing, einsum, ``np.maximum.at``): ~0.2 ms a fill and ~0.1 ms a residual on a
50-waypoint problem, more than the arithmetic. Here each is one loop over the rows.
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
