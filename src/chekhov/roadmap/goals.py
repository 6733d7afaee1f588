"""A roadmap's view of a pose goal: :class:`RoadmapGoals` — the goal's IK solutions, seeded from
the nodes whose end-effector poses are nearest and remembered while the obstacles stay, and
the nodes that already are configurations of the goal (a pre-grasp node for its pose)."""

from __future__ import annotations

import math
import time

import numpy as np
from numpy.typing import NDArray

from chekhov.roadmap.graph import Roadmap
from chekhov.roadmap.memo import ObstacleMemo
from chekhov.roadmap.nearest import NearestNodes, nearest_poses
from chekhov.roadmap.validity import RoadmapValidity
from chekhov.robot.goal import Goal
from chekhov.robot.goal_ik import GoalConfigurations, GoalIKConfig, GoalResolver, distinct_rows
from chekhov.transforms import rotation_angle
from chekhov.world import World

Array = NDArray[np.float64]
IntArray = NDArray[np.int64]

GOAL_NODE_POSITION_M = 1e-4
GOAL_NODE_ROTATION_RAD = 1e-3
"""m and rad: a roadmap node whose end effector is this near a pose goal is one of the goal's
configurations (:meth:`RoadmapGoals.nodes`): the goal resolver's IK calls a seed
converged at these errors (``ChainKinematics.solve``'s defaults), and the roadmap's
pre-grasp nodes are such solutions of their poses."""
GOAL_NODE_CANDIDATES = 8
"""Nodes nearest a pose goal (position, then rotation) looked at for goal nodes."""
GOAL_SETS_KEPT = 16
"""Goal resolver answers remembered by :meth:`RoadmapGoals.configurations`, at most: a
query asks the same ones for its first answer, its routes and its straight line."""

NEAR_IK_SOLUTIONS = 6
"""IK solutions of a pose goal sought from the configuration it is asked ``near`` (and a random
batch) besides the roadmap-seeded ones: :meth:`RoadmapGoals.configurations` keeps the
nearest. The roadmap-seeded nearest was 1.2 rad (shelf_boxes) and 0.9 rad (kitchen) farther
from the start, at the median, than where straight-line TrajOpt ended on the task cases it
solved. Roadmap + TrajOpt, 40 task cases a scene (case seed 3), old then new code: mean path
length -3.3% to -9.6% in all six scenes (shelf_boxes 4.53 -> 4.10 rad, kitchen 5.16 -> 4.71,
panda_cage 3.50 -> 3.38), mean plan time +1.4 to +6.2 ms (+0.6 to +3 ms when alternated in one
process); random cases -3% (kitchen) and -9% (panda_cage). With 2 solutions instead of 6: half
the gain. Not for a first answer to improve on (``seeds(goal_nodes_first=True)``): there it
had cost every query without goal nodes 0.5-0.8 ms (1262edd)."""


