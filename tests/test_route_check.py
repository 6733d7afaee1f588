"""A route's certificate composed from its roadmap edges' (``collision.route_check``): the same
verdict and certificate as the whole path's decision, checked densely by coal too; the cells
at the nodes decided; trusted only in the world the roadmap was built for; the planner's
first answer the route itself; roadmap files whose edges passed another check rebuilt."""

from dataclasses import replace

import numpy as np
import pytest

from chekhov.bench.cases import generate_cases
from chekhov.collision.exact import densify
from chekhov.collision.path_check import CERTIFICATION_ID, cells_free, exact_path_decision
from chekhov.collision.route_check import route_decision
from chekhov.paths import resample_path
from chekhov.planners.roadmap_trajopt import RoadmapTrajOpt
from chekhov.planners.roadmap_trajopt_config import RoadmapTrajOptConfig
from chekhov.planners.status import Stage
from chekhov.roadmap.build import build_roadmap
from chekhov.roadmap.config import RoadmapConfig
from chekhov.roadmap.io import load_or_build_roadmap, save_roadmap
from chekhov.roadmap.seeder import RoadmapSeeder
from chekhov.scene.model import Shape

SMALL = RoadmapConfig(n_nodes=300, n_region_nodes=20, n_wrist_nodes=60, seed=3)


@pytest.fixture(scope="module")
def world(world_of):
    return world_of("shelf_boxes")


@pytest.fixture(scope="module")
def roadmap(world):
    return build_roadmap(world, SMALL)


@pytest.fixture(scope="module")
def seeder(world, roadmap):
    return RoadmapSeeder(world, roadmap)


def _routes(world, seeder, n):
    cases = generate_cases(world, n, seed=5, family="tasks")
    out = []
    for i in range(len(cases)):
        s = seeder.seeds(cases.q_start[i], cases.goal(i), 1)[0]
        if s.path is not None:
            out.append(s)
    return out


def test_the_roadmap_records_the_check_its_edges_passed(roadmap):
    assert roadmap.meta.notes["edges_certified_by"] == CERTIFICATION_ID


def test_a_routes_composed_decision_is_the_whole_paths(world, seeder):
    """On the shelf's task routes (into the levels, between the boxes): the decision that
    leaves the certified edges out agrees with the whole resampled path's, certificate
    included, and coal finds every configuration at 4x the substeps free."""
    world.set_obstacles({})
    composed = 0
    for s in _routes(world, seeder, 20):
        known = seeder.certified_segments(s.path, s.node_path)
        assert known.shape == (len(s.path) - 1,)
        composed += bool(known.any())
        mine = route_decision(world.fast, world.exact, s.path, known)
        D = resample_path(s.path, 0.16)
        whole = exact_path_decision(world.fast, world.exact, D, 100)
        assert mine.valid == whole.valid
        if mine.valid:
            assert mine.certificate.digest == whole.certificate.digest
            assert world.exact.valid(densify(D, 400)).all()
    assert composed >= 10


def test_runs_passed_before_are_not_decided_again_until_the_obstacles_change(
        world, seeder, monkeypatch):
    """With ``PassedRuns`` a route's unknown runs that passed are skipped the next time (the
    same verdict and certificate), and decided again once the obstacles changed."""
    import chekhov.collision.route_check as rc
    world.set_obstacles({})
    routes = [(s.path, seeder.certified_segments(s.path, s.node_path))
              for s in _routes(world, seeder, 8)]
    routes = [(p, k) for p, k in routes if k.any() and not k.all()]
    assert len(routes) >= 4
    decided = []
    real = rc.exact_path_decision
    monkeypatch.setattr(rc, "exact_path_decision",
                        lambda *a, **kw: decided.append(1) or real(*a, **kw))
    passed = rc.PassedRuns()
    first = [route_decision(world.fast, world.exact, p, k, passed=passed) for p, k in routes]
    n_first = len(decided)
    assert n_first >= len(routes)
    again = [route_decision(world.fast, world.exact, p, k, passed=passed) for p, k in routes]
    assert len(decided) == n_first + sum(d.valid is not True for d in first)
    for a, b in zip(first, again, strict=True):
        assert a.valid == b.valid
        if a.valid:
            assert a.certificate.digest == b.certificate.digest
    far = np.eye(4)
    far[:3, 3] = (5.0, 5.0, 5.0)
    world.set_obstacles({"far": (Shape("sphere", (0.05,)), far)})
    world.set_obstacles({})
    route_decision(world.fast, world.exact, *routes[0], passed=passed)
    assert len(decided) > n_first + sum(d.valid is not True for d in first)


def test_the_cells_at_known_segments_ends_are_decided(world, seeder):
    """Segments falsely marked known around a waypoint that is in collision: the waypoint's
    cell is still decided, so the path fails; unmarked, the runs' own decisions fail it."""
    world.set_obstacles({})
    s = next(r for r in _routes(world, seeder, 10) if len(r.path) >= 4)
    P = s.path.copy()
    k = len(P) // 2
    # an obstacle on the end effector at waypoint k
    T = world.robot.compute_ee_pose(P[k])
    world.set_obstacles({"probe": (Shape("sphere", (0.03,)), T)})
    try:
        assert not world.exact.is_valid(P[k])
        known = np.zeros(len(P) - 1, dtype=bool)
        known[k - 1] = known[k] = True
        assert route_decision(world.fast, world.exact, P, known).valid is False
        assert route_decision(world.fast, world.exact, P, ~known).valid is False
        assert route_decision(world.fast, world.exact, P, np.zeros_like(known)).valid is False
    finally:
        world.set_obstacles({})


