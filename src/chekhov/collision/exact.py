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


class ExactChecker:
    """Exact collision checks with coal on the robot's URDF collision geometry."""

    def __init__(self, robot: Robot, scene: Scene | None = None, static_only: bool = False
                 ) -> None:
        self.robot = robot
        self.model = robot.model
        self.data = robot.model.createData()
        self.geom_model = robot.collision_model.copy()
        self._robot_ngeoms = self.geom_model.ngeoms
        self._radii: dict[int, Array] = {}   # motion bounds of the robot's geometries
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
        self._weights = pair_weights(self.model, gm, np.argwhere(np.triu(M, 1)),
                                     self._radii)

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
        self.geom_model = self._scene_model.copy()
        self._obstacles = dict(self._scene_obstacles)
        for name, (shape, T) in obstacles.items():
            self._add(name, shape, T)
        self._rebuild()

    def move_obstacle(self, name: str, T_world_obj: Array) -> None:
        self.geom_model.geometryObjects[self._obstacles[name]].placement = pin.SE3(
            np.asarray(T_world_obj, dtype=float))
        self.geom_data = pin.GeometryData(self.geom_model)

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