class RoadmapGoals:
    """Pose goals against one roadmap in one world. ``ik_seeds``: nodes the goal resolver
    starts from (at least n for n solutions); ``same_robot``: the roadmap's stored poses are
    this robot's (else no node is taken for a goal's)."""

    def __init__(self, world: World, roadmap: Roadmap, validity: RoadmapValidity,
                 ik: GoalIKConfig, ik_seeds: int, *, same_robot: bool) -> None:
        self.roadmap = roadmap
        self.validity = validity
        self.ik_seeds = ik_seeds
        self.same_robot = same_robot
        self.goal_ik = GoalResolver(world.robot, world.fast.valid, ik)
        self.memo: ObstacleMemo[GoalConfigurations] = ObstacleMemo(world.fast, GOAL_SETS_KEPT)
        self._ee_position = NearestNodes(roadmap.ee_position)
        self._ee_rotation = np.ascontiguousarray(roadmap.ee_rotation, dtype=np.float64)

    def configurations(self, T_world_ee: Array, n: int, deadline: float = math.inf,
                       near: Array | None = None, *, from_near: bool = True
                       ) -> tuple[Array, str]:
        """Up to n distinct collision-free IK solutions (n, K) of a goal pose (the goal
        resolver, seeded from the roadmap nodes whose end-effector poses are nearest; random
        restart rounds only before ``deadline``, a perf_counter value), sorted by distance to
        ``near`` when given — with ``from_near``, also those found from ``near`` itself and a
        random batch (:data:`NEAR_IK_SOLUTIONS`); (empty, reason) on failure."""
        T = np.asarray(T_world_ee, dtype=float)
        found = self._resolve(T, n, near, deadline, seeded=True)
        if near is None or not from_near:
            return found.Q, found.reason
        # the solutions the IK finds from near itself and a random batch (as straight-line
        # TrajOpt's goal): the roadmap-seeded ones lie by the nodes nearest the pose, often
        # on a branch of the arm far from near
        local = self._resolve(T, NEAR_IK_SOLUTIONS, near, deadline, seeded=False)
        Q = np.vstack([found.Q, local.Q])
        Q = distinct_rows(Q[np.argsort(np.linalg.norm(Q - near, axis=1), kind="stable")],
                          self.goal_ik.config.min_separation, n)
        return Q, "" if len(Q) else found.reason

    def _resolve(self, T: Array, n: int, near: Array | None, deadline: float,
                 seeded: bool) -> GoalConfigurations:
        """The goal resolver's answer for pose T — ``seeded`` from the roadmap nodes whose
        end-effector poses are nearest — remembered while the obstacles stay: it is
        deterministic (its own seeded random rounds; the seeds a function of T and n), so
        the same question in the same world has the same answer, unless ``deadline`` cut it
        short (not kept)."""
        key = (T.tobytes(), n, seeded,
               None if near is None else np.asarray(near, dtype=float).tobytes())
        kept = self.memo.get(key)
        if kept is not None:
            return kept
        seeds = None
        if seeded:   # the 4·n_seeds nearest end-effector positions, by position (m) + 0.2 · angle
            n_seeds = max(self.ik_seeds, n)
            seeds = self.roadmap.nodes[nearest_poses(self._ee_position, self._ee_rotation, T,
                                                     4 * n_seeds, n_seeds)]
        found = self.goal_ik.resolve(Goal.pose(T), n=n, seeds=seeds, near=near,
                                     deadline=deadline)
        if time.perf_counter() < deadline:   # no round was skipped
            found.Q.setflags(write=False)
            self.memo.put(key, found)
        return found

    def nodes(self, goal: Goal, near: Array | None = None) -> IntArray:
        """Roadmap nodes that are configurations of the pose ``goal``: their end effector within
        :data:`GOAL_NODE_POSITION_M` and :data:`GOAL_NODE_ROTATION_RAD` of it (and of the goal's
        own tolerances), valid in the world now; nearest ``near`` (K,) first. A pre-grasp node
        is one for its object's pre-grasp pose (the paper's premise: the workspace is a limited
        set of pre-grasp poses, and the roadmap holds them), and a route ending there needs
        neither a goal connection nor a check of one. None when the roadmap was built for
        another version of the robot (its stored poses could be another arm's)."""
        if not goal.is_pose or self.roadmap.n_nodes == 0 or not self.same_robot:
            return np.empty(0, dtype=np.int64)
        assert goal.T_world_ee is not None
        T = np.asarray(goal.T_world_ee, dtype=float)
        k = min(GOAL_NODE_CANDIDATES, self.roadmap.n_nodes)
        idx = nearest_poses(self._ee_position, self._ee_rotation, T, k, k)
        dp = np.linalg.norm(self.roadmap.ee_position[idx] - T[:3, 3], axis=1)
        idx = idx[dp <= min(GOAL_NODE_POSITION_M, goal.position_tolerance)]
        # the angles only of those near enough (none, for most poses not a pre-grasp)
        da = np.array([rotation_angle(self._ee_rotation[i], T[:3, :3]) for i in idx])
        idx = idx[da <= min(GOAL_NODE_ROTATION_RAD, goal.orientation_tolerance)]
        self.validity.refresh()
        idx = idx[self.validity.nodes_valid(idx)]
        if near is not None and len(idx) > 1:
            idx = idx[np.argsort(np.linalg.norm(self.roadmap.nodes[idx] - near, axis=1),
                                 kind="stable")]
        return idx
