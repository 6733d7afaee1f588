"""Typed outcomes: every plan() call ends with a PlanStatus and reports its stages in order,
each with its status, time and product; the seed's stage is named (``seed_from``)."""

import itertools

import numpy as np
import pytest

from chekhov import (
    Goal,
    OmplPlanner,
    PlanResult,
    PlanStatus,
    SeededTrajOpt,
    Stage,
    TrajOptPlanner,
)
from chekhov.bench.cases import generate_cases
from chekhov.planners.roadmap_trajopt import RoadmapTrajOpt
from chekhov.planners.roadmap_trajopt_config import RoadmapTrajOptConfig
from chekhov.roadmap.build import build_roadmap
from chekhov.roadmap.config import RoadmapConfig

SMALL = RoadmapConfig(n_nodes=150, n_region_nodes=20, n_wrist_nodes=60, seed=3)


@pytest.fixture(scope="module")
def world(world_of):
    return world_of("tabletop_pole")


@pytest.fixture(scope="module")
def cases(world):
    return generate_cases(world, 6, seed=4)


@pytest.fixture(scope="module")
def roadmap(world):
    return build_roadmap(world, SMALL)


def test_a_status_is_an_enum_equal_to_its_string_and_unknown_ones_are_refused():
    r = PlanResult(False, None, "timeout", 0.0)
    assert r.status is PlanStatus.TIMEOUT and r.status == "timeout" and f"{r.status}" == "timeout"
    with pytest.raises(ValueError, match=r"unknown plan status 'seed_timeout'.*solved"):
        PlanResult(False, None, "seed_timeout", 0.0)


def test_the_paper_planner_reports_seed_shortcut_and_optimise(world, cases, roadmap):
    planner = RoadmapTrajOpt(world, roadmap, RoadmapTrajOptConfig(straight_line_first=False))
    solved = 0
    for i in range(len(cases)):
        r = planner.plan(cases.q_start[i], cases.goal(i), 2.0)
        assert isinstance(r.status, PlanStatus)
        if not r.success:
            continue
        solved += 1
        assert r.status is PlanStatus.SOLVED and r.seed_from is Stage.ROADMAP_SEED
        kinds = [s.stage for s in r.stages]
        assert kinds[:2] == [Stage.ROADMAP_SEED, Stage.SHORTCUT], kinds
        assert Stage.OPTIMISE in kinds and Stage.STRAIGHT_LINE not in kinds, kinds
        seed = r.seed_report
        assert seed is not None and seed.status is PlanStatus.SOLVED
        assert np.allclose(seed.path[0], cases.q_start[i])       # the roadmap's own route
        assert all(s.time_s >= 0 for s in r.stages)
        assert sum(s.time_s for s in r.stages) <= r.time_s + 1e-3
    assert solved >= 5


def test_the_default_planner_answers_from_the_roadmap_first(world, cases, roadmap):
    """The first answer is the roadmap route itself (its edges certified when the roadmap
    was built, no dynamic obstacle here), else the shortcut route; a straight-line TrajOpt
    runs only when the shortcut route is longer than ``straight_line_ratio`` times the
    straight line."""
    planner = RoadmapTrajOpt(world, roadmap)
    firsts = []
    for i in range(len(cases)):
        r = planner.plan(cases.q_start[i], cases.goal(i), 2.0)
        assert r.success, r.status
        assert r.stages[0].stage is Stage.ROADMAP_SEED
        firsts.append(r.solutions[0].stage)
        assert r.solutions[0].stage in (Stage.ROADMAP_SEED, Stage.SHORTCUT)
        assert r.seed_from in {Stage.STRAIGHT_LINE, Stage.ROADMAP_SEED}
        if r.stage(Stage.STRAIGHT_LINE) is not None:   # the first answer was long
            line = np.linalg.norm(r.path[-1] - cases.q_start[i])
            assert r.solutions[0].length_rad > line
    assert firsts.count(Stage.ROADMAP_SEED) >= len(cases) // 2, firsts


