"""Convex-hull lower bounds on the distance of collision pairs with large meshes.

Coal's distance and margin tests on a mesh of tens of thousands of triangles take 1-20 ms a
pair (a Kinova Jaco's visual meshes, used as its collision meshes: 1,500-45,000 triangles a
link), against a few µs for GJK on the mesh's convex hull. The hull holds the mesh, so the
hulls' distance is a lower bound on the meshes' distance: a pair whose hull bound clears a
margin clears it, and a bound can stand in for a distance wherever a distance is only used as
a lower bound (clearance certificates). Near contact the mesh is asked, so decisions stay those
of the mesh: ``ExactChecker`` uses a bound only when it is at least :data:`TRUSTED_BOUND_M`
above what it is compared with.

Only robot geometries get hulls (the scene's obstacles are primitives), and only meshes of at
least :data:`MIN_TRIANGLES` triangles: the Panda's (200-300 triangles) are queried as they
are.
"""

from __future__ import annotations

import coal
import numpy as np
import pinocchio as pin
from numpy.typing import NDArray
from scipy.spatial import ConvexHull, QhullError

Array = NDArray[np.float64]

MIN_TRIANGLES = 1000
"""Meshes with at least this many triangles get a hull bound."""

GJK_SLACK_M = 1e-5
"""m taken from every hull distance: GJK's tolerance (coal's default, 1e-6, is met relative to
the distance; hull and mesh distances of the Jaco's pairs 0.9 m apart differed by 1.6e-6)."""

TRUSTED_BOUND_M = 0.01
"""m: ``ExactChecker.pair_distances`` returns a hull bound (instead of the mesh distance) only
when it is at least this large; below it the mesh is asked, so that contact is decided on the
mesh."""


class HullBounds:
    """Hull distance bounds for the collision pairs of one geometry model."""

    def __init__(self, geom_model: pin.GeometryModel, robot_ngeoms: int) -> None:
        self.hulls: dict[int, coal.CollisionGeometry] = {}
        for i, o in enumerate(geom_model.geometryObjects[:robot_ngeoms]):
            hull = _hull(o.geometry)
            if hull is not None:
                self.hulls[i] = hull
        self._req = coal.DistanceRequest()
        self._res = coal.DistanceResult()

    def __bool__(self) -> bool:
        return bool(self.hulls)

    def covers(self, pairs: NDArray[np.int64]) -> NDArray[np.bool_]:
        """(P,) whether a pair of geometry indices ``pairs`` (P, 2) has a hull on either side."""
        return np.asarray(np.isin(pairs, list(self.hulls)).any(axis=1), dtype=bool)

    def lower_bounds(self, geom_model: pin.GeometryModel, gd: pin.GeometryData,
                     pairs: NDArray[np.int64]) -> Array:
        """(P,) m, a lower bound on the distance of each pair of geometry indices ``pairs``
        (P, 2) as placed in ``gd`` (its ``oMg`` up to date): the distance with each large mesh
        replaced by its hull, less GJK's slack (≤ 0 when the hulls touch)."""
        objs = geom_model.geometryObjects
        out = np.empty(len(pairs))
        for k, (a, b) in enumerate(pairs.tolist()):
            ga, gb = self.hulls.get(a), self.hulls.get(b)
            Ma, Mb = gd.oMg[a], gd.oMg[b]
            self._res.clear()
            out[k] = coal.distance(
                objs[a].geometry if ga is None else ga,
                coal.Transform3s(Ma.rotation, Ma.translation),
                objs[b].geometry if gb is None else gb,
                coal.Transform3s(Mb.rotation, Mb.translation), self._req, self._res)
        return out - GJK_SLACK_M


def _hull(geometry: coal.CollisionGeometry) -> coal.CollisionGeometry | None:
    """The convex hull of a mesh geometry with at least :data:`MIN_TRIANGLES` triangles (in
    the geometry's frame, its scale applied as in the mesh), else None."""
    if not isinstance(geometry, coal.BVHModelBase) or geometry.num_tris < MIN_TRIANGLES:
        return None
    V = np.asarray(geometry.vertices(), dtype=float)
    # not primitives.support_points: that falls back to all the points when qhull fails, and
    # coal's own qhull call crashes the process (a segfault) on a flat set
    try:
        corners = V[ConvexHull(V).vertices]
    except QhullError:   # flat or degenerate: no hull to stand in for it
        return None
    points = coal.StdVec_Vec3s()
    points.extend(list(corners))
    return coal.Convex.convexHull(points, False, "")
