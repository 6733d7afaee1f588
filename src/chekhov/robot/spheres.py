"""Sphere models that cover a robot's collision geometry, for the fast checker.

Every sphere set returned here contains its geometry: cylinders and boxes are cut into slabs
along their long axis, each slab inside one sphere; meshes are split into triangle clusters,
each cluster inside one sphere (a sphere holding a triangle's three corners holds the triangle).
A mesh's triangles are first cut into small ones (:func:`split_triangles`): a low-polygon link
mesh has triangles as long as the link, and a cluster holding one needs a ball as wide as the
link's length — on the Panda, spheres of radius 11-16 cm on links 11 cm across.
"""

from __future__ import annotations

from dataclasses import dataclass

import coal
import numpy as np
from numpy.typing import NDArray
from scipy.cluster.vq import kmeans2

from chekhov.errors import RobotError
from chekhov.robot.description import SphereSettings
from chekhov.robot.robot import Robot

Array = NDArray[np.float64]


@dataclass(frozen=True)
class SphereModel:
    """Spheres covering the moving collision geometry of a robot.

    Attributes:
        centers: sphere centres in their joint's frame, shape (M, 3), metres.
        radii: radii, shape (M,), metres (padding included).
        joints: 0-based group joint each sphere moves with, shape (M,).
        geometries: index of the collision geometry each sphere covers, shape (M,).
    """

    centers: Array
    radii: Array
    joints: NDArray[np.int64]
    geometries: NDArray[np.int64]

    def __len__(self) -> int:
        return len(self.radii)


SPLIT_MAX_TRIANGLES = 500_000
""":func:`split_triangles` stops halving once it holds this many triangles, keeping the rest
as they are (still covered: only the spheres are looser). A mesh split to 1/32 of its
diagonal (``SphereSettings.mesh_split``) needs a few thousand; the bound keeps a tiny
``max_edge_m`` from taking all memory."""


def mesh_arrays(geometry: coal.CollisionGeometry) -> tuple[Array, NDArray[np.int64]]:
    """Vertices (V, 3) (m, the mesh's frame) and triangle corner indices (F, 3) of a coal BVH
    mesh."""
    verts = np.asarray(geometry.vertices(), dtype=float).reshape(-1, 3)
    idx = np.array(
        [[t[0], t[1], t[2]] for t in (geometry.tri_indices(i) for i in range(geometry.num_tris))],
        dtype=np.int64,
    ).reshape(-1, 3)
    return verts, idx


def mesh_triangles(geometry: coal.CollisionGeometry) -> Array:
    """Triangles of a coal BVH mesh as corner coordinates, shape (F, 3, 3)."""
    verts, idx = mesh_arrays(geometry)
    return verts[idx]


def cover_cylinder(radius: float, half_length: float, max_excess: float) -> tuple[Array, Array]:
    """Spheres (centres (n, 3), radii (n,)) covering a z-axis cylinder centred at the origin."""
    return _cover_prism(radius, half_length, max_excess, axis=2)


def cover_box(half_extents: Array, max_excess: float) -> tuple[Array, Array]:
    """Spheres covering an origin-centred box, cut along its longest axis."""
    h = np.asarray(half_extents, dtype=float)
    axis = int(np.argmax(h))
    others = [i for i in range(3) if i != axis]
    cross = float(np.hypot(h[others[0]], h[others[1]]))
    return _cover_prism(cross, float(h[axis]), max_excess, axis)


def _cover_prism(cross: float, half_length: float, max_excess: float, axis: int
                 ) -> tuple[Array, Array]:
    step = cross * np.sqrt((1.0 + max_excess) ** 2 - 1.0)  # largest slab half-height allowed
    n = max(1, int(np.ceil(half_length / step - 1e-9)))
    s = half_length / n
    centers = np.zeros((n, 3))
    centers[:, axis] = -half_length + (2 * np.arange(n) + 1) * s
    return centers, np.full(n, np.hypot(cross, s))


ENCLOSING_STEPS = 64
"""Steps of :func:`enclosing_ball`'s core-set iteration (measured on the Panda's and a UR5's
mesh clusters: radii 5.7-7.0% below the bounding box's centre's after 50, 5.9-7.2% after
100)."""


def enclosing_ball(points: Array) -> tuple[Array, float]:
    """A small ball containing ``points`` (N, 3), m: (centre (3,), radius). The better of the
    bounding box's centre and Bădoiu-Clarkson's iteration towards the minimal enclosing ball
    (the centre moves 1/(i+1) of the way to the farthest point; :data:`ENCLOSING_STEPS`
    steps); the radius is the farthest point's distance from the centre kept, so the ball
    contains every point whatever the iteration reached."""
    centre = 0.5 * (points.min(axis=0) + points.max(axis=0))
    radius = float(np.max(np.linalg.norm(points - centre, axis=1)))
    c = points.mean(axis=0)
    for i in range(1, ENCLOSING_STEPS + 1):
        d = np.linalg.norm(points - c, axis=1)
        j = int(np.argmax(d))
        if d[j] < radius:
            centre, radius = c.copy(), float(d[j])
        c = c + (points[j] - c) / (i + 1)
    return centre, radius


