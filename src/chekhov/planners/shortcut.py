"""Greedy shortcutting of a waypoint path with batched motion checks."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from chekhov.collision.fast import FastChecker

Array = NDArray[np.float64]


def shortcut_path(fast: FastChecker, path: Array, resolution: float = 0.02) -> Array:
    """The path (T, K) with every waypoint skipped that a straight, collision-free motion can
    jump over: from each kept waypoint, go to the farthest later waypoint it sees (one batched
    ``motions_valid`` call per kept waypoint). The result's waypoints are a subsequence of the
    input's, its segments are free at ``resolution`` rad, and it is never longer."""
    P = np.atleast_2d(np.asarray(path, dtype=float))
    keep = [0]
    i = 0
    while i < len(P) - 1:
        later = P[i + 1:]
        ok = fast.motions_valid(np.repeat(P[i:i + 1], len(later), axis=0), later, resolution)
        ok[0] = True  # the original segment (already valid) is always allowed
        i = i + 1 + int(np.flatnonzero(ok)[-1])
        keep.append(i)
    return P[keep]
