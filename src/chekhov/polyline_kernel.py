"""The nearest segment of a polyline to each of many configurations, compiled (numba): what
:func:`chekhov.timing.polyline_offsets` computes for every knot of a timed path (hundreds of
knots against tens of segments, twice per timed answer). Units: rad."""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True, nogil=True)
def nearest_segments(Q, P):  # pragma: no cover - compiled
    """(segment (N,) int64, distance (N,)): for each row of Q (N, K), the segment
    P[s] → P[s + 1] of the polyline P (T ≥ 2, K) nearest it (the first of equals) and the
    distance to it."""
    N, K = Q.shape
    S = P.shape[0] - 1
    seg = np.zeros(N, dtype=np.int64)
    dist = np.empty(N)
    d = np.empty((S, K))
    dd = np.empty(S)
    for s in range(S):
        acc = 0.0
        for k in range(K):
            d[s, k] = P[s + 1, k] - P[s, k]
            acc += d[s, k] * d[s, k]
        dd[s] = max(acc, 1e-300)
    for n in range(N):
        best = np.inf
        for s in range(S):
            dot = 0.0
            for k in range(K):
                dot += (Q[n, k] - P[s, k]) * d[s, k]
            t = min(max(dot / dd[s], 0.0), 1.0)
            g2 = 0.0
            for k in range(K):
                g = Q[n, k] - (P[s, k] + t * d[s, k])
                g2 += g * g
            if g2 < best:
                best = g2
                seg[n] = s
        dist[n] = np.sqrt(best)
    return seg, dist
