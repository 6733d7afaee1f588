"""Obstacle primitives for the fast checker, from scene objects and fixed robot geometry."""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from typing import NamedTuple

import coal
import numpy as np
from numpy.typing import NDArray
from scipy.cluster.vq import kmeans2
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import ConvexHull, QhullError

from chekhov.collision.codes import BOX, CYLINDER, HULL, SPHERE
from chekhov.collision.hull_split import split_part
from chekhov.errors import RobotError
from chekhov.robot.spheres import mesh_arrays, mesh_triangles
from chekhov.scene.model import Shape

Array = NDArray[np.float64]


@dataclass(frozen=True)
class Primitive:
    """One convex primitive in the world: ``kind`` (``codes.SPHERE``, ``BOX``, ``CYLINDER``), pose
    T (4, 4),
    ``size`` (3,) as the kernels read it (radius; half extents; radius and half length).
    ``points`` (n, 3), in the primitive's frame (m): when the primitive stands for part of a
    mesh (a box around a triangle cluster), the support points of that part's convex hull,
    which lies inside the box: sphere hits on the box are confirmed on them. ``triangles``
    (t, 3, 3), world (m): then that part's triangles (the surface grids are built from them).
    """

    kind: int
    T: Array
    size: Array
    points: Array | None = None
    triangles: Array | None = None


def shape_primitive(shape: Shape, T_world_obj: Array) -> Primitive:
    """The primitive of a scene object's shape at ``T_world_obj``."""
    if shape.kind == "box":
        return Primitive(BOX, T_world_obj, np.asarray(shape.size, dtype=float) / 2)
    if shape.kind == "cylinder":
        r, length = shape.size
        return Primitive(CYLINDER, T_world_obj, np.array([r, length / 2, 0.0]))
    return Primitive(SPHERE, T_world_obj, np.array([shape.size[0], 0.0, 0.0]))


def geometry_primitives(geometry: coal.CollisionGeometry, T_world_geom: Array,
                        mesh_boxes: int = 64, max_edge: float = 0.05) -> list[Primitive]:
    """Primitives that contain a coal shape: itself when primitive; for a mesh, the bounding
    boxes of ``mesh_boxes`` clusters of its triangles, cut first into pieces with edges of at
    most ``max_edge`` (m) so that a cluster is a compact patch (each piece lies inside its
    cluster's box), with the support points of each cluster's convex hull
    (``Primitive.points``), on which sphere hits are confirmed."""
    if isinstance(geometry, coal.Sphere):
        return [Primitive(SPHERE, T_world_geom, np.array([geometry.radius, 0, 0]))]
    if isinstance(geometry, coal.Box):
        return [Primitive(BOX, T_world_geom, np.asarray(geometry.halfSide, dtype=float))]
    if isinstance(geometry, coal.Cylinder):
        return [Primitive(CYLINDER, T_world_geom,
                          np.array([geometry.radius, geometry.halfLength, 0.0]))]
    if isinstance(geometry, coal.Capsule):
        out = [Primitive(CYLINDER, T_world_geom,
                         np.array([geometry.radius, geometry.halfLength, 0.0]))]
        for sgn in (-1, 1):
            T = T_world_geom.copy()
            T[:3, 3] += sgn * geometry.halfLength * T_world_geom[:3, 2]
            out.append(Primitive(SPHERE, T, np.array([geometry.radius, 0, 0])))
        return out
    if hasattr(geometry, "num_tris"):
        tris = split_triangles(mesh_triangles(geometry), max_edge)
        k = min(mesh_boxes, len(tris))
        _, labels = kmeans2(tris.mean(axis=1), k, seed=0, minit="++")
        out = []
        Rg, pg = T_world_geom[:3, :3], T_world_geom[:3, 3]
        for c in range(k):
            pts = tris[labels == c].reshape(-1, 3)
            if len(pts) == 0:
                continue
            lo, hi = pts.min(axis=0), pts.max(axis=0)
            T = T_world_geom.copy()
            T[:3, 3] = Rg @ ((lo + hi) / 2) + pg
            out.append(Primitive(BOX, T, np.maximum((hi - lo) / 2, 1e-4),
                                 support_points(pts - (lo + hi) / 2),
                                 tris[labels == c] @ Rg.T + pg))
        return out
    raise RobotError(f"unsupported collision shape {type(geometry).__name__}")


