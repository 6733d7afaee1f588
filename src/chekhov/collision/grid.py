"""Signed-distance grids of static primitives: one lookup decides most sphere tests.

A grid stores, at each voxel centre v, the distance d(v) to the nearest primitive quantised
down to a multiple of ``delta`` (uint8; 255 means "at least cap"). The distance field is
1-Lipschitz, so for a sphere (c, r) with nearest voxel centre v: d(v) - |c - v| ≥ r proves it
free and d(v) + |c - v| < r proves it overlapping. Only the thin band between needs exact
sphere-primitive tests (see ``kernels.grid_classify``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit
from numpy.typing import NDArray

from chekhov.collision.kernels import signed_distance

Array = NDArray[np.float64]
CAP = 0.25  # m: distances beyond this are stored as "at least CAP" (> largest group radius)


@dataclass(frozen=True)
class DistanceGrid:
    """Quantised distances at voxel centres origin + h·index: q·delta ≤ d < (q + 1)·delta."""

    origin: Array
    h: float
    delta: float
    values: NDArray[np.uint8]

    @property
    def nbytes(self) -> int:
        return int(self.values.nbytes)


@njit(cache=True)
def _fill(origin, h, kind, R, p, size, bound, out):  # pragma: no cover - compiled
    """out = min(out, distance to each primitive), visiting only voxels within CAP of it."""
    x = np.empty(3)
    n0, n1, n2 = out.shape
    for o in range(kind.shape[0]):
        lo = np.empty(3, dtype=np.int64)
        hi = np.empty(3, dtype=np.int64)
        for a in range(3):
            lo[a] = max(0, int(np.floor((p[o, a] - bound[o] - CAP - origin[a]) / h)))
            hi[a] = int(np.ceil((p[o, a] + bound[o] + CAP - origin[a]) / h)) + 1
        for i in range(lo[0], min(hi[0], n0)):
            x[0] = origin[0] + h * i
            for j in range(lo[1], min(hi[1], n1)):
                x[1] = origin[1] + h * j
                for k in range(lo[2], min(hi[2], n2)):
                    x[2] = origin[2] + h * k
                    d = signed_distance(kind[o], R[o], p[o], size[o], x)
                    if d < out[i, j, k]:
                        out[i, j, k] = d


def build_grid(lo: Array, hi: Array, h: float,
               prims: tuple[NDArray[np.int64], Array, Array, Array]) -> DistanceGrid:
    """Grid over the box [lo, hi] (m) at spacing h (m) of the distance to packed primitives."""
    shape = tuple(int(n) for n in np.maximum(np.ceil((hi - lo) / h).astype(np.int64) + 1, 1))
    vals = np.full(shape, CAP, dtype=np.float64)
    kind, R, p, size = prims
    bound = np.linalg.norm(size, axis=1) if len(kind) else np.zeros(0)
    _fill(lo.astype(float), float(h), kind, R, p, size, bound, vals)
    delta = CAP / 255.0
    q = np.clip(np.floor(vals / delta), 0, 255).astype(np.uint8)
    return DistanceGrid(lo.astype(float), float(h), delta, q)
