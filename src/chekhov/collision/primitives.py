"""Obstacle primitives for the fast checker, from scene objects and fixed robot geometry."""

from __future__ import annotations

from dataclasses import dataclass

import coal
import numpy as np
from numpy.typing import NDArray
from scipy.cluster.vq import kmeans2

from chekhov.collision.kernels import BOX, CYLINDER, SPHERE
from chekhov.errors import RobotError
from chekhov.robot.spheres import mesh_triangles
from chekhov.scene.model import Shape

Array = NDArray[np.float64]


@dataclass(frozen=True)
class Primitive:
    """One convex primitive in the world: ``kind`` (sphere 0, box 1, cylinder 2), pose T (4, 4),
    ``size`` (3,) as the kernels read it (radius; half extents; radius and half length)."""

    kind: int
    T: Array
    size: Array


def shape_primitive(shape: Shape, T_world_obj: Array) -> Primitive:
    """The primitive of a scene object's shape at ``T_world_obj``."""
    if shape.kind == "box":
        return Primitive(BOX, T_world_obj, np.asarray(shape.size, dtype=float) / 2)
    if shape.kind == "cylinder":
        r, length = shape.size
        return Primitive(CYLINDER, T_world_obj, np.array([r, length / 2, 0.0]))
    return Primitive(SPHERE, T_world_obj, np.array([shape.size[0], 0.0, 0.0]))


def geometry_primitives(geometry: coal.CollisionGeometry, T_world_geom: Array,
                        mesh_boxes: int = 64) -> list[Primitive]:
    """Primitives that contain a coal shape: itself when primitive; for a mesh, the bounding
    boxes of ``mesh_boxes`` triangle clusters (each triangle lies inside its cluster's box)."""
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
        tris = mesh_triangles(geometry)
        k = min(mesh_boxes, len(tris))
        _, labels = kmeans2(tris.mean(axis=1), k, seed=0, minit="++")
        out = []
        for c in range(k):
            pts = tris[labels == c].reshape(-1, 3)
            if len(pts) == 0:
                continue
            lo, hi = pts.min(axis=0), pts.max(axis=0)
            T = T_world_geom.copy()
            T[:3, 3] = T_world_geom[:3, :3] @ ((lo + hi) / 2) + T_world_geom[:3, 3]
            out.append(Primitive(BOX, T, np.maximum((hi - lo) / 2, 1e-4)))
        return out
    raise RobotError(f"unsupported collision shape {type(geometry).__name__}")


def pack(prims: list[Primitive]) -> tuple[NDArray[np.int64], Array, Array, Array]:
    """Arrays (kind (M,), R (M, 3, 3), p (M, 3), size (M, 3)) as the kernels read them."""
    M = len(prims)
    kind = np.array([p.kind for p in prims], dtype=np.int64).reshape(M)
    R = np.array([p.T[:3, :3] for p in prims], dtype=float).reshape(M, 3, 3)
    pos = np.array([p.T[:3, 3] for p in prims], dtype=float).reshape(M, 3)
    size = np.array([p.size for p in prims], dtype=float).reshape(M, 3)
    return kind, R, pos, size


def bounding_radius(kind: NDArray[np.int64], size: Array) -> Array:
    """Radius (m) of a sphere about each primitive's origin that contains it."""
    r = size[:, 0].copy()
    box = kind == BOX
    r[box] = np.linalg.norm(size[box], axis=1)
    cyl = kind == CYLINDER
    r[cyl] = np.hypot(size[cyl, 0], size[cyl, 1])
    return r


def cluster_primitives(fixed: tuple, fixed_pairs: NDArray[np.int64], n_groups: int,
                       clusters: int = 16) -> tuple:
    """Fixed robot parts grouped into spatial clusters with bounding spheres, so that a group
    far from the torso skips all of its primitives with a few tests: (allowed (G, F) bool —
    the group is checked against the primitive —, centre (L, 3), radius (L,), start (L+1,),
    members (F,))."""
    kind, _, pos, size = fixed
    F = len(kind)
    allowed = np.zeros((n_groups, max(F, 1)), dtype=np.bool_)
    allowed[fixed_pairs[:, 0], fixed_pairs[:, 1]] = True
    L = min(clusters, F)
    label = (kmeans2(pos, L, seed=0, minit="++")[1] if L > 0
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
