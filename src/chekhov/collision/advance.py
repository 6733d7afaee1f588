"""Distance-certified path validation for the exact checker (conservative advancement).

A densified path visits configurations D[0], D[1], … in order. Checking every one with coal is
the reference; here a collision pair is only looked at again when it could have changed its
answer. At a checked configuration D[i] coal gives the pair's clearance d (m). Along the
straight joint-space steps that follow, no point of either geometry moves, relative to the
other, by more than

    sum over steps s ≥ i, over joints k of |ΔD[s, k]| · r_k,

where r_k (m) bounds the distance from joint k's origin (a point on its axis) of any point of
the distal geometry, over every configuration, and only the joints between the two geometries
count (for a pair on the arm, the joints after the proximal one; for an obstacle or a fixed
robot part, every joint up to the moving geometry's). While that sum stays below d - EPS the
pair is certified free, so it is skipped. This is the pinocchio + coal referee: it shares no
code with the fast checker, and its first colliding index equals that of checking every
configuration one by one.
"""

from __future__ import annotations

import heapq
from bisect import bisect_left

import coal
import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from chekhov.robot.robot import joint_axis

Array = NDArray[np.float64]
EPS = 1e-4  # m: a pair closer than this at a checked configuration gets the collision test


def _line_distance(x: Array, axis: Array) -> Array:
    """Distance (m) of points x (n, 3) from the line through the origin along unit ``axis``."""
    return np.linalg.norm(x - np.outer(x @ axis, axis), axis=1)


def geometry_extent(go: pin.GeometryObject, axis: Array) -> tuple[float, float]:
    """Upper bounds (m) on the distance of any point of the geometry from its parent joint's
    origin, and from the line through it along ``axis`` (parent joint frame)."""
    g = go.geometry
    R, p = go.placement.rotation, go.placement.translation
    if isinstance(g, coal.Sphere | coal.Cylinder | coal.Capsule):
        # two points on the shape's axis, each with a ball around it holding the shape
        if isinstance(g, coal.Sphere):
            ends, rad = np.zeros((1, 3)), g.radius
        else:
            ends, rad = np.array([[0, 0, -g.halfLength], [0, 0, g.halfLength]]), g.radius
        pts = ends @ R.T + p
        return (float(np.max(np.linalg.norm(pts, axis=1)) + rad),
                float(np.max(_line_distance(pts, axis)) + rad))
    if isinstance(g, coal.Box):
        pts = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)])
        pts = pts * np.asarray(g.halfSide) @ R.T + p
    elif hasattr(g, "num_tris"):
        pts = np.asarray(g.vertices(), dtype=float) @ R.T + p
    else:
        g.computeLocalAABB()
        c = R @ np.asarray(g.aabb_center) + p
        return (float(np.linalg.norm(c) + g.aabb_radius),
                float(_line_distance(c[None], axis)[0] + g.aabb_radius))
    # convex hull of the points: both distances are convex, so their maxima are at the points
    return float(np.max(np.linalg.norm(pts, axis=1))), float(np.max(_line_distance(pts, axis)))