def split_triangles(tris: Array, max_edge: float) -> Array:
    """Triangles (F, 3, 3) halved across their longest edge until every edge is at most
    ``max_edge`` (m) long: (F', 3, 3), covering the same surface."""
    done = []
    while len(tris):
        e = np.linalg.norm(tris - np.roll(tris, -1, axis=1), axis=2)  # edge i: corner i → i+1
        long = e.max(axis=1) > max_edge
        done.append(tris[~long])
        t, k = tris[long], np.argmax(e[long], axis=1)
        a = t[np.arange(len(t)), k]
        b = t[np.arange(len(t)), (k + 1) % 3]
        c = t[np.arange(len(t)), (k + 2) % 3]
        m = 0.5 * (a + b)
        tris = np.concatenate([np.stack([a, m, c], axis=1), np.stack([m, b, c], axis=1)])
    return np.concatenate(done) if done else tris


def support_points(pts: Array) -> Array:
    """The points of pts (n, 3) that the maximum of x·u over pts can need, for any u: the
    vertices of their convex hull and every point qhull found on a facet (option Qc), so that
    the support function over them is the one over all of pts, whatever qhull's rounding; all
    of pts when qhull fails (a flat or tiny set)."""
    try:
        hull = ConvexHull(pts, qhull_options="Qc")
    except (QhullError, ValueError):
        return np.array(pts, dtype=float)
    keep = np.union1d(hull.vertices, hull.coplanar[:, 0]).astype(np.int64)
    return np.array(pts[keep], dtype=float)


def hull_depth(pts: Array, X: Array) -> Array:
    """How deep each point of X (n, 3) lies inside the convex hull of pts (m, 3), same frame
    (m): the distance to the hull's nearest facet plane, so the ball of that radius about the
    point is inside the hull; 0 outside it, or when qhull cannot build the hull (a flat or
    tiny set). One hull for all the points."""
    try:
        eq = ConvexHull(pts).equations   # rows (n, offset): n·y + offset <= 0 inside
    except (QhullError, ValueError):
        return np.zeros(len(X))
    return np.maximum(0.0, -np.max(X @ eq[:, :3].T + eq[:, 3], axis=1))


def fixed_points(prims: list[Primitive]
                 ) -> tuple[NDArray[np.int64], NDArray[np.int64], Array, Array]:
    """What the fast checker confirms a sphere hit on fixed part i against: (kind (F,):
    ``gjk.HULL`` where the primitive carries support points, else its own kind; vstart (F+1,)
    and V (NV, 3): points V[vstart[i]:vstart[i+1]] in the primitive's frame; centre (F, 3): a
    point inside it, world, m)."""
    kind = np.array([HULL if p.points is not None else p.kind for p in prims],
                    dtype=np.int64).reshape(len(prims))
    pts = [p.points if p.points is not None else np.zeros((0, 3)) for p in prims]
    vstart = np.cumsum([0] + [len(x) for x in pts]).astype(np.int64)
    V = np.vstack([np.zeros((0, 3)), *pts]).astype(float)
    centre = np.array([p.T[:3, :3] @ x.mean(axis=0) + p.T[:3, 3] if len(x) else p.T[:3, 3]
                       for p, x in zip(prims, pts, strict=True)], dtype=float).reshape(-1, 3)
    return kind, vstart, V, centre


def hull_parts(geometry: coal.CollisionGeometry, max_pieces: int = 8) -> list[Array]:
    """Support points (:func:`support_points`) of each connected part of a coal mesh, in the
    mesh's frame (m): the confirmation tests a part's convex hull, which contains it. Parts
    are the connected components of the triangles' edges, each cut into at most
    ``max_pieces`` convex pieces where its hull is a poor fit (``hull_split.split_part``; 1:
    the components' own hulls); vertices used by no triangle are ignored."""
    verts, tris = mesh_arrays(geometry)
    if len(tris) == 0:
        raise RobotError("collision mesh has no triangles")
    edges = np.concatenate([tris[:, [0, 1]], tris[:, [1, 2]]])
    graph = coo_matrix((np.ones(len(edges)), (edges[:, 0], edges[:, 1])),
                       shape=(len(verts), len(verts)))
    _, label = connected_components(graph, directed=False)
    return [support_points(piece) for c in np.unique(label[tris[:, 0]])
            for piece in split_part(verts, tris[label[tris[:, 0]] == c],
                                    max_pieces=max_pieces)]


