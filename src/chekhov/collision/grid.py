"""Signed-distance grids of static primitives: one lookup decides most sphere tests.

A grid stores, at each voxel centre v, the distance d(v) to the nearest primitive quantised
down to a multiple of ``delta`` (uint8; ``codes.GRID_SATURATED`` means "at least cap"). The
distance field is 1-Lipschitz, so for a sphere (c, r) with nearest voxel centre v:
d(v) - |c - v| ≥ r proves it free and d(v) + |c - v| < r proves it overlapping. Only the
thin band between needs exact sphere-primitive tests (see ``kernels.grid_classify``).

A *surface* grid (:func:`build_surface_grid`) holds the distance to solid primitives and to
points sampled on the triangles of meshes (their surface: what the exact checker tests) —
never less than the distance to the surface —, computed only within ``reach`` of them and
stored as "at least CAP" beyond. It is only ever used to prove overlap (a ball inside the
robot's geometry that holds a point of a triangle is a collision), for which an overestimated
distance is safe; never to prove a sphere free.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit
from numpy.typing import NDArray
from scipy.spatial import cKDTree

from chekhov.collision.codes import GRID_SATURATED
from chekhov.collision.kernels import signed_distance
from chekhov.collision.primitives import Primitives

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


@njit(cache=True, nogil=True)
def _fill(origin, h, kind, R, p, size, bound, out, reach=CAP):  # pragma: no cover - compiled
    """out = min(out, distance to each primitive), visiting only voxels within ``reach`` of
    it."""
    x = np.empty(3)
    n0, n1, n2 = out.shape
    for o in range(kind.shape[0]):
        lo = np.empty(3, dtype=np.int64)
        hi = np.empty(3, dtype=np.int64)
        for a in range(3):
            lo[a] = max(0, int(np.floor((p[o, a] - bound[o] - reach - origin[a]) / h)))
            hi[a] = int(np.ceil((p[o, a] + bound[o] + reach - origin[a]) / h)) + 1
        for i in range(lo[0], min(hi[0], n0)):
            x[0] = origin[0] + h * i
            for j in range(lo[1], min(hi[1], n1)):
                x[1] = origin[1] + h * j
                for k in range(lo[2], min(hi[2], n2)):
                    x[2] = origin[2] + h * k
                    d = signed_distance(kind[o], R[o], p[o], size[o], x)
                    if d < out[i, j, k]:
                        out[i, j, k] = d


def _shape(lo: Array, hi: Array, h: float) -> NDArray[np.int64]:
    return np.maximum(np.ceil((hi - lo) / h).astype(np.int64) + 1, 1)


def point_field(lo: Array, hi: Array, h: float, points: Array, reach: float
                ) -> tuple[NDArray[np.int64], Array]:
    """Distance (m) from the voxel centres of the grid over [lo, hi] (spacing h, m) near
    ``points`` (P, 3) (world, m) to the nearest point: (i0 (3,), d) for the block of voxels
    from index i0 that lies within ``reach`` (m) of the points' bounding box; CAP beyond
    ``reach``. Duplicate points are dropped first."""
    shape = _shape(lo, hi, h)
    key = np.round(points * 1e6).astype(np.int64)  # µm: exact duplicates (shared corners)
    _, first = np.unique((key[:, 0] * 4_000_037 + key[:, 1]) * 4_000_037 + key[:, 2],
                         return_index=True)
    points = points[first]
    i0 = np.clip(np.floor((points.min(axis=0) - reach - lo) / h), 0, shape).astype(np.int64)
    i1 = np.clip(np.ceil((points.max(axis=0) + reach - lo) / h) + 1, 0, shape).astype(np.int64)
    axes = [lo[a] + h * np.arange(i0[a], i1[a]) for a in range(3)]
    centres = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
    d, _ = cKDTree(points).query(centres, distance_upper_bound=reach)
    return i0, np.minimum(d, CAP).reshape(tuple(int(n) for n in i1 - i0))


def build_surface_grid(lo: Array, hi: Array, h: float,
                       prims: Primitives,
                       fields: list[tuple[NDArray[np.int64], Array]], reach: float
                       ) -> DistanceGrid:
    """Surface grid (see the module docstring) over [lo, hi] (m), spacing h (m): distances to
    the packed solid primitives within ``reach`` (m), and the :func:`point_field` of points on
    mesh surfaces (the distance to the nearest such point bounds the distance to the surface
    from above); "at least CAP" elsewhere."""
    vals = np.full(tuple(int(n) for n in _shape(lo, hi, h)), CAP, dtype=np.float64)
    kind, R, p, size = prims.kind, prims.R, prims.p, prims.size
    bound = np.linalg.norm(size, axis=1) if len(kind) else np.zeros(0)
    _fill(lo.astype(float), float(h), kind, R, p, size, bound, vals, float(reach))
    for i0, d in fields:
        box = vals[i0[0]:i0[0] + d.shape[0], i0[1]:i0[1] + d.shape[1], i0[2]:i0[2] + d.shape[2]]
        np.minimum(box, d, out=box)
    delta = CAP / GRID_SATURATED
    q = np.clip(np.floor(vals / delta), 0, GRID_SATURATED).astype(np.uint8)
    return DistanceGrid(lo.astype(float), float(h), delta, q)


def build_grid(lo: Array, hi: Array, h: float, prims: Primitives) -> DistanceGrid:
    """Grid over the box [lo, hi] (m) at spacing h (m) of the distance to packed primitives."""
    vals = np.full(tuple(int(n) for n in _shape(lo, hi, h)), CAP, dtype=np.float64)
    kind, R, p, size = prims.kind, prims.R, prims.p, prims.size
    bound = np.linalg.norm(size, axis=1) if len(kind) else np.zeros(0)
    _fill(lo.astype(float), float(h), kind, R, p, size, bound, vals)
    delta = CAP / GRID_SATURATED
    q = np.clip(np.floor(vals / delta), 0, GRID_SATURATED).astype(np.uint8)
    return DistanceGrid(lo.astype(float), float(h), delta, q)
