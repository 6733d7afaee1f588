"""The exact checker: pinocchio + coal on the URDF collision geometry and the exact obstacle
shapes. It shares no collision code with the fast checker and is the validation referee
(the paper's independent continuous-time check)."""

from __future__ import annotations

from collections.abc import Mapping

import coal
import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from chekhov.collision.advance import first_collision_certified, pair_weights
from chekhov.collision.hull_bounds import TRUSTED_BOUND_M, HullBounds
from chekhov.errors import RobotError
from chekhov.robot.robot import Robot
from chekhov.scene.model import Scene, Shape

Array = NDArray[np.float64]


def coal_shape(shape: Shape) -> coal.CollisionGeometry:
    """The coal geometry of a scene shape."""
    if shape.kind == "box":
        return coal.Box(*shape.size)
    if shape.kind == "cylinder":
        return coal.Cylinder(shape.size[0], shape.size[1])
    return coal.Sphere(shape.size[0])


def _resize(geometry: coal.CollisionGeometry, shape: Shape) -> None:
    """Give a coal geometry made by :func:`coal_shape` the size of ``shape`` (same kind)."""
    if shape.kind == "box":
        geometry.halfSide = np.asarray(shape.size, dtype=float) / 2
    elif shape.kind == "cylinder":
        geometry.radius, geometry.halfLength = shape.size[0], shape.size[1] / 2
    else:
        geometry.radius = shape.size[0]
    geometry.computeLocalAABB()