def cover_triangles(triangles: Array, n_spheres: int, seed: int = 0) -> tuple[Array, Array]:
    """Spheres covering a triangle soup (F, 3, 3): k-means on centroids, one sphere a cluster
    (:func:`enclosing_ball` of its triangles' corners)."""
    centroids = triangles.mean(axis=1)
    k = min(n_spheres, len(triangles))
    _, labels = kmeans2(centroids, k, seed=seed, minit="++")
    centers, radii = [], []
    for c in range(k):
        pts = triangles[labels == c].reshape(-1, 3)
        if len(pts) == 0:
            continue
        centre, radius = enclosing_ball(pts)
        centers.append(centre)
        radii.append(radius)
    return np.array(centers), np.array(radii)


def split_triangles(triangles: Array, max_edge_m: float) -> Array:
    """The triangles (F, 3, 3), m, each cut in two at the middle of its longest edge until no
    edge is longer than ``max_edge_m`` (m; 0 or less: as they are): the same surface, in
    triangles about ``max_edge_m`` across. Rounds of halving, vectorised; once a round would
    pass :data:`SPLIT_MAX_TRIANGLES`, the triangles still too long are kept as they are."""
    T = np.asarray(triangles, dtype=float).reshape(-1, 3, 3)
    if not max_edge_m > 0.0:
        return T
    done: list[Array] = []
    kept = 0
    while len(T):
        edge = np.linalg.norm(T - np.roll(T, -1, axis=1), axis=2)   # edge i: corner i → i + 1
        long = edge.max(axis=1) > max_edge_m
        done.append(T[~long])
        kept += len(done[-1])
        T, i = T[long], np.argmax(edge[long], axis=1)
        if kept + 2 * len(T) > SPLIT_MAX_TRIANGLES:
            break
        rows = np.arange(len(T))
        a, b, c = T[rows, i], T[rows, (i + 1) % 3], T[rows, (i + 2) % 3]
        m = 0.5 * (a + b)
        T = np.concatenate([np.stack([a, m, c], axis=1), np.stack([m, b, c], axis=1)])
    done.append(T)
    return np.concatenate(done)


def cover_geometry(geometry: coal.CollisionGeometry, max_excess: float, mesh_spheres: int,
                   *, mesh_split: float = SphereSettings.mesh_split) -> tuple[Array, Array]:
    """Spheres covering one coal shape, in the shape's own frame. A mesh's triangles are
    split (:func:`split_triangles`) to edges at most ``mesh_split`` times its bounding box's
    diagonal before they are clustered (``SphereSettings.mesh_split``)."""
    if isinstance(geometry, coal.Sphere):
        return np.zeros((1, 3)), np.array([geometry.radius])
    if isinstance(geometry, coal.Cylinder):
        return cover_cylinder(geometry.radius, geometry.halfLength, max_excess)
    if isinstance(geometry, coal.Capsule):
        c, _ = cover_cylinder(geometry.radius, geometry.halfLength, max_excess)
        c = np.vstack([c, [[0, 0, -geometry.halfLength], [0, 0, geometry.halfLength]]])
        r = np.full(len(c), geometry.radius)
        r[:-2] = np.hypot(geometry.radius, geometry.halfLength / max(1, len(c) - 2))
        return c, r
    if isinstance(geometry, coal.Box):
        return cover_box(np.asarray(geometry.halfSide), max_excess)
    if hasattr(geometry, "num_tris"):
        tri = mesh_triangles(geometry)
        pts = tri.reshape(-1, 3)
        diagonal = float(np.linalg.norm(pts.max(axis=0) - pts.min(axis=0))) if len(pts) else 0.0
        return cover_triangles(split_triangles(tri, mesh_split * diagonal), mesh_spheres)
    raise RobotError(f"cannot cover collision shape of type {type(geometry).__name__} with spheres")


def build_sphere_model(robot: Robot) -> SphereModel:
    """Spheres covering every moving collision geometry of ``robot`` (padding included)."""
    settings = robot.description.spheres
    centers, radii, joints, geoms = [], [], [], []
    for gi in robot.moving_geometries:
        g = robot.collision_model.geometryObjects[gi]
        c, r = cover_geometry(g.geometry, settings.max_excess, settings.mesh_spheres,
                              mesh_split=settings.mesh_split)
        R, p = g.placement.rotation, g.placement.translation
        centers.append(c @ R.T + p)
        radii.append(r + settings.padding)
        joints.append(np.full(len(r), g.parentJoint - 1))
        geoms.append(np.full(len(r), gi))
    return SphereModel(
        centers=np.vstack(centers),
        radii=np.concatenate(radii),
        joints=np.concatenate(joints).astype(np.int64),
        geometries=np.concatenate(geoms).astype(np.int64),
    )
