"""Roadmap + TrajOpt: never a colliding answer, shorter than its seed, reacts to a dynamic
obstacle; shortcutting keeps paths valid."""

import numpy as np
import pytest

from chekhov.bench.cases import generate_cases
from chekhov.planners.base import path_length
from chekhov.planners.roadmap_trajopt import RoadmapTrajOpt
from chekhov.planners.shortcut import shortcut_path
from chekhov.roadmap.build import build_roadmap
from chekhov.roadmap.config import RoadmapConfig
from chekhov.scene.model import Shape
from chekhov.world import World

SMALL = RoadmapConfig(n_nodes=150, n_region_nodes=20, n_wrist_nodes=60, seed=3)


@pytest.fixture(scope="module")
def world():
    return World.load("tabletop_pole")  # own world: this module adds a dynamic obstacle


@pytest.fixture(scope="module")
def roadmap(world):
    return build_roadmap(world, SMALL)


@pytest.fixture(scope="module")
def planner(world, roadmap):
    return RoadmapTrajOpt(world, roadmap)


@pytest.fixture(scope="module")
def paper_planner(world, roadmap):
    """The paper's planner: every query seeded from the roadmap."""
    return RoadmapTrajOpt(world, roadmap, straight_line_first=False)


def test_shortcut_is_a_valid_subsequence_and_never_longer(world, planner):
    cases = generate_cases(world, 5, seed=7)
    for i in range(5):
        s = planner.seeder.seed(cases.q_start[i], cases.goal(i))
        if not s.success:
            continue
        short = shortcut_path(world.fast, s.path)
        assert world.fast.path_valid(short)
        assert path_length(short) <= path_length(s.path) + 1e-9
        assert all(any(np.array_equal(q, p) for p in s.path) for q in short)


@pytest.mark.parametrize("which", ["planner", "paper_planner"])
def test_answers_are_exactly_free_and_shorter_than_the_roadmap_seed(world, which, request):
    planner = request.getfixturevalue(which)
    cases = generate_cases(world, 8, seed=11)
    solved = 0
    for i in range(8):
        r = planner.plan(cases.q_start[i], cases.goal(i))
        if not r.success:
            assert r.path is None
            continue
        solved += 1
        assert world.exact.path_valid(r.path, substeps=100)
        np.testing.assert_allclose(r.path[0], cases.q_start[i])
        T = world.robot.compute_ee_pose(r.path[-1])
        assert np.linalg.norm(T[:3, 3] - cases.T_world_ee_goal[i][:3, 3]) < 0.01
        if r.info["seed_kind"] == "roadmap":  # a straight line may need bending out
            assert r.path_length <= path_length(r.info["roadmap_seed"]) + 1e-6
        else:
            assert which == "planner"
    assert solved >= 6


def test_a_dynamic_obstacle_changes_the_answer_and_is_avoided(world, planner):
    cases = generate_cases(world, 10, seed=5)
    for i in range(10):
        before = planner.plan(cases.q_start[i], cases.goal(i))
        if before.success:
            break
    assert before.success
    # a box where the middle of the answer passes (its end-effector position there)
    mid = before.path[len(before.path) // 2]
    T_box = np.eye(4)
    T_box[:3, 3] = world.robot.compute_ee_pose(mid)[:3, 3]
    world.add_obstacle("person_arm", Shape("box", (0.08, 0.08, 0.08)), T_box)
    try:
        after = planner.plan(cases.q_start[i], cases.goal(i))
        if after.success:
            assert not np.array_equal(after.path, before.path)
            assert world.exact.path_valid(after.path, substeps=100)
        else:
            assert after.path is None
    finally:
        world.remove_obstacle("person_arm")


def test_an_exhausted_time_limit_is_a_timeout_not_an_answer(world, paper_planner):
    cases = generate_cases(world, 1, seed=13)
    r = paper_planner.plan(cases.q_start[0], cases.goal(0), time_limit_s=0.0)
    assert not r.success and r.status == "timeout" and r.path is None
    r = paper_planner.plan(cases.q_start[0], cases.goal(0), time_limit_s=30.0)
    assert r.success
