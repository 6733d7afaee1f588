"""Every planner checks its query and has its answer certified in one place: located errors for
malformed input, no success whose path misses the goal, leaves the limits, collides or arrives
after the deadline (issue 13)."""

import time

import numpy as np
import pytest

from chekhov import ChekhovError, Goal, PlanResult, RobotError, World
from chekhov.bench.cases import generate_cases
from chekhov.collision.exact import densify
from chekhov.collision.path_check import exact_path_decision
from chekhov.errors import PlanningInputError
from chekhov.planners.base import PlannerBase
from chekhov.planners.lazy_prm import LazyPRM
from chekhov.planners.ompl_planner import OmplPlanner
from chekhov.planners.query import LIMIT_TOLERANCE_RAD, PlanQuery
from chekhov.planners.roadmap_trajopt import RoadmapTrajOpt
from chekhov.planners.trajopt_planner import SeededTrajOpt, TrajOptPlanner
from chekhov.roadmap.build import build_roadmap
from chekhov.roadmap.config import RoadmapConfig
from chekhov.scene.model import Shape

SMALL = RoadmapConfig(n_nodes=150, n_region_nodes=20, n_wrist_nodes=60, seed=3)


@pytest.fixture(scope="module")
def world():
    return World.load("tabletop_pole")


@pytest.fixture(scope="module")
def cases(world):
    return generate_cases(world, 6, seed=11)


@pytest.fixture(scope="module")
def planners(world):
    roadmap = build_roadmap(world, SMALL)
    return [RoadmapTrajOpt(world, roadmap), TrajOptPlanner(world),
            OmplPlanner(world, "RRTConnect", seed=1), LazyPRM(world, seed=1),
            SeededTrajOpt(world, OmplPlanner(world, "RRTConnect", seed=2))]


def _over(world, q, joint, by):
    q = q.copy()
    q[joint] = world.robot.upper[joint] + by
    return q


@pytest.mark.parametrize("joint, by", [(6, 1.0), (0, 0.3), (3, 0.02)])
def test_goal_configuration_outside_the_limits_is_an_error_for_every_planner(
        world, cases, planners, joint, by):
    q_goal = _over(world, cases.q_goal[0], joint, by)
    for p in planners:
        with pytest.raises(PlanningInputError, match=world.robot.joint_names[joint]):
            p.plan(cases.q_start[0], Goal.configuration(q_goal), 1.0)


@pytest.mark.parametrize("joint, by", [(3, 0.02), (6, 1.0), (0, 0.3), (5, 0.2)])
def test_start_outside_the_limits_is_an_error_for_every_planner(world, cases, planners, joint,
                                                                 by):
    q_start = _over(world, cases.q_start[0], joint, by)
    for p in planners:
        with pytest.raises(PlanningInputError, match="outside its limits"):
            p.plan(q_start, cases.goal(0), 1.0)


def test_a_start_within_the_tolerance_is_clamped_and_said_so(world, cases, planners):
    q_start = cases.q_start[0].copy()
    q_start[1] = world.robot.upper[1] + LIMIT_TOLERANCE_RAD / 2
    r = planners[0].plan(q_start, cases.goal(0), 2.0)
    assert r.info["clamped"] == ("start",)
    if r.success:
        assert world.robot.within_limits(r.path).all()


@pytest.mark.parametrize("n", [6, 8])
def test_wrong_joint_count_names_expected_and_given(world, cases, planners, n):
    q = np.resize(cases.q_start[0], n)
    for p in planners:
        with pytest.raises(PlanningInputError, match=f"expected 7 joint values.*got {n}"):
            p.plan(q, cases.goal(0), 1.0)
        with pytest.raises(PlanningInputError, match="goal configuration"):
            p.plan(cases.q_start[0], Goal.configuration(q), 1.0)


@pytest.mark.parametrize("limit", [float("nan"), -0.001, -1.0, "1", True, None])
def test_time_limit_must_be_a_number_of_seconds(cases, planners, limit):
    for p in planners:
        with pytest.raises(PlanningInputError, match="time_limit_s"):
            p.plan(cases.q_start[0], cases.goal(0), limit)


@pytest.mark.parametrize("field", ["position_tolerance", "orientation_tolerance",
                                   "joint_tolerance"])
@pytest.mark.parametrize("value", [float("nan"), float("inf"), -0.1, True])
def test_goal_tolerances_must_be_finite_and_non_negative(cases, field, value):
    with pytest.raises(RobotError, match=field):
        Goal(T_world_ee=cases.T_world_ee_goal[0], **{field: value})