class ExactChecker:
    """Exact collision checks with coal on the robot's URDF collision geometry."""

    def __init__(self, robot: Robot, scene: Scene | None = None, static_only: bool = False
                 ) -> None:
        self.robot = robot
        self.model = robot.model
        self.data = robot.model.createData()
        self.geom_model = robot.collision_model.copy()
        self._robot_ngeoms = self.geom_model.ngeoms
        # hull distance bounds for pairs with large meshes (hull_bounds.py)
        self._hulls = HullBounds(self.geom_model, self._robot_ngeoms)
        self._hull_pairs = np.zeros(0, dtype=bool)   # per collision pair: a hull on a side
        self._radii: dict[int, Array] = {}   # motion bounds of the robot's geometries
        # collision data whose requests carry per-pair security margins (pairs_within) and
        # the bounding spheres of the geometries (pair_bounds: joint, centre in its frame,
        # radius): made by _rebuild, below, and at every rebuild after
        self._margin_data: pin.GeometryData
        self._margins: Array
        self._placed: Array | None = None   # where the margin data's geometries are placed
        self._spheres: tuple[NDArray[np.int64], Array, Array]
        self._obstacles: dict[str, int] = {}
        if scene is not None:
            for o in scene.objects:
                if not (o.dynamic and static_only):
                    self._add(o.name, o.shape, o.T_world_obj())
        # the scene as built: set_obstacles starts from it
        self._scene_model = self.geom_model.copy()
        self._scene_obstacles = dict(self._obstacles)
        self._rebuild()

    def _add(self, name: str, shape: Shape, T: Array) -> None:
        go = pin.GeometryObject(f"obstacle:{name}", 0, 0, pin.SE3(np.asarray(T, dtype=float)),
                                coal_shape(shape))
        self._obstacles[name] = self.geom_model.addGeometryObject(go)

    def _rebuild(self) -> None:
        """Collision pairs (self pairs, moving robot geometry × obstacles) set in one call, and
        the data and motion-bound weights for them."""
        gm = self.geom_model
        n = gm.ngeoms
        M = np.zeros((n, n), dtype=bool)
        self_pairs = np.sort(np.asarray(self.robot.self_collision_pairs,
                                        dtype=np.int64).reshape(-1, 2), axis=1)
        M[self_pairs[:, 0], self_pairs[:, 1]] = True
        obstacles = np.fromiter(self._obstacles.values(), dtype=np.int64)
        moving = np.asarray(self.robot.moving_geometries, dtype=np.int64)
        if len(obstacles) and len(moving):
            lo = np.minimum(moving[:, None], obstacles[None, :])
            hi = np.maximum(moving[:, None], obstacles[None, :])
            M[lo, hi] = True
        gm.setCollisionPairs(M, True)   # pinocchio adds (i, j), i < j, in row-major order
        self.geom_data = pin.GeometryData(gm)
        self._new_margin_data()
        self._spheres = self._bounding_spheres()
        self._pairs = np.argwhere(np.triu(M, 1))   # (P, 2), in the model's order
        self._hull_pairs = self._hulls.covers(self._pairs)
        self._weights = pair_weights(self.model, gm, self._pairs, self._radii)

    def add_obstacle(self, name: str, shape: Shape, T_world_obj: Array) -> None:
        if name in self._obstacles:
            raise KeyError(f"obstacle '{name}' already exists; use move_obstacle")
        self._add(name, shape, T_world_obj)
        self._rebuild()

    def set_obstacles(self, obstacles: Mapping[str, tuple[Shape, Array]]) -> None:
        """Make ``obstacles`` (name → (shape, T_world_obj (4, 4))) the obstacles added since
        construction, all at once: one rebuild of the collision pairs, however many change
        (:meth:`add_obstacle` rebuilds them per call)."""
        clash = set(obstacles) & set(self._scene_obstacles)
        if clash:
            raise KeyError(f"obstacle names already used by the scene: {sorted(clash)}")
        if self._reshape(obstacles):
            return
        self.geom_model = self._scene_model.copy()
        self._obstacles = dict(self._scene_obstacles)
        for name, (shape, T) in obstacles.items():
            self._add(name, shape, T)
        self._rebuild()

    def _reshape(self, obstacles: Mapping[str, tuple[Shape, Array]]) -> bool:
        """``obstacles`` set in place when they have the names (in order) and shape kinds of
        those set now: each coal geometry resized and placed, with no rebuild of the
        collision pairs and their data (an executive's predicted sweep changes so every
        sensor frame: ~0.1 ms against 3-9 ms). False (nothing changed) otherwise."""
        gm = self.geom_model
        mine = [n for n in self._obstacles if n not in self._scene_obstacles]
        if mine != list(obstacles):
            return False
        objs = [gm.geometryObjects[self._obstacles[n]] for n in mine]
        if any(type(o.geometry) is not type(coal_shape(sh)) for o, (sh, _) in
               zip(objs, obstacles.values(), strict=True)):
            return False
        for o, (shape, T) in zip(objs, obstacles.values(), strict=True):
            _resize(o.geometry, shape)
            o.placement = pin.SE3(np.asarray(T, dtype=float))
        self._moved(mine)
        return True

    def _moved(self, names: list[str]) -> None:
        """After obstacles ``names`` were moved or resized in place: the margin data's
        placements are stale, and their bounding spheres (fixed to the world) are set anew."""
        self._placed = None
        _, centre, radius = self._spheres
        for n in names:
            k = self._obstacles[n]
            g = self.geom_model.geometryObjects[k]
            centre[k] = g.placement.act(np.asarray(g.geometry.aabb_center))
            radius[k] = g.geometry.aabb_radius

    def move_obstacle(self, name: str, T_world_obj: Array) -> None:
        self.geom_model.geometryObjects[self._obstacles[name]].placement = pin.SE3(
            np.asarray(T_world_obj, dtype=float))
        self.geom_data = pin.GeometryData(self.geom_model)
        self._moved([name])

    def remove_obstacle(self, name: str) -> None:
        idx = self._obstacles.pop(name)
        self.geom_model.removeGeometryObject(self.geom_model.geometryObjects[idx].name)
        self._obstacles = {n: (i if i < idx else i - 1) for n, i in self._obstacles.items()}
        self._rebuild()

    def is_valid(self, q: Array) -> bool:
        """Whether q (K,) is free of collisions with obstacles and the robot itself."""
        return not pin.computeCollisions(self.model, self.data, self.geom_model, self.geom_data,
                                         np.asarray(q, dtype=float), True)

    def valid(self, Q: Array) -> NDArray[np.bool_]:
        """Collision-free flag for each row of Q (N, K)."""
        Q = np.atleast_2d(np.asarray(Q, dtype=float))
        if Q.shape[1] != self.robot.dof:
            raise RobotError(f"expected configurations of shape (N, {self.robot.dof}), "
                             f"got {Q.shape}")
        return np.array([self.is_valid(q) for q in Q], dtype=bool)

    @property
    def collision_pairs(self) -> NDArray[np.int64]:
        """(P, 2) the geometry indices of every collision pair, in ``geom_model``'s order."""
        return self._pairs

    @property
    def motion_weights(self) -> tuple[Array, NDArray[np.int64]] | None:
        """(W (U, K) m/rad, row (P,)): along a straight joint step Δq (rad), the geometries of
        collision pair k move relative to each other by at most |Δq| · W[row[k]] m (no point
        of either travels farther; ``advance.pair_weights``). None when a joint is not
        revolute. Pairs are indexed as in ``geom_model.collisionPairs``."""
        return self._weights

    def pairs_within(self, q: Array, margins: Array, pairs: NDArray[np.int64] | None = None
                     ) -> NDArray[np.int64]:
        """The collision pairs closer than their margin at q (K,): the indices k (into
        ``geom_model.collisionPairs``; of ``pairs`` only, all by default) with clearance below
        ``margins[k]`` (m, one per collision pair; a colliding pair is among them), empty when
        each is clear by its margin.

        coal's collision test with the margin as its security margin (a yes/no with early
        exit, ~30 times cheaper than a distance on the Panda's meshes); the margins are kept in
        the requests of a GeometryData of their own, and only the asked pairs' changed ones
        are set (each a pybind call: all 1493 of the kitchen's took 1.8 ms). A pair with a
        large mesh whose hull bound (``hull_bounds.py``) clears its margin is not asked."""
        gd, gm = self._margin_data, self.geom_model
        asked = np.arange(len(margins)) if pairs is None else np.asarray(pairs, np.int64)
        changed = asked[self._margins[asked] != margins[asked]]
        if len(changed):
            reqs = gd.collisionRequests
            for k in changed.tolist():
                reqs[k].security_margin = float(margins[k])
            self._margins[changed] = margins[changed]
        if self._hulls:
            todo = np.arange(len(margins)) if pairs is None else np.asarray(pairs, np.int64)
            self._place(q)
            hulled = todo[self._hull_pairs[todo]]
            if len(hulled):
                lb = self._hulls.lower_bounds(gm, gd, self._pairs[hulled])
                todo = np.setdiff1d(todo, hulled[lb >= margins[hulled]])
            pairs = todo
        elif pairs is None or 4 * len(pairs) > len(margins):   # all pairs, in one call
            self._placed = np.array(q, dtype=float)
            if not pin.computeCollisions(self.model, self.data, gm, gd, self._placed, True):
                return np.zeros(0, dtype=np.int64)
            pin.computeCollisions(gm, gd, False)   # every pair: which are close
            close = np.array([k for k, r in enumerate(gd.collisionResults) if r.isCollision()],
                             dtype=np.int64)
            return close if pairs is None else np.intersect1d(close, pairs)
        else:
            self._place(q)
        return np.array([k for k in np.asarray(pairs).tolist() if pin.computeCollision(gm, gd, k)],
                        dtype=np.int64)

    def pair_distances(self, q: Array, pairs: NDArray[np.int64]) -> Array:
        """coal's distance (m; ≤ 0 in contact) between the geometries of each collision pair
        in ``pairs`` (indices into ``geom_model.collisionPairs``) at q (K,) — or, for a pair
        with a large mesh, a lower bound on it (the hulls' distance, ``hull_bounds.py``) when
        that bound is at least ``TRUSTED_BOUND_M``: a distance below it is always the mesh's."""
        gd, gm = self._place(q), self.geom_model
        pairs = np.asarray(pairs, dtype=np.int64)
        out = np.full(len(pairs), np.nan)
        if self._hulls:
            hulled = np.flatnonzero(self._hull_pairs[pairs])
            if len(hulled):
                lb = self._hulls.lower_bounds(gm, gd, self._pairs[pairs[hulled]])
                trusted = lb >= TRUSTED_BOUND_M
                out[hulled[trusted]] = lb[trusted]
        for i in np.flatnonzero(np.isnan(out)).tolist():
            out[i] = pin.computeDistance(gm, gd, int(pairs[i])).min_distance
        return out

    def _new_margin_data(self) -> None:
        """A new GeometryData for :meth:`pairs_within` and :meth:`pair_distances`, its margins
        0: made when the collision pairs are rebuilt (an obstacle moved or resized in place
        keeps it, :meth:`_moved`), not by the first query that asks coal for margins after
        (4.5 ms for the kitchen's 1493 pairs; made there, a 3 ms query on a kitchen task case
        returned 4.7 ms late, ``benchmarks/deadline.py``)."""
        self._margin_data = pin.GeometryData(self.geom_model)
        self._margins = np.zeros(len(self.geom_model.collisionPairs))
        self._placed = None

    def _place(self, q: Array) -> pin.GeometryData:
        """The margin GeometryData with the geometries placed at q (K,) (kept from the last
        call at the same q)."""
        gd = self._margin_data
        if self._placed is None or not np.array_equal(self._placed, q):
            self._placed = np.array(q, dtype=float)
            pin.updateGeometryPlacements(self.model, self.data, self.geom_model, gd,
                                         self._placed)
        return gd

    def _bounding_spheres(self) -> tuple[NDArray[np.int64], Array, Array]:
        """Every geometry's bounding sphere (coal's local AABB): its joint, centre in that
        joint's frame (m) and radius (m), for :meth:`pair_bounds`. Made when the geometries
        change, not at the first query that needs them (0.5-0.8 ms for Baxter's scenes)."""
        objs = self.geom_model.geometryObjects
        for o in objs:
            o.geometry.computeLocalAABB()
        return (np.array([o.parentJoint for o in objs], dtype=np.int64),
                np.array([o.placement.act(np.asarray(o.geometry.aabb_center)) for o in objs]),
                np.array([o.geometry.aabb_radius for o in objs], dtype=float))

    def pair_bounds(self, q: Array, pairs: NDArray[np.int64]) -> Array:
        """Lower bounds (m) on the distance of each collision pair in ``pairs`` (indices into
        ``geom_model.collisionPairs``) at q (K,), from bounding spheres of the geometries
        (coal's local AABBs): cheap (joint placements and arithmetic, no coal query), loose by
        up to the geometries' sizes."""
        joint, centre, radius = self._spheres
        pin.forwardKinematics(self.model, self.data, np.asarray(q, dtype=float))
        R = np.array([M.rotation for M in self.data.oMi])
        t = np.array([M.translation for M in self.data.oMi])
        c = np.einsum("gab,gb->ga", R[joint], centre) + t[joint]
        a, b = self._pairs[pairs, 0], self._pairs[pairs, 1]
        return np.sqrt(((c[a] - c[b]) ** 2).sum(axis=1)) - radius[a] - radius[b]

    def colliding_pairs(self, q: Array) -> list[tuple[str, str]]:
        """Names of every colliding geometry pair at q (for diagnostics)."""
        pin.computeCollisions(self.model, self.data, self.geom_model, self.geom_data,
                              np.asarray(q, dtype=float), False)
        out = []
        for k, cr in enumerate(self.geom_data.collisionResults):
            if cr.isCollision():
                p = self.geom_model.collisionPairs[k]
                out.append((self.geom_model.geometryObjects[p.first].name,
                            self.geom_model.geometryObjects[p.second].name))
        return out

    def first_collision(self, path: Array, substeps: int = 100) -> int | None:
        """Index into the densified path of the first colliding configuration, or None.

        The path (T, K) is densified with ``substeps`` configurations interpolated between each
        pair of waypoints (the paper's check: 100), waypoints included. The answer is that of
        checking every densified configuration with :meth:`is_valid`, in order; a collision
        pair is only looked at again once the joint motion since its last coal distance could
        have closed that distance (conservative advancement, see ``advance.py``)."""
        return self.first_collision_dense(densify(path, substeps))

    def first_collision_dense(self, D: Array) -> int | None:
        """Index of the first colliding configuration of the sequence D (N, K), or None:
        :meth:`first_collision` on configurations already interpolated (consecutive rows
        close together, so that the motion bound skips most of them)."""
        D = np.atleast_2d(np.asarray(D, dtype=float))
        if D.shape[1] != self.robot.dof:
            raise RobotError(f"expected a path of shape (T, {self.robot.dof}), got {D.shape}")
        if self._weights is None:  # a joint the motion bound does not cover: one by one
            return self.first_collision_brute(D)
        return first_collision_certified(self.model, self.data, self.geom_model,
                                         self.geom_data, D, *self._weights)

    def first_collision_brute(self, D: Array) -> int | None:
        """Reference: the first configuration of D (N, K) that :meth:`is_valid` rejects."""
        for i, q in enumerate(np.atleast_2d(np.asarray(D, dtype=float))):
            if not self.is_valid(q):
                return i
        return None

    def path_valid(self, path: Array, substeps: int = 100) -> bool:
        """The paper's continuous-time check: every waypoint and ``substeps`` interpolated
        configurations between each pair of waypoints are collision-free."""
        return self.first_collision(path, substeps) is None


def densify(path: Array, substeps: int) -> Array:
    """Waypoints (T, K) with ``substeps`` interpolated configurations between each pair:
    shape ((T - 1) * (substeps + 1) + 1, K)."""
    P = np.atleast_2d(np.asarray(path, dtype=float))
    if len(P) == 1:
        return P
    t = np.arange(substeps + 1) / (substeps + 1)
    seg = P[:-1, None, :] + t[None, :, None] * (P[1:] - P[:-1])[:, None, :]
    return np.vstack([seg.reshape(-1, P.shape[1]), P[-1:]])
