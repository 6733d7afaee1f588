"""Typed outcomes: every plan() call ends with a PlanStatus and reports its stages in order,
each with its status, time and product; the seed's stage is named (``seed_from``)."""

import numpy as np
import pytest

from chekhov import OmplPlanner, PlanResult, PlanStatus, SeededTrajOpt, Stage, TrajOptPlanner
from chekhov.bench.cases import generate_cases
from chekhov.planners.roadmap_trajopt import RoadmapTrajOpt, RoadmapTrajOptConfig
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
        assert kinds[:3] == [Stage.ROADMAP_SEED, Stage.SHORTCUT, Stage.OPTIMISE], kinds
        seed = r.seed_report
        assert seed is not None and seed.status is PlanStatus.SOLVED
        assert np.allclose(seed.path[0], cases.q_start[i])       # the roadmap's own route
        assert all(s.time_s >= 0 for s in r.stages)
        assert sum(s.time_s for s in r.stages) <= r.time_s + 1e-3
    assert solved >= 5


def test_the_default_planner_names_the_straight_line_or_the_roadmap(world, cases, roadmap):
    planner = RoadmapTrajOpt(world, roadmap)
    seen = set()
    for i in range(len(cases)):
        r = planner.plan(cases.q_start[i], cases.goal(i), 2.0)
        assert r.success, r.status
        seen.add(r.seed_from)
        assert r.stages[0].stage in (Stage.STRAIGHT_LINE, Stage.IK)
        if r.seed_from is Stage.STRAIGHT_LINE:
            assert [s.stage for s in r.stages] == [Stage.STRAIGHT_LINE]
            assert r.stages[0].status is PlanStatus.SOLVED
    assert seen <= {Stage.STRAIGHT_LINE, Stage.ROADMAP_SEED, Stage.FALLBACK}


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