class _Fixed(PlannerBase):
    """A planner that answers whatever path it is given (to test the certification)."""

    def __init__(self, world, path=None, sleep_s=0.0):
        self.world, self.name, self.path, self.sleep_s = world, "fixed", path, sleep_s

    def _plan(self, query: PlanQuery) -> PlanResult:
        time.sleep(self.sleep_s)
        path = self.path if self.path is not None else np.vstack([query.q_start,
                                                                   query.goal.q])
        return PlanResult(True, path, "solved", 0.0)


def _free_pair(world, cases):
    """A start and goal joined by a free straight motion (checked exactly, densely)."""
    for q0, q1 in zip(cases.q_start, cases.q_goal, strict=True):
        if world.exact.path_valid(np.vstack([q0, q1]), substeps=400):
            return q0, q1
    rng = np.random.default_rng(5)
    for _ in range(2000):
        q0 = world.robot.sample_uniform(rng, 1)[0]
        q1 = q0 + rng.normal(scale=0.05, size=7)
        if world.robot.within_limits(q1)[0] and \
                world.exact.path_valid(np.vstack([q0, q1]), substeps=400):
            return q0, q1
    raise AssertionError("no free short motion found")


def test_certification_accepts_a_free_path_that_meets_the_goal(world, cases):
    q0, q1 = _free_pair(world, cases)
    r = _Fixed(world).plan(q0, Goal.configuration(q1), 1.0)
    assert r.success and r.info["certificate"] == "certified"
    assert "certify" in r.timing_s


def test_certification_rejects_a_path_that_misses_the_goal(world, cases):
    q0, q1 = _free_pair(world, cases)
    short = np.vstack([q0, q0 + 0.5 * (q1 - q0)])
    r = _Fixed(world, short).plan(q0, Goal.configuration(q1), 1.0)
    assert not r.success and r.status == "goal_unmet" and r.path is None
    assert r.info["rejected_path"] is short
    T = world.robot.compute_ee_pose(q1)
    T[:3, 3] += 0.01   # 10 mm off, tolerance 5 mm
    r = _Fixed(world, np.vstack([q0, q1])).plan(q0, Goal.pose(T), 1.0)
    assert r.status == "goal_unmet" and "mm" in str(r.info["certificate"])


def test_certification_rejects_limits_start_and_collisions(world, cases):
    q0, q1 = _free_pair(world, cases)
    goal = Goal.configuration(q1)
    outside = np.vstack([q0, _over(world, q0, 2, 0.1), q1])
    assert _Fixed(world, outside).plan(q0, goal, 1.0).status == "joint_limits"
    elsewhere = np.vstack([q1, q1])
    assert _Fixed(world, elsewhere).plan(q0, goal, 1.0).status == "start_mismatch"
    assert _Fixed(world, np.vstack([q0, [np.nan] * 7])).plan(q0, goal, 1.0).status == \
        "bad_path"
    # a small ball on the arm halfway (at one of its joints), where both ends are free
    placed = False
    for p in world.robot.compute_joint_placements(0.5 * (q0 + q1))[::-1]:
        T = np.eye(4)
        T[:3, 3] = p[:3, 3]
        world.add_obstacle("block", Shape("sphere", (0.03,)), T)
        if world.exact.is_valid(q0) and world.exact.is_valid(q1):
            placed = True
            break
        world.remove_obstacle("block")
    assert placed
    try:
        assert not world.exact.path_valid(np.vstack([q0, q1]), substeps=400)
        assert _Fixed(world).plan(q0, goal, 1.0).status == "collision"
    finally:
        world.remove_obstacle("block")


def test_a_path_found_after_the_deadline_is_a_timeout(world, cases):
    q0, q1 = _free_pair(world, cases)
    r = _Fixed(world, sleep_s=0.03).plan(q0, Goal.configuration(q1), 0.01)
    assert not r.success and r.status == "timeout" and r.time_s > 0.01


def test_ends_in_collision_are_reported_for_every_planner(world, cases, planners):
    q0, q1 = cases.q_start[0], cases.q_goal[0]
    T = np.eye(4)
    T[:3, 3] = world.robot.compute_ee_pose(q1)[:3, 3]
    world.add_obstacle("on_goal", Shape("sphere", (0.08,)), T)
    try:
        assert not world.exact.is_valid(q1)
        for p in planners:
            assert p.plan(q0, Goal.configuration(q1), 1.0).status == "invalid_goal"
    finally:
        world.remove_obstacle("on_goal")


