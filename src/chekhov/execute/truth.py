"""The world as it truly is at each instant (:class:`TrueWorld`): the scene plus an episode's
moving obstacles at their scripted true poses — what the after-the-fact verdict
(:mod:`~chekhov.execute.evaluate`) and the scripts' way-out rules check against, never the
executive's predictions. Units: s, m.
"""

from __future__ import annotations

import coal
import numpy as np
import pinocchio as pin
from numpy.typing import NDArray

from chekhov.collision.exact import ExactChecker, coal_shape
from chekhov.execute.obstacles import MovingObstacle
from chekhov.world import World

Array = NDArray[np.float64]

FAR = np.array([0.0, 0.0, -100.0])
"""m, where an obstacle not present waits (out of every scene)."""


class TrueWorld:
    """The scene plus the episode's moving obstacles at their true poses, for coal."""

    def __init__(self, world: World, moving: tuple[MovingObstacle, ...]) -> None:
        self.robot, self.moving = world.robot, moving
        self.checker = ExactChecker(world.robot, world.scene)
        for m in moving:
            self.checker.add_obstacle(f"true:{m.name}", m.shape, _far())
        self._geoms = [(coal_shape(m.shape), m) for m in moving]
        self._robot_geoms = [(i, self.robot.collision_model.geometryObjects[i])
                             for i in self.robot.moving_geometries]
        self._data = self.robot.model.createData()
        self._gdata = pin.GeometryData(self.robot.collision_model)

    def present(self, t: float) -> bool:
        """Whether any moving obstacle is present at time t (s)."""
        return any(m.present(t) for m in self.moving)

    def at(self, t: float) -> None:
        for m in self.moving:
            self.checker.move_obstacle(f"true:{m.name}", m.pose(t) if m.present(t) else _far())

    def collides(self, q: Array, t: float) -> bool:
        self.at(t)
        return not self.checker.is_valid(q)

    def meets(self, Q: Array, ts: Array, t_first: float | None = None, *,
              while_present: bool = False) -> bool:
        """Whether the motion Q (n, K) rad, at times ts (n,) s, collides at any of them
        (with ``while_present``, only times a moving obstacle is present are checked).
        Every fourth time is checked before the rest, each group nearest ``t_first`` (s; a
        contact expected then; ts[0] by default) first: a motion that collides is mostly
        found out in a few checks (the answer is the same in any order)."""
        idx = np.flatnonzero([self.present(float(t)) for t in ts]) if while_present \
            else np.arange(len(ts))
        t_ref = ts[0] if t_first is None or not len(ts) else t_first
        order = idx[np.lexsort((np.abs(ts[idx] - t_ref), idx % 4 != 0))]
        return any(self.collides(Q[i], float(ts[i])) for i in order)

    def clearance(self, q: Array, t: float) -> float:
        """m, the distance from the robot's moving geometry to the present moving obstacles."""
        present = [(g, m) for g, m in self._geoms if m.present(t)]
        if not present:
            return float("inf")
        pin.updateGeometryPlacements(self.robot.model, self._data, self.robot.collision_model,
                                     self._gdata, np.asarray(q, dtype=float))
        best = float("inf")
        req, res = coal.DistanceRequest(), coal.DistanceResult()
        for g, m in present:
            T = m.pose(t)
            tf_o = coal.Transform3s(T[:3, :3], T[:3, 3])
            for i, go in self._robot_geoms:
                M = self._gdata.oMg[i]
                res.clear()
                d = coal.distance(go.geometry, coal.Transform3s(M.rotation, M.translation),
                                  g, tf_o, req, res)
                best = min(best, float(d))
        return best


def _far() -> Array:
    T = np.eye(4)
    T[:3, 3] = FAR
    return T
