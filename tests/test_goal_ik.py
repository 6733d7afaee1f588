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


def test_full_turn_joints_take_the_turn_nearest_the_start():
    """A joint whose limits span a full turn or more (the Jaco's continuous ones, ±2π) has two
    values for every angle: solutions found from seeds a turn away come back in the turn
    nearest ``near``, the same pose; the Panda's joints (less than a turn) are left alone."""
    from chekhov.robot.description import example_robot_data_dir

    share = example_robot_data_dir()
    kinova = share / "robots/kinova_description"
    robot = Robot.from_urdf(kinova / "robots/kinova.urdf", srdf=kinova / "srdf/kinova.srdf",
                            joints=[f"j2s6s200_joint_{i}" for i in range(1, 7)],
                            ee_frame="j2s6s200_end_effector", package_dirs=[share.parent])
    resolver = GoalResolver(robot, lambda Q: np.ones(len(Q), dtype=bool))
    turns = np.flatnonzero(robot.upper - robot.lower >= 2 * np.pi)
    assert len(turns) == 3
    rng = np.random.default_rng(4)
    far_rows = 0
    for q_goal in robot.sample_uniform(rng, 10):
        q_goal[turns] = rng.uniform(-np.pi, np.pi, len(turns))   # a turn either way is free
        shifted = [q_goal + 2 * np.pi * np.sign(rng.normal()) * (np.arange(6) == j)
                   for j in turns]
        far_rows += len(shifted)
        goal = Goal.pose(robot.compute_ee_pose(q_goal))
        near = q_goal + 0.02
        found = resolver.resolve(goal, n=4, seeds=np.array(shifted), near=near)
        assert len(found) >= 1
        # each full-turn joint within half a turn of near's (another IK branch may differ
        # by up to that: the wrist's flip), none a whole turn away
        assert np.all(np.abs(found.Q[:, turns] - near[turns]) <= np.pi + 1e-9)
        for q in found.Q:
            T_q = robot.compute_ee_pose(q)
            assert np.linalg.norm(T_q[:3, 3] - goal.T_world_ee[:3, 3]) <= goal.position_tolerance
    assert far_rows == 30
    panda = GoalResolver(Robot.load("panda"), lambda Q: np.ones(len(Q), dtype=bool))
    assert not panda._full_turn.any()