def test_edges_are_trusted_only_in_the_world_they_were_certified_in(world, roadmap, seeder):
    world.set_obstacles({})
    s = next(r for r in _routes(world, seeder, 10) if len(r.node_path) >= 2)
    assert seeder.certified_segments(s.path, s.node_path).any()
    far = np.eye(4)
    far[:3, 3] = (5.0, 5.0, 5.0)          # a dynamic obstacle nowhere near the arm
    world.set_obstacles({"far": (Shape("sphere", (0.05,)), far)})
    try:
        assert not seeder.certified_segments(s.path, s.node_path).any()
    finally:
        world.set_obstacles({})
    other_check = replace(roadmap, meta=replace(roadmap.meta, notes={
        **roadmap.meta.notes, "edges_certified_by": "an older check"}))
    assert not RoadmapSeeder(world, other_check).certified_segments(s.path, s.node_path).any()
    shifted = s.path.copy()
    shifted[1:-1] += 1e-9                 # not the nodes bit for bit
    assert not seeder.certified_segments(shifted, s.node_path).any()


def test_the_planners_first_answer_is_the_route_itself(world, roadmap):
    """With no dynamic obstacle the first certified answer is the roadmap route (then
    improved), ending at a roadmap node of the goal pose when it has one (a pre-grasp node:
    no goal connection to check); with one it is the shortcut route, checked whole; so it is
    without improvements."""
    world.set_obstacles({})
    planner = RoadmapTrajOpt(world, roadmap)
    cases = generate_cases(world, 8, seed=7, family="tasks")
    firsts, at_node = [], 0
    for i in range(len(cases)):
        heard = []
        r = planner.plan(cases.q_start[i], cases.goal(i), 2.0, on_solution=heard.append)
        if r.success:
            firsts.append(heard[0].stage)
            assert r.path_length <= heard[0].length_rad + 1e-9
            nodes = planner.seeder.goal_nodes(cases.goal(i))
            if len(nodes) and heard[0].stage is Stage.ROADMAP_SEED:
                assert any(np.array_equal(heard[0].path[-1], q) for q in roadmap.nodes[nodes])
                at_node += 1
    assert len(firsts) >= 6 and firsts.count(Stage.ROADMAP_SEED) >= len(firsts) - 1
    assert at_node >= 3
    far = np.eye(4)
    far[:3, 3] = (5.0, 5.0, 5.0)
    world.set_obstacles({"far": (Shape("sphere", (0.05,)), far)})
    try:
        r = planner.plan(cases.q_start[0], cases.goal(0), 2.0)
        assert r.success and r.solutions[0].stage is not Stage.ROADMAP_SEED
    finally:
        world.set_obstacles({})
    # a planner that does not improve (the executive's) answers with the shortcut route
    quick = RoadmapTrajOpt(world, roadmap, RoadmapTrajOptConfig(improve_time_s=0.0))
    r = quick.plan(cases.q_start[0], cases.goal(0), 2.0)
    assert r.success and [s.stage for s in r.solutions] == [Stage.SHORTCUT]
    assert "route_check" not in r.timing_s


def test_a_roadmap_file_certified_by_another_check_is_rebuilt(world, roadmap, tmp_path):
    path = tmp_path / "shelf.npz"
    older = replace(roadmap, meta=replace(roadmap.meta, notes={
        **roadmap.meta.notes, "edges_certified_by": "an older check"}))
    save_roadmap(older, path)
    said = []
    again = load_or_build_roadmap(world, SMALL, path, progress=said.append)
    assert any("another certification" in m for m in said), said
    assert again.meta.notes["edges_certified_by"] == CERTIFICATION_ID
    assert load_or_build_roadmap(world, SMALL, path).meta.created == again.meta.created


def test_cells_decided_together_as_each_alone(world, rng):
    """cells_free (one screen of all the middle samples with the largest cell's margins, a
    cell's own decision where it alarms) against each cell's own decision, on cells of random
    free configurations (some near the shelf) and with one colliding cell among them."""
    world.set_obstacles({})
    Q = world.robot.sample_uniform(rng, 400)
    Q = Q[world.fast.valid(Q)][:60]
    step = rng.normal(size=(len(Q), 2, Q.shape[1])) * 0.0016 / np.sqrt(Q.shape[1])
    cells = np.stack([Q - step[:, 0], Q, Q + step[:, 1]], axis=1)
    alone = [exact_path_decision(world.fast, world.exact, c, 0).valid for c in cells]
    assert cells_free(world.fast, world.exact, cells) is all(alone)
    free = cells[np.array(alone, dtype=bool)]
    assert len(free) >= 50 and cells_free(world.fast, world.exact, free) is True
    Qs = world.robot.sample_uniform(rng, 400)
    hit = Qs[~world.exact.valid(Qs)][0]
    bad = np.concatenate([free[:10], np.stack([hit, hit, hit])[None], free[10:20]])
    assert cells_free(world.fast, world.exact, bad) is False