def test_anytime_solutions_come_in_order_each_certified_and_shorter(world, cases, roadmap):
    """Every solution the planner offers reaches ``on_solution`` at once, in order: later
    ones strictly shorter, each an answer by other means (coal at 400 substeps per segment,
    limits, start, goal), the last one the returned path."""
    from test_roadmap_trajopt import check_answer

    planner = RoadmapTrajOpt(world, roadmap)
    improved = 0
    for i in range(len(cases)):
        heard: list = []
        r = planner.plan(cases.q_start[i], cases.goal(i), 2.0, on_solution=heard.append)
        assert r.success, r.status
        assert heard == list(r.solutions) and len(heard) >= 1
        times = [s.time_s for s in heard]
        lengths = [s.length_rad for s in heard]
        assert times == sorted(times) and all(b < a for a, b in itertools.pairwise(lengths))
        assert r.first_solution_s == times[0] <= r.time_s
        assert np.array_equal(heard[-1].path, r.path)
        for s in heard:
            check_answer(world, s.path, cases.q_start[i], cases.goal(i))
        improved += len(heard) > 1
    assert improved >= 2, "TrajOpt (or another route) should shorten some first answers"


def test_a_planner_that_answers_once_reports_one_solution(world, cases):
    heard: list = []
    r = OmplPlanner(world, "RRTConnect", seed=2).plan(cases.q_start[0], cases.goal(0), 2.0,
                                                      on_solution=heard.append)
    assert r.success and heard == list(r.solutions) and len(heard) == 1
    assert np.array_equal(heard[0].path, r.path) and r.first_solution_s == heard[0].time_s


def test_a_failed_seed_planner_gives_its_own_status_and_stage(world, cases):
    """RRTConnect + TrajOpt with no time for the seed: the answer is the seed planner's
    timeout, reported as the SEED stage's outcome (it used to be the string 'seed_timeout')."""
    planner = SeededTrajOpt(world, OmplPlanner(world, "RRTConnect"))
    r = planner.plan(cases.q_start[0], cases.goal(0), 0.0)   # the seed stage gets 0 s
    assert not r.success and r.status is PlanStatus.TIMEOUT
    assert r.seed_from is Stage.SEED and [s.stage for s in r.stages] == [Stage.SEED]
    assert r.seed_report.status is PlanStatus.TIMEOUT and r.seed_report.path is None


def test_straight_line_trajopt_reports_ik_and_optimise(world, cases):
    r = TrajOptPlanner(world).plan(cases.q_start[1], cases.goal(1), 2.0)
    assert [s.stage for s in r.stages] == [Stage.IK, Stage.STRAIGHT_LINE, Stage.OPTIMISE]
    assert r.seed_from is Stage.STRAIGHT_LINE
    assert r.stages[-1].status is r.status


def test_warmup_plans_once_and_says_how_long(world, roadmap):
    planner = RoadmapTrajOpt(world, roadmap)
    t = planner.warmup(seed=1, time_limit_s=0.5)
    assert 0.0 < t < 10.0


def test_a_seed_that_fails_its_certification_is_a_failure_with_that_reason(world, cases,
                                                                         roadmap):
    """A roadmap 'solved' whose path misses the goal, or leaves the joint limits, with nothing
    to rescue it: the answer is a failure with the failed check's status, never 'solved'."""
    from chekhov.roadmap.seeder import SeedResult

    planner = RoadmapTrajOpt(world, roadmap, RoadmapTrajOptConfig(
        straight_line_first=False, straight_line_fallback=False, shortcut=False,
        simplify_rounds=0, goal_routes=1))
    q0, qg = cases.q_start[0], cases.q_goal[0]
    outside = (q0 + qg) / 2
    outside[3] = world.robot.upper[3] + 0.3
    for path, goal, status in ((np.vstack([q0, q0 + 0.01]), cases.goal(0),
                                PlanStatus.GOAL_UNMET),
                               (np.vstack([q0, outside, qg]), Goal.configuration(qg),
                                PlanStatus.JOINT_LIMITS)):
        planner.seeder.seeds = lambda q, g, n, deadline=np.inf, p=path, **k: [SeedResult(
            True, "solved", p, np.empty(0, dtype=np.int64), p[-1], {"total": 0.0}, {})]
        planner._optimise = lambda *a, **k: False          # no TrajOpt to rescue it
        r = planner.plan(q0, goal, 2.0)
        assert not r.success and r.path is None and r.status is status, r.info


