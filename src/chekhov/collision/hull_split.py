"""Convex pieces of a mesh part whose one convex hull is a poor fit.

The fast checker confirms a sphere hit on the convex hulls of a mesh's parts
(``primitives.hull_parts``). Where a part is far from convex — the UR5's upper arm is a tube
of radius 50.5 mm with 57 mm flanges at its ends — its hull stands out of the mesh (6.5 mm
along the tube), and every configuration that brings that stretch within a few millimetres of
something is a false alarm. :func:`split_part` cuts such a part with planes into pieces whose
hulls are smaller: recursively, each piece at the cut (across one of its principal axes, at one
of seven evenly spaced places) that leaves the least total hull volume, while a cut removes at
least ``min_gain_m`` times the piece's hull area (the excess it removes, averaged over the
hull's surface) and there are fewer than ``max_pieces``.

Triangles that straddle a cut are clipped at the plane, and both pieces keep the points where
their edges cross it, so the pieces' hulls together contain every triangle and, as their
cross-sections do, the solid the triangles bound: each hull lies inside the part's hull, and a
"free" proved on the pieces is proved on the part.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray
from scipy.spatial import ConvexHull, QhullError

Array = NDArray[np.float64]
IntArray = NDArray[np.int64]

CUTS_PER_AXIS = 7
"""Cut places tried across each principal axis: at 1/8, …, 7/8 of the piece's extent."""
RANK_POINTS = 400
"""Cuts are ranked on at most this many of a piece's points (a seeded sample; the chosen cut's
gain is then measured on all of them): the Jaco's largest mesh has 22,000."""


def split_part(verts: Array, tris: IntArray, *, min_gain_m: float = 1e-3,
               max_pieces: int = 8, seed: int = 0) -> list[Array]:
    """The points (n, 3) of each piece of the part with triangles ``tris`` (F, 3) (indices into
    ``verts`` (V, 3), m): the part's own points, one piece, when no cut gains enough."""
    V, T = np.asarray(verts, dtype=float), np.asarray(tris, dtype=np.int64).reshape(-1, 3)
    rng = np.random.default_rng(seed)
    todo: list[tuple[Array, IntArray]] = [(V, T)]
    done: list[Array] = []
    while todo:
        piece = todo.pop()
        cut = None
        if len(todo) + len(done) + 2 <= max_pieces:
            cut = _best_cut(*piece, min_gain_m, rng)
        if cut is None:
            done.append(piece[0][np.unique(piece[1])])
        else:
            todo += list(_clip(*piece, *cut))
    return done


def _hull_volume_area(pts: Array) -> tuple[float, float]:
    """(m³, m²) of the convex hull of pts; (0, 0) when qhull cannot build it (flat, tiny)."""
    try:
        hull = ConvexHull(pts)
    except (QhullError, ValueError):
        return 0.0, 0.0
    return float(hull.volume), float(hull.area)


def _best_cut(V: Array, T: IntArray, min_gain_m: float, rng: np.random.Generator
              ) -> tuple[Array, float] | None:
    """(unit normal n (3,), offset d): the plane n·x = d whose two pieces have the least total
    hull volume, when it is smaller than the piece's by at least min_gain_m × its hull area."""
    used = np.unique(T)
    pts = V[used]
    if len(pts) < 8:
        return None
    volume, area = _hull_volume_area(pts)
    if volume <= 0.0:
        return None
    edges = np.unique(np.sort(np.concatenate([T[:, [0, 1]], T[:, [1, 2]], T[:, [2, 0]]]),
                              axis=1), axis=0)
    axes = np.linalg.svd(pts - pts.mean(axis=0), full_matrices=False)[2]
    best: tuple[float, Array, float] | None = None
    for n in axes:
        s = pts @ n
        for d in s.min() + (s.max() - s.min()) * np.arange(1, CUTS_PER_AXIS + 1) / (
                CUTS_PER_AXIS + 1):
            total = sum(_hull_volume_area(_sample(p, rng))[0]
                        for p in _cut_points(V, used, edges, n, d))
            if best is None or total < best[0]:
                best = (total, n, float(d))
    if best is None:
        return None
    total = sum(_hull_volume_area(p)[0] for p in _cut_points(V, used, edges, best[1], best[2]))
    return (best[1], best[2]) if volume - total >= min_gain_m * area else None


def _sample(pts: Array, rng: np.random.Generator) -> Array:
    return pts if len(pts) <= RANK_POINTS else pts[rng.choice(len(pts), RANK_POINTS,
                                                                replace=False)]


def _cut_points(V: Array, used: IntArray, edges: IntArray, n: Array, d: float
                ) -> tuple[Array, Array]:
    """The points of the two pieces of the plane n·x = d (below, above), without clipping the
    triangles: each side's corners (of ``used``, the vertices of the piece's triangles) and
    the points where the triangles' ``edges`` (E, 2) cross the plane."""
    s = V @ n - d
    e = edges[(s[edges[:, 0]] <= 0) != (s[edges[:, 1]] <= 0)]
    t = (s[e[:, 0]] / (s[e[:, 0]] - s[e[:, 1]]))[:, None]
    cross = V[e[:, 0]] + t * (V[e[:, 1]] - V[e[:, 0]])
    below = s[used] <= 0
    return np.vstack([V[used[below]], cross]), np.vstack([V[used[~below]], cross])


def _clip(V: Array, T: IntArray, n: Array, d: float
          ) -> tuple[tuple[Array, IntArray], tuple[Array, IntArray]]:
    """The piece's triangles clipped at the plane n·x = d: (vertices, triangles) below it and
    above it. A straddling triangle's lone corner keeps the triangle it makes with the two
    crossings; the other side keeps the quadrilateral, as two triangles."""
    s = V @ n - d
    side = s[T] > 0                                   # (F, 3): above
    k = side.sum(axis=1)
    out: list[list[Array]] = [[], []]                 # triangle corner coordinates per side
    for above, whole in ((False, k == 0), (True, k == 3)):
        out[above].append(V[T[whole]])
    mixed = T[(k == 1) | (k == 2)]
    ms = side[(k == 1) | (k == 2)]
    lone = np.argmax(ms != (ms.sum(axis=1, keepdims=True) >= 2), axis=1)   # the odd corner
    rows = np.arange(len(mixed))
    a, b, c = (mixed[rows, (lone + i) % 3] for i in range(3))
    ab = V[a] + (s[a] / (s[a] - s[b]))[:, None] * (V[b] - V[a])
    ac = V[a] + (s[a] / (s[a] - s[c]))[:, None] * (V[c] - V[a])
    lone_above = ms[rows, lone]
    for above in (False, True):
        m = lone_above == above
        out[above].append(np.stack([V[a[m]], ab[m], ac[m]], axis=1))
        m = ~m
        out[above].append(np.stack([ab[m], V[b[m]], V[c[m]]], axis=1))
        out[above].append(np.stack([ab[m], V[c[m]], ac[m]], axis=1))
    below, above_ = (_index(np.concatenate(o).reshape(-1, 3, 3)) for o in out)
    return below, above_


def _index(tris: Array) -> tuple[Array, IntArray]:
    """A triangle soup (F, 3, 3) as (vertices, triangles), equal corners merged."""
    verts, inv = np.unique(tris.reshape(-1, 3), axis=0, return_inverse=True)
    return verts, inv.reshape(-1, 3).astype(np.int64)
