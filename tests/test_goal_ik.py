"""The one goal resolver (robot/goal_ik.py): answers checked by pinocchio's forward kinematics
and the exact checker, not by the compiled kinematics that produced them."""

import numpy as np
import pytest

from chekhov import Goal, Robot
from chekhov.robot.goal_ik import GoalIKConfig, GoalResolver, distinct_rows
from chekhov.transforms import rotation_angle


@pytest.fixture(scope="module", params=["tabletop_pole", "panda_table_shelf"])
def world(request, world_of):
    return world_of(request.param)


def _free_poses(world, n: int, seed: int) -> list[np.ndarray]:
    rng = np.random.default_rng(seed)
    Q = world.robot.sample_uniform(rng, 400)
    Q = Q[[world.is_free(q) for q in Q]][:n]
    return [world.robot.compute_ee_pose(q) for q in Q]


def test_pose_goals_resolve_to_free_configurations_that_meet_them(world):
    solved = 0
    for T in _free_poses(world, 12, seed=5):
        goal = Goal.pose(T)
        q_near = world.robot.sample_uniform(np.random.default_rng(9), 1)[0]
        found = world.goal_ik.resolve(goal, n=4, near=q_near)
        if len(found) == 0:
            continue
        solved += 1
        for q in found.Q:
            T_q = world.robot.compute_ee_pose(q)  # pinocchio, not the compiled chain
            assert np.linalg.norm(T_q[:3, 3] - T[:3, 3]) <= goal.position_tolerance
            assert rotation_angle(T_q[:3, :3], T[:3, :3]) <= goal.orientation_tolerance
            assert world.robot.within_limits(q)[0]
        # the fast checker accepted them; they are collision-free for the exact one too
        assert sum(world.exact.is_valid(q) for q in found.Q) >= len(found.Q) - 1
        d = np.linalg.norm(found.Q - q_near, axis=1)
        assert np.all(np.diff(d) >= 0), "sorted by distance to `near`"
        assert np.array_equal(found.nearest(q_near), found.Q[0])
        # deterministic: the same query, the same answer
        again = world.goal_ik.resolve(goal, n=4, near=q_near)
        np.testing.assert_array_equal(again.Q, found.Q)
    assert solved >= 10, f"only {solved} of 12 reachable poses resolved"


def test_unreachable_and_colliding_goals_say_why(world):
    T = np.eye(4)
    T[:3, 3] = world.robot.reach[0] + [5.0, 0.0, 0.0]
    found = world.goal_ik.resolve(Goal.pose(T), n=2)
    assert len(found) == 0 and "reach" in found.reason
    with pytest.raises(Exception, match="reach"):
        found.nearest(np.zeros(world.robot.dof))
    never = GoalResolver(world.robot, lambda Q: np.zeros(len(Q), dtype=bool),
                         GoalIKConfig(random_rounds=1, thorough=False))
    pose = _free_poses(world, 1, seed=6)[0]
    assert len(never.resolve(Goal.pose(pose), n=2)) == 0
    q = world.robot.sample_uniform(np.random.default_rng(3), 1)[0]
    rejected = never.resolve(Goal.configuration(q), n=1)
    assert len(rejected) == 0 and "collision" in rejected.reason


def test_distinct_rows_keeps_order_and_separation():
    Q = np.array([[0.0, 0], [0.05, 0], [0.2, 0], [0.21, 0.01], [1, 1]])
    np.testing.assert_array_equal(distinct_rows(Q, 0.1, 5), Q[[0, 2, 4]])
    np.testing.assert_array_equal(distinct_rows(Q, 0.1, 2), Q[[0, 2]])


def test_a_pose_whose_free_solutions_are_rare_gets_more_restarts():
    """Solutions found but all rejected (in collision) mean the pose is reachable: random
    rounds go on (``obstructed_rounds``) until one is accepted. Here ``valid`` accepts only
    solutions with joint 3 within 0.1 rad of 1.5 rad: the 4 usual rounds find none, the
    further rounds do, and the solution meets the pose and the filter."""
    robot = Robot.load("panda")
    T = robot.compute_ee_pose(np.array([0.3, 0.2, -0.1, -1.8, 0.2, 1.9, 0.5]))

    def rare(Q):
        return np.abs(Q[:, 2] - 1.5) < 0.1

    plain = GoalResolver(robot, rare, GoalIKConfig(obstructed_rounds=0, thorough=False))
    assert len(plain.resolve(Goal.pose(T), n=1)) == 0
    found = GoalResolver(robot, rare, GoalIKConfig(thorough=False)).resolve(Goal.pose(T), n=1)
    assert len(found) == 1 and rare(found.Q).all()
    T_found = robot.compute_ee_pose(found.Q[0])
    assert np.linalg.norm(T_found[:3, 3] - T[:3, 3]) < 1e-3
    assert rotation_angle(T_found[:3, :3], T[:3, :3]) < 1e-2
