"""One entry object: a scene, its robot at the scene's base pose, and both collision checkers."""

from __future__ import annotations

import math
from collections.abc import Mapping
from functools import cached_property
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from chekhov.collision.exact import ExactChecker
from chekhov.collision.fast import FastChecker
from chekhov.robot.goal_ik import GoalResolver
from chekhov.robot.ik import solve_ik
from chekhov.robot.robot import Robot
from chekhov.scene.io import load_scene
from chekhov.scene.model import Scene, Shape

Array = NDArray[np.float64]


class World:
    """A planning world. ``World.load("shelf_boxes")`` gives the scene, the robot placed as the
    scene says (its base pose and locked joints), a fast checker (planning) and an exact
    checker (validation). ``World(scene, robot)`` plans for any robot (e.g.
    :meth:`Robot.from_urdf`) in any scene; the robot is then used as given."""

    def __init__(self, scene: Scene, robot: Robot | None = None) -> None:
        self.scene = scene
        self.robot = robot if robot is not None else Robot.load(
            scene.robot, scene.base_pose.T if scene.base_pose is not None else None,
            locked=dict(scene.locked_joints))

    @classmethod
    def load(cls, scene: str | Path) -> World:
        """A built-in scene by name, or a scene YAML file."""
        return cls(load_scene(scene))

    @cached_property
    def fast(self) -> FastChecker:
        fast = FastChecker(self.robot, self.scene)
        fast.warm_up()  # compile (or load) its kernels before anyone times a query
        return fast

    @cached_property
    def goal_ik(self) -> GoalResolver:
        """The goal resolver of this world: configurations meeting a goal, collision-free by
        the fast checker (its current obstacles)."""
        resolver = GoalResolver(self.robot, self.fast.valid)
        resolver.warmup()
        return resolver

    @cached_property
    def exact(self) -> ExactChecker:
        return ExactChecker(self.robot, self.scene)

    def add_obstacle(self, name: str, shape: Shape, T_world_obj: Array) -> None:
        """Add a dynamic obstacle to both checkers."""
        self.fast.add_obstacle(name, shape, T_world_obj)
        self.exact.add_obstacle(name, shape, T_world_obj)

    def set_obstacles(self, obstacles: Mapping[str, tuple[Shape, Array]]) -> None:
        """Make ``obstacles`` (name → (shape, T_world_obj (4, 4), m)) the world's dynamic
        obstacles, replacing those added before, in both checkers at once (one rebuild each:
        the way to update many obstacles per sensor frame)."""
        self.fast.set_obstacles(obstacles)
        self.exact.set_obstacles(obstacles)

    def move_obstacle(self, name: str, T_world_obj: Array) -> None:
        self.fast.move_obstacle(name, T_world_obj)
        self.exact.move_obstacle(name, T_world_obj)

    def remove_obstacle(self, name: str) -> None:
        self.fast.remove_obstacle(name)
        self.exact.remove_obstacle(name)

    def is_free(self, q: Array) -> bool:
        """Within limits and collision-free for both checkers."""
        q = self.robot.check_configuration(q)
        return bool(self.robot.within_limits(q)[0] and self.fast.is_valid(q)
                    and self.exact.is_valid(q))

    def solve_ik(self, T_world_ee: Array, n_solutions: int = 1, collision_free: bool = True,
                 rng: np.random.Generator | None = None, deadline: float = math.inf
                 ) -> Array:
        """IK solutions (n, K) for a goal pose; collision-free (fast checker) by default; no
        restart after ``deadline`` (``time.perf_counter()`` value, s)."""
        return solve_ik(self.robot, T_world_ee, n_solutions, rng=rng,
                        accept=self.fast.is_valid if collision_free else None,
                        deadline=deadline)