def test_a_candidate_that_fails_its_certification_leaves_the_longer_one_before_it(world,
                                                                                 roadmap):
    """Offers nobody listens to wait, uncertified, and the shortest is certified at the end:
    when it fails (here: a straight line through the pole), the next shortest (a certified
    answer's path, offered again) is certified and answers — not the first answer — and the
    failure is reported with its stage."""
    import time

    from chekhov.planners.anytime import AnytimeRun
    from chekhov.planners.query import PlanQuery

    planner = RoadmapTrajOpt(world, roadmap)
    more = generate_cases(world, 30, seed=4)   # 7 of them with a colliding line (measured)
    for i in range(len(more)):
        q0, qg = more.q_start[i], more.q_goal[i]
        line = np.vstack([q0, qg])
        if world.exact.path_valid(line, substeps=100):
            continue   # a case whose straight line collides
        r = planner.plan(q0, Goal.configuration(qg), 2.0)
        assert r.success and len(r.path) >= 2
        detour = np.vstack([r.path[:2], r.path[:1], r.path])   # the same motions, and more
        run = AnytimeRun(world, PlanQuery(q0, Goal.configuration(qg), 10.0,
                                          time.perf_counter()))
        assert run.offer(detour, Stage.SHORTCUT)               # certified at once
        assert run.offer(r.path, Stage.ROUTES) and run.offer(line, Stage.SIMPLIFY)
        assert len(run.solutions) == 1                         # both wait
        res = run.result(PlanStatus.SOLVED)
        assert res.success and res.solutions[-1].stage is Stage.ROUTES
        np.testing.assert_array_equal(res.path, r.path)
        assert "simplify: collision" in str(res.info["rejected_offers"])
        return
    pytest.fail("no case with a colliding straight line")


def test_no_offer_is_certified_in_the_final_checks_reserve(world, roadmap):
    """An offer whose certification would end within FINAL_CHECK_RESERVE_S of the time limit
    is refused as a timeout (the final check must fit before the limit); the same offer with
    time to spare becomes the answer."""
    import time

    from chekhov.planners.anytime import FINAL_CHECK_RESERVE_S, AnytimeRun
    from chekhov.planners.query import PlanQuery

    cases = generate_cases(world, 10, seed=5)
    q0, qg = cases.q_start[0], cases.q_goal[0]
    r = RoadmapTrajOpt(world, roadmap).plan(q0, Goal.configuration(qg), 2.0)
    assert r.success
    late = AnytimeRun(world, PlanQuery(q0, Goal.configuration(qg), 0.8 * FINAL_CHECK_RESERVE_S,
                                       time.perf_counter()))
    assert not late.offer(r.path, Stage.SHORTCUT) and late.best is None
    assert late.result(PlanStatus.SOLVED).status is PlanStatus.TIMEOUT
    on_time = AnytimeRun(world, PlanQuery(q0, Goal.configuration(qg), 10.0,
                                          time.perf_counter()))
    assert on_time.offer(r.path, Stage.SHORTCUT) and on_time.best is not None


def test_an_improvement_not_certified_in_its_window_leaves_the_answer(world, roadmap):
    """Once there is an answer, an improvement must be certified by the planner's bound
    (``certify_improvements_by``): a shorter path offered after it — heard (``on_solution``)
    or waiting as a candidate — is dropped as a timeout, and the first answer stands; with
    the bound ahead the same path becomes the answer."""
    import time

    from chekhov.planners.anytime import AnytimeRun
    from chekhov.planners.query import PlanQuery

    cases = generate_cases(world, 10, seed=5)
    q0, qg = cases.q_start[0], cases.q_goal[0]
    r = RoadmapTrajOpt(world, roadmap).plan(q0, Goal.configuration(qg), 2.0)
    assert r.success
    detour = np.vstack([r.path[:2], r.path[:1], r.path])   # the same motions, and more
    heard: list[object] = []
    for listener in (None, heard.append):
        for bound_s, answer in ((-1.0, detour), (10.0, r.path)):
            run = AnytimeRun(world, PlanQuery(q0, Goal.configuration(qg), 10.0,
                                              time.perf_counter(), on_solution=listener))
            assert run.offer(detour, Stage.SHORTCUT)            # the answer: certified at once
            run.certify_improvements_by(time.perf_counter() + bound_s)
            run.offer(r.path, Stage.ROUTES)
            res = run.result(PlanStatus.SOLVED)
            assert res.success
            np.testing.assert_array_equal(res.path, answer)
            if bound_s < 0:
                assert "routes: timeout" in str(res.info["rejected_offers"])
