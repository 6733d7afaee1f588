"""Completeness under dynamic obstacles (issue 16): the tree repair, Roadmap + TrajOpt falling
back on it when every roadmap route is cut, and the invariant against RRTConnect."""

import sys
import time
from pathlib import Path

import numpy as np
import pytest
from test_roadmap_trajopt import SMALL, check_answer

from chekhov.bench.cases import generate_cases
from chekhov.planners.roadmap_trajopt import RoadmapTrajOpt
from chekhov.planners.status import PlanStatus, Stage
from chekhov.roadmap.build import build_roadmap
from chekhov.roadmap.config import RepairConfig
from chekhov.roadmap.repair import TreeRepair
from chekhov.roadmap.seeder import SeedResult
from chekhov.world import World

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "benchmarks"))
import completeness


@pytest.fixture(scope="module")
def world():
    return World.load("tabletop_pole")


@pytest.fixture(scope="module")
def roadmap(world):
    return build_roadmap(world, SMALL)


def test_the_trees_alone_join_start_and_goal(world, roadmap):
    """No roadmap attachments: RRT-Connect's trees meet; the path's segments are free by the
    fast checker at a quarter of the search's resolution and by coal at 400 substeps."""
    planner = RoadmapTrajOpt(world, roadmap)
    repair = TreeRepair(world, roadmap, planner.seeder.validity, planner.seeder._route_nodes,
                        0.02, RepairConfig(attach_candidates=0))
    cases = generate_cases(world, 6, seed=11)
    for i in range(len(cases)):
        q0, q1 = cases.q_start[i], cases.q_goal[i]
        r = repair.search(q0, q1[None], time.perf_counter() + 5.0)
        assert r.success, r.status
        assert r.info["via"] == "trees"
        np.testing.assert_array_equal(r.path[0], q0)
        np.testing.assert_array_equal(r.path[-1], q1)
        assert world.fast.path_valid(r.path, resolution=0.005)
        assert world.exact.path_valid(r.path, substeps=400)
    again = repair.search(cases.q_start[0], cases.q_goal[0][None], time.perf_counter() + 5.0)
    first = repair.search(cases.q_start[0], cases.q_goal[0][None], time.perf_counter() + 5.0)
    np.testing.assert_array_equal(again.path, first.path)   # seeded: the same answer


def test_roadmap_trajopt_repairs_when_every_route_is_cut(world, roadmap, monkeypatch):
    """The roadmap says no_path (as when obstacles cut every route): the answer comes from
    the repair (a REPAIR stage, seed_from), certified, checked here by other means."""
    planner = RoadmapTrajOpt(world, roadmap)

    def cut(q_start, goal, n_routes, deadline=np.inf, goal_nodes_first=False):
        return [SeedResult(False, "no_path", None, np.empty(0, dtype=np.int64), None,
                           {"total": 0.0}, {})]

    monkeypatch.setattr(planner.seeder, "seeds", cut)
    cases = generate_cases(world, 4, seed=12)
    for i in range(len(cases)):
        r = planner.plan(cases.q_start[i], cases.goal(i), 3.0)
        assert r.success, (r.status, r.info.get("rejected_offers"))
        report = r.stage(Stage.REPAIR)
        assert report is not None and report.status is PlanStatus.SOLVED
        assert r.solutions[0].stage is Stage.SHORTCUT
        assert r.seed_from in (Stage.REPAIR, Stage.STRAIGHT_LINE)
        check_answer(world, r.path, cases.q_start[i], cases.goal(i), brute=i == 0)


@pytest.mark.parametrize("scene,family", [("tabletop_pole", "boxed"),
                                          ("panda_cage", "empty_roadmap"),
                                          ("panda_table_shelf", "dynamic")])
def test_roadmap_trajopt_solves_whatever_rrtconnect_solves(scene, family, tmp_path):
    """The invariant on a sample: the same world, time limit and certification; every case
    RRTConnect (OMPL's, and ours seeded) solves, Roadmap + TrajOpt solves too; no returned
    path collides at 400 substeps. Measured (benchmarks/completeness.py, 5 cases, 1 s): all
    solved by all three."""
    r = completeness.run_family(scene, family, 5, 1.0, 0, tmp_path, SMALL)
    assert r["rrtconnect_only"] == 0 and r["rrtconnect_deterministic_only"] == 0, r
    assert r["roadmap_trajopt_solved"] >= 4, r
    assert r["returned_collisions"] == {"rrtconnect": 0, "rrtconnect_deterministic": 0,
                                        "roadmap_trajopt": 0}, r