class Primitives(NamedTuple):
    """Convex primitives in the world (M of them), as the kernels read them: kind (M,)
    (``codes``), R (M, 3, 3), p (M, 3), size (M, 3) (see ``kernels.signed_distance``),
    bound (M,) m: radius of a sphere about p containing the primitive."""

    kind: NDArray[np.int64]
    R: Array
    p: Array
    size: Array
    bound: Array


def pack_primitives(prims: Iterable[Primitive]) -> Primitives:
    """The arrays of :class:`Primitives` for a list of primitives."""
    prims = list(prims)
    M = len(prims)
    kind = np.array([p.kind for p in prims], dtype=np.int64).reshape(M)
    size = np.array([p.size for p in prims], dtype=float).reshape(M, 3)
    return Primitives(
        kind=kind,
        R=np.array([p.T[:3, :3] for p in prims], dtype=float).reshape(M, 3, 3),
        p=np.array([p.T[:3, 3] for p in prims], dtype=float).reshape(M, 3),
        size=size, bound=bounding_radius(kind, size))


class PrefixPacker:
    """:func:`pack_primitives` for lists that keep a long prefix from one call to the next
    (a checker's obstacles: the scene's, then the few dynamic ones set each sensor frame):
    the rows of the longest prefix of the same :class:`Primitive` objects (``is``) as the last
    call's are reused and only the rest is packed (the kitchen's 66 obstacles were packed
    again several times a control step). The arrays returned are new ones, never changed."""

    def __init__(self) -> None:
        self._prims: list[Primitive] = []
        self._packed = pack_primitives([])

    def pack(self, prims: Iterable[Primitive]) -> Primitives:
        prims = list(prims)
        old, n = self._prims, 0
        while n < min(len(old), len(prims)) and old[n] is prims[n]:
            n += 1
        if n == len(old) == len(prims):
            return self._packed
        tail = pack_primitives(prims[n:])
        packed = Primitives(*(np.concatenate([a[:n], b])
                              for a, b in zip(self._packed, tail, strict=True)))
        self._prims, self._packed = prims, packed
        return packed


def bounding_radius(kind: NDArray[np.int64], size: Array) -> Array:
    """Radius (m) of a sphere about each primitive's origin that contains it."""
    r = size[:, 0].copy()
    box = kind == BOX
    r[box] = np.linalg.norm(size[box], axis=1)
    cyl = kind == CYLINDER
    r[cyl] = np.hypot(size[cyl, 0], size[cyl, 1])
    return r


def cluster_primitives(fixed: Primitives, fixed_pairs: NDArray[np.int64], n_groups: int,
                       clusters: int = 16, seed: int = 0) -> tuple:
    """Fixed robot parts grouped into spatial clusters with bounding spheres, so that a group
    far from the torso skips all of its primitives with a few tests: (allowed (G, F) bool —
    the group is checked against the primitive —, centre (L, 3), radius (L,), start (L+1,),
    members (F,)). seed: of the k-means that forms the clusters."""
    kind, pos, size = fixed.kind, fixed.p, fixed.size
    F = len(kind)
    allowed = np.zeros((n_groups, max(F, 1)), dtype=np.bool_)
    allowed[fixed_pairs[:, 0], fixed_pairs[:, 1]] = True
    L = min(clusters, F)
    label = (kmeans2(pos, L, seed=seed, minit="++")[1] if L > 0
             else np.zeros(0, dtype=np.int64))
    members = np.argsort(label, kind="stable").astype(np.int64)
    start = np.searchsorted(label[members], np.arange(L + 1)).astype(np.int64)
    bound = bounding_radius(kind, size) if F else np.zeros(0)
    centre = np.zeros((L, 3))
    radius = np.zeros(L)
    for c in range(L):
        idx = members[start[c]:start[c + 1]]
        if len(idx):
            centre[c] = pos[idx].mean(axis=0)
            radius[c] = float(np.max(np.linalg.norm(pos[idx] - centre[c], axis=1) + bound[idx]))
    return allowed, centre, radius, start, members