def pair_weights(model: pin.Model, geom_model: pin.GeometryModel,
                 pairs: NDArray[np.int64] | None = None,
                 radii_cache: dict[int, Array] | None = None
                 ) -> tuple[Array, NDArray[np.int64]] | None:
    """Motion-bound weights of every collision pair of ``geom_model``, or None when a joint is
    not revolute.

    Returns (W (U, K), row (P,)): pair p's geometries move relative to each other by at most
    |Δq| · W[row[p]] metres along a straight joint step Δq (rad); U distinct rows. A point x
    moving with joint k's rotation moves at most |Δq_k| · (its distance from the axis); that
    distance is bounded over all configurations from the fixed link offsets: the distance of
    joint k+1's origin from axis k plus |x - origin k+1|.

    ``pairs`` (P, 2): the geometry indices of the collision pairs, in the model's order (read
    from the model when None); ``radii_cache``: per-geometry bounds kept between calls (a
    geometry index must keep meaning the same geometry, as the robot's do).
    """
    K = model.nq
    found = [joint_axis(model.joints[k]) for k in range(1, K + 1)]
    axes = [a for a in found if a is not None]
    if len(axes) != K:
        return None
    off = [model.jointPlacements[k].translation for k in range(1, K + 1)]
    link = [float(np.linalg.norm(t)) for t in off]  # |o_k - o_(k-1)| (group index k)
    # distance of joint k+1's origin from axis k (a fixed offset in frame k)
    lever = [float(_line_distance(off[k + 1][None], axes[k])[0]) if k + 1 < K else 0.0
             for k in range(K)]
    cache = radii_cache if radii_cache is not None else {}
    objs = geom_model.geometryObjects
    parents = np.array([objs[g].parentJoint for g in range(geom_model.ngeoms)], dtype=np.int64)

    def radii(gi: int) -> Array:
        """r_k for every joint moving geometry gi (0 for the others)."""
        J = int(parents[gi])
        if J == 0:
            return np.zeros(K)
        if gi not in cache:
            w = np.zeros(K)
            origin, line = geometry_extent(objs[gi], axes[J - 1])
            w[J - 1] = min(origin, line)
            for k in range(J - 2, -1, -1):
                w[k] = min(origin + link[k + 1], lever[k] + origin)
                origin += link[k + 1]
            cache[gi] = w * (1 + 1e-9) + 1e-12
        return cache[gi]

    if pairs is None:
        pairs = np.array([(cp.first, cp.second) for cp in geom_model.collisionPairs],
                         dtype=np.int64).reshape(-1, 2)
    R = np.stack([radii(g) for g in range(geom_model.ngeoms)]) if geom_model.ngeoms else \
        np.zeros((0, K))
    a, b = pairs[:, 0], pairs[:, 1]
    swap = parents[a] > parents[b]   # b is distal: only the joints after a's move b
    a, b = np.where(swap, b, a), np.where(swap, a, b)
    # a pair's weights depend only on (b, a's joint): one row per distinct key
    _, first, row = np.unique(b * (K + 1) + parents[a], return_index=True,
                              return_inverse=True)
    U = R[b[first]].copy()
    U[np.arange(K)[None, :] < parents[a[first]][:, None]] = 0.0
    return U.reshape(-1, K), row.reshape(-1).astype(np.int64)


def first_collision_certified(model: pin.Model, data: pin.Data, geom_model: pin.GeometryModel,
                              geom_data: pin.GeometryData, D: Array, W: Array,
                              row: NDArray[np.int64]) -> int | None:
    """Index of the first configuration of D (N, K) where a collision pair of ``geom_model``
    collides (coal), or None; pairs are only re-checked when their clearance no longer
    certifies them (see the module docstring). W, row: from :func:`pair_weights`."""
    N, P = len(D), len(row)
    if P == 0 or N == 0:
        return None
    U = len(W)
    C = np.zeros((U, N))
    if N > 1:
        # einsum, not a matrix product: at (N ≈ 3000) × K × U OpenBLAS runs the product on
        # its thread pool, whose threads then spin on the cores for a while after it; beside
        # another planning process on two cores, that halved the other's speed (2.3 → 5.6 ms
        # a first answer, ``docs/history.md``). einsum's own loops: 0.45 → 1.0 ms of a 25 ms
        # check of 1,200-2,900 configurations
        C[:, 1:] = np.cumsum(np.einsum("nk,uk->un", np.abs(np.diff(D, axis=0)), W), axis=1)
    top = float(C[:, -1].max()) + 1.0
    # configuration 0: every pair, at once
    pin.updateGeometryPlacements(model, data, geom_model, geom_data, D[0])
    pin.computeDistances(geom_model, geom_data)
    d = np.array([r.min_distance for r in geom_data.distanceResults])
    for k in np.flatnonzero(d < EPS).tolist():
        if pin.computeCollision(geom_model, geom_data, k):
            return 0
    # last index j with C[row, j] - C[row, 0] < d - EPS: certified up to j
    flat = (C + (np.arange(U) * (top + 1.0))[:, None]).ravel()
    target = np.minimum(d - EPS, top) + row * (top + 1.0)
    j = np.searchsorted(flat, target, side="left") - 1 - row * N
    nxt = np.maximum(np.minimum(j, N - 1) + 1, 1)
    heap = [(int(n), k) for k, n in enumerate(nxt.tolist()) if n < N]
    heapq.heapify(heap)
    rows: dict[int, list[float]] = {}
    rowl = row.tolist()
    while heap:
        i = heap[0][0]
        pin.updateGeometryPlacements(model, data, geom_model, geom_data, D[i])
        while heap and heap[0][0] == i:
            k = heapq.heappop(heap)[1]
            dk = pin.computeDistance(geom_model, geom_data, k).min_distance
            if dk < EPS and pin.computeCollision(geom_model, geom_data, k):
                return i
            u = rowl[k]
            r = rows.get(u)
            if r is None:
                r = rows[u] = C[u].tolist()
            n = bisect_left(r, r[i] + dk - EPS, i + 1) if dk > EPS else i + 1
            if n < N:
                heapq.heappush(heap, (n, k))
    return None
