"""Joint-space paths (T, K) in radians: length and resampling (floor 0: used by every layer)."""

from __future__ import annotations

from itertools import pairwise

import numpy as np
from numpy.typing import NDArray

Array = NDArray[np.float64]


def path_length(path: Array) -> float:
    """Sum of joint-space L2 segment lengths of a (T, K) path, rad."""
    P = np.asarray(path, dtype=float)
    return float(np.linalg.norm(np.diff(P, axis=0), axis=1).sum()) if len(P) > 1 else 0.0


def resample_path(path: Array, max_step: float = 0.16) -> Array:
    """The path (T, K) with each segment split evenly so that adjacent waypoints are at most
    ``max_step`` rad apart (joint-space L2, the paper's 0.16 rad pre-processing). Waypoints of
    the input are kept; repeated waypoints are dropped."""
    P = np.atleast_2d(np.asarray(path, dtype=float))
    out = [P[0]]
    for a, b in pairwise(P):
        d = float(np.linalg.norm(b - a))
        if d < 1e-12:
            continue
        n = int(np.ceil(d / max_step - 1e-9))
        for i in range(1, n + 1):
            out.append(a + (b - a) * (i / n))
    return np.array(out)
