"""Greedy shortcutting of a waypoint path with batched motion checks."""

from __future__ import annotations

import math
import time

import numpy as np
from numpy.typing import NDArray

from chekhov.collision.fast import FastChecker

Array = NDArray[np.float64]


def shortcut_path(fast: FastChecker, path: Array, resolution: float = 0.02,
                  coarse: float = 0.1, deadline: float = math.inf) -> Array:
    """The path (T, K) with every waypoint skipped that a straight, collision-free motion can
    jump over: from each kept waypoint, go to the farthest later waypoint it sees. Candidate
    jumps are screened at a ``coarse`` resolution (one batched motion check), then the farthest
    survivor is confirmed at ``resolution`` (rad) before it is taken. The result's waypoints
    are a subsequence of the input's, its segments are free at ``resolution``, and it is never
    longer (the path's own segments are assumed free, as a planner's are). After ``deadline``
    (a ``time.perf_counter()`` value, s) the rest of the path is kept as it is."""
    P = np.atleast_2d(np.asarray(path, dtype=float))
    keep = [0]
    i = 0
    while i < len(P) - 1:
        j = i + 1
        if i + 2 < len(P) and time.perf_counter() < deadline:
            later = np.arange(i + 2, len(P))
            start = np.repeat(P[i:i + 1], len(later), axis=0)
            ok = fast.motions_valid(start, P[later], coarse)
            for cand in later[ok][::-1]:
                if time.perf_counter() >= deadline:
                    break
                if fast.motions_valid(P[i:i + 1], P[cand:cand + 1], resolution)[0]:
                    j = int(cand)
                    break
        keep.append(j)
        i = j
    return P[keep]