def test_every_planner_answer_is_certified(world, cases, planners):
    """Real planners on real cases: each success meets the goal, the limits and an exact
    check at 400 substeps (denser than the certification's 100); at least half succeed."""
    solved = 0
    for p in planners:
        for i in range(3):
            r = p.plan(cases.q_start[i], cases.goal(i), 2.0)
            if not r.success:
                continue
            solved += 1
            assert r.info["certificate"] == "certified"
            assert np.allclose(r.path[0], cases.q_start[i], atol=1e-6)
            assert world.robot.within_limits(r.path).all()
            T = world.robot.compute_ee_pose(r.path[-1])
            assert np.linalg.norm(T[:3, 3] - cases.T_world_ee_goal[i][:3, 3]) <= 0.005 + 1e-6
            assert world.exact.path_valid(r.path, substeps=400)
    assert solved >= 8, solved


def test_exact_path_decision_matches_the_exact_checker(world):
    """The fast-screened decision equals coal on every densified configuration, on random
    short paths of which some collide; resuming the fast walk at ``start`` finds the same
    alarm as a brute-force scan from there."""
    rng = np.random.default_rng(7)
    both = 0
    for _ in range(40):
        q0 = world.robot.sample_uniform(rng, 1)[0]
        P = np.clip(q0 + np.cumsum(rng.normal(scale=0.15, size=(4, 7)), axis=0),
                    world.robot.lower, world.robot.upper)
        P = np.vstack([q0, P])
        D = densify(P, 20)
        ref = bool(world.exact.valid(D).all())
        valid, cert = exact_path_decision(world.fast, world.exact, P, 20)
        assert valid == ref and (cert is not None) == ref
        both += ref
        flagged = np.flatnonzero(~world.fast.valid(D))
        start = int(rng.integers(0, len(D)))
        later = flagged[flagged >= start]
        got = world.fast.first_dense_collision(P, 20, start=start)
        assert got == (int(later[0]) if len(later) else None)
    assert 5 <= both <= 35, both


def test_a_certificate_covers_only_its_path_and_world(world, cases):
    q0, q1 = _free_pair(world, cases)
    P = np.vstack([q0, q1])
    valid, cert = exact_path_decision(world.fast, world.exact, P, 100)
    assert valid and cert is not None and cert.covers(P, 100, world.fast)
    assert not cert.covers(P + 1e-9, 100, world.fast)
    assert not cert.covers(P, 50, world.fast)
    T_far = np.eye(4)
    T_far[:3, 3] = [5.0, 0.0, 0.0]   # far from the robot: only the version changes
    world.add_obstacle("far", Shape("sphere", (0.01,)), T_far)
    try:
        assert not cert.covers(P, 100, world.fast)
    finally:
        world.remove_obstacle("far")


def test_a_certified_path_is_known_by_the_path_it_resampled(world, cases):
    """check_path's certificate names the path it resampled: the same path passes again on
    the certificate alone (the final check of an anytime answer), another path or world
    does not, and a certificate that does not cover a path gets no say."""
    from chekhov.planners.certify import check_path
    from chekhov.planners.query import make_query

    q0, q1 = _free_pair(world, cases)
    P = np.vstack([q0, 0.5 * (q0 + q1), q1])
    query = make_query(world.robot, q0, Goal.configuration(q1), 10.0)
    why, cert = check_path(world, query, P)
    assert why is None and cert is not None and cert.covers_resampled(P, 100, world.fast)
    assert not cert.covers_resampled(P[[0, 2]], 100, world.fast)
    why_again, same = check_path(world, query, P, cert)
    assert why_again is None and same is cert
    T_far = np.eye(4)
    T_far[:3, 3] = [5.0, 0.0, 0.0]
    world.add_obstacle("far", Shape("sphere", (0.01,)), T_far)
    try:
        assert not cert.covers_resampled(P, 100, world.fast)
    finally:
        world.remove_obstacle("far")
    # the start is still checked with a certificate
    moved = make_query(world.robot, q1, Goal.configuration(q1), 10.0)
    assert check_path(world, moved, P, cert)[0] is not None


def test_errors_are_chekhov_errors():
    assert issubclass(PlanningInputError, ChekhovError)
